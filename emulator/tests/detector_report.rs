//! `drive-emu analyze` on a simulator-format CSV: detector JSON and PNG plots are written.

use drive_emu::analysis::{constant_velocity_run, RunOptions};
use drive_emu::cli::analyze::{run, AnalyzeArgs};
use drive_emu::cli::sim::write_trace_csv;
use drive_emu::presets::AxisConfig;

#[test]
fn analyze_writes_json_and_plots_from_a_sim_trace() {
    let dir = std::env::temp_dir().join(format!("drive-emu-analyze-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("backlash_mm", "0.05")
        .unwrap();
    let opts = RunOptions {
        velocity: 1000.0 / 60.0,
        duration: 3.0,
        accel: 0.0,
        record: true,
        kick: None,
    };
    let r = constant_velocity_run(&cfg, &opts).unwrap();
    let csv = dir.join("trace.csv");
    let mut w = std::io::BufWriter::new(std::fs::File::create(&csv).unwrap());
    write_trace_csv(&mut w, &r.trace, "mm").unwrap();
    drop(w);
    let out = dir.join("report");
    let code = run(&AnalyzeArgs {
        trace: csv,
        kv: Some(cfg.kv_per_s),
        rotary: false,
        suspect: None,
        alarm: None,
        out: Some(out.clone()),
        fail_on_backlash: true,
        ..Default::default()
    })
    .unwrap();
    assert_eq!(
        code,
        std::process::ExitCode::from(1),
        "backlash must be flagged"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("detector.json")).unwrap()).unwrap();
    assert_ne!(json["verdict"], "ok");
    let f = json["frequency_hz"].as_f64().unwrap();
    assert!((f - 18.0).abs() < 2.0, "{f}");
    for png in ["traces.png", "spectrum.png", "amplitude.png"] {
        let bytes = std::fs::read(out.join(png)).unwrap();
        assert!(bytes.len() > 5000 && bytes.starts_with(b"\x89PNG"), "{png}");
    }
    if std::env::var_os("KEEP_REPORT").is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    } else {
        eprintln!("report kept in {}", out.display());
    }
}
