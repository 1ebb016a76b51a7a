//! The trace the backlash detector reads ([`AxisTrace`]): one axis' set velocity, motor
//! velocity, current and positions on one time base, from a sample log, a trace file or a
//! capture. Below the detector and its gap estimate, which both read it.

use crate::samples::{Sample, SampleSource};

/// A trace as the detector needs it. Positions in one unit `u` (um for a linear axis, mdeg for a
/// rotary one: the master's user units), velocities in u/s, current in any unit (per mille of
/// rated current for the master's log, A for the simulator's trace).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AxisTrace {
    pub t_s: Vec<f64>,
    pub set_velocity: Vec<f64>,
    pub motor_velocity: Vec<f64>,
    pub current: Vec<f64>,
    pub motor_position: Vec<f64>,
    pub direct_position: Vec<f64>,
    /// Unit names for reports, e.g. ("um", "permille").
    pub position_unit: String,
    pub current_unit: String,
    /// Where `set_velocity` came from, for the report (e.g. "0x607A target position (CSP,
    /// RPDO)"); empty: "set velocity column".
    pub set_velocity_source: String,
    /// The position set-point per sample as the master sent it (CSP targets, the integral of
    /// CSV/PV target velocities, a demand column), position unit, with its jitter, gaps and
    /// duplicates; NaN where none is in force; empty when the trace has none. Used to find
    /// constant speed on average where the set-points jitter, and to tell a line the
    /// set-point forces from the axis's own.
    pub set_position: Vec<f64>,
    /// How `t_s` was had, for the report (a capture: its SYNC time stamps or the SYNC count,
    /// and why); empty: the trace's time column.
    pub time_base: String,
}

impl AxisTrace {
    pub fn len(&self) -> usize {
        self.t_s.len()
    }
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }
    /// Check that every column has the same length.
    pub fn check(&self) -> Result<(), String> {
        let n = self.t_s.len();
        for (name, c) in [
            ("set_velocity", &self.set_velocity),
            ("motor_velocity", &self.motor_velocity),
            ("current", &self.current),
            ("motor_position", &self.motor_position),
            ("direct_position", &self.direct_position),
        ] {
            if c.len() != n {
                return Err(format!(
                    "column {name} has {} samples, time has {n}",
                    c.len()
                ));
            }
        }
        if !self.set_position.is_empty() && self.set_position.len() != n {
            return Err(format!(
                "column set_position has {} samples, time has {n}",
                self.set_position.len()
            ));
        }
        Ok(())
    }
}

impl AxisTrace {
    /// From the simulator's trace (`analysis::Trace`, axis units mm or deg): positions to user
    /// units (um / mdeg), set velocity from the set-point, motor velocity from the motor
    /// speed (rpm) scaled by the kinematic ratio estimated from the motor-encoder position.
    pub fn from_sim(
        t_s: &[f64],
        setpoint: &[f64],
        motor_position: &[f64],
        direct_position: &[f64],
        motor_rpm: &[f64],
        current_a: &[f64],
        rotary: bool,
    ) -> Self {
        let n = t_s.len();
        let uu = |v: &[f64]| v.iter().map(|x| x * 1000.0).collect::<Vec<_>>();
        let deriv = |x: &[f64]| {
            let mut d = vec![0.0; n];
            for i in 1..n {
                let dt = t_s[i] - t_s[i - 1];
                d[i] = if dt > 0.0 {
                    (x[i] - x[i - 1]) / dt
                } else {
                    d[i - 1]
                };
            }
            if n > 1 {
                d[0] = d[1];
            }
            d
        };
        let motor_position = uu(motor_position);
        let set_position = uu(setpoint);
        let set_velocity: Vec<f64> = deriv(&set_position)
            .into_iter()
            // The set-point is stored with finite precision: round the noise away so constant
            // segments are exactly constant.
            .map(|v| (v * 1e3).round() / 1e3)
            .collect();
        let mv = deriv(&motor_position);
        let (sa, sb): (f64, f64) = mv
            .iter()
            .zip(motor_rpm)
            .filter(|(_, r)| r.abs() > 1e-9)
            .fold((0.0, 0.0), |(a, b), (v, r)| (a + v * r, b + r * r));
        let k = if sb > 0.0 { sa / sb } else { 0.0 };
        Self {
            t_s: t_s.to_vec(),
            set_velocity,
            motor_velocity: motor_rpm.iter().map(|r| r * k).collect(),
            current: current_a.to_vec(),
            motor_position,
            direct_position: uu(direct_position),
            position_unit: if rotary { "mdeg" } else { "um" }.into(),
            current_unit: "A".into(),
            set_velocity_source: "derivative of the position set-point".into(),
            set_position,
            time_base: String::new(),
        }
    }

