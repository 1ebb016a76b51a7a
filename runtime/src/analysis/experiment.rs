//! The paper's experiment: an axis in closed position loop follows a constant-velocity
//! set-point; after the start-up transient, the spectrum of the measured motor speed (and of
//! the motor current) gives the vibration's fundamental frequency and amplitude.

use std::sync::atomic::{AtomicBool, Ordering};

use crate::control::{Command, Servo, Setpoint, VelocityProfile};
use crate::presets::{AxisConfig, ConfigError};

use super::spectrum::{half_peak_to_peak, SpectrumAnalyzer};

/// How to run the experiment. Velocities in axis units (mm/s or deg/s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunOptions {
    /// Commanded constant velocity, mm/s (linear) or deg/s (rotary).
    pub velocity: f64,
    /// Simulated time, s.
    pub duration: f64,
    /// Acceleration of the start ramp, axis units/s^2 (<= 0: reach the velocity in 0.1 s).
    pub accel: f64,
    /// Keep the full trace (otherwise only the analysis window's signals).
    pub record: bool,
    /// Start disturbance: a velocity change of the load (axis units/s) given by a short
    /// external force pulse (5 ms) once the position loop has settled after the start ramp
    /// (5 / k_v after it), like a knock on the carriage.
    /// The backlash limit cycle is a hard excitation: it needs a disturbance to start.
    /// `None`: 0.6 x the commanded velocity (enough to enter the limit cycle of every preset
    /// at k_v = 15..60 1/s); `Some(0.0)`: no disturbance.
    pub kick: Option<f64>,
}

impl RunOptions {
    pub fn new(velocity: f64, duration: f64) -> Self {
        RunOptions {
            velocity,
            duration,
            accel: 0.0,
            record: false,
            kick: None,
        }
    }
}

/// Sampled signals, one row per position cycle. Positions and velocities in axis units
/// (mm, mm/s or deg, deg/s), motor speed in rpm, torque N m, current A.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    pub time_s: Vec<f64>,
    pub position_setpoint: Vec<f64>,
    pub direct_position: Vec<f64>,
    pub motor_position: Vec<f64>,
    pub motor_velocity_rpm: Vec<f64>,
    pub load_velocity: Vec<f64>,
    pub torque_nm: Vec<f64>,
    pub current_a: Vec<f64>,
    pub following_error: Vec<f64>,
}

impl Trace {
    fn with_capacity(n: usize) -> Self {
        Trace {
            time_s: Vec::with_capacity(n),
            position_setpoint: Vec::with_capacity(n),
            direct_position: Vec::with_capacity(n),
            motor_position: Vec::with_capacity(n),
            motor_velocity_rpm: Vec::with_capacity(n),
            load_velocity: Vec::with_capacity(n),
            torque_nm: Vec::with_capacity(n),
            current_a: Vec::with_capacity(n),
            following_error: Vec::with_capacity(n),
        }
    }

    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// Column names, units in them (`u` = "mm" or "deg"), in the order of
    /// [`Trace::into_columns`]: the header of `sim --trace`'s CSV and the Python module's
    /// trace.
    pub fn column_names(u: &str) -> [String; 9] {
        [
            "time_s".to_string(),
            format!("position_setpoint_{u}"),
            format!("direct_encoder_position_{u}"),
            format!("motor_encoder_position_{u}"),
            "motor_velocity_rpm".to_string(),
            format!("load_velocity_{u}_per_s"),
            "motor_torque_nm".to_string(),
            "motor_current_a".to_string(),
            format!("following_error_{u}"),
        ]
    }

    /// The signals with their [`Trace::column_names`].
    pub fn into_columns(self, u: &str) -> [(String, Vec<f64>); 9] {
        let [a, b, c, d, e, f, g, h, i] = Self::column_names(u);
        [
            (a, self.time_s),
            (b, self.position_setpoint),
            (c, self.direct_position),
            (d, self.motor_position),
            (e, self.motor_velocity_rpm),
            (f, self.load_velocity),
            (g, self.torque_nm),
            (h, self.current_a),
            (i, self.following_error),
        ]
    }
}

