//! `drive_emu._native`: the Python binding of the emulator's library (PyO3). Thin on purpose:
//! every function builds a request of the typed API (`drive_runtime::api`: the code under
//! `drive-emu sim`, `analyze` and `eds`) or calls the study code `sweep` and `presets` run,
//! and hands back JSON text (parsed by `python/drive_emu/__init__.py`) and numpy arrays. No
//! command line is parsed here.
//!
//! Every run goes through `interruptible`: the work runs on a thread of its own with the GIL
//! released, while the calling thread wakes every `POLL` (50 ms) to look at Python's signals
//! (Ctrl-C: the run is stopped through its stop flag and `KeyboardInterrupt` raised) and to
//! report progress; a panic in the work becomes `drive_emu.InternalError`, never an abort.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::create_exception;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use drive_runtime::analysis::{RunError, Trace};
use drive_runtime::api::analyze::write_report;
use drive_runtime::api::eds::Real32Notation;
use drive_runtime::api::{AnalyzeInput, AnalyzeRequest, ApiError, EdsRequest, SimRequest};
use drive_runtime::presets::{preset_names, AxisConfig, AxisKind};
use drive_runtime::study::{
    backlash_key, default_velocity, measure_until, own_backlash, run_parallel, CaseRow,
    CASE_DURATION_S,
};

create_exception!(
    _native,
    InternalError,
    PyRuntimeError,
    "drive-emu panicked: a bug in the emulator (please report it with the arguments that \
     caused it); the run was abandoned, the interpreter is fine."
);

/// How often the calling thread looks at Python's signals and reports progress.
const POLL: Duration = Duration::from_millis(50);

/// Run `work` on a thread of its own with the GIL released; meanwhile look at Python's signals
/// every [`POLL`] (a pending `KeyboardInterrupt` sets the stop flag, waits for the work to
/// end and is raised, with the note `stopped(result, done)` says: how far the work got) and
/// call `progress(done)` when the count of finished items changed. A panic in `work` is
/// raised as [`InternalError`].
fn interruptible<T: Send>(
    py: Python<'_>,
    progress: Option<Py<PyAny>>,
    work: impl FnOnce(&AtomicBool, &AtomicUsize) -> T + Send,
    stopped: impl FnOnce(&T, usize) -> Option<String> + Send,
) -> PyResult<T> {
    let stop = AtomicBool::new(false);
    let done = AtomicUsize::new(0);
    py.detach(|| {
        std::thread::scope(|s| {
            let (tx, rx) = mpsc::channel::<()>();
            let (stop, done) = (&stop, &done);
            let worker = s.spawn(move || {
                let r = catch_unwind(AssertUnwindSafe(|| work(stop, done)));
                let _ = tx.send(());
                r
            });
            let mut reported = 0;
            loop {
                let finished =
                    !matches!(rx.recv_timeout(POLL), Err(mpsc::RecvTimeoutError::Timeout));
                let looked = Python::attach(|py| -> PyResult<()> {
                    py.check_signals()?;
                    let n = done.load(Ordering::Relaxed);
                    if let Some(p) = progress.as_ref().filter(|_| n != reported) {
                        p.call1(py, (n,))?;
                        reported = n;
                    }
                    Ok(())
                });
                if let Err(e) = looked {
                    stop.store(true, Ordering::Relaxed);
                    // The work ends within a fraction of a millisecond once it sees the flag.
                    let note = match worker.join() {
                        Ok(Ok(v)) => stopped(&v, done.load(Ordering::Relaxed)),
                        _ => None,
                    };
                    if let Some(note) = note {
                        Python::attach(|py| {
                            // BaseException.add_note: Python 3.11 and later
                            let _ = e.value(py).call_method1("add_note", (note,));
                        });
                    }
                    return Err(e);
                }
                if finished {
                    break;
                }
            }
            match worker.join() {
                Ok(Ok(v)) => Ok(v),
                Ok(Err(panic)) | Err(panic) => Err(InternalError::new_err(format!(
                    "drive-emu panicked: {}",
                    panic_text(panic.as_ref())
                ))),
            }
        })
    })
}

fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(no message)".into())
}

