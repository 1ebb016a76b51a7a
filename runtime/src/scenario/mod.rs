//! Scenarios: a machine, a motion program for the reference master, a timeline of events (wear,
//! sensor and CAN faults) and expectations, in one TOML file. See `scenarios/README.md` for the
//! format.
//!
//! - [`parse`] / [`load`]: strict parsing; every error names file, line, key and reason.
//! - [`timeline::Timeline`]: which events are due at a time; usable from any loop.
//! - [`expect`]: checking a run's record against the expectations.
//! - [`runner`]: offline lock-step execution with idle fast-forward, detector and report.

pub mod expect;
pub mod file;
pub mod inject;
pub mod live;
pub mod runner;
pub mod timeline;
pub mod units;
mod validate;

use crate::master::{MasterConfig, Step};
use std::fmt;
use std::path::{Path, PathBuf};

pub use file::{ProgramOutcome, Verdict};
pub use units::{ParamKey, Time};

/// A scenario file problem: where and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScenarioError {
    pub file: PathBuf,
    /// 1-based; 0 when the file could not be read.
    pub line: usize,
    pub column: usize,
    /// The offending key (dotted from its table when known), e.g. `motion[2].duration`.
    pub key: String,
    pub reason: String,
}

impl ScenarioError {
    /// The reason as printed: it may repeat the file's text (a name, a value), so control
    /// characters are escaped and its length capped.
    fn reason(&self) -> String {
        crate::quote::text_max(&self.reason, 2 * crate::quote::MAX_MESSAGE_CHARS)
    }
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match (self.line, self.key.is_empty()) {
            (0, _) => write!(f, "{}: {}", self.file.display(), self.reason()),
            (_, true) => write!(
                f,
                "{}:{}:{}: {}",
                self.file.display(),
                self.line,
                self.column,
                self.reason()
            ),
            _ => write!(
                f,
                "{}:{}:{}: key `{}`: {}",
                self.file.display(),
                self.line,
                self.column,
                crate::quote::text(&self.key),
                self.reason()
            ),
        }
    }
}

impl std::error::Error for ScenarioError {}

/// 1-based line and column of a byte offset.
pub(crate) fn line_col(src: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(src.len());
    let before = &src[..offset];
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    (line, col)
}

/// The `[table]` / `[[array]]` header in force at `offset`, as `name` or `name[i]` (0-based).
fn table_at(src: &str, offset: usize) -> Option<String> {
    let mut current: Option<String> = None;
    let mut counts: std::collections::HashMap<String, usize> = Default::default();
    let mut pos = 0;
    for line in src.split_inclusive('\n') {
        if pos > offset {
            break;
        }
        let t = line.trim();
        if let Some(name) = t.strip_prefix("[[").and_then(|r| r.split("]]").next()) {
            let name = name.trim().to_string();
            let n = counts.entry(name.clone()).or_insert(0);
            current = Some(format!("{name}[{n}]"));
            *n += 1;
        } else if let Some(name) = t.strip_prefix('[').and_then(|r| r.split(']').next()) {
            current = Some(name.trim().to_string());
        }
        pos += line.len();
    }
    current
}

fn is_key_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_' || c == '-'
}

/// The key whose value (or which itself) starts at `offset`.
fn key_at(src: &str, offset: usize) -> Option<String> {
    let offset = offset.min(src.len());
    let rest = &src[offset..];
    // The span is a bare key followed by `=`.
    let word: String = rest.chars().take_while(|c| is_key_char(*c)).collect();
    if !word.is_empty() && rest[word.len()..].trim_start().starts_with('=') {
        return Some(word);
    }
    // The span is a value: the key is before the nearest `=` to the left on this line.
    let line_start = src[..offset].rfind('\n').map_or(0, |i| i + 1);
    let before = &src[line_start..offset];
    let eq = before.rfind('=')?;
    let k: String = before[..eq]
        .trim_end()
        .chars()
        .rev()
        .take_while(|c| is_key_char(*c) || *c == '.')
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect();
    (!k.is_empty()).then_some(k)
}

