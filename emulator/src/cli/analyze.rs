//! `drive-emu analyze TRACE`: run the backlash detector on a CSV trace and write a report.
//!
//! Two CSV layouts are read, by column name:
//! - the simulator's trace (`drive-emu sim --trace`): `time_s`, `position_setpoint_<u>`,
//!   `direct_encoder_position_<u>`, `motor_encoder_position_<u>`, `motor_velocity_rpm`,
//!   `motor_current_a` (u = mm or deg);
//! - the reference master's sample log (`samples.csv` of a scenario report): `t_s`,
//!   `setpoint_velocity_uu_s`, `velocity_uu_s`, `current_permille`, `position_uu`,
//!   `direct_position_uu`.

use crate::analysis::detector::{analyze, AxisTrace, DetectorConfig, Verdict};
use anyhow::{bail, Context};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug, Clone)]
pub struct AnalyzeArgs {
    /// CSV trace (simulator trace or master sample log).
    pub trace: PathBuf,
    /// Position-loop gain k_v of the axis, 1/s (the band check is k_v/4 .. k_v).
    #[arg(long)]
    pub kv: f64,
    /// The trace is of a rotary axis (deg / mdeg); only for units in the report.
    #[arg(long)]
    pub rotary: bool,
    /// Amplitude thresholds (displacement equivalent, um or mdeg).
    #[arg(long)]
    pub suspect: Option<f64>,
    #[arg(long)]
    pub alarm: Option<f64>,
    /// Output directory (default out/analyze-<trace stem>/).
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Exit with status 2 when the verdict is not ok.
    #[arg(long)]
    pub fail_on_backlash: bool,
}

/// Read a CSV into named columns.
pub fn read_csv(path: &Path) -> anyhow::Result<Vec<(String, Vec<f64>)>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut lines = text
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'));
    let header = lines.next().context("empty trace")?;
    let mut cols: Vec<(String, Vec<f64>)> = header
        .split(',')
        .map(|h| (h.trim().to_string(), Vec::new()))
        .collect();
    for (i, line) in lines.enumerate() {
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != cols.len() {
            bail!(
                "{}: data line {}: {} fields, header has {}",
                path.display(),
                i + 2,
                fields.len(),
                cols.len()
            );
        }
        for (c, f) in cols.iter_mut().zip(fields) {
            let v: f64 = f.trim().parse().with_context(|| {
                format!(
                    "{}: data line {}: column {}: `{f}` is not a number",
                    path.display(),
                    i + 2,
                    c.0
                )
            })?;
            c.1.push(v);
        }
    }
    Ok(cols)
}

/// Build the detector's trace from either CSV layout.
pub fn trace_from_csv(path: &Path, rotary: bool) -> anyhow::Result<AxisTrace> {
    let cols = read_csv(path)?;
    let find = |names: &[&str]| -> Option<&Vec<f64>> {
        cols.iter()
            .find(|(n, _)| names.contains(&n.as_str()))
            .map(|(_, v)| v)
    };
    let need = |names: &[&str]| -> anyhow::Result<&Vec<f64>> {
        find(names).with_context(|| format!("{}: no column {}", path.display(), names.join(" or ")))
    };
    let tr = if find(&["t_s"]).is_some() {
        AxisTrace {
            t_s: need(&["t_s"])?.clone(),
            set_velocity: need(&["setpoint_velocity_uu_s"])?.clone(),
            motor_velocity: need(&["velocity_uu_s"])?.clone(),
            current: need(&["current_permille"])?.clone(),
            motor_position: need(&["position_uu"])?.clone(),
            direct_position: need(&["direct_position_uu"])?.clone(),
            position_unit: if rotary { "mdeg" } else { "um" }.into(),
            current_unit: "permille".into(),
        }
    } else {
        let rot = find(&["position_setpoint_deg"]).is_some();
        let u = if rot { "deg" } else { "mm" };
        AxisTrace::from_sim(
            need(&["time_s"])?,
            need(&[&format!("position_setpoint_{u}")])?,
            need(&[&format!("motor_encoder_position_{u}")])?,
            need(&[&format!("direct_encoder_position_{u}")])?,
            need(&["motor_velocity_rpm"])?,
            need(&["motor_current_a"])?,
            rot,
        )
    };
    tr.check()
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(tr)
}

pub fn run(args: &AnalyzeArgs) -> anyhow::Result<std::process::ExitCode> {
    anyhow::ensure!(args.kv > 0.0 && args.kv.is_finite(), "--kv must be > 0");
    let tr = trace_from_csv(&args.trace, args.rotary)?;
    let mut cfg = DetectorConfig::new(args.kv);
    if let Some(s) = args.suspect {
        cfg.suspect_um = s;
    }
    if let Some(a) = args.alarm {
        cfg.alarm_um = a;
    }
    let rep = analyze(&tr, &cfg);
    let out = args.out.clone().unwrap_or_else(|| {
        let stem = args
            .trace
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("trace");
        PathBuf::from("out").join(format!("analyze-{stem}"))
    });
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    crate::report::write_json(&out.join("detector.json"), &rep)?;
    let plots = crate::report::detector_plots(&out, "", &tr, &rep, None)?;
    println!(
        "verdict {} | amplitude {:.2} {} | severity {:.2} | frequency {} | windows {} | report {}",
        rep.verdict.as_str(),
        rep.amplitude,
        rep.position_unit,
        rep.severity,
        rep.frequency_hz
            .or(rep.dominant_hz)
            .map_or("-".into(), |f| format!(
                "{f:.2} Hz ({:.2} k_v)",
                f / args.kv
            )),
        rep.windows.len(),
        out.display()
    );
    for p in plots {
        println!("  {}", p.display());
    }
    Ok(if args.fail_on_backlash && rep.verdict != Verdict::Ok {
        std::process::ExitCode::from(2)
    } else {
        std::process::ExitCode::SUCCESS
    })
}
