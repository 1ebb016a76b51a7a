//! `drive-emu analyze` on the inputs a user brings: bad files refused with a clear error and
//! exit 4 (never unbounded memory), NaN traces inconclusive (exit 3, never "ok"), a trace cut
//! mid-line read with the cut reported, k_v from the capture or the preset, set-points written
//! over SDO and PP moves, and verdicts that a small change of the capture does not flip.

mod scratch;

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn corpus(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/corpus")
        .join(name)
}

fn tmp(name: &str) -> PathBuf {
    scratch::path(name)
}

fn analyze(trace: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .arg("analyze")
        .arg(trace)
        .args(args)
        .arg("--out")
        .arg(tmp("report"))
        .output()
        .expect("run drive-emu analyze")
}

fn json(o: &Output) -> serde_json::Value {
    serde_json::from_slice(&o.stdout).unwrap_or_else(|e| {
        panic!(
            "no JSON ({e}): {}\n{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        )
    })
}

fn gunzip(name: &str) -> String {
    let mut s = String::new();
    flate2::read::GzDecoder::new(std::fs::File::open(corpus(name)).unwrap())
        .read_to_string(&mut s)
        .unwrap();
    s
}

/// A sample-log CSV (the `run --trace` layout): a 4 s cruise at 10 mm/s after a ramp, with
/// a limit cycle of `x_um` at 18 Hz in the speed; `speed` replaces the speed column.
fn sample_log(x_um: f64, speed: Option<&str>) -> String {
    let mut s = String::from(
        "t_s,target_uu,velocity_uu_s,current_permille,position_uu,direct_position_uu\n",
    );
    let w = 2.0 * std::f64::consts::PI * 18.0;
    let mut target = 0.0f64;
    for i in 0..5000 {
        let t = i as f64 * 1e-3;
        let v_set = (t / 0.2).min(1.0) * 10_000.0;
        target += v_set * 1e-3;
        let v = v_set
            + if t > 0.3 {
                x_um * w * (w * t).cos()
            } else {
                0.0
            };
        let v = speed.map_or(format!("{v:.1}"), str::to_string);
        s += &format!(
            "{t:.3},{:.0},{v},{:.0},{:.0},{:.0}\n",
            target.round(),
            100.0,
            target,
            target
        );
    }
    s
}

#[test]
fn dev_zero_and_binary_input_are_refused_with_a_clear_error() {
    let o = analyze(Path::new("/dev/zero"), &["--kv", "30"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(4), "{err}");
    assert!(
        err.contains("/dev/zero: a character device, not a regular file"),
        "{err}"
    );
    let missing = analyze(&tmp("does-not-exist.log"), &["--kv", "30"]);
    assert_eq!(missing.status.code(), Some(4));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("cannot read"));
    // Usage errors are clap's 2: a bad --kv, or no k_v known at all.
    let csv = tmp("ok.csv");
    std::fs::write(&csv, sample_log(0.0, None)).unwrap();
    let bad = analyze(&csv, &["--kv", "-3"]);
    assert_eq!(bad.status.code(), Some(2));
    let no_kv = analyze(&csv, &[]);
    assert_eq!(no_kv.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&no_kv.stderr).contains("no k_v"));
}

#[test]
fn a_nan_trace_is_inconclusive_never_ok() {
    for (name, text) in [
        ("speed-nan.csv", sample_log(0.0, Some("NaN"))),
        (
            "all-nan.csv",
            sample_log(0.0, None)
                .lines()
                .enumerate()
                .map(|(i, l)| {
                    if i == 0 {
                        l.to_string()
                    } else {
                        ["NaN"; 6].join(",")
                    }
                })
                .collect::<Vec<_>>()
                .join("\n"),
        ),
    ] {
        let p = tmp(name);
        std::fs::write(&p, text).unwrap();
        let o = analyze(&p, &["--kv", "30", "--json"]);
        let j = json(&o);
        assert_eq!(o.status.code(), Some(3), "{name}: {j}");
        assert_eq!(j["report"]["verdict"], "inconclusive", "{name}");
        assert_eq!(j["report"]["inconclusive"], "no_finite_samples", "{name}");
        assert!(j["report"]["reasons"][0].as_str().unwrap().contains("NaN"));
    }
    // The same trace with finite values is measured: backlash at 18 Hz, exit 1.
    let p = tmp("finite.csv");
    std::fs::write(&p, sample_log(8.0, None)).unwrap();
    let o = analyze(&p, &["--kv", "30", "--json", "--fail-on-backlash"]);
    let j = json(&o);
    assert_eq!(o.status.code(), Some(1), "{j}");
    assert_eq!(j["report"]["verdict"], "backlash");
}

