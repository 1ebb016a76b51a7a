//! Nonsense on the command line is refused before anything runs, with a message that names
//! the flag or key, the value and the allowed range.

mod scratch;

use std::path::PathBuf;
use std::process::Command;

/// Run drive-emu with `args`; it must fail, and its stderr must contain every `needle`.
fn refused(args: &[&str], needles: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(args)
        .output()
        .expect("run drive-emu");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "{args:?} was accepted; stdout:\n{}",
        String::from_utf8_lossy(&out.stdout)
    );
    for n in needles {
        assert!(stderr.contains(n), "{args:?}: `{n}` missing in:\n{stderr}");
    }
}

#[test]
fn sim_refuses_non_finite_and_absurd_values() {
    refused(&["sim", "--velocity", "NaN"], &["--velocity NaN", "finite"]);
    refused(&["sim", "--velocity", "1e12"], &["--velocity", "1000"]);
    refused(
        &["sim", "--velocity", "10", "--duration", "inf"],
        &["--duration inf"],
    );
    refused(
        &["sim", "--velocity", "10", "--accel=-5"],
        &["--accel -5", ">= 0"],
    );
    refused(
        &["sim", "--velocity", "10", "--kick", "nan"],
        &["--kick NaN"],
    );
}

#[test]
fn sim_refuses_a_run_beyond_the_memory_cap_and_says_how_to_raise_it() {
    refused(
        &["sim", "--velocity", "10", "--duration", "1e6"],
        &["--duration 1000000", "--max-memory-mb", "MB"],
    );
}

#[test]
fn preset_overrides_name_the_key_the_value_and_the_limit() {
    for (set, needles) in [
        ("backlash_mm=1e9", ["backlash_mm", "must be <= 10"]),
        ("kv_per_s=1e308", ["kv_per_s", "must be <= 1000"]),
        ("speed_ti_ms=0", ["speed_ti_ms", "must be > 0"]),
        (
            "stiffness_n_per_um=1e-30",
            ["stiffness_n_per_um", "must be >="],
        ),
    ] {
        refused(&["sim", "--velocity", "10", "--set", set], &needles);
    }
}

#[test]
fn run_refuses_bad_timing_flags_before_touching_the_bus() {
    refused(
        &[
            "run",
            "--iface",
            "nonexistent0",
            "--lockstep",
            "--sync-period-us",
            "0",
        ],
        &["--sync-period-us", "'0'", "100..=1000000"],
    );
    refused(
        &[
            "run",
            "--iface",
            "nonexistent0",
            "--lockstep",
            "--sync-period-us",
            "1500",
        ],
        &["--sync-period-us 1500", "multiple of the tick period"],
    );
    refused(
        &["run", "--iface", "nonexistent0", "--duration", "nan"],
        &["--duration", "'nan'", "more than 0"],
    );
    refused(
        &["run", "--iface", "nonexistent0", "--rt-priority", "500"],
        &["--rt-priority 500", "0..=99"],
    );
}

#[test]
fn demo_and_scenario_refuse_nonsense() {
    refused(&["demo", "--velocity", "nan"], &["--velocity NaN"]);
    refused(&["demo", "--cruise-s", "0"], &["--cruise-s 0"]);
    refused(
        &["demo", "--backlash-mm", "1e9"],
        &["--backlash-mm", "0.01-0.1 mm"],
    );
    refused(
        &[
            "scenario",
            "scenarios/cnc1-wear-ramp.toml",
            "--idle-dwell",
            "0",
        ],
        &["--idle-dwell 0"],
    );
}

/// A scenario file in a temporary directory.
fn scenario_file(name: &str, text: &str) -> PathBuf {
    let p = scratch::path(name);
    std::fs::write(&p, text).unwrap();
    p
}

const SCENARIO: &str = r#"name = "nonsense"
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
"#;

