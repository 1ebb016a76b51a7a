//! [`AnalyzeRequest`]: the backlash detector on a trace (`drive-emu analyze`,
//! `drive_emu.analyze`). The trace formats are the command's (`drive-emu analyze --help`):
//! a candump log decoded with the drive's PDO mapping, the simulator's trace CSV or a sample
//! log CSV.

use std::path::{Path, PathBuf};

use anyhow::Context;

use super::ApiError;
use crate::analysis::candump::{self, DriveDefaults};
use crate::analysis::detector::{
    analyze, AxisTrace, DetectorConfig, DetectorReport, Inconclusive, Verdict,
};
use crate::analysis::windows::{set_velocity_from_demand, DEMAND_SPAN_S};
use crate::samples::csv::{read_csv_stream, Columns, Streamed, TraceLines};
use crate::samples::{Sample, SampleSource};

/// The detector on a trace. Thresholds are displacement-equivalent amplitudes, µm on a linear
/// axis, mdeg on a rotary one. Messages name the fields as the command line's flags.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalyzeRequest {
    /// The trace file (for [`AnalyzeInput::File`]; the name in messages otherwise).
    pub trace: PathBuf,
    /// Position-loop gain k_v, 1/s (`--kv`). Default: the last k_v written to 0x2007 in a
    /// candump log, else `preset`'s.
    pub kv_per_s: Option<f64>,
    /// A rotary axis's trace (deg / mdeg in the report; `--rotary`).
    pub rotary: bool,
    /// Threshold for "suspected", µm or mdeg (`--suspect`, default 1).
    pub suspect_um: Option<f64>,
    /// Threshold for "backlash", µm or mdeg (`--alarm`, default 3).
    pub alarm_um: Option<f64>,
    /// The exit code says 1 when backlash is found (`--fail-on-backlash`).
    pub fail_on_backlash: bool,
    /// candump log: node ID of the drive (`--node`, default 5).
    pub node: u8,
    /// Preset of the drive (`--preset`): its k_v, its PDO mapping and units (default cnc1).
    pub preset: Option<String>,
    /// candump log: SYNC period, us (`--sync-period-us`).
    pub sync_period_us: Option<u32>,
    /// candump log: the time base (`--time-base`); `None`: told from the capture.
    pub time_base: Option<candump::TimeBase>,
}

/// The columns `analyze` keeps of a CSV trace (either layout); the others are read as
/// numbers, checked for whole values where that decides the layout, and dropped.
const ANALYZE_COLUMNS: &[&str] = &[
    // the sample log (and the t_s layout)
    "t_s",
    "mode_display",
    "target_uu",
    "setpoint_velocity_uu_s",
    "position_uu",
    "direct_position_uu",
    "velocity_uu_s",
    "current_permille",
    // the simulator's trace
    "time_s",
    "position_setpoint_mm",
    "position_setpoint_deg",
    "motor_encoder_position_mm",
    "motor_encoder_position_deg",
    "direct_encoder_position_mm",
    "direct_encoder_position_deg",
    "motor_velocity_rpm",
    "motor_current_a",
];

/// Build the detector's trace from either CSV layout.
pub fn trace_from_csv(path: &Path, rotary: bool) -> anyhow::Result<AxisTrace> {
    match trace_from_csv_lines(path, TraceLines::open(path)?, rotary)? {
        Some((t, _)) => Ok(t),
        None => anyhow::bail!("{}: a candump log, not a CSV trace", path.display()),
    }
}

/// The trace of a CSV read line by line (never held whole), and the reader's notes; `None`
/// when the file is a candump log.
fn trace_from_csv_lines(
    path: &Path,
    lines: TraceLines<'_>,
    rotary: bool,
) -> anyhow::Result<Option<(AxisTrace, Vec<String>)>> {
    let csv = match read_csv_stream(lines, |n| ANALYZE_COLUMNS.contains(&n))? {
        Streamed::Candump => return Ok(None),
        Streamed::Csv(c) => c,
    };
    let source = path.display().to_string();
    let tr = trace_from_parts(&source, &csv.columns, &csv.whole, rotary)?;
    Ok(Some((tr, csv.notes)))
}