/// A CLI message for Python: `--max-memory-mb` becomes `max_memory_mb`, the argument's name.
fn python_names(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find("--") {
        out.push_str(&rest[..at]);
        let tail = &rest[at + 2..];
        let end = tail
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
            .unwrap_or(tail.len());
        if end == 0 {
            out.push_str("--");
        } else {
            out.push_str(&tail[..end].replace('-', "_"));
        }
        rest = &tail[end..];
    }
    out.push_str(rest);
    out
}

/// An error of the library as a Python exception: a file that cannot be read is an
/// `OSError` (`FileNotFoundError` when missing), anything else the caller gave a `ValueError`.
fn to_py_err(e: ApiError) -> PyErr {
    let text = python_names(&format!("{e:#}"));
    // The bounded reader's errors (drive_runtime::infile) say what the file is, not an io::Error.
    if let Some(input) = e.input_error() {
        return match &input.problem {
            drive_runtime::infile::Problem::NotFound => PyFileNotFoundError::new_err(text),
            drive_runtime::infile::Problem::Io(_)
            | drive_runtime::infile::Problem::NotRegular(_) => PyOSError::new_err(text),
            _ => PyValueError::new_err(text),
        };
    }
    let io = e
        .inner()
        .and_then(|e| e.chain().find_map(|c| c.downcast_ref::<std::io::Error>()));
    match io {
        Some(io) if io.kind() == std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(text),
        Some(_) => PyOSError::new_err(text),
        None => PyValueError::new_err(text),
    }
}

/// `drive-emu sim`: returns the summary (the JSON `sim --json` prints) and the trace as
/// columns named as in `sim --trace`'s CSV (the analysis window only when `record` is false).
#[pyfunction]
#[pyo3(signature = (preset, sets, velocity, duration, accel, kick, max_memory_mb, record))]
#[allow(clippy::too_many_arguments)]
fn sim<'py>(
    py: Python<'py>,
    preset: String,
    sets: Vec<String>,
    velocity: f64,
    duration: f64,
    accel: f64,
    kick: Option<f64>,
    max_memory_mb: f64,
    record: bool,
) -> PyResult<(String, Bound<'py, PyDict>)> {
    let request = SimRequest {
        preset,
        sets,
        velocity_per_s: velocity,
        duration_s: duration,
        accel_per_s2: accel,
        kick_per_s: kick,
        max_memory_mb,
        record,
        trace_csv: false,
    };
    let res = interruptible(
        py,
        None,
        |stop, _| request.run(stop),
        |r, _| match r.as_ref().err()? {
            ApiError::Stopped { at_s } => Some(format!(
                "drive_emu.sim: stopped at {at_s:.3} of {duration} simulated s"
            )),
            _ => None,
        },
    )?;
    let res = res.map_err(to_py_err)?;
    let summary = serde_json::to_string(&res.summary)
        .map_err(|e| InternalError::new_err(format!("summary as JSON: {e}")))?;
    let trace = PyDict::new(py);
    for (name, column) in res.trace.into_columns(&res.summary.unit) {
        trace.set_item(name, PyArray1::from_vec(py, column))?;
    }
    Ok((summary, trace))
}

/// The column names of a simulator trace (`u` = "mm" or "deg").
#[pyfunction]
fn trace_columns(u: &str) -> Vec<String> {
    Trace::column_names(u).to_vec()
}