/// Issue 23: what an outside audit found accepted is refused with file, line, key and reason
/// (exit status 2, the file is bad), or, where only the run can tell, reported (exit 1).
#[test]
fn scenario_nonsense_is_refused_with_file_line_key_and_reason() {
    let event = |body: &str| format!("{SCENARIO}\n[[event]]\nat = \"0 s\"\n{body}\n");
    for (name, text, needles) in [
        (
            "velocity.toml",
            SCENARIO.replace("600.0", "1e300"),
            vec![
                ":11:19: key `motion[1].velocity_mm_min`",
                "1e300 is beyond the top speed of the cnc1 axis, 30000 mm/min",
            ],
        ),
        (
            "profile.toml",
            event("profile = \"load_force_n\"\namplitude = 100.0\nfrequency_hz = 1e12"),
            vec![
                ":19:16: key `event[0].frequency_hz`",
                "1e12 Hz: a load profile is applied once per tick",
                "must stay below 500 Hz",
            ],
        ),
        (
            "delay.toml",
            event("can = \"delay\"\nshare = 0.5\nticks = 1000000000"),
            vec![":19:9: key `event[0].ticks`", "at most 1000 ticks"],
        ),
        (
            "late.toml",
            format!(
                "duration = \"1 s\"\n{}",
                event("can = \"restore\"").replace("0 s", "10 s")
            ),
            vec![
                ":17:6: key `event[0].at`",
                "at or after the scenario's end (duration = 1 s, line 1)",
            ],
        ),
    ] {
        let p = scenario_file(name, &text);
        let out = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
            .args(["scenario", p.to_str().unwrap(), "--quiet", "--no-plots"])
            .output()
            .expect("run drive-emu");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {stderr}");
        assert!(
            stderr.contains(&p.display().to_string()),
            "{name}: {stderr}"
        );
        for n in needles {
            assert!(stderr.contains(n), "{name}: `{n}` missing in:\n{stderr}");
        }
    }
}

#[test]
fn a_scenario_event_after_the_program_is_reported_and_fails_the_run() {
    // No `duration`: the run ends with the program, before the event.
    let p = scenario_file(
        "unfired.toml",
        &format!("{SCENARIO}\n[[event]]\nat = \"1 h\"\nset = \"backlash_mm\"\nvalue = 0.02\n"),
    );
    let dir = p.with_extension("out");
    let out = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args([
            "scenario",
            p.to_str().unwrap(),
            "--quiet",
            "--no-plots",
            "--out",
        ])
        .arg(&dir)
        .output()
        .expect("run drive-emu");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    for n in [
        "FAIL the scenario did not finish: 1 event had not fired",
        "line 15: set backlash_mm = 0.02",
        "nonsense: FAILED",
    ] {
        assert!(stdout.contains(n), "`{n}` missing in:\n{stdout}");
    }
}

#[test]
fn an_override_of_the_wrong_type_names_the_key() {
    refused(
        &["sim", "--velocity", "10", "--set", "noise_seed=-1"],
        &["`noise_seed`", "invalid value: integer `-1`, expected u64"],
    );
}

#[cfg(feature = "socketcan")]
#[test]
fn an_interface_that_exists_but_is_not_can_is_named_so() {
    // lo exists on every Linux machine, with or without CAN in the kernel.
    let out = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(["run", "--iface", "lo", "--duration", "0.1"])
        .output()
        .expect("run drive-emu");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("No such device"), "{stderr}");
    refused(
        &["run", "--iface", "lo", "--duration", "0.1"],
        &[
            "cannot open CAN interface lo: lo exists but is not a CAN interface",
            "link type 772, loopback",
        ],
    );
}

/// Built without SocketCAN (`--no-default-features`): an interface is refused with the way
/// out, and --socketcand with --iface is one bus too many.
#[cfg(not(feature = "socketcan"))]
#[test]
fn without_socketcan_an_interface_is_refused_with_the_way_out() {
    refused(
        &["run", "--iface", "vcan0", "--duration", "0.1"],
        &[
            "cannot open CAN interface vcan0",
            "built without SocketCAN",
            "--socketcand ADDR:PORT",
        ],
    );
}

