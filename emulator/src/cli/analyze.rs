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
use crate::analysis::detector::{
    analyze, AxisTrace, DetectorConfig, DetectorReport, Inconclusive, Verdict,
};
use crate::analysis::windows::{set_velocity_from_demand, DEMAND_SPAN_S};
use crate::samples::csv::{read_csv_stream, Columns, Streamed, TraceLines};
use crate::samples::{Sample, SampleSource};
use anyhow::Context;
use std::path::{Path, PathBuf};

/// Arguments of `drive-emu analyze`.
#[derive(clap::Args, Debug, Clone)]
#[command(after_help = "\
TRACE formats, recognised by content (gzip-compressed files are read too; at most 256 MiB,
lines at most 64 KiB):
  candump log  `candump -L` (`(1700000000.123456) vcan0 185#...`) or `candump -ta`; decoded with
               the PDO mapping of drive --node/--preset, following the SDO remaps and NMT resets
               in the log, and the set-points written over SDO; one sample per SYNC.
  CSV          `drive-emu run --trace`, `drive-emu sim --trace`, a scenario report's samples.csv.
  A last line cut short (a writer killed mid-line) is skipped and reported, not an error.

Time base of a candump log (--time-base): each sample is a SYNC's row, the set-points in force at
it and the drive's synchronous TPDOs that answered it (taken in order: a drive that falls
behind answers late, and its answers still go to the SYNCs they answer). A drive on its own
clock (a real drive, `run`) samples when the SYNC comes: the samples go at the SYNCs' time
stamps, so late and lost SYNCs are where they happened. A drive clocked by SYNC (`run
--lockstep`) moves one period per SYNC whatever the wall clock did: sample k goes at k x the
period. By default the capture tells which: the axis's increments between SYNCs regressed on the
intervals (slope 1: stamps, 0: count); the report says which and why. On uneven times the
spectra are weighted least-squares sine fits on the samples' own times (a Lomb-Scargle
periodogram; even samples: the FFT, which it equals there). Limits: the band stops at the mean
sample rate / 2.5; a gap longer than half a period of k_v/4 (2/k_v: 67 ms at 30 1/s) ends a
window; a value answered in a burst after a stall is taken at its SYNC's stamp, not at the
time the drive sampled it; an uneven capture spreads a line's leakage over the band, so its
prominence is measured once the line is taken out.

A master that closes the position loop itself (the paper's CNCs: position loop in the NC on
the direct encoder, speed set-points to the drive in CSV): in each window the set velocity is
fitted as v0 + a t - k x(t - lag), x the direct or motor position the master had from the
drive (lags of 0-3 set-points); where that explains 80 % or more of the set-point's motion
in most windows, the set-point follows the axis: its motion is the loop's answer, not a force,
the windows are measured, and the limit cycle is judged against the master's k (fitted,
reported, and the band k/4..k), not the drive's k_v. A set-point that does not follow the
axis (its own jitter, a task that beats with SYNC) stays `set_point_not_constant`.

Constant-speed windows: from the set-point in force (CSP 0x607A targets, CSV/PV 0x60FF, in an
RPDO or written over SDO); where there is none (a PP move, an unknown mode) from the actual
position (constant speed over 0.5 s); where set-points jitter so that no stretch is exactly
constant, constant on average over 0.5 s. The report says which source was used. A window
is not measured when the set-point itself moves in the search band by the suspect level and
half the speed's line (jitter, a set-point task that beats with SYNC: the axis is forced),
or when the axis does not follow the set speed (a drive in fault).

Verdicts and reasons:
  ok                  windows were measured; no in-band line above the suspect threshold
  backlash_suspected  line in k_v/4..k_v, prominent, amplitude >= --suspect (default 1 µm or mdeg)
  backlash            ... amplitude >= --alarm (default 3 µm or mdeg); a level holds when the last
                      2 windows, or windows of 2 s in all, agree (the lowest of them)
  inconclusive        nothing measured: no_constant_speed, too_short (settle 0.4 s + 1 s
                      needed), missing_objects (no motor speed 0x606C, no set-point or
                      position), no_finite_samples (NaN), set_point_not_constant (every
                      window forced by the set-point), axis_not_following (in every
                      window the axis did not follow the set speed)
Every verdict is printed with its reasons: the windows, frequency against the band, prominence,
amplitude against the threshold.

Exit status: 0 verdict given (ok, or backlash without --fail-on-backlash); 1 backlash or
backlash_suspected with --fail-on-backlash; 2 usage error (bad flags, no k_v known);
3 inconclusive; 4 the trace cannot be read (missing file, malformed line, too large).