/// What the experiment found.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct RunSummary {
    pub preset: String,
    pub unit: String,
    pub velocity: f64,
    pub kv_per_s: f64,
    pub backlash: f64,
    /// Fundamental frequency of the measured motor speed, Hz (None if the signal is flat).
    pub fundamental_hz: Option<f64>,
    pub f_over_kv: Option<f64>,
    /// Amplitude of the fundamental line of the measured motor speed, rpm.
    pub motor_velocity_amplitude_rpm: f64,
    /// Half the peak-to-peak excursion of the measured motor speed, rpm.
    pub motor_velocity_half_p2p_rpm: f64,
    /// Fundamental frequency and amplitude of the motor current, Hz and A.
    pub current_fundamental_hz: Option<f64>,
    pub current_amplitude_a: f64,
    /// Amplitude (half peak-to-peak) of the true load velocity, axis units/s.
    pub load_velocity_half_p2p: f64,
    /// Amplitude (half peak-to-peak) of the following error, axis units.
    pub following_error_half_p2p: f64,
    /// Mean motor speed in the window, rpm.
    pub mean_motor_velocity_rpm: f64,
    pub window_start_s: f64,
    pub window_end_s: f64,
}

/// Trace (full if requested, else the analysis window only) and the summary.
#[derive(Clone, Debug)]
pub struct RunResult {
    pub trace: Trace,
    pub summary: RunSummary,
}

/// Search band for the fundamental, Hz: wide, so that the result is not forced into the
/// paper's k_v/4 .. k_v band.
pub const SEARCH_BAND_HZ: (f64, f64) = (1.0, 200.0);

/// Why [`constant_velocity_run_until`] gave no result.
#[derive(Clone, Debug, PartialEq)]
pub enum RunError {
    /// The configuration was rejected (key and reason).
    Config(ConfigError),
    /// The stop flag was set before the run had finished, at this simulated time, s.
    Stopped { at_s: f64 },
}

impl std::fmt::Display for RunError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RunError::Config(e) => e.fmt(f),
            RunError::Stopped { at_s } => write!(f, "the run was stopped at {at_s:.3} s"),
        }
    }
}

impl std::error::Error for RunError {}

impl From<ConfigError> for RunError {
    fn from(e: ConfigError) -> Self {
        RunError::Config(e)
    }
}

/// Position cycles between two looks at the stop flag of [`constant_velocity_run_until`]
/// (about 0.1-0.3 ms of wall time).
const STOP_CHECK_CYCLES: usize = 256;

/// Run the constant-velocity experiment on a configured axis.
pub fn constant_velocity_run(
    cfg: &AxisConfig,
    opts: &RunOptions,
) -> Result<RunResult, ConfigError> {
    run(cfg, opts, || false).map_err(|e| match e {
        RunError::Config(e) => e,
        // `|| false` never stops the run.
        RunError::Stopped { .. } => ConfigError::new("stop", "stopped"),
    })
}

/// [`constant_velocity_run`] that ends early, with [`RunError::Stopped`], once `stop` is set
/// (from another thread: a Ctrl-C, a cancelled sweep). The flag is read every few hundred
/// position cycles, so a run stops within a fraction of a millisecond.
pub fn constant_velocity_run_until(
    cfg: &AxisConfig,
    opts: &RunOptions,
    stop: &AtomicBool,
) -> Result<RunResult, RunError> {
    run(cfg, opts, || stop.load(Ordering::Relaxed))
}