/// Build the detector's trace from named columns as either CSV layout has them (the
/// simulator's trace or the sample log; see the module doc); `source` names them in errors.
pub fn trace_from_columns(source: &str, cols: &Columns, rotary: bool) -> anyhow::Result<AxisTrace> {
    trace_from_parts(source, cols, &[], rotary)
}

/// [`trace_from_columns`], where `whole` names columns read but not kept, with whether each
/// held only finite whole numbers.
fn trace_from_parts(
    source: &str,
    cols: &Columns,
    whole: &[(String, bool)],
    rotary: bool,
) -> anyhow::Result<AxisTrace> {
    let find = |names: &[&str]| -> Option<&Vec<f64>> {
        cols.iter()
            .find(|(n, _)| names.contains(&n.as_str()))
            .map(|(_, v)| v)
    };
    let need = |names: &[&str]| -> anyhow::Result<&Vec<f64>> {
        find(names).with_context(|| format!("{source}: no column {}", names.join(" or ")))
    };
    let tr = if let Some(tr) = sample_log_trace(&find, whole, rotary) {
        // A sample log (`run --trace`, a scenario's samples.csv): read as the drive's own
        // samples, as `run --detect` reads them (the set speed from the position demand;
        // in CSV/PV from the velocity column).
        let mut tr = tr;
        tr.set_velocity_source = format!("columns of the sample log: {}", tr.set_velocity_source);
        tr
    } else if find(&["t_s"]).is_some() {
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
            set_velocity_source: "column target_uu (position demand)".into(),
            set_position: need(&["target_uu"])?.clone(),
            time_base: String::new(),
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
    tr.check().map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
    Ok(tr)
}

/// The trace of a sample log with every column of [`Sample::CSV_HEADER`] and whole numbers in
/// its integer columns (kept in `find`, or read and dropped: `whole`), else None.
fn sample_log_trace<'a>(
    find: &impl Fn(&[&str]) -> Option<&'a Vec<f64>>,
    whole: &[(String, bool)],
    rotary: bool,
) -> Option<AxisTrace> {
    let col = |n: &str| find(&[n]);
    // A column only checked: present, and whether all its values were whole.
    let checked = |n: &str| -> Option<bool> {
        match col(n) {
            Some(c) => Some(c.iter().all(|x| x.is_finite() && x.fract() == 0.0)),
            None => whole.iter().find(|(w, _)| w == n).map(|(_, ok)| *ok),
        }
    };
    let t = col("t_s")?;
    let (sw, mode, target, sv) = (
        checked("statusword")?,
        col("mode_display")?,
        col("target_uu")?,
        col("setpoint_velocity_uu_s")?,
    );
    let (pos, direct, vel) = (
        col("position_uu")?,
        col("direct_position_uu")?,
        col("velocity_uu_s")?,
    );
    let (torque, current, ferr) = (
        checked("torque_permille")?,
        col("current_permille")?,
        checked("following_error_uu")?,
    );
    // Whole numbers in the drive's objects; anything else (NaN, a value cut) is read by
    // columns as it is.
    let whole = sw
        && torque
        && ferr
        && [mode, pos, direct, vel, current]
            .iter()
            .all(|c| c.iter().all(|x| x.is_finite() && x.fract() == 0.0));
    if !whole {
        return None;
    }
    // The analysis reads no statusword, torque or following error: left 0.
    Some(AxisTrace::from_sample_rows(
        t.len(),
        |k| Sample {
            t_s: t[k],
            mode_display: mode[k] as i8,
            target_uu: target[k],
            setpoint_velocity_uu_s: sv[k],
            position_uu: pos[k] as i32,
            direct_position_uu: direct[k] as i32,
            velocity_uu_s: vel[k] as i32,
            current_permille: current[k] as i16,
            ..Sample::default()
        },
        SampleSource::Drive,
        rotary,
    ))
}

