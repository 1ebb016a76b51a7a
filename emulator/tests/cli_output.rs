//! What a user reads: the main commands run as a user runs them (the built binary), their
//! output checked for Rust Debug text and raw bits, `--json` for pure, parseable JSON with the
//! expectations, and errors for a plain message without a backtrace, even with
//! RUST_BACKTRACE=1.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_drive-emu"));
    c.current_dir(repo());
    c
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("drive-emu-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn run(args: &[&str]) -> Output {
    let out = bin().args(args).output().expect("start drive-emu");
    out
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Rust Debug formatting in user text: `Some(..)`, `None`, `Name { field: .. }`, a struct or
/// enum variant name in CamelCase (`SyncLoss`, `MotorEncoderLoss`), `Ok(`/`Err(`.
fn debug_text(s: &str) -> Vec<String> {
    let mut found = Vec::new();
    for line in s.lines() {
        for pat in ["Some(", "None", "Ok(", "Err(", " { ", ": {"] {
            if line.contains(pat) {
                found.push(format!("`{pat}` in: {line}"));
            }
        }
        for word in line.split(|c: char| !c.is_ascii_alphanumeric() && c != '_') {
            let upper_after_lower = word
                .as_bytes()
                .windows(2)
                .any(|w| w[0].is_ascii_lowercase() && w[1].is_ascii_uppercase());
            let starts_upper = word.chars().next().is_some_and(|c| c.is_ascii_uppercase());
            // CamelCase words, not units like kHz or names like k_v.
            if starts_upper && upper_after_lower && !word.contains('_') && word != "CiA" {
                found.push(format!("`{word}` in: {line}"));
            }
        }
    }
    found
}

fn assert_clean(what: &str, o: &Output) {
    let t = text(o);
    assert!(o.status.success(), "{what}: {}\n{t}", o.status);
    let bad = debug_text(&t);
    assert!(
        bad.is_empty(),
        "{what}: Debug text:\n{}\n\n{t}",
        bad.join("\n")
    );
    assert!(!t.contains("panicked"), "{what}:\n{t}");
}

#[test]
fn the_main_commands_print_no_debug_text() {
    assert_clean("presets", &run(&["presets"]));
    let demo = run(&["demo"]);
    assert_clean("demo", &demo);
    let demo_text = text(&demo);
    // The SDO write of the demo's master is decoded with the object's type, not raw bits.
    assert!(demo_text.contains("uu"), "{demo_text}");
    assert!(
        demo_text.contains("--preset cnc1"),
        "hints follow the preset: {demo_text}"
    );
    let demo3 = run(&["demo", "--preset", "cnc3", "--backlash-deg", "0.05"]);
    assert_clean("demo cnc3", &demo3);
    let t3 = text(&demo3);
    assert!(
        t3.contains("--preset cnc3 --set backlash_deg=0.05"),
        "hints follow the preset: {t3}"
    );
    assert!(!t3.contains("cnc1"), "{t3}");
    assert!(
        t3.contains("0.001 deg"),
        "uu defined for a rotary axis: {t3}"
    );
    assert_clean(
        "sim",
        &run(&[
            "sim",
            "--preset",
            "cnc1",
            "--set",
            "backlash_mm=0.05",
            "--velocity",
            "16.7",
            "--duration",
            "1",
        ]),
    );
    for name in ["sync-loss", "encoder-loss", "heartbeat-loss"] {
        let dir = out_dir(name);
        let file = format!("scenarios/{name}.toml");
        let o = run(&[
            "scenario",
            &file,
            "--quiet",
            "--no-plots",
            "-o",
            dir.to_str().unwrap(),
        ]);
        assert_clean(name, &o);
        let t = text(&o);
        assert!(!t.contains("never fired"), "{t}");
        if name == "sync-loss" {
            let samples = dir.join("cnc1-samples.csv");
            let a = run(&[
                "analyze",
                samples.to_str().unwrap(),
                "--kv",
                "30",
                "-o",
                dir.join("analyze").to_str().unwrap(),
            ]);
            assert_clean("analyze", &a);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn a_master_sdo_write_of_a_real32_prints_the_number() {
    use drive_emu::master::{sdo_value_text, Step};
    // 0x2000 backlash_mm is REAL32: on the wire 0.05 is the bits 1028443341 (0x3D4CCCCD).
    let t = sdo_value_text(0x2000, 0, 0.05f32.to_bits(), 4);
    assert!(t.ends_with("= 0.05"), "{t}");
    assert!(t.starts_with("0x2000 sub 0"), "{t}");
    // Signed objects as signed: target position 0x607A = -1000.
    let t = sdo_value_text(0x607A, 0, (-1000i32) as u32, 4);
    assert!(t.ends_with("= -1000"), "{t}");
    // The master's program steps in words, not Debug.
    for step in [
        Step::Cruise {
            velocity_uu_s: 10_000.0,
            accel_uu_s2: 100_000.0,
            duration_s: 4.0,
        },
        Step::Enable { mode: 8 },
        Step::WriteSdo {
            index: 0x2000,
            sub: 0,
            value: 0.05f32.to_bits(),
            len: 4,
        },
    ] {
        let text = step.to_string();
        assert!(debug_text(&text).is_empty(), "{text}");
        assert!(!text.contains("1028443341"), "{text}");
    }
}

#[test]
fn scenario_json_is_pure_json_with_the_expectations() {
    let dir = out_dir("json");
    let o = run(&[
        "scenario",
        "scenarios/sync-loss.toml",
        "--json",
        "--no-plots",
        "-o",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|e| panic!("stdout is not JSON ({e}):\n{}", text(&o)));
    let exps = v["runs"][0]["expectations"]
        .as_array()
        .expect("expectations in the JSON");
    assert!(!exps.is_empty());
    assert!(exps
        .iter()
        .all(|e| e["passed"] == true && e["expectation"].is_string()));
    assert_eq!(v["passed"], true);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn user_errors_print_a_message_and_no_backtrace() {
    let cases: &[&[&str]] = &[
        &["run", "--preset", "nope"],
        &["run", "--set", "backlash_mm=-3"],
        &["scenario", "does-not-exist.toml"],
        &["analyze", "does-not-exist.csv", "--kv", "30"],
        &["sim", "--preset", "cnc9", "--velocity", "1"],
        &["run", "--duration", "-1"],
    ];
    for args in cases {
        let o = bin()
            .args(*args)
            .env("RUST_BACKTRACE", "1")
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded:\n{err}");
        assert!(err.contains("error"), "{args:?}: {err}");
        for bad in [
            "backtrace",
            "Backtrace",
            "panicked",
            "Caused by",
            "src/",
            ".rs:",
        ] {
            assert!(!err.contains(bad), "{args:?}: `{bad}` in:\n{err}");
        }
    }
}

/// `demo --velocity -10` runs its constant-speed segment towards negative positions (the
/// argument parser takes the minus sign) and finds the same limit cycle as at +10: k_v sets
/// the frequency whatever the direction.
#[test]
fn demo_runs_at_a_negative_speed() {
    let o = run(&["demo", "--velocity", "-10", "--json"]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("demo --json is JSON");
    let runs = v["runs"].as_array().expect("runs");
    let (healthy, worn) = (&runs[0], &runs[1]);
    assert_eq!(v["velocity"], -10.0);
    // The master's log says where it went.
    let narrated = run(&["demo", "--velocity", "-10"]);
    let t = text(&narrated);
    assert!(narrated.status.success(), "{t}");
    assert!(t.contains("cruise at -10000 uu/s"), "{t}");
    assert!(t.contains("at -10 mm/s"), "{t}");
    assert!(healthy["fundamental_hz"].is_null(), "{healthy}");
    let kv = worn["kv_per_s"].as_f64().unwrap();
    let f = worn["fundamental_hz"]
        .as_f64()
        .expect("the worn run's limit cycle");
    assert!(
        (0.45..=0.75).contains(&(f / kv)),
        "f = {f} Hz, k_v = {kv} 1/s: f/k_v = {}",
        f / kv
    );
}

/// A gap far beyond wear (5 mm) keeps the PP move from ever ending: the demo says where the
/// axis stood, that the position window is why, and what a worn gap is; it does not say only
/// "target not reached".
#[test]
fn demo_explains_a_target_a_huge_gap_never_reaches() {
    let o = run(&["demo", "--backlash-mm", "5"]);
    let t = text(&o);
    assert!(!o.status.success(), "{t}");
    for needle in [
        "target not reached",
        "uu off",
        "position window (0x6067)",
        "5 mm",
        "--backlash-mm 0.05",
    ] {
        assert!(t.contains(needle), "`{needle}` missing in:\n{t}");
    }
    assert!(!t.contains("panicked"), "{t}");
}

/// `demo --panel 127.0.0.1:0`: the demo's drive in real time with the panel on it, in one
/// command and no bus: it prints the page's address, the page's `hello` names the preset, its
/// stream shows the drive enabled and moving, and Ctrl-C (SIGINT) ends it cleanly.
#[test]
fn demo_with_the_panel_serves_the_page_until_ctrl_c() {
    use std::io::{BufRead, BufReader, Read};
    use std::process::Stdio;
    let mut child = bin()
        .args(["demo", "--panel", "127.0.0.1:0", "--backlash-mm", "0.05"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start drive-emu demo --panel");
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    let url = line
        .trim()
        .strip_prefix("drive-emu demo: panel on ")
        .unwrap_or_else(|| panic!("no address in: {line}"))
        .to_string();
    let http = |path: &str| -> String {
        let addr = url.trim_start_matches("http://").trim_end_matches('/');
        let mut s = std::net::TcpStream::connect(addr).expect("connect to the panel");
        s.set_read_timeout(Some(std::time::Duration::from_secs(30)))
            .unwrap();
        use std::io::Write;
        write!(
            s,
            "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
        )
        .unwrap();
        let mut body = String::new();
        // The stream never ends: read until the drive is seen enabled and moving.
        let mut buf = [0u8; 4096];
        while let Ok(n) = s.read(&mut buf) {
            if n == 0 {
                break;
            }
            body.push_str(&String::from_utf8_lossy(&buf[..n]));
            if path != "/api/stream"
                || body.contains("OPERATION ENABLED") && body.contains("\"mode_name\":\"CSP\"")
            {
                break;
            }
        }
        body
    };
    let info = http("/api/info");
    assert!(info.starts_with("HTTP/1.1 200"), "{info}");
    assert!(info.contains("\"preset\":\"cnc1\""), "{info}");
    let stream = http("/api/stream");
    assert!(
        stream.contains("OPERATION ENABLED") && stream.contains("\"mode_name\":\"CSP\""),
        "{stream}"
    );
    let pid = child.id() as i32;
    // SAFETY: kill(2) on our own child's pid.
    assert_eq!(unsafe { libc::kill(pid, libc::SIGINT) }, 0);
    let status = child.wait().unwrap();
    let mut rest = String::new();
    out.read_to_string(&mut rest).unwrap();
    assert!(status.success(), "{status}: {rest}");
    assert!(rest.contains("stopped at"), "{rest}");
}

/// `drive-emu demo | head -1`: the reader goes away after the first line; the demo ends as a
/// Unix filter does (SIGPIPE, or done), not with a panic "failed printing to stdout".
#[test]
fn a_reader_that_goes_away_ends_the_demo_without_a_panic() {
    use std::io::{BufRead, BufReader};
    use std::os::unix::process::ExitStatusExt;
    use std::process::Stdio;
    let mut child = bin()
        .args(["demo"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start drive-emu demo");
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .expect("the demo's first line");
    assert!(!first.is_empty(), "the demo printed nothing");
    // The read end is closed here; the demo's later lines meet a broken pipe.
    let out = child.wait_with_output().expect("wait for the demo");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "the demo panicked: {err}");
    assert!(
        out.status.success() || out.status.signal() == Some(libc::SIGPIPE),
        "the demo ended with {:?}: {err}",
        out.status
    );
}