#[test]
fn socketcand_and_an_interface_are_not_both_taken() {
    refused(
        &["run", "--iface", "vcan0", "--socketcand", "127.0.0.1:0"],
        &["--socketcand", "--iface"],
    );
    refused(
        &[
            "run",
            "--socketcand",
            "127.0.0.1:99999",
            "--duration",
            "0.1",
        ],
        &["cannot serve socketcand on 127.0.0.1:99999"],
    );
}

/// LSS (CiA 305) flags: node-ID 255 (non-configured) is taken, other IDs outside 1..=127 are
/// not; the `--lss-store` file is read (and checked) before the bus is opened, its node-ID
/// replaces --node; it is one drive's memory (one axis) and not for lock-step.
#[test]
fn run_checks_lss_flags_and_the_store_file_before_touching_the_bus() {
    let dir = std::env::temp_dir().join(format!("cli-lss-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p.display().to_string()
    };
    refused(
        &["run", "--iface", "nonexistent0", "--node", "200"],
        &["--node 200", "1..=127", "255"],
    );
    let good = file("good.lss", "node_id = 12\nbit_timing_index = 2\n");
    refused(
        &[
            "run",
            "--iface",
            "nonexistent0",
            "--lss-store",
            &good,
            "--lockstep",
        ],
        &["--lss-store", "--lockstep", "in memory"],
    );
    refused(
        &[
            "run",
            "--iface",
            "nonexistent0",
            "--lss-store",
            "/nonexistent-dir-drive-emu/x.lss",
        ],
        &["/nonexistent-dir-drive-emu", "does not exist"],
    );
    let bad = file("bad.lss", "node_id = 0\nbit_timing_index = 2\n");
    refused(
        &["run", "--iface", "nonexistent0", "--lss-store", &bad],
        &["bad.lss", "`node_id`: 0", "1..=127"],
    );
    let machine = file(
        "two.toml",
        "[[axis]]\nnode_id = 5\npreset = \"cnc1\"\n[[axis]]\nnode_id = 6\npreset = \"cnc1\"\n",
    );
    refused(
        &[
            "run",
            "--iface",
            "nonexistent0",
            "--config",
            &machine,
            "--lss-store",
            &good,
        ],
        &["--lss-store", "one axis only"],
    );
    // accepted: only the missing interface stops them, after the LSS lines
    refused(
        &["run", "--iface", "nonexistent0", "--node", "255"],
        &["node-ID 255: non-configured", "nonexistent0"],
    );
    refused(
        &[
            "run",
            "--iface",
            "nonexistent0",
            "--node",
            "255",
            "--lss-store",
            &good,
        ],
        &[
            "node-ID 12, bit timing index 2 (500 kbit/s) (instead of --node 255)",
            "nonexistent0",
        ],
    );
    let fresh = dir.join("fresh.lss").display().to_string();
    refused(
        &[
            "run",
            "--iface",
            "nonexistent0",
            "--node",
            "255",
            "--lss-store",
            &fresh,
        ],
        &[
            "nothing stored yet",
            "node-ID 255: non-configured",
            "nonexistent0",
        ],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_panel_on_a_non_loopback_address_needs_a_token() {
    // Refused before the CAN interface is opened (it does not exist here).
    for addr in ["0.0.0.0:8080", "192.168.7.2:8080", "[::]:8080"] {
        refused(
            &["run", "--iface", "no-such-can9", "--panel", addr],
            &[addr, "not a loopback address", "--panel-token"],
        );
    }
    refused(
        &["run", "--iface", "no-such-can9", "--panel", "localhost"],
        &["--panel localhost", "not an address with a port"],
    );
    refused(
        &[
            "run",
            "--iface",
            "no-such-can9",
            "--panel",
            "0.0.0.0:8080",
            "--panel-token",
            "a b",
        ],
        &["--panel-token", "not allowed"],
    );
    // With a token, the panel's options pass and the run goes on to the interface.
    refused(
        &[
            "run",
            "--iface",
            "no-such-can9",
            "--panel",
            "0.0.0.0:0",
            "--panel-token",
            "t0k",
        ],
        &["no-such-can9"],
    );
    // The token needs the panel.
    refused(&["run", "--panel-token", "t0k"], &["--panel"]);
}

/// Issue 29: one exit status per kind of error, whichever command finds it
/// (`cli::exit`, docs/getting-started.md "Exit status"): 2 for what the user wrote (an
/// argument, or an input file's content), 4 for an input file that cannot be read, 1 for a
/// run that failed; and the message names the flag the user wrote.
#[test]
fn each_kind_of_error_has_one_exit_status_in_every_command() {
    let dir = std::env::temp_dir().join(format!("drive-emu-exit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad_toml = dir.join("bad.toml");
    std::fs::write(&bad_toml, "[[axis]]\nnode_id = \"five\"\n").unwrap();
    let bad_scenario = dir.join("bad-scenario.toml");
    std::fs::write(&bad_scenario, "name = 3\n").unwrap();
    let bad_eds = dir.join("bad.eds");
    std::fs::write(&bad_eds, "[FileInfo]\nthis is not an EDS\n").unwrap();
    let missing = dir.join("missing.toml");
    let f = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let cases: Vec<(Vec<String>, i32, &str)> = vec![
        // 2: an argument
        (
            vec!["run".into(), "--node".into(), "0".into()],
            2,
            "--node 0",
        ),
        (vec!["eds".into(), "--node".into(), "0".into()], 2, "--node"),
        (
            vec![
                "sim".into(),
                "--velocity".into(),
                "10".into(),
                "--set".into(),
                "backlsh_mm=1".into(),
            ],
            2,
            "did you mean `backlash_mm`",
        ),
        (
            vec!["run".into(), "--set".into(), "backlash_mm".into()],
            2,
            "key=value",
        ),
        (
            vec!["ballbar".into(), "--radius-mm".into(), "-1".into()],
            2,
            "radius",
        ),
        (
            vec![
                "scenario".into(),
                "x.toml".into(),
                "--idle-dwell".into(),
                "0".into(),
            ],
            2,
            "--idle-dwell",
        ),
        // 2: an input file's content
        (
            vec!["run".into(), "--config".into(), f(&bad_toml)],
            2,
            "node_id",
        ),
        (
            vec!["scenario".into(), f(&bad_scenario), "--quiet".into()],
            2,
            "bad-scenario.toml",
        ),
        (
            vec!["eds".into(), "--from".into(), f(&bad_eds)],
            2,
            "bad.eds",
        ),
        // 4: an input file that cannot be read
        (
            vec!["run".into(), "--config".into(), f(&missing)],
            4,
            "missing.toml",
        ),
        (
            vec!["run".into(), "--config".into(), "/dev/zero".into()],
            4,
            "/dev/zero",
        ),
        (
            vec!["run".into(), "--eds".into(), f(&missing)],
            4,
            "missing.toml",
        ),
        (
            vec!["scenario".into(), f(&missing), "--quiet".into()],
            4,
            "missing.toml",
        ),
        (
            vec!["eds".into(), "--from".into(), f(&missing)],
            4,
            "missing.toml",
        ),
        (vec!["analyze".into(), f(&missing)], 4, "missing.toml"),
    ];
    let mut wrong = Vec::new();
    for (args, want, needle) in &cases {
        let out = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
            .args(args)
            .output()
            .expect("run drive-emu");
        let stderr = String::from_utf8_lossy(&out.stderr);
        if out.status.code() != Some(*want) || !stderr.contains(needle) {
            wrong.push(format!(
                "{args:?}: exit {:?} (want {want}), stderr without `{needle}`?\n{stderr}",
                out.status.code()
            ));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}