/// Everything `analyze` says, for `--json`.
#[derive(Debug, serde::Serialize)]
pub struct AnalyzeOutput {
    pub trace: String,
    /// "candump", "csv" or "columns" (arrays given to the Python module).
    pub format: &'static str,
    pub kv_per_s: f64,
    /// "--kv", "0x2007 written in the capture", "preset cnc1".
    pub kv_source: String,
    /// What the reader noticed (a cut last line, decoding notes).
    pub notes: Vec<String>,
    /// candump: the decoding summary.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub capture: Option<String>,
    pub report: crate::analysis::detector::DetectorReport,
    pub exit_code: u8,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub plots: Vec<PathBuf>,
    pub report_dir: PathBuf,
}

/// Exit status of `analyze` for a verdict.
pub fn exit_code(verdict: Verdict, fail_on_backlash: bool) -> u8 {
    match verdict {
        Verdict::Inconclusive => 3,
        Verdict::Ok => 0,
        Verdict::BacklashSuspected | Verdict::Backlash if fail_on_backlash => 1,
        _ => 0,
    }
}

/// A usage error (exit 2, as clap's).
#[derive(Debug)]
pub struct UsageError(pub String);
impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}
impl std::error::Error for UsageError {}

fn preset_kv(name: &str) -> anyhow::Result<f64> {
    let cfg = crate::presets::AxisConfig::from_preset(name)
        .map_err(|e| UsageError(format!("--preset {name}: {e}")))?;
    Ok(cfg.kv_per_s)
}

/// What [`analyze_input`] takes the trace from.
#[derive(Clone, Copy, Debug)]
pub enum AnalyzeInput<'a> {
    /// The file [`AnalyzeRequest::trace`]: a candump log or a CSV trace.
    File,
    /// The content of such a file, in memory (named [`AnalyzeRequest::trace`] in messages), read as the
    /// file would be (gzip or plain, the same caps).
    Bytes(&'a [u8]),
    /// Named columns as a CSV trace has them (the Python module's arrays), named `source` in
    /// errors.
    Columns {
        source: &'a str,
        columns: &'a Columns,
    },
}

/// What `analyze` found, before it writes anything: the output (without plots or report
/// directory) and the trace the detector ran on (none when the capture lacked objects).
#[derive(Debug)]
pub struct Analysis {
    pub output: AnalyzeOutput,
    pub trace: Option<AxisTrace>,
}

/// The k_v the drive accepts (0x2007), 1/s; `analyze` takes no other.
pub const KV_RANGE_PER_S: (f64, f64) = (1e-9, 1000.0);

fn kv_in_range(kv: f64) -> bool {
    kv.is_finite() && (KV_RANGE_PER_S.0..=KV_RANGE_PER_S.1).contains(&kv)
}

impl Default for AnalyzeRequest {
    /// The command line's defaults (node 5), the trace and k_v still to be set.
    fn default() -> Self {
        Self {
            trace: PathBuf::new(),
            kv_per_s: None,
            rotary: false,
            suspect_um: None,
            alarm_um: None,
            fail_on_backlash: false,
            node: 5,
            preset: None,
            sync_period_us: None,
            time_base: None,
        }
    }
}

impl AnalyzeRequest {
    /// The request of `drive-emu analyze TRACE` with every other flag at its default.
    pub fn new(trace: impl Into<PathBuf>) -> Self {
        Self {
            trace: trace.into(),
            ..Self::default()
        }
    }

