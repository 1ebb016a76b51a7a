//! `drive-emu sim`: run a preset axis offline at constant velocity, write a CSV trace and/or
//! print a JSON summary of the vibration (fundamental frequency and amplitudes).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;

use crate::analysis::{constant_velocity_run, RunOptions};
use crate::presets::AxisConfig;

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
    #[arg(long, default_value_t = 5.0)]
    pub duration: f64,
    /// Start-ramp acceleration, axis units/s^2 (default: reach the velocity in 0.1 s).
    #[arg(long, default_value_t = 0.0)]
    pub accel: f64,
    /// Start disturbance: load velocity change (axis units/s) from a 5 ms force pulse after the
    /// start ramp (default 0.6 x velocity; 0 = none). The backlash limit cycle is a hard
    /// excitation: it needs a disturbance to start.
    #[arg(long, allow_negative_numbers = true)]
    pub kick: Option<f64>,
    /// Write the full trace as CSV to this file.
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &SimArgs) -> anyhow::Result<()> {
    let cfg = AxisConfig::from_preset(&args.preset)
        .and_then(|c| c.with_overrides(args.set.iter().map(String::as_str)))
        .map_err(|e| anyhow::anyhow!("invalid configuration: {e}"))?;
    anyhow::ensure!(
        args.duration > 0.0 && args.duration.is_finite(),
        "--duration must be > 0"
    );
    let opts = RunOptions {
        velocity: args.velocity,
        duration: args.duration,
        accel: args.accel,
        record: args.trace.is_some(),
        kick: args.kick,
    };
    let res = constant_velocity_run(&cfg, &opts).map_err(|e| anyhow::anyhow!("{e}"))?;
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
    writeln!(
        w,
        "time_s,position_setpoint_{u},direct_encoder_position_{u},motor_encoder_position_{u},\
         motor_velocity_rpm,load_velocity_{u}_per_s,motor_torque_nm,motor_current_a,\
         following_error_{u}"
    )?;
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
