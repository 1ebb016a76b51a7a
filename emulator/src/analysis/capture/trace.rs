//! From a followed bus log to the detector's trace: the time base, the set velocity (from the
//! set-points in the capture, or from the actual values where there are none) and the columns.

use super::follow::{BusLog, BusSample, DecodeOptions, Object, PdoConfig};
use crate::analysis::detector::AxisTrace;
use crate::analysis::windows::{
    set_velocity_from_actual, set_velocity_from_demand, ACTUAL_SPAN_S, DEMAND_SPAN_S,
};
use anyhow::Result;

/// The capture lacks an object the detector needs: the verdict is inconclusive (not an error
/// in the input), with this text as the reason.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MissingObjects(pub String);

impl std::fmt::Display for MissingObjects {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for MissingObjects {}
use std::fmt::Write as _;
use std::path::Path;

impl BusLog {
    /// Whether an object was decoded at least once.
    pub fn seen(&self, o: Object) -> bool {
        self.seen[o.slot()]
    }

    /// Time of sample k, s.
    pub fn t_s(&self, k: usize) -> f64 {
        k as f64 * f64::from(self.period_us) * 1e-6
    }

    /// The CSP targets as a demand series, uu (holding the last one where a sample has none).
    fn csp_targets_held(&self) -> Vec<f64> {
        let mut last = 0.0;
        self.samples
            .iter()
            .map(|s| {
                if let Some(t) = s.target_position_uu {
                    last = f64::from(t);
                }
                last
            })
            .collect()
    }

    /// The actual position per sample, uu, and which object it comes from: 0x6064, else
    /// 0x60E4 sub 1, else the integral of 0x606C; None when the log holds none of them.
    fn actual_position_series(&self) -> Option<(Vec<f64>, &'static str)> {
        if self.seen(Object::Position) {
            Some((
                self.samples
                    .iter()
                    .map(|s| f64::from(s.position_uu))
                    .collect(),
                "0x6064 position actual",
            ))
        } else if self.seen(Object::DirectPosition) {
            Some((
                self.samples
                    .iter()
                    .map(|s| f64::from(s.direct_position_uu))
                    .collect(),
                "0x60E4 sub 1 direct encoder",
            ))
        } else if self.seen(Object::Velocity) {
            let dt = f64::from(self.period_us) * 1e-6;
            let mut x = 0.0;
            Some((
                self.samples
                    .iter()
                    .map(|s| {
                        x += f64::from(s.velocity_uu_s) * dt;
                        x
                    })
                    .collect(),
                "the integral of 0x606C velocity actual",
            ))
        } else {
            None
        }
    }

    /// Why no set velocity can be had: neither a set-point nor an actual position or speed.
    fn no_set_velocity_source(&self) -> MissingObjects {
        let seen = |o: Object| {
            if self.seen(o) {
                "seen"
            } else {
                "not in the log"
            }
        };
        MissingObjects(format!(
            "{}: node {}: no set-point and no actual position or speed: needs {} in CSP [{}], \
             or {} in CSV or PV [{}], or {} / {} to derive the set speed from",
            self.source,
            self.node_id,
            Object::TargetPosition.name(),
            seen(Object::TargetPosition),
            Object::TargetVelocity.name(),
            seen(Object::TargetVelocity),
            Object::Position.name(),
            Object::Velocity.name(),
        ))
    }

    /// The set velocity per sample, uu/s, and where it came from; an error
    /// ([`MissingObjects`]) when the log holds neither a set-point nor an actual position or
    /// speed to derive it from.
    ///
    /// Per sample, by the mode in force: CSP (8) with a target position: from the 0x607A
    /// targets ([`set_velocity_from_demand`]); CSV or PV (9, 3) with a target velocity:
    /// 0x60FF (received in an RPDO or written over SDO); any other mode (a PP move, whose
    /// profile is the drive's), an unknown mode, or a mode without its set-point: from the
    /// actual values ([`set_velocity_from_actual`] of 0x6064, or of 0x60E4 sub 1, or of the
    /// integral of 0x606C), the paper's criterion applied to what the axis did.
    pub fn set_velocity_uu_s(&self) -> Result<(Vec<f64>, String)> {
        use crate::master::{MODE_CSP, MODE_CSV, MODE_PV};
        let n = self.samples.len();
        let t: Vec<f64> = (0..n).map(|k| self.t_s(k)).collect();
        let from_targets = set_velocity_from_demand(&t, &self.csp_targets_held(), DEMAND_SPAN_S);
        let actual = self.actual_position_series();
        let from_actual = actual
            .as_ref()
            .map(|(x, _)| set_velocity_from_actual(&t, x));
        let (mut csp, mut csv, mut act) = (0usize, 0usize, 0usize);
        let mut out = Vec::with_capacity(n);
        for (k, (s, v_csp)) in self.samples.iter().zip(from_targets).enumerate() {
            let v = match (s.mode, s.target_position_uu, s.target_velocity_uu_s) {
                (Some(MODE_CSP), Some(_), _) => {
                    csp += 1;
                    v_csp
                }
                (Some(MODE_CSV | MODE_PV), _, Some(v)) => {
                    csv += 1;
                    f64::from(v)
                }
                _ => match &from_actual {
                    Some(a) => {
                        act += 1;
                        a[k]
                    }
                    None => 0.0,
                },
            };
            out.push(v);
        }
        if csp == 0 && csv == 0 && act == 0 {
            return Err(self.no_set_velocity_source().into());
        }
        let via = |o: Object| match (
            self.stats.pdo_setpoints > 0,
            self.stats.sdo_setpoint_writes > 0,
        ) {
            (true, true) => format!("{} (RPDO and SDO)", o.name()),
            (false, true) => format!("{} (written over SDO)", o.name()),
            _ => format!("{} (RPDO)", o.name()),
        };
        let pct = |c: usize| 100.0 * c as f64 / n.max(1) as f64;
        let mut parts = Vec::new();
        if csp > 0 {
            parts.push(format!(
                "CSP targets {} in {:.0} % of samples",
                via(Object::TargetPosition),
                pct(csp)
            ));
        }
        if csv > 0 {
            parts.push(format!(
                "CSV/PV {} in {:.0} %",
                via(Object::TargetVelocity),
                pct(csv)
            ));
        }
        if act > 0 {
            parts.push(format!(
                "actual values ({}, constant over {} s; no set-point in force: PP or unknown mode) in {:.0} %",
                actual.as_ref().map_or("", |a| a.1),
                ACTUAL_SPAN_S,
                pct(act)
            ));
        }
        Ok((out, parts.join("; ")))
    }