    /// Read and decode the trace, find k_v and run the detector: everything `analyze` does
    /// but writing the report directory ([`write_report`]) and printing. A bad field (no k_v,
    /// a threshold out of range) is [`ApiError::Invalid`]; a trace that cannot be read or
    /// decoded is [`ApiError::Unreadable`]. An inconclusive verdict is a result, not an
    /// error.
    pub fn run(&self, input: AnalyzeInput<'_>) -> Result<Analysis, ApiError> {
        analyze_request(self, input).map_err(|e| {
            if e.chain().any(|c| c.downcast_ref::<UsageError>().is_some()) {
                ApiError::Invalid(e)
            } else {
                ApiError::Unreadable(e)
            }
        })
    }
}

/// [`AnalyzeRequest::run`], its errors as they come: a usage error holds [`UsageError`].
fn analyze_request(args: &AnalyzeRequest, input: AnalyzeInput<'_>) -> anyhow::Result<Analysis> {
    check_flags(args)?;
    let preset = args.preset.clone().unwrap_or_else(|| "cnc1".into());
    if args.preset.is_some() {
        preset_kv(&preset)?;
    }
    let read = read_trace(args, input, &preset)?;
    let (kv, kv_source) = kv_in_force(args, read.kv_written)?;
    let cfg = detector_config(args, kv, &read.built, &preset);
    let unit = if args.rotary { "mdeg" } else { "um" };
    let rep = match &read.built {
        Ok(tr) => analyze(tr, &cfg),
        Err(why) => {
            DetectorReport::inconclusive(&cfg, Inconclusive::MissingObjects, why.clone(), unit)
        }
    };
    // The master closes the position loop itself: the band is its gain, fitted.
    let (kv, kv_source) = match rep.master_loop {
        Some(m) => (
            m.kv_per_s,
            format!(
                "the master's own position loop, fitted from the trace; the drive's k_v {kv:.2} \
                 1/s ({kv_source}) is not in the loop"
            ),
        ),
        None => (kv, kv_source),
    };
    let output = AnalyzeOutput {
        trace: match input {
            AnalyzeInput::File | AnalyzeInput::Bytes(_) => args.trace.display().to_string(),
            AnalyzeInput::Columns { source, .. } => source.to_string(),
        },
        format: match input {
            AnalyzeInput::Columns { .. } => "columns",
            AnalyzeInput::File | AnalyzeInput::Bytes(_) if read.candump => "candump",
            AnalyzeInput::File | AnalyzeInput::Bytes(_) => "csv",
        },
        kv_per_s: kv,
        kv_source,
        notes: read.notes,
        capture: read.capture,
        exit_code: exit_code(rep.verdict, args.fail_on_backlash),
        report: rep,
        plots: Vec::new(),
        report_dir: PathBuf::new(),
    };
    Ok(Analysis {
        output,
        trace: read.built.ok(),
    })
}

/// The flags' own limits: `--kv` within the drive's range, `--suspect` and `--alarm` finite
/// and positive.
fn check_flags(args: &AnalyzeRequest) -> anyhow::Result<()> {
    if let Some(kv) = args.kv_per_s {
        if !kv_in_range(kv) {
            return Err(UsageError(format!(
                "--kv {}: must be within the drive's range {} .. {} (1/s)",
                crate::quote::number(kv),
                crate::quote::number(KV_RANGE_PER_S.0),
                crate::quote::number(KV_RANGE_PER_S.1)
            ))
            .into());
        }
    }
    for (name, v) in [("--suspect", args.suspect_um), ("--alarm", args.alarm_um)] {
        if v.is_some_and(|v| !(v > 0.0 && v.is_finite())) {
            return Err(UsageError(format!("{name}: must be a finite number > 0")).into());
        }
    }
    Ok(())
}

/// The trace as read, and what the reading found beside it.
struct ReadTrace {
    /// The detector's trace, or why there is none (a capture without the objects it needs).
    built: Result<AxisTrace, String>,
    /// Notes on the CSV's columns.
    notes: Vec<String>,
    /// A candump log's decoding summary.
    capture: Option<String>,
    /// The k_v a capture writes to 0x2007.
    kv_written: Option<f64>,
    /// The file was a candump log.
    candump: bool,
}

