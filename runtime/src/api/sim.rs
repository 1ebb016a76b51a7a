//! [`SimRequest`]: a preset axis run offline at constant velocity (`drive-emu sim`,
//! `drive_emu.sim`).

use std::sync::atomic::AtomicBool;

use super::ApiError;
use crate::analysis::{constant_velocity_run_until, RunError, RunOptions, RunResult};
use crate::presets::AxisConfig;

/// Default of [`SimRequest::max_memory_mb`] (`--max-memory-mb`): about an hour of samples at a
/// 1 ms position cycle.
pub const DEFAULT_MAX_MEMORY_MB: f64 = 512.0;
/// Default of [`SimRequest::duration_s`] (`--duration`).
pub const DEFAULT_DURATION_S: f64 = 5.0;
/// Bytes kept per sample (nine f64 columns of the trace).
const BYTES_PER_SAMPLE: f64 = 9.0 * 8.0;
/// Bytes per CSV row of `--trace`, about.
const CSV_BYTES_PER_SAMPLE: f64 = 110.0;
/// Largest |velocity| accepted, axis units/s: a feed axis above 1000 mm/s (60 m/min) or a
/// table above 1000 deg/s is beyond any of the presets' motors.
const MAX_VELOCITY: f64 = 1000.0;

/// A constant-velocity run of a preset axis. Velocities are in axis units: mm/s on a linear
/// axis, deg/s on a rotary one. Messages name the fields as the command line's flags.
#[derive(Debug, Clone, PartialEq)]
pub struct SimRequest {
    /// Preset name (cnc1 ... cnc5); default cnc1.
    pub preset: String,
    /// Preset overrides, `key=value` (`--set`).
    pub sets: Vec<String>,
    /// Constant velocity, axis units/s (`--velocity`; no default).
    pub velocity_per_s: f64,
    /// Simulated duration, s (`--duration`, default 5).
    pub duration_s: f64,
    /// Start-ramp acceleration, axis units/s^2 (`--accel`; 0: reach the velocity in 0.1 s).
    pub accel_per_s2: f64,
    /// Start disturbance: load velocity change, axis units/s (`--kick`; default 0.6 x
    /// velocity, 0 = none).
    pub kick_per_s: Option<f64>,
    /// Memory cap for the samples the run keeps, MB (`--max-memory-mb`): a run needing more
    /// is refused before it starts.
    pub max_memory_mb: f64,
    /// Keep the full trace (every position cycle); false: the analysis window's only.
    pub record: bool,
    /// The caller writes the trace as CSV (`--trace FILE`): the memory cap's message says
    /// how large that file would be.
    pub trace_csv: bool,
}

impl Default for SimRequest {
    /// The command line's defaults, at velocity 0 (to be set: a run at rest is refused by
    /// nothing, but measures nothing).
    fn default() -> Self {
        Self {
            preset: "cnc1".into(),
            sets: Vec::new(),
            velocity_per_s: 0.0,
            duration_s: DEFAULT_DURATION_S,
            accel_per_s2: 0.0,
            kick_per_s: None,
            max_memory_mb: DEFAULT_MAX_MEMORY_MB,
            record: false,
            trace_csv: false,
        }
    }
}

impl SimRequest {
    /// A run of `preset` at `velocity_per_s`, every other field the command line's default.
    pub fn new(preset: impl Into<String>, velocity_per_s: f64) -> Self {
        Self {
            preset: preset.into(),
            velocity_per_s,
            ..Self::default()
        }
    }

    /// Run it: the preset with its overrides, the fields checked, the constant-velocity run
    /// (the full trace when [`record`](Self::record), else the analysis window's), ended early
    /// with [`ApiError::Stopped`] once `stop` is set; a run whose signals are not finite is
    /// [`ApiError::Diverged`], never a result.
    pub fn run(&self, stop: &AtomicBool) -> Result<RunResult, ApiError> {
        let cfg = AxisConfig::from_preset(&self.preset)
            .and_then(|c| c.with_overrides(self.sets.iter().map(String::as_str)))
            .map_err(|e| ApiError::invalid(format!("invalid configuration: {e}")))?;
        let built = cfg
            .build()
            .map_err(|e| ApiError::invalid(format!("invalid configuration: {e}")))?;
        self.validate(built.control.position_cycle)
            .map_err(ApiError::Invalid)?;
        let opts = RunOptions {
            velocity: self.velocity_per_s,
            duration: self.duration_s,
            accel: self.accel_per_s2,
            record: self.record,
            kick: self.kick_per_s,
        };
        let res = constant_velocity_run_until(&cfg, &opts, stop).map_err(|e| match e {
            RunError::Stopped { at_s } => ApiError::Stopped { at_s },
            RunError::Config(e) => ApiError::Failed(anyhow::anyhow!("{e}")),
        })?;
        if let Some(what) = not_finite(&res) {
            return Err(ApiError::Diverged {
                what,
                sets: self.sets.clone(),
            });
        }
        Ok(res)
    }