Example: drive-emu analyze run.log --node 5 --preset cnc1      # k_v from 0x2007 or the preset")]
pub struct AnalyzeArgs {
    /// Trace: candump log (`candump -L` / `-ta`), simulator trace CSV or master sample log CSV.
    pub trace: PathBuf,
    /// Position-loop gain k_v of the axis, 1/s (the band check is k_v/4 .. k_v). Default: the
    /// last k_v written to 0x2007 over SDO in a candump log, else --preset's k_v.
    #[arg(long)]
    pub kv: Option<f64>,
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
    /// Output directory (default out/analyze-TRACE_STEM/).
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Exit with status 1 when backlash is found (verdict backlash or backlash_suspected).
    #[arg(long)]
    pub fail_on_backlash: bool,
    /// Print everything as one JSON document on stdout (verdict, reasons, windows, k_v and
    /// its source, what was decoded) instead of text.
    #[arg(long)]
    pub json: bool,
    /// candump log: node ID of the drive.
    #[arg(long, default_value_t = 5)]
    pub node: u8,
    /// Preset of the drive: its k_v when --kv is not given (and the log wrote no 0x2007);
    /// for a candump log also its default PDO mapping and units (default cnc1).
    #[arg(long)]
    pub preset: Option<String>,
    /// candump log: SYNC period, us (default: 0x1006 if written in the log, else the median
    /// SYNC interval of the timestamps; a lock-step drive's time per SYNC: 0x1006, else 0x60C2
    /// as written, else that median); places sample k at k x this period.
    #[arg(long)]
    pub sync_period_us: Option<u32>,
    /// candump log: when each sample was taken: `stamps` (the SYNC's time stamp in the log: a
    /// drive on its own clock), `sync-count` (k x the SYNC period: a drive clocked by SYNC,
    /// `run --lockstep`); default: told from the capture (which clock the axis moves on).
    #[arg(long, value_enum, default_value_t = TimeBaseArg::Auto)]
    pub time_base: TimeBaseArg,
    /// candump log of a master interpolating the ballbar's circle (ISO 230-4, both ways) on two
    /// drives in CSP: the ballbar's figures (G, reversal spikes, radius deviation, a backlash
    /// estimate per axis) for nodes X,Y, as `drive-emu ballbar` reports them (docs/ballbar.md).
    #[arg(long, value_name = "X,Y")]
    pub ballbar: Option<String>,
    /// With --ballbar: the nominal radius, mm (default: the commanded circle's, fitted).
    #[arg(long, requires = "ballbar")]
    pub radius_mm: Option<f64>,
}

/// `--time-base`.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TimeBaseArg {
    /// Told from the capture.
    #[default]
    Auto,
    /// The SYNCs' time stamps.
    Stamps,
    /// k x the SYNC period.
    SyncCount,
}

impl TimeBaseArg {
    fn base(self) -> Option<candump::TimeBase> {
        match self {
            TimeBaseArg::Auto => None,
            TimeBaseArg::Stamps => Some(candump::TimeBase::Stamps),
            TimeBaseArg::SyncCount => Some(candump::TimeBase::SyncCount),
        }
    }
}

