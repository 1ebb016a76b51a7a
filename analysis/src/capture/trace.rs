//! From a followed bus log to the detector's trace: the time base, the set velocity (from the
//! set-points in the capture, or from the actual values where there are none) and the columns.

use super::follow::{BusLog, BusSample, DecodeOptions, Object, PdoConfig};
use crate::detector::AxisTrace;
use crate::windows::{
    set_velocity_from_actual, set_velocity_from_demand, set_velocity_from_speed, ACTUAL_SPAN_S,
    DEMAND_SPAN_S,
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

/// How a capture's samples are placed in time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeBase {
    /// At the time stamp of the SYNC each sample answers (the kernel time of the frame): a
    /// drive on its own clock (a real drive, `run` without `--lockstep`) samples when the SYNC
    /// comes, so late and lost SYNCs are where they happened.
    Stamps,
    /// Sample k at k times the SYNC period: a drive whose clock is the SYNC count (`run
    /// --lockstep`) advances one period per SYNC however late it comes.
    SyncCount,
}

impl TimeBase {
    pub fn as_str(self) -> &'static str {
        match self {
            TimeBase::Stamps => "stamps",
            TimeBase::SyncCount => "sync-count",
        }
    }
}

impl std::str::FromStr for TimeBase {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "stamps" => Ok(TimeBase::Stamps),
            "sync-count" => Ok(TimeBase::SyncCount),
            _ => Err(format!(
                "`{s}`: the time base is auto, stamps or sync-count"
            )),
        }
    }
}

/// An interval counts as telling the time bases apart when it differs from the median SYNC
/// interval by this share or more.
pub const INFORMATIVE_SPREAD: f64 = 0.3;
/// Telling intervals needed to choose by the test.
pub const MIN_INFORMATIVE: usize = 5;
/// Moving: the local median position increment is at least this many user units per SYNC.
pub const MIN_STEP_UU: f64 = 2.0;

