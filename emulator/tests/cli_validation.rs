//! Nonsense on the command line is refused before anything runs, with a message that names
//! the flag or key, the value and the allowed range.

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
        &["demo", "--backlash", "1e9"],
        &["--backlash", "0.01-0.1 mm"],
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
        &["node_id", "200", "1..=127", "255"],
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