/// Read the trace from `input`: a CSV trace, named columns, or a candump log of our drive
/// with `preset` (all streamed: only the decoded samples are kept).
fn read_trace(
    args: &AnalyzeRequest,
    input: AnalyzeInput<'_>,
    preset: &str,
) -> anyhow::Result<ReadTrace> {
    let path = &args.trace;
    let rotary_units = args.rotary;
    // A CSV is read line by line, and so is a candump log (found by its first line).
    let csv = match input {
        AnalyzeInput::File => trace_from_csv_lines(path, TraceLines::open(path)?, rotary_units)?,
        AnalyzeInput::Bytes(b) => {
            trace_from_csv_lines(path, TraceLines::from_reader(path, b)?, rotary_units)?
        }
        AnalyzeInput::Columns { .. } => None,
    };
    let from_file = matches!(input, AnalyzeInput::File | AnalyzeInput::Bytes(_));
    let mut read = ReadTrace {
        built: Err(String::new()),
        notes: Vec::new(),
        capture: None,
        kv_written: None,
        candump: from_file && csv.is_none(),
    };
    read.built = if let AnalyzeInput::Columns { source, columns } = input {
        Ok(trace_from_columns(source, columns, rotary_units)?)
    } else if let Some((t, n)) = csv {
        read.notes.extend(n);
        Ok(t)
    } else {
        read_capture(args, input, preset, &mut read)?
    };
    Ok(read)
}

/// Decode a candump log of node `args.node` of our drive with `preset` into the detector's
/// trace, its summary and the k_v it writes into `read`; streamed as the CSV is: only the
/// decoded samples are kept, never the log's text.
fn read_capture(
    args: &AnalyzeRequest,
    input: AnalyzeInput<'_>,
    preset: &str,
    read: &mut ReadTrace,
) -> anyhow::Result<Result<AxisTrace, String>> {
    let path = &args.trace;
    let mut lines = match input {
        AnalyzeInput::Bytes(b) => TraceLines::from_reader(path, b)?,
        _ => TraceLines::open(path)?,
    };
    let (defaults, preset_rotary) = candump::PdoConfig::drive_defaults(args.node, preset)?;
    let log = candump::decode_lines(
        &mut lines,
        &path.display().to_string(),
        &candump::DecodeOptions {
            node_id: args.node,
            defaults,
            sync_period_us: args.sync_period_us,
        },
    )?;
    drop(lines);
    read.capture = Some(log.summary());
    read.kv_written = log.kv_written;
    match log.to_axis_trace_on(args.rotary || preset_rotary, args.time_base) {
        Ok(t) => Ok(Ok(t)),
        Err(e) => match e.downcast::<candump::MissingObjects>() {
            Ok(m) => Ok(Err(m.0)),
            Err(e) => Err(e),
        },
    }
}

/// The k_v the band is judged against and where it came from: `--kv`, else the one the
/// capture writes (within the drive's range), else the preset's.
fn kv_in_force(args: &AnalyzeRequest, kv_written: Option<f64>) -> anyhow::Result<(f64, String)> {
    if let (None, Some(k)) = (args.kv_per_s, kv_written) {
        if !kv_in_range(k) {
            return Err(UsageError(format!(
                "the capture writes k_v = {} 1/s to 0x2007, outside the drive's range {} .. {} \
                 (the drive refuses it): give the k_v in effect with --kv",
                crate::quote::number(k),
                crate::quote::number(KV_RANGE_PER_S.0),
                crate::quote::number(KV_RANGE_PER_S.1)
            ))
            .into());
        }
    }
    Ok(match (args.kv_per_s, kv_written, &args.preset) {
        (Some(k), _, _) => (k, "--kv".to_string()),
        (None, Some(k), _) => (k, "0x2007 kv_per_s written in the capture".to_string()),
        (None, _, Some(p)) => (preset_kv(p)?, format!("preset {p}")),
        (None, _, None) => {
            return Err(UsageError(
                "no k_v: give --kv, or --preset (its k_v), or a capture that writes 0x2007".into(),
            )
            .into())
        }
    })
}