/// Which clock the axis moves on, from the capture itself: at constant speed a drive on its
/// own clock moves by `v x interval` between two SYNCs, a drive clocked by the SYNC count by
/// `v x period` however long the interval was. Over the intervals that differ from the median
/// by [`INFORMATIVE_SPREAD`] or more while the axis moves steadily (the 17 increments around
/// agree within half their median), the increment over the local median increment (r) is
/// regressed on the interval over the median interval (s): a slope
/// near 1 says the time stamps, near 0 the SYNC count; the base is the nearer of the two
/// (slope 0.5 or more: the stamps). Returns the base and why.
pub fn choose_time_base(stamps_s: &[f64], position: &[f64]) -> (TimeBase, String) {
    let n = stamps_s.len().min(position.len());
    let d_t: Vec<f64> = stamps_s[..n].windows(2).map(|w| w[1] - w[0]).collect();
    let d_x: Vec<f64> = position[..n].windows(2).map(|w| w[1] - w[0]).collect();
    let period = {
        let mut v: Vec<f64> = d_t.iter().copied().filter(|d| *d > 0.0).collect();
        if v.is_empty() {
            return (
                TimeBase::SyncCount,
                "sample k at k x the SYNC period (fewer than two SYNC time stamps)".into(),
            );
        }
        let mid = v.len() / 2;
        *v.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    let mut pairs: Vec<(f64, f64)> = Vec::new();
    let mut buf = [0.0f64; 17];
    for i in 0..d_x.len() {
        let s = d_t[i] / period;
        if (s - 1.0).abs() < INFORMATIVE_SPREAD {
            continue;
        }
        let (a, b) = (i.saturating_sub(8), (i + 9).min(d_x.len()));
        let w = &mut buf[..b - a];
        w.copy_from_slice(&d_x[a..b]);
        w.sort_unstable_by(f64::total_cmp);
        let step = w[w.len() / 2];
        // Moving steadily: the increments around agree (their median absolute deviation at
        // most half the step); an axis at rest that hunts in its gap tells nothing.
        for x in w.iter_mut() {
            *x = (*x - step).abs();
        }
        w.sort_unstable_by(f64::total_cmp);
        let spread = w[w.len() / 2];
        if step.abs() < MIN_STEP_UU || spread > 0.5 * step.abs() {
            continue;
        }
        // An answer taken for the wrong SYNC gives a ratio far off either line: clipped.
        pairs.push((s.min(5.0), (d_x[i] / step).clamp(-1.0, 5.0)));
    }
    let telling = pairs.len();
    let slope = {
        let m = telling.max(1) as f64;
        let (ms, mr) = pairs
            .iter()
            .fold((0.0, 0.0), |(a, b), (s, r)| (a + s / m, b + r / m));
        let (sxx, sxy) = pairs.iter().fold((0.0, 0.0), |(a, b), (s, r)| {
            (a + (s - ms) * (s - ms), b + (s - ms) * (r - mr))
        });
        if sxx > 0.0 {
            sxy / sxx
        } else {
            f64::NAN
        }
    };
    // Too few telling intervals to fit a line: said so, not "a slope of NaN".
    let slope_text = if slope.is_finite() {
        format!("the increments grow with the interval by a slope of {slope:.2}")
    } else {
        "too few of them, or all alike, to fit how the increments grow with the interval"
            .to_string()
    };
    let said = format!(
        "{telling} SYNC intervals off the median {:.3} ms by {:.0} % or more while the axis \
         moved; {slope_text} (slope 1: the time stamps, 0: the SYNC count)",
        period * 1e3,
        INFORMATIVE_SPREAD * 100.0
    );
    if telling < MIN_INFORMATIVE || !slope.is_finite() {
        (
            TimeBase::SyncCount,
            format!(
                "sample k at k x the SYNC period: the SYNCs came evenly enough that both \
                 bases agree; {said}"
            ),
        )
    } else if slope >= 0.5 {
        (
            TimeBase::Stamps,
            format!(
                "the SYNC time stamps of the capture: the axis moves on the bus's clock (a \
                 drive on its own clock); {said}"
            ),
        )
    } else {
        (
            TimeBase::SyncCount,
            format!(
                "sample k at k x the SYNC period: the axis moves one period per SYNC whatever \
                 the time between them (a drive clocked by SYNC, lock-step); {said}"
            ),
        )
    }
}

impl BusLog {
    /// Whether an object was decoded at least once.
    pub fn seen(&self, o: Object) -> bool {
        self.seen[o.slot()]
    }

    /// Time of sample k of a drive clocked by SYNC: k times its period per SYNC
    /// ([`BusLog::lockstep_period_us`]), s.
    pub fn t_s(&self, k: usize) -> f64 {
        k as f64 * f64::from(self.lockstep_period_us) * 1e-6
    }

    /// The SYNC time stamps, s, from the first one.
    pub fn stamps_s(&self) -> Vec<f64> {
        let t0 = self.sync_t_us.first().copied().unwrap_or(0);
        self.sync_t_us
            .iter()
            .map(|t| (t - t0) as f64 * 1e-6)
            .collect()
    }

    /// The actual position per row, uu, and which object it comes from: 0x6064, else
    /// 0x60E4 sub 1, else the integral of 0x606C; None when the log holds none of them.
    fn actual_position_series(
        &self,
        rows: &[BusSample],
        t: &[f64],
    ) -> Option<(Vec<f64>, &'static str)> {
        if self.seen(Object::Position) {
            Some((
                rows.iter().map(|s| f64::from(s.position_uu)).collect(),
                "0x6064 position actual",
            ))
        } else if self.seen(Object::DirectPosition) {
            Some((
                rows.iter()
                    .map(|s| f64::from(s.direct_position_uu))
                    .collect(),
                "0x60E4 sub 1 direct encoder",
            ))
        } else if self.seen(Object::Velocity) {
            let mut x = 0.0;
            Some((
                rows.iter()
                    .enumerate()
                    .map(|(k, s)| {
                        let dt = if k > 0 { t[k] - t[k - 1] } else { 0.0 };
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

    /// The set velocity per row (`rows` at times `t`, s), uu/s, and where it came from; an
    /// error ([`MissingObjects`]) when the log holds neither a set-point nor an actual
    /// position or speed to derive it from.
    ///
    /// Per row, by the mode in force: CSP (8) with a target position: from the 0x607A
    /// targets ([`set_velocity_from_demand`]); CSV or PV (9, 3) with a target velocity:
    /// 0x60FF (received in an RPDO or written over SDO); any other mode (a PP move, whose
    /// profile is the drive's), an unknown mode, or a mode without its set-point: from the
    /// actual values ([`set_velocity_from_actual`] of 0x6064, or of 0x60E4 sub 1, or of the
    /// integral of 0x606C), the paper's criterion applied to what the axis did.
    fn set_velocity_uu_s(&self, rows: &[BusSample], t: &[f64]) -> Result<(Vec<f64>, String)> {
        use drive_protocol::cia402::mode::value::{
            CSP as MODE_CSP, CSV as MODE_CSV, PV as MODE_PV,
        };
        let n = rows.len();
        let mut last = 0.0;
        let targets_held: Vec<f64> = rows
            .iter()
            .map(|s| {
                if let Some(p) = s.target_position_uu {
                    last = f64::from(p);
                }
                last
            })
            .collect();
        let from_targets = set_velocity_from_demand(t, &targets_held, DEMAND_SPAN_S);
        // Without a set-point: the drive's own speed 0x606C where the capture has it (needs no
        // clock), else the actual position.
        let actual = if self.seen(Object::Velocity) {
            Some((
                rows.iter()
                    .map(|s| f64::from(s.velocity_uu_s))
                    .collect::<Vec<_>>(),
                "0x606C velocity actual, averaged",
            ))
        } else {
            self.actual_position_series(rows, t)
        };
        let from_actual = actual.as_ref().map(|(x, what)| {
            if what.starts_with("0x606C") {
                set_velocity_from_speed(t, x)
            } else {
                set_velocity_from_actual(t, x)
            }
        });
        let (mut csp, mut csv, mut act) = (0usize, 0usize, 0usize);
        let mut out = Vec::with_capacity(n);
        for (k, (s, v_csp)) in rows.iter().zip(from_targets).enumerate() {
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

    /// The position set-point per row (`rows` at times `t`, s) as the master sent it, uu: the
    /// CSP target in force, or the integral of the CSV/PV target velocity; NaN where neither
    /// is in force (PP, an unknown mode).
    fn set_position_uu(&self, rows: &[BusSample], t: &[f64]) -> Vec<f64> {
        use drive_protocol::cia402::mode::value::{
            CSP as MODE_CSP, CSV as MODE_CSV, PV as MODE_PV,
        };
        let mut x = f64::NAN;
        rows.iter()
            .enumerate()
            .map(|(k, s)| {
                let dt = if k > 0 { t[k] - t[k - 1] } else { 0.0 };
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

    /// The detector's trace (user units: um or mdeg, velocities in uu/s, current in per mille),
    /// on the time base the capture shows ([`choose_time_base`]).
    /// Err([`MissingObjects`]) when the log lacks what the detector needs.
    pub fn to_axis_trace(&self, rotary: bool) -> Result<AxisTrace> {
        self.to_axis_trace_on(rotary, None)
    }

    /// [`BusLog::to_axis_trace`] on a given time base (None: chosen by
    /// [`choose_time_base`], or the SYNC count when the period was given on the command
    /// line). One row per SYNC ([`BusLog::rows`]: its set-points and the drive's answer to
    /// it); on the time stamps, SYNCs the drive never answered are left out.
    pub fn to_axis_trace_on(&self, rotary: bool, base: Option<TimeBase>) -> Result<AxisTrace> {
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
        let all_stamps = self.stamps_s();
        let (answered_rows, answered_stamps): (Vec<BusSample>, Vec<f64>) = self
            .rows
            .iter()
            .zip(&all_stamps)
            .zip(&self.answered)
            .filter(|(_, a)| **a)
            .map(|((r, t), _)| (*r, *t))
            .unzip();
        let stamps = &answered_stamps;
        let position: Vec<f64> = answered_rows
            .iter()
            .map(|s| {
                if self.seen(Object::DirectPosition) && !self.seen(Object::Position) {
                    f64::from(s.direct_position_uu)
                } else {
                    f64::from(s.position_uu)
                }
            })
            .collect();
        let (base, time_base) = match base {
            Some(b) => (b, format!("{}: as asked (--time-base)", b.as_str())),
            None if self.period_source == super::follow::PeriodSource::CommandLine => (
                TimeBase::SyncCount,
                format!("sample k at k x {} us (--sync-period-us)", self.period_us),
            ),
            None => {
                let (b, why) = choose_time_base(stamps, &position);
                match b {
                    TimeBase::SyncCount => (
                        b,
                        format!(
                            "{why}; period {} us per SYNC ({})",
                            self.lockstep_period_us, self.lockstep_period_source
                        ),
                    ),
                    TimeBase::Stamps => (b, why),
                }
            }
        };
        let (rows, t): (Vec<BusSample>, Vec<f64>) = match base {
            TimeBase::Stamps => (answered_rows, answered_stamps),
            TimeBase::SyncCount => (
                self.rows.clone(),
                (0..self.rows.len()).map(|k| self.t_s(k)).collect(),
            ),
        };
        let (set_velocity, source) = self.set_velocity_uu_s(&rows, &t)?;
        let set_position = self.set_position_uu(&rows, &t);
        let col = |f: fn(&BusSample) -> f64| rows.iter().map(f).collect::<Vec<f64>>();
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
            t_s: t,
            set_velocity,
            motor_velocity: col(|s| f64::from(s.velocity_uu_s)),
            current: col(|s| f64::from(s.current_permille)),
            motor_position,
            direct_position,
            position_unit: if rotary { "mdeg" } else { "um" }.into(),
            current_unit: "permille".into(),
            set_velocity_source: source,
            set_position,
            time_base,
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

/// Read a candump log and build the detector's trace for node `node_id`, whose PDO
/// configuration after reset is `defaults` (the emulator's `trace_from_candump` takes them from
/// its drive); `rotary`: rotary units.
pub fn trace_from_candump_with(
    path: &Path,
    text: &str,
    node_id: u8,
    defaults: PdoConfig,
    sync_period_us: Option<u32>,
    rotary: bool,
) -> Result<(AxisTrace, BusLog)> {
    let log = super::follow::decode(
        text,
        &path.display().to_string(),
        &DecodeOptions {
            node_id,
            defaults,
            sync_period_us,
        },
    )?;
    let tr = log.to_axis_trace(rotary)?;
    Ok((tr, log))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cruise at 10 units per ms sampled at SYNCs due every 4 ms, a fifth of them 2 ms late:
    /// positions of a drive on its own clock (moving with the stamps) or clocked by the SYNC
    /// count (one period per SYNC), with +-2 units of limit cycle on top.
    fn cruise(own_clock: bool) -> (Vec<f64>, Vec<f64>) {
        let (mut t, mut x) = (Vec::new(), Vec::new());
        for k in 0..500u32 {
            let late = if k % 5 == 3 { 2.0 } else { 0.0 };
            let tk = 4.0 * f64::from(k) + late;
            let drive_t = if own_clock { tk } else { 4.0 * f64::from(k) };
            t.push(tk * 1e-3);
            x.push(10.0 * drive_t + 2.0 * (0.11 * drive_t).sin());
        }
        (t, x)
    }

    #[test]
    fn the_axis_tells_which_clock_it_moves_on() {
        let (t, x) = cruise(true);
        let (base, why) = choose_time_base(&t, &x);
        assert_eq!(base, TimeBase::Stamps, "{why}");
        let (t, x) = cruise(false);
        let (base, why) = choose_time_base(&t, &x);
        assert_eq!(base, TimeBase::SyncCount, "{why}");
        assert!(why.contains("lock-step"), "{why}");
        // Even SYNCs: nothing tells, and nothing needs to.
        let t: Vec<f64> = (0..500).map(|k| f64::from(k) * 4e-3).collect();
        let x: Vec<f64> = t.iter().map(|t| 1e4 * t).collect();
        let (base, why) = choose_time_base(&t, &x);
        assert_eq!(base, TimeBase::SyncCount);
        assert!(why.contains("both bases agree"), "{why}");
        // At standstill neither can be told either.
        let (t, _) = cruise(true);
        let (_, why) = choose_time_base(&t, &vec![5.0; t.len()]);
        assert!(why.contains("both bases agree"), "{why}");
        // Even SYNCs and a short log: no slope to fit, and no "NaN" said.
        let t: Vec<f64> = (0..20).map(|k| f64::from(k) * 4e-3).collect();
        let x: Vec<f64> = t.iter().map(|t| 1e4 * t).collect();
        let (_, why) = choose_time_base(&t, &x);
        assert!(!why.contains("NaN") && why.contains("too few"), "{why}");
    }
}
