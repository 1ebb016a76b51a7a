//! `drive-emu sim`: run a preset axis offline at constant velocity, write a CSV trace and/or
//! print a JSON summary of the vibration (fundamental frequency and amplitudes).

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use anyhow::Context;

use crate::analysis::{RunError, RunResult};
use crate::api::{ApiError, SimRequest};

/// Arguments of `drive-emu sim`.
#[derive(clap::Args, Debug, Clone)]
pub struct SimArgs {
    /// Preset name (cnc1 ... cnc5).
    #[arg(long, default_value = "cnc1")]
    pub preset: String,
    /// Override a preset key, e.g. --set backlash_mm=0.05 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Constant velocity in axis units per second (mm/s for linear, deg/s for rotary axes).
    #[arg(long, allow_negative_numbers = true)]
    pub velocity: f64,
    /// Simulated duration, s.
    #[arg(long, default_value_t = crate::api::sim::DEFAULT_DURATION_S)]
    pub duration: f64,
    /// Start-ramp acceleration, axis units/s^2 (default: reach the velocity in 0.1 s).
    #[arg(long, default_value_t = 0.0)]
    pub accel: f64,
    /// Start disturbance: load velocity change (axis units/s) from a 5 ms force pulse once the
    /// position loop has settled, 5/k_v after the start ramp (default 0.6 x velocity; 0 = none). The backlash limit cycle is a hard
    /// excitation: it needs a disturbance to start.
    #[arg(long, allow_negative_numbers = true)]
    pub kick: Option<f64>,
    /// Write the full trace as CSV to this file.
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// Memory cap for the samples the run keeps for its analysis (and the trace), MB. A run
    /// needing more is refused before it starts.
    #[arg(long, default_value_t = DEFAULT_MAX_MEMORY_MB)]
    pub max_memory_mb: f64,
}

/// Default of `--max-memory-mb`: about an hour of samples at a 1 ms position cycle.
pub use crate::api::sim::DEFAULT_MAX_MEMORY_MB;

impl SimArgs {
    /// The request these arguments make (`record`: keep the full trace).
    pub fn request(&self, record: bool) -> SimRequest {
        SimRequest {
            preset: self.preset.clone(),
            sets: self.set.clone(),
            velocity_per_s: self.velocity,
            duration_s: self.duration,
            accel_per_s2: self.accel,
            kick_per_s: self.kick,
            max_memory_mb: self.max_memory_mb,
            record,
            trace_csv: self.trace.is_some(),
        }
    }
}

/// What `sim` runs, without printing or writing anything ([`SimRequest::run`] of the
/// arguments), with the command line's errors: exit status 2 for a bad flag or preset, a
/// stopped run with [`RunError::Stopped`] in the error's chain.
pub fn simulate(args: &SimArgs, record: bool, stop: &AtomicBool) -> anyhow::Result<RunResult> {
    args.request(record).run(stop).map_err(|e| match e {
        ApiError::Stopped { at_s } => anyhow::Error::new(RunError::Stopped { at_s }),
        e => super::api_error(e),
    })
}

pub fn run(args: &SimArgs) -> anyhow::Result<()> {
    let res = args
        .request(args.trace.is_some())
        .run(&AtomicBool::new(false))
        .map_err(super::api_error)?;
    if let Some(path) = &args.trace {
        let u = &res.summary.unit;
        let file = std::fs::File::create(path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        let mut w = std::io::BufWriter::new(file);
        write_trace_csv(&mut w, &res.trace, u)?;
        w.flush()?;
    }
    let s = &res.summary;
    if args.json {
        println!("{}", serde_json::to_string_pretty(s)?);
    } else {
        let f = s
            .fundamental_hz
            .map(|f| format!("{f:.2} Hz (f/k_v = {:.3})", f / s.kv_per_s))
            .unwrap_or_else(|| "none".into());
        println!(
            "{}: v = {} {u}/s, k_v = {} 1/s, backlash = {} {u}\n  fundamental {f}\n  motor speed \
             amplitude {:.4} rpm (half p-p {:.4}), current amplitude {:.4} A\n  window {:.2}-{:.2} s",
            s.preset,
            s.velocity,
            s.kv_per_s,
            s.backlash,
            s.motor_velocity_amplitude_rpm,
            s.motor_velocity_half_p2p_rpm,
            s.current_amplitude_a,
            s.window_start_s,
            s.window_end_s,
            u = s.unit
        );
    }
    Ok(())
}

/// Write a trace as the CSV `sim --trace` produces (units in the header; `u` = mm or deg).
pub fn write_trace_csv(
    w: &mut impl Write,
    t: &crate::analysis::Trace,
    u: &str,
) -> std::io::Result<()> {
    writeln!(w, "{}", crate::analysis::Trace::column_names(u).join(","))?;
    for i in 0..t.len() {
        writeln!(
            w,
            "{:.6},{:.9},{:.9},{:.9},{:.6},{:.9},{:.6},{:.6},{:.9}",
            t.time_s[i],
            t.position_setpoint[i],
            t.direct_position[i],
            t.motor_position[i],
            t.motor_velocity_rpm[i],
            t.load_velocity[i],
            t.torque_nm[i],
            t.current_a[i],
            t.following_error[i]
        )?;
    }
    Ok(())
}
