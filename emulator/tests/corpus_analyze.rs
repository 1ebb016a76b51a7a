//! The capture corpus (tests/corpus/, recorded by tests/corpus/record.py: a python canopen
//! master, not ours, driving `drive-emu run` on vcan0 at several SYNC periods, modes and gaps,
//! with `candump -L` running) scored against its ground truth (tests/corpus/NAME.json,
//! measured by tests/corpus/truth.py with python-can's log reader and numpy's FFT of 0x606C):
//! every verdict right (worn: backlash found; healthy: ok; no constant-speed window:
//! inconclusive), every worn frequency within 5 % of the truth, no false alarm, and the exit
//! status CI sees matching the verdict. Issue 19: captures of a drive in real time with SYNC
//! from the kernel's broadcast manager are read on their own time stamps, those of a
//! lock-step drive on the SYNC count; where the master closes the position loop itself
//! (truth: numpy's fit of its set-point on the direct encoder) the detector reports its k
//! within 5 % of the master's configured gain. Issue 31: real-time captures whose python
//! SYNCs jitter and stall in a busy guest get their verdict (constant speed on the capture's
//! own time stamps), and the gap estimate (`backlash_estimate_mm`) is null wherever the truth
//! has no limit cycle, within 30 % of the truth on the worn captures of today's drive (real-time
//! and lock-step), and given on those recorded before its speed loop was re-derived (da70044,
//! truth `drive_speed_loop`; their limit cycle is about twice today's: docs/scenarios.md). A
//! lock-step drive's capture is read in the drive's time: the period per SYNC the master wrote
//! (0x60C2, 0x1006), however slowly its SYNCs came.

use std::path::{Path, PathBuf};
use std::process::Command;

fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("tests")
        .join("corpus")
}

struct Case {
    name: String,
    capture: PathBuf,
    truth: serde_json::Value,
}

fn cases() -> Vec<Case> {
    let mut out: Vec<Case> = std::fs::read_dir(corpus_dir())
        .expect("tests/corpus")
        .filter_map(|e| {
            let p = e.ok()?.path();
            let name = p.file_name()?.to_str()?.strip_suffix(".json")?.to_string();
            let capture = p.with_file_name(format!("{name}.log.gz"));
            let truth = serde_json::from_str(&std::fs::read_to_string(&p).ok()?).ok()?;
            Some(Case {
                name,
                capture,
                truth,
            })
        })
        .collect();
    out.sort_by(|a, b| a.name.cmp(&b.name));
    out
}

/// What the truth says the verdict must be: no constant-speed part (the master made none, or
/// the real-time drive inside user-mode Linux could not hold one), or one where the
/// set-point itself moves in the band by the suspect level and half the line or more (the
/// master's set-point timing forces the axis: `forced`): inconclusive; a limit cycle
/// in the velocity actual's spectrum: backlash; else ok (a healthy axis, or a worn one in a
/// speed loop without k_v, CSV or PV, which has no limit cycle to find).
fn expected(t: &serde_json::Value) -> &'static str {
    let window = t["case"]["window"].as_bool().unwrap()
        && t["frequency_hz"].is_number()
        && !t["forced"].as_bool().unwrap_or(false);
    match (window, t["limit_cycle"].as_bool().unwrap()) {
        (false, _) => "inconclusive",
        (true, true) => "backlash",
        (true, false) => "ok",
    }
}

fn analyze(capture: &Path, out: &Path, extra: &[&str]) -> (serde_json::Value, i32) {
    let o = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .arg("analyze")
        .arg(capture)
        .args([
            "--node",
            "5",
            "--preset",
            "cnc1",
            "--json",
            "--fail-on-backlash",
        ])
        .args(extra)
        .arg("--out")
        .arg(out)
        .output()
        .expect("run drive-emu analyze");
    let code = o.status.code().expect("exit code");
    let json = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| {
        panic!(
            "{}: no JSON ({e}): exit {code}\n{}\n{}",
            capture.display(),
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        )
    });
    (json, code)
}

/// A worn capture's gap (truth, mm), the estimate and its range.
type GapSeen = (f64, Option<f64>, Option<(f64, f64)>);

