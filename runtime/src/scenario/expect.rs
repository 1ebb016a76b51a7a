//! Expectations and their evaluation against the record of a run.

use super::file::{ProgramOutcome, Verdict};
use crate::analysis::detector::DetectorReport;
use crate::master::state_name;
use crate::samples::Sample;
use drive_protocol::Cia402State;
use std::collections::HashMap;

#[derive(Debug, Clone, PartialEq)]
pub enum Expectation {
    /// This EMCY code arrives within `within_us` of the event `after` firing (of the start when
    /// `after` is None); `within_us` None = any time.
    Emcy {
        code: u16,
        within_us: Option<u64>,
        after: Option<String>,
    },
    /// No EMCY at all in `from_us .. until_us`.
    NoEmcy { from_us: u64, until_us: Option<u64> },
    /// The drive is in this CiA 402 state at `at_us` (at the end when None).
    State {
        state: Cia402State,
        at_us: Option<u64>,
    },
    /// |following error| stays within `max_uu` while OPERATION ENABLED in `from_us .. until_us`.
    FollowingError {
        max_uu: f64,
        from_us: u64,
        until_us: Option<u64>,
    },
    /// The detector's final verdict; with `by_us`, first confirmed no later than that; with
    /// `not_before_us`, not confirmed (at any level above ok) before that.
    Verdict {
        verdict: Verdict,
        by_us: Option<u64>,
        not_before_us: Option<u64>,
    },
    /// The detected frequency is `hz` within `tolerance_pct`.
    FrequencyHz { hz: f64, tolerance_pct: f64 },
    /// The detected (or, unflagged, dominant) frequency over k_v is within `min .. max`.
    FrequencyOverKv { min: f64, max: f64 },
    /// The master's program finished, or failed.
    Program(ProgramOutcome),
}

/// One expectation with its place in the file.
#[derive(Debug, Clone, PartialEq)]
pub struct Expect {
    pub what: Expectation,
    pub line: usize,
}

/// What a run produced, in scenario time.
#[derive(Debug, Clone, Default)]
pub struct RunRecord {
    /// The master's per-SYNC samples, `t_s` in scenario time.
    pub samples: Vec<Sample>,
    /// (scenario time us, EMCY code).
    pub emcys: Vec<(u64, u16)>,
    /// Firing time of each event with an id.
    pub events: HashMap<String, u64>,
    pub detector: Option<DetectorReport>,
    pub program_finished: bool,
    pub program_error: Option<String>,
    pub end_us: u64,
}

/// The outcome of one expectation.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ExpectResult {
    pub line: usize,
    pub expectation: String,
    pub passed: bool,
    pub detail: String,
}

impl std::fmt::Display for ExpectResult {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} line {}: {} ({})",
            if self.passed { "ok  " } else { "FAIL" },
            self.line,
            self.expectation,
            self.detail
        )
    }
}

fn secs(us: u64) -> f64 {
    us as f64 * 1e-6
}

/// A duration for people: "10 ms", "1.5 s".
pub fn seconds_text(us: u64) -> String {
    if us < 1_000_000 {
        format!("{} ms", fs(us * 1000))
    } else {
        format!("{} s", fs(us))
    }
}