pub(crate) fn error_at(
    src: &str,
    file: &Path,
    span: std::ops::Range<usize>,
    key: Option<&str>,
    reason: impl Into<String>,
) -> ScenarioError {
    let (line, column) = line_col(src, span.start);
    let key = key.map(str::to_string).or_else(|| key_at(src, span.start));
    let key = match (table_at(src, span.start), key) {
        (Some(t), Some(k)) if !k.starts_with(&t) => format!("{t}.{k}"),
        (_, Some(k)) => k,
        (Some(t), None) => t,
        (None, None) => String::new(),
    };
    ScenarioError {
        file: file.to_path_buf(),
        line,
        column,
        key,
        reason: reason.into(),
    }
}

/// Motion program entry: a master step, or an idle period the engine may fast-forward.
#[derive(Debug, Clone, PartialEq)]
pub enum ProgramStep {
    Master(Step),
    /// The machine stands still for `duration_us` of scenario time (between measurement passes).
    Idle {
        duration_us: u64,
    },
}

/// The machine: preset(s) and overrides of preset-file keys.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineSpec {
    /// One preset, or several for a sweep (the scenario runs once per preset).
    pub presets: Vec<String>,
    /// (preset key, value as TOML), in file order.
    pub overrides: Vec<(String, String)>,
    /// Each preset with the overrides applied.
    pub configs: Vec<crate::presets::AxisConfig>,
    /// Whether the file's position/velocity keys are rotary (deg) or linear (mm); None if the
    /// program uses neither.
    pub rotary_units: Option<bool>,
}

/// Physical time and rates of the run.
#[derive(Debug, Clone)]
pub struct RunSpec {
    pub master: MasterConfig,
    /// Physics tick, us.
    pub tick_us: u64,
    pub seed: u64,
    /// Stop at this scenario time (default: when the motion program ends).
    pub duration_us: Option<u64>,
    pub fast_forward_idle: bool,
}

/// Detector settings from the file (None = the detector's defaults).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DetectorSpec {
    pub enabled: bool,
    pub kv_per_s: Option<f64>,
    pub suspect_um: Option<f64>,
    pub alarm_um: Option<f64>,
    pub min_window_s: Option<f64>,
    pub settle_s: Option<f64>,
    pub confirm_windows: Option<usize>,
}

/// A parsed and validated scenario.
#[derive(Debug, Clone)]
pub struct Scenario {
    pub name: String,
    pub description: String,
    pub path: PathBuf,
    pub machine: MachineSpec,
    pub run: RunSpec,
    pub program: Vec<ProgramStep>,
    pub events: Vec<timeline::Event>,
    pub expectations: Vec<expect::Expect>,
    pub detector: DetectorSpec,
}

impl Scenario {
    /// The program as the master runs it: idle steps become dwells of `idle_dwell_s` (fast
    /// forward) or of their full length. Returns the steps and, per master step, the scenario
    /// time it skips when fast-forwarded.
    pub fn master_program(&self, idle_dwell_s: f64) -> (Vec<Step>, Vec<u64>) {
        let mut steps = Vec::new();
        let mut skip = Vec::new();
        for s in &self.program {
            match s {
                ProgramStep::Master(m) => {
                    steps.push(m.clone());
                    skip.push(0);
                }
                ProgramStep::Idle { duration_us } => {
                    if self.run.fast_forward_idle {
                        let dwell_us = ((idle_dwell_s * 1e6) as u64).min(*duration_us);
                        steps.push(Step::Dwell {
                            duration_s: dwell_us as f64 * 1e-6,
                        });
                        skip.push(duration_us - dwell_us);
                    } else {
                        steps.push(Step::Dwell {
                            duration_s: *duration_us as f64 * 1e-6,
                        });
                        skip.push(0);
                    }
                }
            }
        }
        (steps, skip)
    }

    /// Total scenario time of the motion program, ignoring the time to boot and enable.
    pub fn program_duration_us(&self) -> u64 {
        self.program
            .iter()
            .map(|s| match s {
                ProgramStep::Idle { duration_us } => *duration_us,
                ProgramStep::Master(Step::Cruise { duration_s, .. })
                | ProgramStep::Master(Step::Dwell { duration_s }) => (duration_s * 1e6) as u64,
                _ => 0,
            })
            .sum()
    }
}

