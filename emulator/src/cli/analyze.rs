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
use crate::api::{AnalyzeRequest, ApiError};
use std::path::PathBuf;

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

impl AnalyzeArgs {
    /// The request these arguments make.
    pub fn request(&self) -> AnalyzeRequest {
        AnalyzeRequest {
            trace: self.trace.clone(),
            kv_per_s: self.kv,
            rotary: self.rotary,
            suspect_um: self.suspect,
            alarm_um: self.alarm,
            fail_on_backlash: self.fail_on_backlash,
            node: self.node,
            preset: self.preset.clone(),
            sync_period_us: self.sync_period_us,
            time_base: self.time_base.base(),
        }
    }
}

pub use crate::api::analyze::{
    exit_code, trace_from_columns, trace_from_csv, write_report, Analysis, AnalyzeInput,
    AnalyzeOutput, UsageError, KV_RANGE_PER_S,
};

/// Read and decode the trace, find k_v and run the detector ([`AnalyzeRequest::run`] of the
/// arguments): a usage error (bad flags, no k_v) is an error whose chain holds
/// [`UsageError`].
pub fn analyze_input(args: &AnalyzeArgs, input: AnalyzeInput<'_>) -> anyhow::Result<Analysis> {
    args.request().run(input).map_err(ApiError::into_anyhow)
}

/// `drive-emu analyze`: exit 2 for usage errors, 4 when the trace cannot be read, else the
/// verdict's code ([`exit_code`]).
pub fn run(args: &AnalyzeArgs) -> anyhow::Result<std::process::ExitCode> {
    if let Some(spec) = &args.ballbar {
        let ballbar = super::analyze_ballbar::BallbarArgs {
            trace: &args.trace,
            preset: args.preset.as_deref(),
            sync_period_us: args.sync_period_us,
            radius_mm: args.radius_mm,
            json: args.json,
        };
        super::analyze_ballbar::run(&ballbar, spec)?;
        return Ok(std::process::ExitCode::SUCCESS);
    }
    match run_inner(args) {
        Ok(code) => Ok(std::process::ExitCode::from(code)),
        Err(e) => {
            eprintln!("drive-emu analyze: error: {e:#}");
            Ok(std::process::ExitCode::from(e.exit_code()))
        }
    }
}

/// The analysis, its report written and printed; an error that is not the request's (the
/// report cannot be written) says exit status 4, as one reading the trace does.
fn run_inner(args: &AnalyzeArgs) -> Result<u8, ApiError> {
    let mut analysis = args.request().run(AnalyzeInput::File)?;
    let out = args.out.clone().unwrap_or_else(|| {
        let stem = args
            .trace
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("trace");
        PathBuf::from("out").join(format!("analyze-{stem}"))
    });
    // exit status 4 as before the typed API: `analyze` says 2 or 4 on every error
    write_report(&mut analysis, &out).map_err(ApiError::Unreadable)?;
    let output = analysis.output;
    let code = output.exit_code;
    if args.json {
        let text =
            serde_json::to_string_pretty(&output).map_err(|e| ApiError::Unreadable(e.into()))?;
        println!("{text}");
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