impl Default for AnalyzeArgs {
    /// The command-line defaults (trace and k_v still to be set).
    fn default() -> Self {
        Self {
            trace: PathBuf::new(),
            kv: None,
            rotary: false,
            suspect: None,
            alarm: None,
            out: None,
            fail_on_backlash: false,
            json: false,
            node: 5,
            preset: None,
            sync_period_us: None,
            time_base: TimeBaseArg::Auto,
            ballbar: None,
            radius_mm: None,
        }
    }
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

/// `drive-emu analyze`: exit 2 for usage errors, 4 when the trace cannot be read, else the
/// verdict's code ([`exit_code`]).
pub fn run(args: &AnalyzeArgs) -> anyhow::Result<std::process::ExitCode> {
    if let Some(spec) = &args.ballbar {
        super::analyze_ballbar::run(args, spec)?;
        return Ok(std::process::ExitCode::SUCCESS);
    }
    match run_inner(args) {
        Ok(code) => Ok(std::process::ExitCode::from(code)),
        Err(e) => {
            let usage = e.downcast_ref::<UsageError>().is_some();
            eprintln!("drive-emu analyze: error: {e:#}");
            Ok(std::process::ExitCode::from(if usage { 2 } else { 4 }))
        }
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
    /// The file `args.trace`: a candump log or a CSV trace.
    File,
    /// The content of such a file, in memory (named `args.trace` in messages), read as the
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

/// Read and decode the trace, find k_v and run the detector: everything `analyze` does but
/// writing the report directory and printing. A usage error (bad flags, no k_v) is an error
/// whose chain holds [`UsageError`]; the Python module's `drive_emu.analyze` calls this.
pub fn analyze_input(args: &AnalyzeArgs, input: AnalyzeInput<'_>) -> anyhow::Result<Analysis> {
    if let Some(kv) = args.kv {
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
    for (name, v) in [("--suspect", args.suspect), ("--alarm", args.alarm)] {
        if v.is_some_and(|v| !(v > 0.0 && v.is_finite())) {
            return Err(UsageError(format!("{name}: must be a finite number > 0")).into());
        }
    }
    let preset = args.preset.clone().unwrap_or_else(|| "cnc1".into());
    if args.preset.is_some() {
        preset_kv(&preset)?;
    }
    let path = &args.trace;
    let mut notes = Vec::new();
    let mut capture = None;
    let mut kv_written = None;
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
    let candump = from_file && csv.is_none();
    let built: Result<AxisTrace, String> = if let AnalyzeInput::Columns { source, columns } = input
    {
        Ok(trace_from_columns(source, columns, rotary_units)?)
    } else if let Some((t, n)) = csv {
        notes.extend(n);
        Ok(t)
    } else {
        // Streamed as the CSV is: only the decoded samples are kept, never the log's text.
        let mut lines = match input {
            AnalyzeInput::Bytes(b) => TraceLines::from_reader(path, b)?,
            _ => TraceLines::open(path)?,
        };
        let (defaults, preset_rotary) = candump::PdoConfig::drive_defaults(args.node, &preset)?;
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
        capture = Some(log.summary());
        kv_written = log.kv_written;
        match log.to_axis_trace_on(rotary_units || preset_rotary, args.time_base.base()) {
            Ok(t) => Ok(t),
            Err(e) => match e.downcast::<candump::MissingObjects>() {
                Ok(m) => Err(m.0),
                Err(e) => return Err(e),
            },
        }
    };
    if let (None, Some(k)) = (args.kv, kv_written) {
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
    let (kv, kv_source) = match (args.kv, kv_written, &args.preset) {
        (Some(k), _, _) => (k, "--kv".to_string()),
        (None, Some(k), _) => (k, "0x2007 kv_per_s written in the capture".to_string()),
        (None, _, Some(p)) => (preset_kv(p)?, format!("preset {p}")),
        (None, _, None) => {
            return Err(UsageError(
                "no k_v: give --kv, or --preset (its k_v), or a capture that writes 0x2007".into(),
            )
            .into())
        }
    };
    let mut cfg = DetectorConfig::new(kv);
    if let Some(s) = args.suspect {
        cfg.suspect_um = s;
    }
    if let Some(a) = args.alarm {
        cfg.alarm_um = a;
    }
    // The preset's mechanics for the gap estimate, in the trace's current unit.
    cfg.gap = match (&built, crate::presets::AxisConfig::from_preset(&preset)) {
        (Ok(tr), Ok(axis)) => crate::analysis::gap::GapModel::current_unit(&tr.current_unit)
            .and_then(|u| crate::analysis::gap::GapModel::for_axis(&axis, u)),
        _ => None,
    };
    let unit = if rotary_units { "mdeg" } else { "um" };
    let rep = match &built {
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
            AnalyzeInput::File | AnalyzeInput::Bytes(_) => path.display().to_string(),
            AnalyzeInput::Columns { source, .. } => source.to_string(),
        },
        format: match input {
            AnalyzeInput::Columns { .. } => "columns",
            AnalyzeInput::File | AnalyzeInput::Bytes(_) if candump => "candump",
            AnalyzeInput::File | AnalyzeInput::Bytes(_) => "csv",
        },
        kv_per_s: kv,
        kv_source,
        notes,
        capture,
        exit_code: exit_code(rep.verdict, args.fail_on_backlash),
        report: rep,
        plots: Vec::new(),
        report_dir: PathBuf::new(),
    };
    Ok(Analysis {
        output,
        trace: built.ok(),
    })
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

fn run_inner(args: &AnalyzeArgs) -> anyhow::Result<u8> {
    let mut analysis = analyze_input(args, AnalyzeInput::File)?;
    let out = args.out.clone().unwrap_or_else(|| {
        let stem = args
            .trace
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("trace");
        PathBuf::from("out").join(format!("analyze-{stem}"))
    });
    write_report(&mut analysis, &out)?;
    let output = analysis.output;
    let code = output.exit_code;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&output)?);
    } else {
        print!("{}", render_text(&output));
    }
    Ok(code)
}

/// The text report: what was read, the verdict line, the reasons, the plots.
pub fn render_text(o: &AnalyzeOutput) -> String {
    use std::fmt::Write as _;
    let rep = &o.report;
    let mut s = String::new();
    if let Some(c) = &o.capture {
        let _ = writeln!(s, "{c}");
    }
    for n in &o.notes {
        let _ = writeln!(s, "note: {n}");
    }
    let _ = writeln!(
        s,
        "verdict {} | amplitude {:.2} {} | severity {:.2} | frequency {} | windows {} | k_v {:.2} 1/s ({}) | report {}",
        rep.verdict.as_str(),
        rep.amplitude,
        crate::report::unit_text(&rep.position_unit),
        rep.severity,
        rep.frequency_hz
            .or(rep.dominant_hz)
            .map_or("-".into(), |f| format!("{f:.2} Hz ({:.2} k_v)", f / o.kv_per_s)),
        rep.windows.len(),
        o.kv_per_s,
        o.kv_source,
        o.report_dir.display()
    );
    let _ = writeln!(s, "  constant speed from: {}", rep.window_source);
    let _ = writeln!(s, "  time: {}", rep.time_base);
    for r in &rep.reasons {
        let _ = writeln!(s, "  {r}");
    }
    for p in &o.plots {
        let _ = writeln!(s, "  {}", p.display());
    }
    let _ = writeln!(s, "exit status {}", o.exit_code);
    s
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
