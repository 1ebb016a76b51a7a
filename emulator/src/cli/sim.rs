//! `drive-emu sim`: run a preset axis offline at constant velocity, write a CSV trace and/or
//! print a JSON summary of the vibration (fundamental frequency and amplitudes).

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use anyhow::Context;

use crate::analysis::{constant_velocity_run_until, RunError, RunOptions, RunResult};
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
pub const DEFAULT_MAX_MEMORY_MB: f64 = 512.0;
/// Bytes kept per sample (nine f64 columns of the trace).
const BYTES_PER_SAMPLE: f64 = 9.0 * 8.0;
/// Bytes per CSV row of `--trace`, about.
const CSV_BYTES_PER_SAMPLE: f64 = 110.0;
/// Largest |velocity| accepted, axis units/s: a feed axis above 1000 mm/s (60 m/min) or a
/// table above 1000 deg/s is beyond any of the presets' motors.
const MAX_VELOCITY: f64 = 1000.0;

/// Check the numeric flags: finite, in range, and a run that fits the memory cap.
fn validate(args: &SimArgs, cycle_s: f64) -> anyhow::Result<()> {
    let v = args.velocity;
    anyhow::ensure!(
        v.is_finite() && v.abs() <= MAX_VELOCITY,
        "--velocity {v}: must be a finite number within +-{MAX_VELOCITY} axis units/s (mm/s \
         or deg/s)"
    );
    anyhow::ensure!(
        args.duration.is_finite() && args.duration > 0.0,
        "--duration {}: must be a finite number of seconds > 0",
        args.duration
    );
    anyhow::ensure!(
        args.accel.is_finite() && args.accel >= 0.0,
        "--accel {}: must be a finite acceleration >= 0 axis units/s^2 (0 = reach the \
         velocity in 0.1 s)",
        args.accel
    );
    if let Some(k) = args.kick {
        anyhow::ensure!(
            k.is_finite() && k.abs() <= MAX_VELOCITY,
            "--kick {k}: must be a finite velocity change within +-{MAX_VELOCITY} axis units/s"
        );
    }
    anyhow::ensure!(
        args.max_memory_mb.is_finite() && args.max_memory_mb > 0.0,
        "--max-memory-mb {}: must be > 0",
        args.max_memory_mb
    );
    let samples = (args.duration / cycle_s).ceil();
    let mb = samples * BYTES_PER_SAMPLE / 1e6;
    if mb > args.max_memory_mb {
        let max_s = args.max_memory_mb * 1e6 / BYTES_PER_SAMPLE * cycle_s;
        anyhow::bail!(
            "--duration {} s needs {samples:.0} samples ({mb:.0} MB in memory{}): above the cap \
             of {} MB (--max-memory-mb); at this preset's {} us position cycle the cap allows \
             {max_s:.0} s. Shorten --duration or raise --max-memory-mb.",
            args.duration,
            if args.trace.is_some() {
                format!(", a {:.0} MB trace", samples * CSV_BYTES_PER_SAMPLE / 1e6)
            } else {
                String::new()
            },
            args.max_memory_mb,
            cycle_s * 1e6,
        );
    }
    Ok(())
}

/// What `sim` runs, without printing or writing anything: the preset with its `--set`
/// overrides, the flags checked, the constant-velocity run (the full trace when `record`, else
/// the analysis window's), ended early with [`RunError::Stopped`] in the error's chain once
/// `stop` is set. The Python module's `drive_emu.sim` calls this.
pub fn simulate(args: &SimArgs, record: bool, stop: &AtomicBool) -> anyhow::Result<RunResult> {
    let cfg = AxisConfig::from_preset(&args.preset)
        .and_then(|c| c.with_overrides(args.set.iter().map(String::as_str)))
        .map_err(|e| crate::cli::exit::usage_msg(format!("invalid configuration: {e}")))?;
    let built = cfg
        .build()
        .map_err(|e| crate::cli::exit::usage_msg(format!("invalid configuration: {e}")))?;
    validate(args, built.control.position_cycle).map_err(crate::cli::exit::usage)?;
    let opts = RunOptions {
        velocity: args.velocity,
        duration: args.duration,
        accel: args.accel,
        record,
        kick: args.kick,
    };
    let res = constant_velocity_run_until(&cfg, &opts, stop).map_err(|e| match e {
        RunError::Stopped { .. } => anyhow::Error::new(e),
        RunError::Config(e) => anyhow::anyhow!("{e}"),
    })?;
    check_finite(&res, &args.set)?;
    Ok(res)
}

/// A run whose signals hold a NaN or an infinity diverged: an error naming the first signal
/// and time, never a result with "fundamental none".
pub fn check_finite(res: &RunResult, set: &[String]) -> anyhow::Result<()> {
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
    let mut bad = columns.iter().find_map(|(name, col)| {
        col.iter().position(|x| !x.is_finite()).map(|i| {
            format!(
                "{name} is {} at t = {:.6} s",
                crate::quote::number(col[i]),
                t.time_s[i]
            )
        })
    });
    if bad.is_none() {
        bad = [
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
        .map(|(name, v)| format!("{name} is {}", crate::quote::number(*v)));
    }
    match bad {
        None => Ok(()),
        Some(what) => anyhow::bail!(
            "the simulation diverged: {what}; a parameter is outside what the model resolves{}",
            if set.is_empty() {
                String::new()
            } else {
                format!(
                    " (check --set {})",
                    set.iter()
                        .map(|x| crate::quote::text(x))
                        .collect::<Vec<_>>()
                        .join(" ")
                )
            }
        ),
    }
}

pub fn run(args: &SimArgs) -> anyhow::Result<()> {
    let res = simulate(args, args.trace.is_some(), &AtomicBool::new(false))?;
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
