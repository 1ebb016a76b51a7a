//! Every shipped scenario runs offline and its expectations hold.

use drive_emu::scenario::{self, runner};
use std::path::{Path, PathBuf};

fn file(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(format!("{name}.toml"))
}

fn run(name: &str) -> runner::Outcome {
    let s = scenario::load(&file(name)).unwrap_or_else(|e| panic!("{e}"));
    let opts = runner::RunOptions {
        progress: false,
        ..Default::default()
    };
    let out = runner::run(&s, &opts).unwrap();
    let dir =
        std::env::temp_dir().join(format!("drive-emu-scenario-{}-{name}", std::process::id()));
    let files = runner::write_report(&out, &dir, true).unwrap();
    assert!(files.iter().any(|f| f.ends_with("summary.json")));
    let mut msg = String::new();
    for r in &out.runs {
        msg += &format!(
            "[{}] physical {:.1} s, scenario {:.1} s, wall {:.2} s, emcys {:?}, error {:?}\n",
            r.preset, r.physical_s, r.scenario_s, r.wall_s, r.emcys, r.program_error
        );
        if let Some(d) = &r.detector {
            msg += &format!(
                "  detector {} amp {:.2} f {:?} dominant {:?} windows {}\n",
                d.verdict.as_str(),
                d.amplitude,
                d.frequency_hz,
                d.dominant_hz,
                d.windows.len()
            );
        }
        for e in &r.expectations {
            msg += &format!(
                "  line {}: {} -> {} ({})\n",
                e.line,
                e.expectation,
                if e.passed { "ok" } else { "FAILED" },
                e.detail
            );
        }
    }
    eprintln!("{msg}");
    assert!(out.passed, "{name}:\n{msg}");
    if std::env::var_os("KEEP_REPORT").is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    } else {
        eprintln!("report in {}", dir.display());
    }
    out
}

#[test]
fn scenario_cnc1_wear_ramp() {
    let out = run("cnc1-wear-ramp");
    let r = &out.runs[0];
    assert!(r.scenario_s >= 3600.0, "{}", r.scenario_s);
    assert!(r.fast_forwarded_s > 3500.0);
}

#[test]
fn scenario_kv_sweep() {
    let out = run("kv-sweep");
    assert_eq!(out.runs.len(), 5);
}

#[test]
fn scenario_encoder_loss() {
    run("encoder-loss");
}

#[test]
fn scenario_sync_loss() {
    run("sync-loss");
}

#[test]
fn scenario_heartbeat_loss() {
    run("heartbeat-loss");
}

#[test]
fn scenario_cutting_load() {
    run("cutting-load");
}

#[test]
fn scenario_loose_coupling() {
    run("loose-coupling");
}

#[test]
fn scenario_cnc_position_loop() {
    let out = run("cnc-position-loop");
    assert_eq!(out.runs.len(), 5);
    // The detector's band is the master's loop's: k_v 30 1/s on every machine, whatever the
    // preset's own.
    for r in &out.runs {
        let d = r.detector.as_ref().unwrap();
        assert_eq!(d.kv_per_s, 30.0, "{}", r.preset);
    }
}
