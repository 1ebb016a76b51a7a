//! `drive-emu analyze TRACE`: run the backlash detector on a trace and write a report.
//!
//! A candump log (can-utils `candump -L` or `candump -ta`; recognised by its first data line
//! starting with `(`) is decoded with the drive's PDO mapping, following the remaps seen in the
//! log: `--node` (default 5) and `--preset` (default cnc1) name the drive whose default mapping
//! the log starts from, `--sync-period-us` overrides the sample period (see
//! [`crate::analysis::candump`]).
//!
//! Otherwise two CSV layouts are read, by column name:
//! - the simulator's trace (`drive-emu sim --trace`): `time_s`, `position_setpoint_<u>`,
//!   `direct_encoder_position_<u>`, `motor_encoder_position_<u>`, `motor_velocity_rpm`,
//!   `motor_current_a` (u = mm or deg);
//! - the sample log (`samples.csv` of a scenario report, `drive-emu run --trace`): `t_s`,
//!   `target_uu` (the position demand, from which the set velocity is derived),
//!   `velocity_uu_s`, `current_permille`, `position_uu`, `direct_position_uu`.

use crate::analysis::candump;
use crate::analysis::detector::{analyze, AxisTrace, DetectorConfig, Verdict};
use crate::analysis::windows::{set_velocity_from_demand, DEMAND_SPAN_S};
use anyhow::{bail, Context};
use std::path::{Path, PathBuf};

/// Arguments of `drive-emu analyze`.
#[derive(clap::Args, Debug, Clone)]
#[command(after_help = "\
TRACE formats, recognised by content:
  candump log  `candump -L` (`(1700000000.123456) vcan0 185#...`) or `candump -ta`; decoded with
               the PDO mapping of drive --node/--preset, following the SDO remaps and NMT resets
               in the log; one sample per SYNC at k * period.
  CSV          `drive-emu sim --trace` output, or a scenario report's samples.csv.

Example: drive-emu analyze run.log --kv 30 --node 5 --preset cnc1")]
pub struct AnalyzeArgs {
    /// Trace: candump log (`candump -L` / `-ta`), simulator trace CSV or master sample log CSV.
    pub trace: PathBuf,
    /// Position-loop gain k_v of the axis, 1/s (the band check is k_v/4 .. k_v).
    #[arg(long)]
    pub kv: f64,
    /// The trace is of a rotary axis (deg / mdeg); only for units in the report (a candump log
    /// takes it from --preset).
    #[arg(long)]
    pub rotary: bool,
    /// Threshold for "suspected": displacement-equivalent amplitude of the limit cycle
    /// (µm on linear axes, mdeg on rotary ones) at which a window in the k_v band is flagged
    /// as suspected backlash (default 1).
    #[arg(long, value_name = "AMPLITUDE")]
    pub suspect: Option<f64>,
    /// Threshold for "backlash": the same amplitude (µm or mdeg) at which a window is flagged
    /// as backlash, the verdict once it holds for the confirm windows; severity is the
    /// amplitude over this threshold (default 3).
    #[arg(long, value_name = "AMPLITUDE")]
    pub alarm: Option<f64>,
    /// Output directory (default out/analyze-<trace stem>/).
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Exit with status 2 when the verdict is not ok.
    #[arg(long)]
    pub fail_on_backlash: bool,
    /// candump log: node ID of the drive.
    #[arg(long, default_value_t = 5)]
    pub node: u8,
    /// candump log: preset of the drive, for its default PDO mapping and units.
    #[arg(long, default_value = "cnc1")]
    pub preset: String,
    /// candump log: SYNC period, us (default: 0x1006 if written in the log, else the median
    /// SYNC interval of the timestamps).
    #[arg(long)]
    pub sync_period_us: Option<u32>,
}

impl Default for AnalyzeArgs {
    /// The command-line defaults (trace and k_v still to be set).
    fn default() -> Self {
        Self {
            trace: PathBuf::new(),
            kv: 0.0,
            rotary: false,
            suspect: None,
            alarm: None,
            out: None,
            fail_on_backlash: false,
            node: 5,
            preset: "cnc1".into(),
            sync_period_us: None,
        }
    }
}

/// Read a CSV into named columns.
pub fn read_csv(path: &Path) -> anyhow::Result<Vec<(String, Vec<f64>)>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    parse_csv(path, &text)
}

/// Parse CSV text (read from `path`) into named columns.
fn parse_csv(path: &Path, text: &str) -> anyhow::Result<Vec<(String, Vec<f64>)>> {
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
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    trace_from_csv_text(path, &text, rotary)
}

fn trace_from_csv_text(path: &Path, text: &str, rotary: bool) -> anyhow::Result<AxisTrace> {
    let cols = parse_csv(path, text)?;
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
            // From the position demand: exact for the master's interpolated targets, and
            // what makes `run --trace` usable, whose demand (0x6062) is in whole units.
            set_velocity: set_velocity_from_demand(
                need(&["t_s"])?,
                need(&["target_uu"])?,
                DEMAND_SPAN_S,
            ),
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
    let path = &args.trace;
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let tr = if candump::looks_like_candump(&text) {
        let (tr, log) = candump::trace_from_candump(
            path,
            &text,
            args.node,
            &args.preset,
            args.sync_period_us,
            args.rotary,
        )?;
        println!("{}", log.summary());
        tr
    } else {
        trace_from_csv_text(path, &text, args.rotary)?
    };
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
        crate::report::unit_text(&rep.position_unit),
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