fn run(
    cfg: &AxisConfig,
    opts: &RunOptions,
    stopped: impl Fn() -> bool,
) -> Result<RunResult, RunError> {
    let built = cfg.build()?;
    let unit = built.display_unit;
    let mut servo = Servo::new(built.axis, built.control).map_err(|e| ConfigError {
        key: "physics_step_us".into(),
        reason: e.to_string(),
    })?;
    let dt = servo.cycle_time();
    let v = opts.velocity * unit;
    let accel = if opts.accel > 0.0 {
        opts.accel * unit
    } else {
        (v / 0.1).abs().max(1e-12)
    };
    let ramp = (v / accel).abs();
    // The knock comes once the position loop has settled after the ramp: the following error
    // approaches its cruise value as exp(-k_v t), and while it does, the residual acceleration
    // presses the load against the driving flank (m a(t)) and swallows the knock. At low k_v
    // and high speed that transient outlasts the knock (cnc1, k_v 10 1/s, 20 mm/s: 0.6 x the
    // ramp's 160 N at 5 ms): five time constants leave 0.7 %.
    let settle = ramp + 5.0 / built.control.kv.max(1e-3);
    let mut profile = VelocityProfile::constant(0.0, v, accel);
    let n = (opts.duration / dt).round() as usize;
    let skip = settle + (0.4 * (opts.duration - settle)).clamp(0.0, 1.5);
    let first = ((skip / dt).ceil() as usize).min(n);
    let mut trace = Trace::with_capacity(if opts.record { n } else { n - first });
    let ratio = servo.axis.ratio();
    let to_rpm = 30.0 / std::f64::consts::PI;
    let kick_start = ((settle / dt).ceil() as usize).min(n);
    let kick_cycles = ((0.005 / dt).round() as usize).max(1);
    let kick = opts.kick.unwrap_or(0.6 * opts.velocity);
    let kick_force = built.axis.mech.load_mass * kick * unit / (kick_cycles as f64 * dt);
    for i in 0..n {
        if i % STOP_CHECK_CYCLES == 0 && stopped() {
            return Err(RunError::Stopped { at_s: servo.time() });
        }
        if kick != 0.0 {
            let on = i >= kick_start && i < kick_start + kick_cycles;
            servo
                .axis
                .set_external_load(if on { kick_force } else { 0.0 });
        }
        let s = profile.next(dt);
        servo.set_command(Command::new(Setpoint::Position {
            position: s.position,
            velocity_ff: 0.0,
            torque_ff: 0.0,
        }));
        servo.step();
        if opts.record || i >= first {
            trace.time_s.push(servo.time());
            trace.position_setpoint.push(s.position / unit);
            trace
                .direct_position
                .push(servo.direct_encoder_position() / unit);
            trace
                .motor_position
                .push(servo.motor_encoder_position() / unit);
            trace
                .motor_velocity_rpm
                .push(servo.motor_velocity() * to_rpm);
            trace.load_velocity.push(servo.axis.load_velocity() / unit);
            trace.torque_nm.push(servo.torque());
            trace.current_a.push(servo.current());
            trace.following_error.push(servo.following_error() / unit);
        }
    }
    let start = if opts.record { first } else { 0 };
    let w = |x: &Vec<f64>| x[start..].to_vec();
    let speed = w(&trace.motor_velocity_rpm);
    let current = w(&trace.current_a);
    let rate = 1.0 / dt;
    let mut an = SpectrumAnalyzer::new(speed.len().max(8));
    let (f, amp) = if speed.len() >= 8 {
        match an.fundamental(&speed, rate, SEARCH_BAND_HZ) {
            Some(p) => (Some(p.frequency_hz), p.amplitude),
            None => (None, 0.0),
        }
    } else {
        (None, 0.0)
    };
    let (fi, ampi) = if current.len() >= 8 {
        match an.fundamental(&current, rate, SEARCH_BAND_HZ) {
            Some(p) => (Some(p.frequency_hz), p.amplitude),
            None => (None, 0.0),
        }
    } else {
        (None, 0.0)
    };
    let kv = built.control.kv;
    let mean_speed = speed.iter().sum::<f64>() / speed.len().max(1) as f64;
    let summary = RunSummary {
        preset: cfg.name.clone(),
        unit: built.display_unit_name.to_string(),
        velocity: opts.velocity,
        kv_per_s: kv,
        backlash: built.axis.mech.contact.backlash / unit,
        fundamental_hz: f,
        f_over_kv: f.map(|f| f / kv),
        motor_velocity_amplitude_rpm: amp,
        motor_velocity_half_p2p_rpm: half_peak_to_peak(&speed),
        current_fundamental_hz: fi,
        current_amplitude_a: ampi,
        load_velocity_half_p2p: half_peak_to_peak(&w(&trace.load_velocity)),
        following_error_half_p2p: half_peak_to_peak(&w(&trace.following_error)),
        mean_motor_velocity_rpm: mean_speed,
        window_start_s: first as f64 * dt,
        window_end_s: n as f64 * dt,
    };
    let _ = ratio;
    Ok(RunResult { trace, summary })
}
