//! A scenario passes only when the master program ran to its end: an SDO that times out in
//! the program, or a program too long to hold in memory, is a failure the user is told about.

use drive_emu::scenario::{self, runner};
use std::path::Path;

fn opts() -> runner::RunOptions {
    runner::RunOptions {
        progress: false,
        ..Default::default()
    }
}

const PROGRAM: &str = r#"
name = "t"
[machine]
preset = "cnc1"

[[motion]]
step = "enable"
mode = "csp"

[[motion]]
step = "cruise"
velocity_mm_min = 600.0
accel_mm_s2 = 500.0
duration = "1 s"

[[expect]]
no_emcy = true
"#;

#[test]
fn the_healthy_program_passes() {
    let s = scenario::parse(PROGRAM, Path::new("ok.toml")).unwrap();
    let out = runner::run(&s, &opts()).unwrap();
    assert!(out.passed, "{:?}", out.runs[0].program_failure);
    assert!(out.runs[0].program_finished);
}

#[test]
fn an_sdo_timeout_in_the_program_fails_the_scenario() {
    // Every SDO answer of the drive is lost: the master's first SDO times out.
    let src = format!(
        "{PROGRAM}\n[[event]]\nat = \"0 s\"\ncan = \"drop\"\nshare = 1.0\ncob_id = \"0x585\"\n"
    );
    let s = scenario::parse(&src, Path::new("sdo.toml")).unwrap();
    let out = runner::run(&s, &opts()).unwrap();
    let r = &out.runs[0];
    assert!(r.program_error.is_some(), "the master saw no error");
    assert!(!out.passed, "a failed program must fail the scenario");
    let why = r.program_failure.as_deref().unwrap();
    assert!(why.contains("master program failed"), "{why}");
    // Said in the JSON summary too.
    let json = serde_json::to_value(&out).unwrap();
    assert_eq!(json["passed"], false);
    assert!(json["runs"][0]["program_failure"].is_string(), "{json}");
}

#[test]
fn a_mistyped_100000_h_cruise_is_refused_before_it_runs() {
    let src = PROGRAM.replace("duration = \"1 s\"", "duration = \"100000 h\"");
    let s = scenario::parse(&src, Path::new("long.toml")).unwrap();
    let e = runner::run(&s, &opts()).unwrap_err().to_string();
    assert!(
        e.contains("--max-memory-mb") && e.contains("360000000 s"),
        "{e}"
    );
}

#[test]
fn events_that_never_fired_fail_the_scenario_and_are_named() {
    // One event after the program's end (no `duration` to refuse it at the file: the run
    // ends 0.2 s after the program), one whose condition never comes; both were dropped
    // silently and the scenario passed.
    let late = "\n[[event]]\nat = \"30 s\"\nset = \"backlash_mm\"\nvalue = 0.01\n";
    let never = "\n[[event]]\non_emcy = \"0x7300\"\ncan = \"restore\"\n";
    let src = format!("{PROGRAM}{late}{never}");
    let s = scenario::parse(&src, Path::new("late.toml")).unwrap();
    let out = runner::run(&s, &opts()).unwrap();
    let r = &out.runs[0];
    assert!(r.program_failure.is_none() && r.expectations.iter().all(|e| e.passed));
    assert!(
        !out.passed,
        "an event that never fired must fail the scenario"
    );
    // each named by the line of its table's header, the line before its first key
    let line = |needle: &str| src.lines().position(|l| l.contains(needle)).unwrap();
    let lines: Vec<usize> = r.not_fired.iter().map(|n| n.0).collect();
    assert_eq!(lines, [line("at = \"30 s\""), line("on_emcy")], "{src}");
    let why = r.unfinished.as_deref().unwrap();
    for needle in [
        "2 events had not fired",
        &format!("line {}: set backlash_mm = 0.01", r.not_fired[0].0),
        &format!("line {}: CAN: faults removed", r.not_fired[1].0),
    ] {
        assert!(why.contains(needle), "`{needle}` missing: {why}");
    }
    let json = serde_json::to_value(&out).unwrap();
    assert!(json["runs"][0]["unfinished"].is_string(), "{json}");
    // Without them the same run passes.
    let s = scenario::parse(PROGRAM, Path::new("ok.toml")).unwrap();
    assert!(runner::run(&s, &opts()).unwrap().passed);
}