    /// From a sample log (user units, per mille current), read by who wrote it: the set
    /// velocity is the master's interpolator velocity ([`SampleSource::Master`]). A drive has
    /// none to report in a position mode (its 0x606B is the position controller's output,
    /// which carries the limit cycle), so for [`SampleSource::Drive`] (`run --trace`, live
    /// scenarios: the emulator's `runtime::trace::node_sample`) it is derived from the position
    /// demand `target_uu` (0x6062); in a velocity mode (CSV, PV: mode display 9 or 3) 0x606B is
    /// the commanded velocity itself (0x60FF, or PV's ramp), and the set position its integral.
    pub fn from_sample_log(samples: &[Sample], source: SampleSource, rotary: bool) -> Self {
        Self::from_sample_rows(samples.len(), |k| samples[k], source, rotary)
    }

    /// [`AxisTrace::from_sample_log`] of `n` samples that `row` gives by index (`analyze`
    /// reads a CSV sample log by columns, without a copy of it as samples).
    pub fn from_sample_rows(
        n: usize,
        row: impl Fn(usize) -> Sample,
        source: SampleSource,
        rotary: bool,
    ) -> Self {
        let t_s: Vec<f64> = (0..n).map(|k| row(k).t_s).collect();
        let demand: Vec<f64> = (0..n).map(|k| row(k).target_uu).collect();
        let (set_velocity, set_position, set_velocity_source) = match source {
            SampleSource::Master => (
                (0..n).map(|k| row(k).setpoint_velocity_uu_s).collect(),
                demand,
                "the master's interpolator velocity".to_string(),
            ),
            SampleSource::Drive => {
                let from_demand = crate::windows::set_velocity_from_demand(
                    &t_s,
                    &demand,
                    crate::windows::DEMAND_SPAN_S,
                );
                drop(demand);
                let velocity_mode = |s: &Sample| matches!(s.mode_display, 3 | 9);
                let (mut v, mut sp) = (Vec::with_capacity(n), Vec::new());
                let mut x = f64::NAN;
                let mut any_velocity_mode = false;
                for k in 0..n {
                    let s = row(k);
                    if velocity_mode(&s) {
                        any_velocity_mode = true;
                        let dt = if k > 0 { t_s[k] - t_s[k - 1] } else { 0.0 };
                        x = if x.is_finite() { x } else { s.target_uu }
                            + s.setpoint_velocity_uu_s * dt;
                        v.push(s.setpoint_velocity_uu_s);
                        sp.push(x);
                    } else {
                        x = f64::NAN;
                        v.push(from_demand[k]);
                        sp.push(s.target_uu);
                    }
                }
                let text = if any_velocity_mode {
                    "position demand 0x6062; in CSV/PV velocity demand 0x606B"
                } else {
                    "position demand 0x6062"
                };
                (v, sp, text.to_string())
            }
        };
        Self {
            t_s,
            set_velocity,
            motor_velocity: (0..n).map(|k| f64::from(row(k).velocity_uu_s)).collect(),
            current: (0..n).map(|k| f64::from(row(k).current_permille)).collect(),
            motor_position: (0..n).map(|k| f64::from(row(k).position_uu)).collect(),
            direct_position: (0..n)
                .map(|k| f64::from(row(k).direct_position_uu))
                .collect(),
            position_unit: if rotary { "mdeg" } else { "um" }.into(),
            current_unit: "permille".into(),
            set_velocity_source,
            set_position,
            time_base: String::new(),
        }
    }
}