#[test]
fn every_corpus_verdict_is_right() {
    let cases = cases();
    // The corpus covers what the issue asks for.
    let has = |f: &dyn Fn(&serde_json::Value) -> bool| cases.iter().any(|c| f(&c.truth));
    assert!(cases.len() >= 8, "{} cases", cases.len());
    for ms in [1, 4, 10] {
        assert!(
            has(&|t| t["case"]["sync_ms"] == ms),
            "no capture at {ms} ms"
        );
    }
    for mode in ["csp", "csv", "pv", "pp"] {
        assert!(has(&|t| t["case"]["mode"] == mode), "no {mode} capture");
    }
    for e in ["ok", "backlash", "inconclusive"] {
        assert!(cases.iter().any(|c| expected(&c.truth) == e), "no {e} case");
    }
    assert!(has(&|t| t["case"]["lockstep"] == false));
    // Issue 19: a real-time drive with SYNC from the kernel (BCM) and a limit cycle, and a
    // master closing the position loop itself with one.
    assert!(has(&|t| t["case"]["lockstep"] == false
        && t["case"]["sync"] == "bcm"
        && t["limit_cycle"] == true));
    assert!(has(
        &|t| t["case"]["master_kv"].is_number() && t["limit_cycle"] == true
    ));
    let tmp = std::env::temp_dir().join(format!("corpus-analyze-{}", std::process::id()));
    let mut failures = Vec::new();
    let mut table = String::new();
    let mut traces = 0;
    let mut gaps: Vec<GapSeen> = Vec::new();
    for c in &cases {
        let (j, code) = analyze(&c.capture, &tmp.join(&c.name), &[]);
        let rep = &j["report"];
        let verdict = rep["verdict"].as_str().unwrap().to_string();
        let want = expected(&c.truth);
        // Where the truth saw the master's set-point force the axis, the verdict says so.
        if c.truth["forced"].as_bool() == Some(true)
            && c.truth["case"]["window"].as_bool() == Some(true)
            && rep["inconclusive"].as_str() != Some("set_point_not_constant")
        {
            failures.push(format!(
                "{}: the set-point forces the axis (truth: {} um) but the reason is {}",
                c.name, c.truth["set_point_um"], rep["inconclusive"]
            ));
        }
        let f = rep["frequency_hz"].as_f64();
        let f_true = c.truth["frequency_hz"].as_f64();
        table += &format!(
            "{:24} truth {:12} f {:>6} | verdict {:18} f {:>6} exit {code} | {}\n",
            c.name,
            want,
            f_true.map_or("-".into(), |f| format!("{f:.2}")),
            verdict,
            f.map_or("-".into(), |f| format!("{f:.2}")),
            rep["window_source"].as_str().unwrap_or("")
        );
        let time_base = rep["time_base"].as_str().unwrap_or("");
        let right = match want {
            "backlash" => verdict == "backlash" || verdict == "backlash_suspected",
            w => verdict == w,
        };
        if !right {
            failures.push(format!(
                "{}: verdict {verdict}, truth {want}: {}",
                c.name, rep["reasons"]
            ));
        }
        // The time base: a drive on its own clock on the stamps, a lock-step one on the SYNC
        // count (wherever something was measured).
        let lockstep = c.truth["case"]["lockstep"].as_bool().unwrap();
        let stamps = time_base.starts_with("the SYNC time stamps");
        if want != "inconclusive" && stamps == lockstep {
            failures.push(format!(
                "{}: lock-step {lockstep}, but time base: {time_base}",
                c.name
            ));
        }
        // The master's own loop: seen where the truth's fit sees it, with its gain.
        let fitted = c.truth["master_kv_fit"].as_f64();
        let seen = rep["master_loop"]["kv_per_s"].as_f64();
        match (fitted, seen) {
            (Some(_), Some(k)) => {
                let kv = c.truth["case"]["master_kv"].as_f64().unwrap();
                if (k - kv).abs() > 0.05 * kv {
                    failures.push(format!("{}: master's k {k:.2}, configured {kv}", c.name));
                }
            }
            (None, None) => {}
            (a, b) => failures.push(format!(
                "{}: master's loop: truth's fit {a:?}, detector {b:?}",
                c.name
            )),
        }
        let want_code = match want {
            "backlash" => 1,
            "ok" => 0,
            _ => 3,
        };
        if right && code != want_code {
            failures.push(format!("{}: exit {code}, expected {want_code}", c.name));
        }
        if want == "backlash" {
            // The truth is in bus time; a lock-step drive's capture is read in the drive's
            // time, `period N us per SYNC` as the analysis says (0x60C2 or 0x1006 where the
            // master wrote them, however slowly its SYNCs came): the truth in drive time is
            // f * measured / N.
            let ft = f_true.unwrap() * drive_time_scale(time_base, &c.truth);
            let f = f.unwrap_or(0.0);
            if (f - ft).abs() > 0.05 * ft {
                failures.push(format!(
                    "{}: {f:.2} Hz, truth {ft:.2} Hz in the analysis' time (> 5 %)",
                    c.name
                ));
            }
        }
        // Issue 31: the gap in mm where the truth has a limit cycle; null everywhere else.
        let est = rep["backlash_estimate_mm"].as_f64();
        let range = rep["backlash_estimate_range_mm"]
            .as_array()
            .map(|r| (r[0].as_f64().unwrap(), r[1].as_f64().unwrap()));
        if !rep
            .as_object()
            .unwrap()
            .contains_key("backlash_estimate_mm")
        {
            failures.push(format!("{}: no backlash_estimate_mm in the report", c.name));
        }
        if want == "backlash" {
            let gap = c.truth["case"]["gap"].as_f64().unwrap();
            table += &format!(
                "{:24}   gap {gap:.3} mm: estimate {} range {} ({})\n",
                "",
                est.map_or("-".into(), |e| format!("{e:.4}")),
                range.map_or("-".into(), |(a, b)| format!("{a:.4}..{b:.4}")),
                rep["backlash_estimate_method"]
            );
            if c.truth["case"]["master_kv"].is_number() {
                // The master's own loop: its limit cycle, not the drive's cascade the
                // estimate is calibrated on: it says nothing.
                if est.is_some() {
                    failures.push(format!("{}: a gap estimate in the master's loop", c.name));
                }
            } else if c.truth["drive_speed_loop"].is_string() {
                // Recorded by the drive before its speed loop was re-derived (da70044): its
                // limit cycle is about twice today's (the truth's displacement 9-15 um at
                // 0.05 mm; the same cases recorded again, `-v2`, 7 um), and the estimate is
                // calibrated on today's drive: it is given, not scored.
                if est.is_none() {
                    failures.push(format!("{}: no gap estimate on a worn axis", c.name));
                }
            } else {
                gaps.push((gap, est, range));
            }
        } else if est.is_some() || range.is_some() {
            failures.push(format!(
                "{}: a gap estimate ({est:?}) where the truth has no limit cycle",
                c.name
            ));
        }
        // Every verdict says why.
        if rep["reasons"].as_array().is_none_or(|r| r.is_empty()) {
            failures.push(format!("{}: no reasons", c.name));
        }
        // The drive's own `run --trace` of the same run says the same (it said "ok, windows
        // 0" once: its set speed now comes from the position demand 0x6062).
        let trace = c.capture.with_file_name(format!("{}.trace.csv.gz", c.name));
        if trace.exists() {
            traces += 1;
            let (j, code) = analyze(&trace, &tmp.join(format!("{}-trace", c.name)), &[]);
            let rep = &j["report"];
            let verdict = rep["verdict"].as_str().unwrap();
            let f = rep["frequency_hz"].as_f64();
            table += &format!(
                "{:24}   run --trace: verdict {verdict:18} f {:>6} exit {code}\n",
                "",
                f.map_or("-".into(), |f| format!("{f:.2}"))
            );
            let right = match want {
                "backlash" => verdict == "backlash" || verdict == "backlash_suspected",
                w => verdict == w,
            };
            if !right {
                failures.push(format!(
                    "{} run --trace: verdict {verdict}, truth {want}: {}",
                    c.name, rep["reasons"]
                ));
            }
            if want == "backlash" {
                // The trace is in the drive's time; the capture (and the truth) in the bus
                // timestamps' median SYNC interval. A lock-step drive advances one nominal
                // period per SYNC however slowly python sends them: the truth in drive time
                // is f * measured / nominal.
                let nominal = c.truth["case"]["sync_ms"].as_f64().unwrap() * 1e-3;
                let measured = c.truth["sync_period_s_measured"].as_f64().unwrap();
                let lockstep = c.truth["case"]["lockstep"].as_bool().unwrap();
                let ft = f_true.unwrap() * if lockstep { measured / nominal } else { 1.0 };
                let f = f.unwrap_or(0.0);
                if (f - ft).abs() > 0.05 * ft {
                    failures.push(format!(
                        "{} run --trace: {f:.2} Hz, truth in drive time {ft:.2} Hz (> 5 %)",
                        c.name
                    ));
                }
            }
        }
    }
    assert!(traces >= 2, "{traces} drive traces in the corpus");
    // The gap estimate on the worn captures of today's drive, real-time and lock-step: within
    // 30 % of the truth on 80 % or more, the truth inside the range on 90 % or more.
    let n = gaps.len().max(1) as f64;
    let within = gaps
        .iter()
        .filter(|(g, e, _)| e.is_some_and(|e| (e - g).abs() <= 0.3 * g))
        .count() as f64
        / n;
    let inside = gaps
        .iter()
        .filter(|(g, _, r)| r.is_some_and(|(a, b)| a <= *g && *g <= b))
        .count() as f64
        / n;
    table += &format!(
        "gap estimate on {} worn captures of today's drive: within 30 % {:.0} %, truth inside the range {:.0} %\n",
        gaps.len(),
        100.0 * within,
        100.0 * inside
    );
    assert!(gaps.len() >= 2, "{table}");
    if within < 0.8 || inside < 0.9 {
        failures.push("the gap estimate misses on the corpus (see the table)".into());
    }
    let _ = std::fs::remove_dir_all(&tmp);
    eprintln!("{table}");
    assert!(failures.is_empty(), "{table}\n{}", failures.join("\n"));
}

/// How much faster the analysis' time runs than the bus's: 1 on the time stamps; for a
/// capture read on the SYNC count, the measured SYNC interval over the period per SYNC the
/// analysis took (its `time_base` says `period N us per SYNC`).
fn drive_time_scale(time_base: &str, truth: &serde_json::Value) -> f64 {
    let us_per_sync = time_base
        .split("; period ")
        .nth(1)
        .and_then(|rest| rest.split(" us per SYNC").next())
        .and_then(|n| n.trim().parse::<f64>().ok());
    match us_per_sync {
        Some(n) => truth["sync_period_s_measured"].as_f64().unwrap() / (n * 1e-6),
        None => 1.0,
    }
}