#[test]
fn a_trace_cut_mid_line_is_read_and_the_cut_reported() {
    // A candump log whose writer was killed: the last line stops mid-frame.
    let log = gunzip("pp-4ms-lock-worn05.log.gz");
    let cut = &log[..log.len() - 9];
    assert!(!cut.ends_with('\n'));
    let p = tmp("cut.log");
    std::fs::write(&p, cut).unwrap();
    let o = analyze(&p, &["--preset", "cnc1", "--json", "--fail-on-backlash"]);
    let j = json(&o);
    assert_eq!(o.status.code(), Some(1), "{j}");
    let n_lines = cut.lines().count();
    assert!(
        j["capture"]
            .as_str()
            .unwrap()
            .contains(&format!("cut.log:{n_lines}: last line cut short")),
        "{}",
        j["capture"]
    );
    // The same cut inside the log is an error with its line.
    let mut lines: Vec<&str> = log.lines().collect();
    let mid = lines.len() / 2;
    let half = &lines[mid][..lines[mid].len() - 5].to_string();
    lines[mid] = half;
    let p = tmp("broken.log");
    std::fs::write(&p, lines.join("\n") + "\n").unwrap();
    let o = analyze(&p, &["--preset", "cnc1"]);
    assert_eq!(o.status.code(), Some(4));
    assert!(String::from_utf8_lossy(&o.stderr).contains(&format!("broken.log:{}:", mid + 1)));
    // A CSV trace cut mid-line (run --trace killed by SIGKILL).
    let csv = sample_log(8.0, None);
    let p = tmp("cut.csv");
    std::fs::write(&p, &csv[..csv.len() - 7]).unwrap();
    let o = analyze(&p, &["--kv", "30", "--json"]);
    let j = json(&o);
    assert_eq!(o.status.code(), Some(0), "{j}");
    assert_eq!(j["report"]["verdict"], "backlash");
    assert!(j["notes"][0]
        .as_str()
        .unwrap()
        .contains("last line cut short"));
}

#[test]
fn kv_comes_from_the_capture_or_the_preset_and_sdo_set_points_are_followed() {
    // The PV capture writes 0x2007 = 30 and its target velocity over SDO.
    let o = analyze(
        &corpus("pv-4ms-lock-worn05.log.gz"),
        &["--preset", "cnc3", "--json"],
    );
    let j = json(&o);
    assert_eq!(j["kv_per_s"], 30.0, "{j}");
    assert!(j["kv_source"].as_str().unwrap().contains("0x2007"));
    let src = j["report"]["window_source"].as_str().unwrap();
    assert!(
        src.contains("0x60FF") && src.contains("written over SDO"),
        "{src}"
    );
    assert!(!j["report"]["windows"].as_array().unwrap().is_empty());
    // No 0x2007 in the PP capture: the preset's k_v; --kv wins over both.
    let pp = corpus("pp-4ms-lock-worn05.log.gz");
    let j = json(&analyze(&pp, &["--preset", "cnc1", "--json"]));
    assert_eq!(j["kv_source"], "preset cnc1");
    assert_eq!(j["kv_per_s"], 30.0);
    assert!(j["report"]["window_source"]
        .as_str()
        .unwrap()
        .contains("actual values"));
    let j = json(&analyze(&pp, &["--kv", "25", "--json"]));
    assert_eq!(j["kv_source"], "--kv");
    // Text output says the same as the JSON: verdict, source, reasons, exit status.
    let o = analyze(&pp, &["--preset", "cnc1", "--fail-on-backlash"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(1));
    for s in [
        "verdict backlash",
        "constant speed from: actual values",
        "in band",
        "exit status 1",
    ] {
        assert!(text.contains(s), "{s}: {text}");
    }
}

#[test]
fn a_clear_case_does_not_flip_when_the_capture_changes_a_little() {
    // Drop a little of the start or the end of each capture (whole lines): worn stays
    // backlash at the same frequency, healthy stays ok.
    for (name, want) in [
        ("csp-1ms-lock-worn05", "backlash"),
        ("csp-10ms-lock-worn03", "backlash"),
        ("pp-4ms-lock-worn05", "backlash"),
        ("csp-4ms-lock-healthy", "ok"),
        ("pp-10ms-lock-healthy", "ok"),
    ] {
        let log = gunzip(&format!("{name}.log.gz"));
        let lines: Vec<&str> = log.lines().collect();
        let n = lines.len();
        let mut freqs = Vec::new();
        for (a, b) in [
            (0, n),
            (n / 50, n),
            (n / 20, n),
            (0, n - n / 50),
            (0, n - n / 25),
        ] {
            // Keep the configuration at the start (SDO remaps): drop only PDO/SYNC traffic
            // lines after the first 400.
            let kept: Vec<&str> = lines
                .iter()
                .enumerate()
                .filter(|(i, _)| *i < 400 || (*i >= a && *i < b))
                .map(|(_, l)| *l)
                .collect();
            let p = tmp(&format!("{name}-{a}-{b}.log"));
            std::fs::write(&p, kept.join("\n") + "\n").unwrap();
            let j = json(&analyze(&p, &["--preset", "cnc1", "--json"]));
            let v = j["report"]["verdict"].as_str().unwrap().to_string();
            assert_eq!(v, want, "{name} lines {a}..{b}: {}", j["report"]["reasons"]);
            if let Some(f) = j["report"]["frequency_hz"].as_f64() {
                freqs.push(f);
            }
            let _ = std::fs::remove_file(&p);
        }
        if want == "backlash" {
            let (lo, hi) = freqs
                .iter()
                .fold((f64::MAX, 0.0f64), |(l, h), f| (l.min(*f), h.max(*f)));
            assert!(hi - lo <= 0.03 * hi, "{name}: {freqs:?}");
        }
    }
}
