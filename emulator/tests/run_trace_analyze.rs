//! The trace `drive-emu run --trace` writes is what `drive-emu analyze` reads: the drive's
//! own velocity demand (0x606B) marks the constant-speed windows, and the detector finds the
//! backlash limit cycle in it, at the frequency a master sees in its TPDOs.

use drive_emu::analysis::detector::{analyze, AxisTrace, DetectorConfig, Verdict};
use drive_emu::analysis::spectrum::fundamental;
use drive_emu::cli::analyze::trace_from_csv;
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::master::{Master, MasterConfig, Step, MODE_CSP, MODE_PP};
use drive_emu::observe::trace::Recorder;
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::trace::node_sample;
use drive_emu::runtime::AxisSlot;
use drive_emu::samples::SampleSource;
use drive_emu::session::OfflineRun;

/// A CNC1 axis with `backlash_mm`: PP move, then 6 s of CSP cruise at 10 mm/s from the
/// reference master, offline; `each_tick` sees the run after every tick.
fn cruise(
    backlash_mm: f64,
    mut each_tick: impl FnMut(&mut OfflineRun<AxisDrive>),
) -> OfflineRun<AxisDrive> {
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("backlash_mm", &backlash_mm.to_string())
        .unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node(&mut drive, 5).unwrap();
    let program = vec![
        Step::Enable { mode: MODE_PP },
        Step::MoveTo {
            target_uu: 5_000,
            velocity_uu_s: 50_000,
            accel_uu_s2: 500_000,
        },
        Step::SetMode { mode: MODE_CSP },
        Step::Cruise {
            velocity_uu_s: 10_000.0,
            accel_uu_s2: 100_000.0,
            duration_s: 6.0,
        },
    ];
    let mut run = OfflineRun::new(
        vec![AxisSlot { node, drive }],
        1000,
        Master::new(MasterConfig::default(), program),
    );
    while !run.master.finished() {
        run.step();
        each_tick(&mut run);
    }
    assert!(run.master.error().is_none(), "{:?}", run.master.error());
    run
}

/// `run --trace` of that cruise, read back as `drive-emu analyze` does, and the speed the
/// master saw in its TPDOs at constant set-point.
fn traced_run(backlash_mm: f64, name: &str) -> (AxisTrace, Vec<f64>) {
    let dir = std::env::temp_dir().join(format!("drive-emu-rta-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.csv"));
    let (mut observer, obs) = drive_emu::observe::channel(1, 1 << 14);
    let rec = Recorder::start(obs, vec![path.clone()]).unwrap();
    let run = cruise(backlash_mm, |run| observer.publish(&mut run.runtime));
    assert_eq!(rec.finish().unwrap().lost, 0);
    let tr = trace_from_csv(&path, false).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    // The master's own view of the same run: speed from its TPDOs at constant set-point.
    let wire: Vec<f64> = run
        .master
        .samples()
        .iter()
        .filter(|s| s.setpoint_velocity_uu_s == 10_000.0 && s.t_s > run.master.samples()[0].t_s)
        .map(|s| f64::from(s.velocity_uu_s))
        .collect();
    (tr, wire)
}

#[test]
fn a_run_trace_shows_the_limit_cycle_to_the_detector() {
    let kv = 30.0;
    let (worn, wire) = traced_run(0.05, "worn");
    let rep = analyze(&worn, &DetectorConfig::new(kv));
    assert_ne!(rep.verdict, Verdict::Ok, "{rep:?}");
    let f = rep.frequency_hz.expect("a fundamental");
    assert!((kv / 4.0..kv).contains(&f), "f = {f}");
    // The same frequency as the master measures from its TPDOs (last 4 s of the cruise).
    let tail = &wire[wire.len().saturating_sub(4000)..];
    let f_wire = fundamental(tail, 1000.0, (kv / 4.0, kv))
        .unwrap()
        .frequency_hz;
    assert!(
        (f - f_wire).abs() / f_wire < 0.05,
        "trace {f} Hz, wire {f_wire} Hz"
    );

    let (healthy, _) = traced_run(0.0, "healthy");
    let rep = analyze(&healthy, &DetectorConfig::new(kv));
    assert_eq!(rep.verdict, Verdict::Ok, "{rep:?}");
    assert!(
        !rep.windows.is_empty(),
        "constant-speed windows found in the trace"
    );
}

#[test]
fn a_live_scenario_detector_sees_the_drive_side_samples_right() {
    // What the observation bus carries every tick, and run_timeline analyses.
    let mut samples = Vec::new();
    cruise(0.05, |run| {
        samples.push(node_sample(
            &run.runtime.axes[0].node,
            run.runtime.sim_time_us,
        ))
    });
    let rep = analyze(
        &AxisTrace::from_sample_log(&samples, SampleSource::Drive, false),
        &DetectorConfig::new(30.0),
    );
    assert_ne!(rep.verdict, Verdict::Ok, "{rep:?}");
    assert!(rep
        .windows
        .iter()
        .all(|w| (w.set_velocity - 10_000.0).abs() < 1.0));
}