    /// The position set-point per sample as the master sent it, uu: the CSP target in force,
    /// or the integral of the CSV/PV target velocity; NaN where neither is in force (PP, an
    /// unknown mode).
    pub fn set_position_uu(&self) -> Vec<f64> {
        use crate::master::{MODE_CSP, MODE_CSV, MODE_PV};
        let dt = f64::from(self.period_us) * 1e-6;
        let mut x = f64::NAN;
        self.samples
            .iter()
            .map(|s| {
                x = match (s.mode, s.target_position_uu, s.target_velocity_uu_s) {
                    (Some(MODE_CSP), Some(p), _) => f64::from(p),
                    (Some(MODE_CSV | MODE_PV), _, Some(v)) => {
                        (if x.is_finite() { x } else { 0.0 }) + f64::from(v) * dt
                    }
                    _ => f64::NAN,
                };
                x
            })
            .collect()
    }

    /// The detector's trace (user units: um or mdeg, velocities in uu/s, current in per mille).
    /// Err([`MissingObjects`]) when the log lacks what the detector needs.
    pub fn to_axis_trace(&self, rotary: bool) -> Result<AxisTrace> {
        if !self.seen(Object::Velocity) {
            let mut missing = vec![Object::Velocity.name()];
            if !self.seen(Object::Current) {
                missing.push(Object::Current.name());
            }
            let decoded: Vec<&str> = Object::ALL
                .iter()
                .filter(|o| self.seen(**o))
                .map(|o| o.name())
                .collect();
            return Err(MissingObjects(format!(
                "{}: node {}: {} never in a PDO of the log (decoded: {}); the detector needs the \
                 motor speed (and current): map them into a TPDO",
                self.source,
                self.node_id,
                missing.join(" and "),
                if decoded.is_empty() {
                    "nothing".to_string()
                } else {
                    decoded.join(", ")
                }
            ))
            .into());
        }
        let (set_velocity, source) = self.set_velocity_uu_s()?;
        let set_position = self.set_position_uu();
        let col = |f: fn(&BusSample) -> f64| self.samples.iter().map(f).collect::<Vec<f64>>();
        let position = col(|s| f64::from(s.position_uu));
        let direct = col(|s| f64::from(s.direct_position_uu));
        let (motor_position, direct_position) = match (
            self.seen(Object::Position),
            self.seen(Object::DirectPosition),
        ) {
            (true, true) | (false, false) => (position, direct),
            (true, false) => (position.clone(), position),
            (false, true) => (direct.clone(), direct),
        };
        let tr = AxisTrace {
            t_s: (0..self.samples.len()).map(|k| self.t_s(k)).collect(),
            set_velocity,
            motor_velocity: col(|s| f64::from(s.velocity_uu_s)),
            current: col(|s| f64::from(s.current_permille)),
            motor_position,
            direct_position,
            position_unit: if rotary { "mdeg" } else { "um" }.into(),
            current_unit: "permille".into(),
            set_velocity_source: source,
            set_position,
        };
        tr.check()
            .map_err(|e| anyhow::anyhow!("{}: {e}", self.source))?;
        Ok(tr)
    }

    /// One paragraph for the terminal: what was in the log and what was decoded.
    pub fn summary(&self) -> String {
        let s = &self.stats;
        let mut out = format!(
            "candump: {} lines, {} frames; node {}: {} frames ({} PDOs decoded, {} PDO \
             configuration writes followed, {} SDO aborts, {} NMT resets); {} SYNCs -> {} \
             samples every {} us ({}); {} frames of other COB-IDs; skipped {} RTR, {} error, {} \
             extended-ID, {} CAN FD frames",
            s.lines,
            s.frames,
            self.node_id,
            s.node_frames,
            s.pdos_decoded,
            s.pdo_config_writes,
            s.sdo_writes_aborted,
            s.nmt_resets,
            s.syncs,
            self.samples.len(),
            self.period_us,
            self.period_source.as_str(),
            s.unknown_frames,
            s.remote_frames,
            s.error_frames,
            s.extended_frames,
            s.fd_frames
        );
        for n in &self.notes {
            let _ = write!(out, "\n  note: {n}");
        }
        out
    }
}

/// Read a candump log and build the detector's trace for node `node_id` of our drive with
/// `preset`. `rotary` forces rotary units; the preset decides otherwise.
pub fn trace_from_candump(
    path: &Path,
    text: &str,
    node_id: u8,
    preset: &str,
    sync_period_us: Option<u32>,
    rotary: bool,
) -> Result<(AxisTrace, BusLog)> {
    let (defaults, preset_rotary) = PdoConfig::drive_defaults(node_id, preset)?;
    let log = super::follow::decode(
        text,
        &path.display().to_string(),
        &DecodeOptions {
            node_id,
            defaults,
            sync_period_us,
        },
    )?;
    let tr = log.to_axis_trace(rotary || preset_rotary)?;
    Ok((tr, log))
}