/// Seconds, at most three decimals, no trailing zeros.
fn fs(us: u64) -> String {
    let s = format!("{:.3}", secs(us));
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

impl Expectation {
    pub fn describe(&self) -> String {
        match self {
            Expectation::Emcy {
                code,
                within_us,
                after,
            } => {
                let mut s = format!("EMCY {code:#06X} ({})", crate::master::emcy_name(*code));
                if let Some(w) = within_us {
                    s += &format!(" within {} s", fs(*w));
                }
                if let Some(a) = after {
                    s += &format!(" after event `{a}`");
                }
                s
            }
            Expectation::NoEmcy { from_us, until_us } => format!(
                "no EMCY from {} s{}",
                fs(*from_us),
                until_us
                    .map(|u| format!(" until {} s", fs(u)))
                    .unwrap_or_default()
            ),
            Expectation::State { state, at_us } => format!(
                "state {state} {}",
                at_us.map_or("at the end".into(), |t| format!("at {} s", fs(t)))
            ),
            Expectation::FollowingError { max_uu, .. } => {
                format!("|following error| <= {max_uu} uu while enabled")
            }
            Expectation::Verdict {
                verdict,
                by_us,
                not_before_us,
            } => {
                let mut s = format!("detector verdict {}", verdict.as_str());
                if let Some(b) = by_us {
                    s += &format!(" by {} s", fs(*b));
                }
                if let Some(b) = not_before_us {
                    s += &format!(", nothing flagged before {} s", fs(*b));
                }
                s
            }
            Expectation::FrequencyHz { hz, tolerance_pct } => {
                format!("detected frequency {hz} Hz +- {tolerance_pct} %")
            }
            Expectation::FrequencyOverKv { min, max } => format!("f / k_v in {min} .. {max}"),
            Expectation::Program(o) => match o {
                ProgramOutcome::Finished => "master program finished".into(),
                ProgramOutcome::Failed => "master program failed".into(),
            },
        }
    }

    /// Evaluate against a run record: one `match` arm per expectation kind, the longer checks
    /// in functions of their own (`check_emcy`, `check_state`, ...).
    pub fn check(&self, rec: &RunRecord) -> (bool, String) {
        match self {
            Expectation::Emcy {
                code,
                within_us,
                after,
            } => check_emcy(rec, code, within_us, after),
            Expectation::NoEmcy { from_us, until_us } => {
                let bad: Vec<_> = rec
                    .emcys
                    .iter()
                    .filter(|(t, c)| *t >= *from_us && until_us.is_none_or(|u| *t <= u) && *c != 0)
                    .collect();
                if bad.is_empty() {
                    (true, "no EMCY".into())
                } else {
                    (false, format!("EMCY seen: {}", list_emcys(rec)))
                }
            }
            Expectation::State { state, at_us } => check_state(rec, state, at_us),
            Expectation::FollowingError {
                max_uu,
                from_us,
                until_us,
            } => check_following_error(rec, max_uu, from_us, until_us),
            Expectation::Verdict {
                verdict,
                by_us,
                not_before_us,
            } => check_verdict(rec, verdict, by_us, not_before_us),
            Expectation::FrequencyHz { hz, tolerance_pct } => match rec.detector.as_ref() {
                Some(d) => match d.frequency_hz.or(d.dominant_hz) {
                    Some(f) => (
                        (f - hz).abs() <= hz * tolerance_pct / 100.0,
                        format!("frequency {f:.2} Hz"),
                    ),
                    None => (false, "no frequency detected".into()),
                },
                None => (false, "the detector did not run".into()),
            },
            Expectation::FrequencyOverKv { min, max } => match rec.detector.as_ref() {
                Some(d) => match d.frequency_hz.or(d.dominant_hz) {
                    Some(f) => {
                        let r = f / d.kv_per_s;
                        (
                            r >= *min && r <= *max,
                            format!("f = {f:.2} Hz, k_v = {} 1/s, f/k_v = {r:.3}", d.kv_per_s),
                        )
                    }
                    None => (false, "no frequency detected".into()),
                },
                None => (false, "the detector did not run".into()),
            },
            Expectation::Program(o) => {
                let got = match (&rec.program_error, rec.program_finished) {
                    (Some(_), _) => ProgramOutcome::Failed,
                    (None, true) => ProgramOutcome::Finished,
                    (None, false) => {
                        return (false, "the program did not end".into());
                    }
                };
                (
                    got == *o,
                    rec.program_error
                        .clone()
                        .unwrap_or_else(|| "program finished".into()),
                )
            }
        }
    }
}

/// `[[expect]] emcy`: the EMCY `code` after event `after` (or the start), within
/// `within_us` when given.
fn check_emcy(
    rec: &RunRecord,
    code: &u16,
    within_us: &Option<u64>,
    after: &Option<String>,
) -> (bool, String) {
    let t0 = match after {
        Some(id) => match rec.events.get(id) {
            Some(t) => *t,
            None => return (false, format!("event `{id}` never fired")),
        },
        None => 0,
    };
    let hit = rec.emcys.iter().find(|(t, c)| *c == *code && *t >= t0);
    match (hit, within_us) {
        (None, _) => (
            false,
            format!(
                "no EMCY {code:#06X} after {} s; seen: {}",
                secs(t0),
                list_emcys(rec)
            ),
        ),
        (Some((t, _)), Some(w)) if t - t0 > *w => (
            false,
            format!(
                "EMCY {code:#06X} came {} s after, later than {} s",
                secs(t - t0),
                secs(*w)
            ),
        ),
        (Some((t, _)), _) => (
            true,
            format!(
                "EMCY {code:#06X} at {:.3} s ({:.3} s after)",
                secs(*t),
                secs(t - t0)
            ),
        ),
    }
}

/// `[[expect]] state`: the CiA 402 state of the last sample by `at_us` (the end: `None`).
fn check_state(rec: &RunRecord, state: &Cia402State, at_us: &Option<u64>) -> (bool, String) {
    let at = at_us.map_or(f64::INFINITY, secs);
    // samples are in time order: the last one by then, in O(log n)
    let n = rec.samples.partition_point(|s| s.t_s <= at + 1e-9);
    let s = n.checked_sub(1).map(|i| &rec.samples[i]);
    match s {
        None => (false, "no sample recorded by then".into()),
        Some(s) => {
            let got = Cia402State::from_statusword(s.statusword);
            (
                got == Some(*state),
                format!(
                    "statusword {:#06X} ({}) at {:.3} s",
                    s.statusword,
                    state_name(s.statusword),
                    s.t_s
                ),
            )
        }
    }
}

/// `[[expect]] following_error`: the largest |following error| in OPERATION ENABLED within
/// the interval.
fn check_following_error(
    rec: &RunRecord,
    max_uu: &f64,
    from_us: &u64,
    until_us: &Option<u64>,
) -> (bool, String) {
    let from = secs(*from_us);
    let until = until_us.map_or(f64::INFINITY, secs);
    let worst = rec
        .samples
        .iter()
        .filter(|s| s.t_s >= from && s.t_s <= until)
        .filter(|s| {
            Cia402State::from_statusword(s.statusword) == Some(Cia402State::OperationEnabled)
        })
        .map(|s| (s.following_error_uu.unsigned_abs(), s.t_s))
        .max_by_key(|x| x.0);
    match worst {
        None => (
            false,
            "no sample in OPERATION ENABLED in the interval".into(),
        ),
        Some((e, t)) => (
            f64::from(e) <= *max_uu,
            format!("max |following error| {e} uu at {t:.3} s"),
        ),
    }
}

/// `[[expect]] verdict`: the detector's verdict, confirmed by `by_us`, nothing flagged before
/// `not_before_us`.
fn check_verdict(
    rec: &RunRecord,
    verdict: &Verdict,
    by_us: &Option<u64>,
    not_before_us: &Option<u64>,
) -> (bool, String) {
    let Some(d) = &rec.detector else {
        return (false, "the detector did not run".into());
    };
    let mut ok = d.verdict == *verdict;
    let mut detail = format!(
        "verdict {} (amplitude {:.2} {}, severity {:.2}); first suspected {}, first backlash {}",
        d.verdict.as_str(),
        d.amplitude,
        crate::report::unit_text(&d.position_unit),
        d.severity,
        fmt_t(d.first_suspected_s),
        fmt_t(d.first_backlash_s)
    );
    let first = match verdict {
        Verdict::Inconclusive | Verdict::Ok => None,
        Verdict::BacklashSuspected => d.first_suspected_s,
        Verdict::Backlash => d.first_backlash_s,
    };
    if let Some(b) = by_us {
        if !first.is_some_and(|f| f <= secs(*b)) {
            ok = false;
            detail += &format!("; not confirmed by {} s", secs(*b));
        }
    }
    if let Some(nb) = not_before_us {
        if d.first_suspected_s.is_some_and(|f| f < secs(*nb)) {
            ok = false;
            detail += &format!("; flagged before {} s", secs(*nb));
        }
    }
    (ok, detail)
}

fn fmt_t(t: Option<f64>) -> String {
    t.map_or("never".into(), |t| format!("at {t:.1} s"))
}

fn list_emcys(rec: &RunRecord) -> String {
    if rec.emcys.is_empty() {
        return "none".into();
    }
    rec.emcys
        .iter()
        .take(8)
        .map(|(t, c)| {
            format!(
                "{c:#06X} ({})@{:.3}s",
                crate::master::emcy_name(*c),
                secs(*t)
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Evaluate every expectation.
pub fn check_all(expects: &[Expect], rec: &RunRecord) -> Vec<ExpectResult> {
    expects
        .iter()
        .map(|e| {
            let (passed, detail) = e.what.check(rec);
            ExpectResult {
                line: e.line,
                expectation: e.what.describe(),
                passed,
                detail,
            }
        })
        .collect()
}