/// The detector's settings: k_v, the flags' thresholds, and the preset's mechanics for the
/// gap estimate in the trace's current unit.
fn detector_config(
    args: &AnalyzeRequest,
    kv: f64,
    built: &Result<AxisTrace, String>,
    preset: &str,
) -> DetectorConfig {
    let mut cfg = DetectorConfig::new(kv);
    if let Some(s) = args.suspect_um {
        cfg.suspect_um = s;
    }
    if let Some(a) = args.alarm_um {
        cfg.alarm_um = a;
    }
    cfg.gap = match (built, crate::presets::AxisConfig::from_preset(preset)) {
        (Ok(tr), Ok(axis)) => crate::analysis::gap::GapModel::current_unit(&tr.current_unit)
            .and_then(|u| crate::analysis::gap::GapModel::for_axis(&axis, u)),
        _ => None,
    };
    cfg
}

/// Write the report directory of an analysis (`detector.json`, and the plots when windows
/// were measured) to `out` and record it in the output.
pub fn write_report(analysis: &mut Analysis, out: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let output = &mut analysis.output;
    if let Some(tr) = &analysis.trace {
        if !output.report.windows.is_empty() {
            output.plots = crate::report::detector_plots(out, "", tr, &output.report, None)?;
        }
    }
    crate::report::write_json(&out.join("detector.json"), &output.report)?;
    output.report_dir = out.to_path_buf();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn drive_sample() -> impl Strategy<Value = (u64, Sample)> {
        (
            1u64..5_000,
            (any::<u16>(), prop::sample::select(vec![1i8, 3, 6, 7, 8, 9])),
            (-1_000_000i32..1_000_000, -100_000i32..100_000),
            (any::<i32>(), any::<i32>(), any::<i32>(), any::<i32>()),
            (any::<i16>(), any::<i16>()),
        )
            .prop_map(|(dt, (sw, mode), (dem, vdem), (p, d, v, fe), (tq, cur))| {
                let s = Sample {
                    t_s: 0.0,
                    statusword: sw,
                    mode_display: mode,
                    target_uu: f64::from(dem),
                    setpoint_velocity_uu_s: f64::from(vdem),
                    position_uu: p,
                    direct_position_uu: d,
                    velocity_uu_s: v,
                    torque_permille: tq,
                    current_permille: cur,
                    following_error_uu: fe,
                };
                (dt, s)
            })
    }

    proptest! {
        /// A drive's sample log (`run --trace`, a panel recording) read back by `analyze` is
        /// the trace `run --detect` analyses in memory: the same numbers, to the bit.
        #[test]
        fn a_drive_sample_log_reads_back_as_the_trace_analysed_live(
            start_us in 0u64..100_000_000_000,
            rows in prop::collection::vec(drive_sample(), 2..200),
        ) {
            let mut t_us = start_us;
            let samples: Vec<Sample> = rows
                .into_iter()
                .map(|(dt, mut s)| {
                    t_us += dt;
                    s.t_s = Sample::t_s_of_us(t_us);
                    s
                })
                .collect();
            let mut text = format!("{}\n", Sample::CSV_HEADER).into_bytes();
            for s in &samples {
                s.write_csv_row(&mut text).unwrap();
            }
            let text = String::from_utf8(text).unwrap();
            let lines = TraceLines::from_reader(Path::new("trace.csv"), text.as_bytes()).unwrap();
            let (read, notes) = trace_from_csv_lines(Path::new("trace.csv"), lines, false)
                .unwrap()
                .expect("a CSV");
            prop_assert!(notes.is_empty(), "{:?}", notes);
            let mut live = AxisTrace::from_sample_log(&samples, SampleSource::Drive, false);
            live.set_velocity_source = read.set_velocity_source.clone();
            prop_assert_eq!(read, live);
        }
    }
}
