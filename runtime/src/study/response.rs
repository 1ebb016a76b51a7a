//! The closed speed loop's frequency response, measured the way a drive's measuring function
//! does it (the paper's Fig. 3): the speed set-point gets a sine on top of a constant speed,
//! injected every speed-controller cycle, and the measured motor speed (the drive's own
//! encoder-based speed) is correlated with it. Nothing is computed from a transfer function.

use std::f64::consts::PI;

use crate::control::{Command, Servo, Setpoint};
use crate::presets::{AxisConfig, ConfigError};

/// One frequency of the measurement.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ResponsePoint {
    pub frequency_hz: f64,
    /// |measured speed / speed set-point| in dB.
    pub magnitude_db: f64,
    /// Phase of measured speed relative to the set-point, degrees (negative = lag).
    pub phase_deg: f64,
}

/// The measured response of one axis.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SpeedLoopResponse {
    pub preset: String,
    /// Constant motor speed the sine rides on, rpm (keeps the drive train in contact).
    pub offset_rpm: f64,
    /// Sine amplitude at the speed set-point, rpm.
    pub amplitude_rpm: f64,
    pub speed_cycle_us: f64,
    pub points: Vec<ResponsePoint>,
    /// First frequency where the magnitude falls below -3 dB (interpolated in log f), Hz.
    pub bandwidth_3db_hz: Option<f64>,
}

/// Log-spaced frequencies from `lo` to `hi` Hz, `n` points.
pub fn log_frequencies(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n.max(2) - 1) as f64))
        .collect()
}

/// Measure the closed speed loop of `cfg` (as configured: set `backlash_mm=0` for a healthy
/// axis) at `freqs` Hz, with a sine of `amplitude_rpm` on a constant `offset_rpm`.
pub fn speed_loop_response(
    cfg: &AxisConfig,
    freqs: &[f64],
    offset_rpm: f64,
    amplitude_rpm: f64,
) -> Result<SpeedLoopResponse, ConfigError> {
    // The measuring function injects at the speed-controller cycle: run the position cycle
    // (which hands the speed set-point to the speed loop) at the speed cycle.
    let cfg = cfg.with_override("position_cycle_us", &format!("{}", cfg.speed_cycle_us))?;
    let built = cfg.build()?;
    let mut servo = Servo::new(built.axis, built.control)
        .map_err(|e| ConfigError::new("physics_step_us", e.to_string()))?;
    let dt = servo.cycle_time();
    let ratio = servo.axis.ratio();
    let rpm = PI / 30.0;
    let w0 = offset_rpm * rpm;
    let a = amplitude_rpm * rpm;
    let set = |servo: &mut Servo, w: f64| {
        servo.set_command(Command::new(Setpoint::Velocity {
            velocity: w / ratio,
            torque_ff: 0.0,
        }));
    };
    // Ramp to the offset speed in 0.1 s and settle 0.3 s.
    let ramp = (0.1 / dt).round() as usize;
    for i in 0..ramp {
        set(&mut servo, w0 * (i + 1) as f64 / ramp as f64);
        servo.step();
    }
    for _ in 0..(0.3 / dt).round() as usize {
        set(&mut servo, w0);
        servo.step();
    }
    let mut points = Vec::with_capacity(freqs.len());
    let mut x = Vec::new();
    let mut y = Vec::new();
    for &f in freqs {
        if !(f > 0.0 && f < 0.5 / dt) {
            return Err(ConfigError::new(
                "frequency",
                format!(
                    "{f} Hz outside 0 .. {} Hz (half the speed-cycle rate)",
                    0.5 / dt
                ),
            ));
        }
        let settle = ((5.0 / f).max(0.02) / dt).round() as usize;
        let measure = ((20.0 / f).max(0.2) / dt).round() as usize;
        x.clear();
        y.clear();
        for k in 0..settle + measure {
            let t = k as f64 * dt;
            let xs = a * (2.0 * PI * f * t).sin();
            set(&mut servo, w0 + xs);
            servo.step();
            if k >= settle {
                x.push((t, xs));
                y.push(servo.motor_velocity() - w0);
            }
        }
        // Hann-weighted correlation at f; the mean of the output is removed first.
        let n = y.len();
        let mean = y.iter().sum::<f64>() / n as f64;
        let (mut xr, mut xi, mut yr, mut yi) = (0.0, 0.0, 0.0, 0.0);
        for (i, (&(t, xs), &ys)) in x.iter().zip(&y).enumerate() {
            let wgt = 0.5 - 0.5 * (2.0 * PI * i as f64 / (n - 1) as f64).cos();
            let (s, c) = (2.0 * PI * f * t).sin_cos();
            xr += wgt * xs * c;
            xi -= wgt * xs * s;
            yr += wgt * (ys - mean) * c;
            yi -= wgt * (ys - mean) * s;
        }
        let (xm, ym) = (xr.hypot(xi), yr.hypot(yi));
        // Unwrapped: within 180 degrees of the previous frequency's phase.
        let prev = points.last().map_or(0.0, |p: &ResponsePoint| p.phase_deg);
        let mut phase = (yi.atan2(yr) - xi.atan2(xr)).to_degrees();
        while phase > prev + 180.0 {
            phase -= 360.0;
        }
        while phase <= prev - 180.0 {
            phase += 360.0;
        }
        points.push(ResponsePoint {
            frequency_hz: f,
            magnitude_db: 20.0 * (ym / xm).log10(),
            phase_deg: phase,
        });
    }
    let bandwidth_3db_hz = points.windows(2).find_map(|w| {
        let (p, q) = (w[0], w[1]);
        (p.magnitude_db >= -3.0 && q.magnitude_db < -3.0).then(|| {
            let t = (p.magnitude_db + 3.0) / (p.magnitude_db - q.magnitude_db);
            (p.frequency_hz.ln() + t * (q.frequency_hz.ln() - p.frequency_hz.ln())).exp()
        })
    });
    Ok(SpeedLoopResponse {
        preset: cfg.name.clone(),
        offset_rpm,
        amplitude_rpm,
        speed_cycle_us: cfg.speed_cycle_us,
        points,
        bandwidth_3db_hz,
    })
}