/// Largest scenario file read, bytes (8 MiB: 130 000 events of four lines; the counts below
/// bind first for files of ordinary events). Checked before the file is parsed, so a huge
/// file costs neither time nor memory: the TOML parser holds the whole document, 30-65 bytes
/// per byte of text (a file at the cap: about 0.5 GB and 1 s, measured).
pub const MAX_FILE_BYTES: u64 = 8 << 20;
/// Most `[[event]]`s a scenario has (ramps and load profiles included).
pub const MAX_EVENTS: usize = 100_000;
/// Most `[[expect]]`s a scenario has (each is checked against the whole sample log).
pub const MAX_EXPECTATIONS: usize = 1_000;
/// Most motion steps, with every `repeat` unrolled.
pub const MAX_PROGRAM_STEPS: usize = 1_000_000;

/// Parse a scenario from text; `file` is used in error messages.
pub fn parse(src: &str, file: &Path) -> Result<Scenario, ScenarioError> {
    let raw: file::RawScenario = toml::from_str(src).map_err(|e| {
        let span = e.span().unwrap_or(0..0);
        let msg = e.message().to_string();
        // serde's unknown-field message names the key: use it.
        let key = msg
            .strip_prefix("unknown field `")
            .and_then(|r| r.split('`').next())
            .map(str::to_string);
        let reason = crate::quote::text_max(msg.trim(), crate::quote::MAX_MESSAGE_CHARS);
        error_at(src, file, span, key.as_deref(), reason)
    })?;
    validate::validate(raw, src, file)
}

/// Refuse a scenario whose bus faults are not of the bus `on` ("can", "ethercat"; the
/// offline runner's simulated bus is CAN): the file, the event's line and why.
pub fn check_bus(s: &Scenario, on: &str) -> anyhow::Result<()> {
    for e in &s.events {
        if let Some(bus) = e.action.bus().filter(|b| *b != on) {
            anyhow::bail!(
                "{}: line {}: `{bus}` fault ({}) on {}: {}",
                s.name,
                e.line,
                e.describe(),
                if on == "can" { "a CAN bus" } else { "EtherCAT" },
                if bus == "ethercat" {
                    "EtherCAT faults need `drive-emu run --ethercat IFACE --scenario FILE`"
                } else {
                    "CAN faults need a CAN bus (`drive-emu run --scenario` or `drive-emu scenario`)"
                }
            );
        }
    }
    Ok(())
}

/// The action of an `[[event]]` given outside a file (the live panel's JSON deserialised into
/// the file reader's own [`file::RawEvent`]), checked as in a file, on a `rotary` or linear
/// axis; the error names the key at fault.
pub fn action_of(raw: &file::RawEvent, rotary: bool) -> Result<timeline::Action, ScenarioError> {
    validate::action_of(raw, rotary)
}

/// Read and parse a scenario file (at most [`MAX_FILE_BYTES`]; a longer one, or an endless
/// one such as `/dev/zero`, is refused after reading one byte beyond the cap).
pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
    use std::io::Read;
    let err = |reason: String| ScenarioError {
        file: path.to_path_buf(),
        line: 0,
        column: 0,
        key: String::new(),
        reason,
    };
    let crate::infile::Opened { file, size } =
        crate::infile::open(path, "").map_err(|e| err(e.reason()))?;
    let too_long = |bytes: String| {
        err(format!(
            "{bytes} bytes, above the cap of {MAX_FILE_BYTES} bytes ({} MiB) for a scenario \
             file (at most {MAX_EVENTS} events, {MAX_EXPECTATIONS} expectations and \
             {MAX_PROGRAM_STEPS} motion steps)",
            MAX_FILE_BYTES >> 20
        ))
    };
    if size > MAX_FILE_BYTES {
        return Err(too_long(size.to_string()));
    }
    let mut bytes = Vec::new();
    file.take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| err(format!("cannot read: {e}")))?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(too_long(format!("more than {MAX_FILE_BYTES}")));
    }
    let src = String::from_utf8(bytes).map_err(|e| {
        let (line, column) = line_col_bytes(e.as_bytes(), e.utf8_error().valid_up_to());
        ScenarioError {
            line,
            column,
            ..err("not UTF-8 text (a TOML file is UTF-8)".into())
        }
    })?;
    parse(&src, path)
}

/// 1-based line and column of a byte offset in bytes that may not be UTF-8.
fn line_col_bytes(bytes: &[u8], offset: usize) -> (usize, usize) {
    let before = &bytes[..offset.min(bytes.len())];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let col = offset
        - before
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |i| i + 1)
        + 1;
    (line, col)
}