    /// Check the numeric fields: finite, in range, and a run that fits the memory cap.
    fn validate(&self, cycle_s: f64) -> anyhow::Result<()> {
        let v = self.velocity_per_s;
        anyhow::ensure!(
            v.is_finite() && v.abs() <= MAX_VELOCITY,
            "--velocity {v}: must be a finite number within +-{MAX_VELOCITY} axis units/s (mm/s \
             or deg/s)"
        );
        anyhow::ensure!(
            self.duration_s.is_finite() && self.duration_s > 0.0,
            "--duration {}: must be a finite number of seconds > 0",
            self.duration_s
        );
        anyhow::ensure!(
            self.accel_per_s2.is_finite() && self.accel_per_s2 >= 0.0,
            "--accel {}: must be a finite acceleration >= 0 axis units/s^2 (0 = reach the \
             velocity in 0.1 s)",
            self.accel_per_s2
        );
        if let Some(k) = self.kick_per_s {
            anyhow::ensure!(
                k.is_finite() && k.abs() <= MAX_VELOCITY,
                "--kick {k}: must be a finite velocity change within +-{MAX_VELOCITY} axis \
                 units/s"
            );
        }
        anyhow::ensure!(
            self.max_memory_mb.is_finite() && self.max_memory_mb > 0.0,
            "--max-memory-mb {}: must be > 0",
            self.max_memory_mb
        );
        let samples = (self.duration_s / cycle_s).ceil();
        let mb = samples * BYTES_PER_SAMPLE / 1e6;
        if mb > self.max_memory_mb {
            let max_s = self.max_memory_mb * 1e6 / BYTES_PER_SAMPLE * cycle_s;
            anyhow::bail!(
                "--duration {} s needs {samples:.0} samples ({mb:.0} MB in memory{}): above the \
                 cap of {} MB (--max-memory-mb); at this preset's {} us position cycle the cap \
                 allows {max_s:.0} s. Shorten --duration or raise --max-memory-mb.",
                self.duration_s,
                if self.trace_csv {
                    format!(", a {:.0} MB trace", samples * CSV_BYTES_PER_SAMPLE / 1e6)
                } else {
                    String::new()
                },
                self.max_memory_mb,
                cycle_s * 1e6,
            );
        }
        Ok(())
    }
}

/// The first signal of a run that holds a NaN or an infinity (named, with its time), or the
/// first summary figure that is not finite; `None` when everything is finite.
pub fn not_finite(res: &RunResult) -> Option<String> {
    let s = &res.summary;
    let t = &res.trace;
    let columns: [(&str, &[f64]); 8] = [
        ("position set point", &t.position_setpoint),
        ("direct position", &t.direct_position),
        ("motor position", &t.motor_position),
        ("motor speed", &t.motor_velocity_rpm),
        ("load velocity", &t.load_velocity),
        ("torque", &t.torque_nm),
        ("current", &t.current_a),
        ("following error", &t.following_error),
    ];
    let bad = columns.iter().find_map(|(name, col)| {
        col.iter().position(|x| !x.is_finite()).map(|i| {
            format!(
                "{name} is {} at t = {:.6} s",
                crate::quote::number(col[i]),
                t.time_s[i]
            )
        })
    });
    bad.or_else(|| {
        [
            ("motor speed amplitude", s.motor_velocity_amplitude_rpm),
            (
                "motor speed half peak-to-peak",
                s.motor_velocity_half_p2p_rpm,
            ),
            ("current amplitude", s.current_amplitude_a),
            ("load velocity half peak-to-peak", s.load_velocity_half_p2p),
            (
                "following error half peak-to-peak",
                s.following_error_half_p2p,
            ),
            ("mean motor speed", s.mean_motor_velocity_rpm),
        ]
        .iter()
        .find(|(_, v)| !v.is_finite())
        .map(|(name, v)| format!("{name} is {}", crate::quote::number(*v)))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bad_field_is_invalid_naming_its_flag_and_a_stop_is_stopped() {
        let never = AtomicBool::new(false);
        let e = SimRequest {
            duration_s: -1.0,
            ..SimRequest::new("cnc1", 10.0)
        }
        .run(&never)
        .unwrap_err();
        assert!(matches!(e, ApiError::Invalid(_)), "{e:?}");
        assert!(e.to_string().starts_with("--duration -1:"), "{e}");
        let e = SimRequest::new("cnc9", 10.0).run(&never).unwrap_err();
        assert!(matches!(e, ApiError::Invalid(_)), "{e:?}");
        let stop = AtomicBool::new(true);
        let e = SimRequest::new("cnc1", 10.0).run(&stop).unwrap_err();
        assert!(matches!(e, ApiError::Stopped { .. }), "{e:?}");
    }
}
