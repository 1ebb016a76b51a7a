//! The live-run trace recorder (observe/trace.rs, a reader of the observation bus) against an
//! offline run of the reference master: every tick of every axis is written, and nothing stays
//! in a buffer after `finish`.
//! (An integration test: the runtime layer itself does not know the master or the drive.)

use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::master::{Master, MasterConfig, Step, MODE_CSP};
use drive_emu::observe::trace::Recorder;
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::trace::trace_paths;
use drive_emu::runtime::AxisSlot;
use drive_emu::samples::csv::read_csv;
use drive_emu::session::OfflineRun;

#[test]
fn the_recorder_writes_every_tick_of_every_axis_and_flushes_on_finish() {
    let axes = [5u8, 6]
        .iter()
        .map(|&id| {
            let mut drive =
                AxisDrive::from_config(&AxisConfig::from_preset("cnc1").unwrap()).unwrap();
            let node = drive_emu::drive::node(&mut drive, id).unwrap();
            AxisSlot { node, drive }
        })
        .collect();
    let program = vec![
        Step::Enable { mode: MODE_CSP },
        Step::Cruise {
            velocity_uu_s: 5_000.0,
            accel_uu_s2: 50_000.0,
            duration_s: 1.0,
        },
    ];
    let mut run = OfflineRun::new(axes, 1000, Master::new(MasterConfig::default(), program));
    let dir = std::env::temp_dir().join(format!("drive-emu-trace-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let paths = trace_paths(&dir.join("t.csv"), &[5, 6]);
    let (mut observer, obs) = drive_emu::observe::channel(2, 1 << 14);
    let rec = Recorder::start(obs, paths.clone()).unwrap();
    let mut ticks = 0u64;
    let mut last_position = 0;
    while !run.master.finished() {
        run.step();
        observer.publish(&mut run.runtime);
        ticks += 1;
        last_position = run.runtime.axes[0].node.position_actual();
    }
    let summary = rec.finish().unwrap();
    assert_eq!(summary.samples, 2 * ticks);
    assert_eq!(summary.lost, 0);
    let cols = read_csv(&paths[0]).unwrap();
    let col = |name: &str| &cols.iter().find(|(n, _)| n == name).unwrap().1;
    let t = col("t_s");
    assert_eq!(t.len() as u64, ticks);
    assert!(t.windows(2).all(|w| ((w[1] - w[0]) - 1e-3).abs() < 1e-9));
    // The last row is the last tick: nothing stayed in a buffer.
    assert_eq!(
        *col("position_uu").last().unwrap(),
        f64::from(last_position)
    );
    assert!(last_position > 3_000, "node 5 cruised: {last_position}");
    // Node 6 got no commands: it never moved, and its file says so.
    let cols6 = read_csv(&paths[1]).unwrap();
    let pos6 = &cols6.iter().find(|(n, _)| n == "position_uu").unwrap().1;
    assert_eq!(pos6.len() as u64, ticks);
    assert!(pos6.iter().all(|p| p.abs() < 50.0), "node 6 stood still");
    std::fs::remove_dir_all(&dir).ok();
}