/// `drive-emu analyze`: the detector on a file (`path`) or on named columns; the JSON of
/// `analyze --json` (report directory and plots only when `out` is given).
#[pyfunction]
#[pyo3(signature = (path, columns, source, kv, preset, node, rotary, suspect, alarm, sync_period_us, out))]
#[allow(clippy::too_many_arguments)]
fn analyze(
    py: Python<'_>,
    path: Option<PathBuf>,
    columns: Option<Vec<(String, PyReadonlyArray1<'_, f64>)>>,
    source: String,
    kv: Option<f64>,
    preset: Option<String>,
    node: u8,
    rotary: bool,
    suspect: Option<f64>,
    alarm: Option<f64>,
    sync_period_us: Option<u32>,
    out: Option<PathBuf>,
) -> PyResult<String> {
    let columns: Option<Vec<(String, Vec<f64>)>> = columns
        .map(|cols| {
            cols.into_iter()
                .map(|(name, a)| Ok((name, a.as_slice()?.to_vec())))
                .collect::<PyResult<_>>()
        })
        .transpose()?;
    let request = AnalyzeRequest {
        trace: path.unwrap_or_default(),
        kv_per_s: kv,
        rotary,
        suspect_um: suspect,
        alarm_um: alarm,
        node,
        preset,
        sync_period_us,
        ..AnalyzeRequest::default()
    };
    let result = interruptible(
        py,
        None,
        |_, _| -> Result<String, ApiError> {
            let input = match &columns {
                Some(columns) => AnalyzeInput::Columns {
                    source: &source,
                    columns,
                },
                None => AnalyzeInput::File,
            };
            let mut analysis = request.run(input)?;
            if let Some(out) = &out {
                // the report directory cannot be made: an OSError naming it
                write_report(&mut analysis, out).map_err(ApiError::Failed)?;
            }
            serde_json::to_string(&analysis.output).map_err(|e| ApiError::Failed(e.into()))
        },
        |_, _| None,
    )?;
    result.map_err(to_py_err)
}

/// The presets, as `drive-emu presets` lists them, with every key of the preset file: JSON of
/// a list of objects (the file's keys plus `backlash` in the axis unit, `unit` and
/// `user_unit`).
#[pyfunction]
fn presets() -> PyResult<String> {
    let mut all = Vec::new();
    for name in preset_names() {
        let cfg =
            AxisConfig::from_preset(name).map_err(|e| PyValueError::new_err(e.to_string()))?;
        let rotary = cfg.kind == AxisKind::Rotary;
        let mut v = serde_json::to_value(&cfg)
            .map_err(|e| InternalError::new_err(format!("preset {name} as JSON: {e}")))?;
        if let Some(o) = v.as_object_mut() {
            o.insert("backlash".into(), own_backlash(&cfg).into());
            o.insert("unit".into(), if rotary { "deg" } else { "mm" }.into());
            o.insert(
                "user_unit".into(),
                drive_runtime::report::user_unit(rotary).into(),
            );
        }
        all.push(v);
    }
    serde_json::to_string(&all).map_err(|e| InternalError::new_err(e.to_string()))
}

/// `drive-emu eds`: the EDS text ([`EdsRequest`]; every field the module does not set keeps
/// the command line's default). `real32`: "bits" or "decimal".
#[pyfunction]
#[pyo3(signature = (preset, node, sets, real32, canopen_monitor))]
fn eds(
    preset: String,
    node: Option<u8>,
    sets: Vec<String>,
    real32: String,
    canopen_monitor: bool,
) -> PyResult<String> {
    let real32 = match real32.as_str() {
        "bits" => Real32Notation::Bits,
        "decimal" => Real32Notation::Decimal,
        other => {
            return Err(PyValueError::new_err(format!(
                "invalid value {} for real32: possible values bits, decimal",
                drive_runtime::quote::text(&format!("'{other}'"))
            )))
        }
    };
    let request = EdsRequest {
        preset,
        node,
        sets,
        real32,
        canopen_monitor,
        ..EdsRequest::default()
    };
    request.build().map(|o| o.eds).map_err(to_py_err)
}

/// One case of a sweep as Python sends it: preset, `key=value` overrides by their registry
/// names (`backlash`, a grid key that moved and the module still takes for one release with a
/// DeprecationWarning, is the preset's own backlash key), velocity (None: the preset's
/// default), duration.
type CaseIn = (String, Vec<String>, Option<f64>, f64);

/// The sweep of one chunk of a grid: every case measured as `drive-emu sweep` measures one,
/// on `threads` threads (0 = all cores); `progress(done)` is called as cases finish. The JSON
/// of the rows, in the order of the cases. A bad case is a `ValueError` naming it by its
/// index in the grid (`first_index` + its index here) and stops the others; a Ctrl-C's note
/// counts the runs of the whole grid (`first_index` before this chunk, `total` in all, None
/// where unknown).
#[pyfunction]
#[pyo3(signature = (cases, threads, progress, first_index = 0, total = None))]
fn sweep(
    py: Python<'_>,
    cases: Vec<CaseIn>,
    threads: usize,
    progress: Option<Py<PyAny>>,
    first_index: usize,
    total: Option<usize>,
) -> PyResult<String> {
    // The presets once; each case applies its overrides to a copy.
    let mut bases: Vec<AxisConfig> = Vec::new();
    for (preset, ..) in &cases {
        if !bases.iter().any(|b| b.name.eq_ignore_ascii_case(preset)) {
            bases.push(
                AxisConfig::from_preset(preset)
                    .map_err(|e| PyValueError::new_err(format!("preset: {e}")))?,
            );
        }
    }
    let total = total.map_or_else(|| "?".to_string(), |n| n.to_string());
    let rows = interruptible(
        py,
        progress,
        |stop, done| {
            run_parallel(&cases, threads, stop, done, |case| {
                let r = run_one(&bases, case, stop);
                if matches!(r, Err(Some(_))) {
                    stop.store(true, Ordering::Relaxed);
                }
                r
            })
        },
        |rows, _| {
            let finished = rows.iter().filter(|r| matches!(r, Some(Ok(_)))).count();
            Some(format!(
                "drive_emu.sweep: stopped after {} of {total} runs",
                first_index + finished
            ))
        },
    )?;
    let mut out = Vec::with_capacity(rows.len());
    let mut first_error = None;
    for (i, r) in rows.into_iter().enumerate() {
        match r {
            Some(Ok(row)) => out.push(row),
            Some(Err(Some(why))) => {
                let (preset, sets, ..) = &cases[i];
                first_error.get_or_insert(format!(
                    "case {} (preset {preset}{}{}): {why}",
                    first_index + i,
                    if sets.is_empty() { "" } else { ", " },
                    sets.join(", ")
                ));
            }
            // Stopped by another case's error.
            Some(Err(None)) | None => {}
        }
    }
    if let Some(e) = first_error {
        return Err(PyValueError::new_err(e));
    }
    serde_json::to_string(&out).map_err(|e| InternalError::new_err(e.to_string()))
}

/// One case; `Err(None)`: stopped.
fn run_one(
    bases: &[AxisConfig],
    case: &CaseIn,
    stop: &AtomicBool,
) -> Result<CaseRow, Option<String>> {
    let (preset, sets, velocity, duration) = case;
    let base = bases
        .iter()
        .find(|b| b.name.eq_ignore_ascii_case(preset))
        .ok_or_else(|| Some(format!("unknown preset `{preset}`")))?;
    let mut cfg = base.clone();
    for s in sets {
        let (k, v) = s
            .split_once('=')
            .ok_or_else(|| Some(format!("`{s}`: an override must be written key=value")))?;
        let k = if k == "backlash" {
            backlash_key(base)
        } else {
            k
        };
        cfg = cfg.with_override(k, v).map_err(|e| Some(e.to_string()))?;
    }
    if !CASE_DURATION_S.contains(duration) {
        return Err(Some(format!(
            "duration {duration}: must be {}..{} s (the FFT window is the cruise after the \
             start-up transient)",
            CASE_DURATION_S.start(),
            CASE_DURATION_S.end()
        )));
    }
    let velocity = velocity.unwrap_or_else(|| default_velocity(&cfg));
    if !(velocity.is_finite() && velocity != 0.0) {
        return Err(Some(format!(
            "velocity {velocity}: must be a finite non-zero number"
        )));
    }
    measure_until(&cfg, velocity, *duration, stop).map_err(|e| match e {
        RunError::Stopped { .. } => None,
        RunError::Config(e) => Some(e.to_string()),
    })
}

/// Panics on purpose: the test that a panic in the emulator becomes `InternalError` and
/// leaves the interpreter running (it runs on the worker thread, as real work does).
#[pyfunction]
fn _panic_for_test(py: Python<'_>, message: String) -> PyResult<()> {
    interruptible(py, None, |_, _| -> () { panic!("{message}") }, |_, _| None)
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("InternalError", m.py().get_type::<InternalError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add(
        "DEFAULT_SWEEP_DURATION_S",
        drive_runtime::study::DEFAULT_DURATION_S,
    )?;
    m.add("MAX_SWEEP_CASES", drive_runtime::study::MAX_SWEEP_CASES)?;
    m.add(
        "DEFAULT_MAX_MEMORY_MB",
        drive_runtime::api::sim::DEFAULT_MAX_MEMORY_MB,
    )?;
    m.add_function(wrap_pyfunction!(sim, m)?)?;
    m.add_function(wrap_pyfunction!(trace_columns, m)?)?;
    m.add_function(wrap_pyfunction!(analyze, m)?)?;
    m.add_function(wrap_pyfunction!(presets, m)?)?;
    m.add_function(wrap_pyfunction!(eds, m)?)?;
    m.add_function(wrap_pyfunction!(sweep, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_test, m)?)?;
    Ok(())
}
