//! What the live panel costs the loop: one tick of a drive in CSP on an in-process bus, without
//! and with the observation fan-out's publish (one snapshot per axis into its ring, node events
//! drained), and the publish alone.
//!
//! cargo bench -p drive-emu --bench observe -- --warm-up-time 1 --measurement-time 3

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::master::{Master, MasterConfig, Step, MODE_CSP};
use drive_emu::observe;
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::AxisSlot;
use drive_emu::session::OfflineRun;

fn cruising() -> OfflineRun<AxisDrive> {
    let cfg = AxisConfig::from_preset("cnc1").unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node(&mut drive, 5).unwrap();
    let program = vec![
        Step::Enable { mode: MODE_CSP },
        Step::Cruise {
            velocity_uu_s: 10_000.0,
            accel_uu_s2: 100_000.0,
            duration_s: 1e6,
        },
    ];
    let mut run = OfflineRun::new(
        vec![AxisSlot { node, drive }],
        1000,
        Master::new(MasterConfig::default(), program),
    );
    while run.now_us() < 2_000_000 {
        run.step();
    }
    run
}

fn bench(c: &mut Criterion) {
    let mut run = cruising();
    c.bench_function("tick_without_publish", |b| {
        b.iter(|| {
            run.step();
            black_box(run.now_us())
        })
    });
    let mut run = cruising();
    let (mut observer, obs) = observe::channel(1, 1024);
    c.bench_function("tick_with_publish", |b| {
        b.iter(|| {
            run.step();
            observer.publish(&mut run.runtime);
            black_box(obs.board.ticks.load(std::sync::atomic::Ordering::Relaxed))
        })
    });
    c.bench_function("publish_alone", |b| {
        b.iter(|| {
            observer.publish(&mut run.runtime);
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
