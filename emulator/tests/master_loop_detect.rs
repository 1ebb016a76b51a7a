//! A master that closes the position loop itself (issue 19, item 2), seen from the bus: the
//! reference master in CSV sends 0x60FF = v_ref + k (x_ref - x) on the direct encoder, every
//! frame written as `candump -L`. The detector must recognise that the set-point follows the
//! axis, report the master's k (within 5 % of the true one, whatever the drive's own k_v),
//! and judge the limit cycle against it: backlash, at the frequency the drive's own samples
//! show; a healthy axis under the same master is ok; and the set-points that force an axis by
//! their own timing (jitter, a task that beats with SYNC) are not taken for a loop.

use drive_emu::analysis::candump::{decode, DecodeOptions, DriveDefaults, PdoConfig};
use drive_emu::analysis::detector::{analyze, AxisTrace, DetectorConfig, Verdict};
use drive_emu::analysis::spectrum::fundamental;
use drive_emu::bus::CanBus;
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::master::outer_loop::{LoopEncoder, PositionLoop};
use drive_emu::master::{Master, MasterConfig, Step, MODE_CSV};
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::trace::node_sample;
use drive_emu::runtime::AxisSlot;
use drive_emu::session::OfflineRun;
use std::fmt::Write as _;

const NODE: u8 = 5;

struct Captured {
    log: String,
    /// The drive's own motor speed at constant speed, every 1 ms tick.
    speed_uu_s: Vec<f64>,
}

/// The master's loop at `kv` on `preset` (its own k_v untouched) with `backlash` (axis unit),
/// SYNC `sync_us`, a cruise at 10 mm/s (10 deg/s), the bus written as `candump -L`.
fn capture(preset: &str, backlash: f64, kv: f64, sync_us: u32) -> Captured {
    let base = AxisConfig::from_preset(preset).unwrap();
    let key = drive_emu::study::backlash_key(&base);
    let cfg = base.with_override(key, &backlash.to_string()).unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node::node(&mut drive, NODE).unwrap();
    let mcfg = MasterConfig {
        sync_period_us: sync_us,
        position_loop: Some(PositionLoop {
            kv_per_s: kv,
            encoder: LoopEncoder::Direct,
        }),
        ..MasterConfig::default()
    };
    let program = vec![
        Step::Enable { mode: MODE_CSV },
        Step::Cruise {
            velocity_uu_s: 10_000.0,
            accel_uu_s2: 1_000_000.0,
            duration_s: 6.0,
        },
    ];
    let mut run = OfflineRun::new(
        vec![AxisSlot { node, drive }],
        1000,
        Master::new(mcfg, program),
    );
    let mut monitor = run.take_monitor().unwrap();
    let mut log = String::new();
    let mut speed = Vec::new();
    let mut cruise_from = None;
    let drain = |m: &mut drive_emu::bus::inproc::InProcEndpoint, now: u64, log: &mut String| {
        let mut k = 0;
        while let Ok(Some(f)) = m.recv() {
            let t = 1_700_000_000_000_000 + now + k;
            k += 2;
            let hex: String = f.payload().iter().map(|b| format!("{b:02X}")).collect();
            let _ = writeln!(
                log,
                "({}.{:06}) vcan0 {:03X}#{hex}",
                t / 1_000_000,
                t % 1_000_000,
                f.id
            );
        }
    };
    while !run.master.finished() && run.now_us() < 30_000_000 {
        run.master_send();
        drain(&mut monitor, run.now_us(), &mut log);
        run.runtime.tick();
        drain(&mut monitor, run.now_us(), &mut log);
        run.master_receive();
        if cruise_from.is_none() && run.master.current_step() == 1 {
            cruise_from = Some(run.now_us());
        }
        if cruise_from.is_some_and(|t0| run.now_us() > t0 + 1_500_000) {
            speed.push(f64::from(
                node_sample(&run.runtime.axes[0].node, run.now_us()).velocity_uu_s,
            ));
        }
    }
    assert_eq!(run.master.error(), None);
    Captured {
        log,
        speed_uu_s: speed,
    }
}

fn detect(
    c: &Captured,
    preset: &str,
    drive_kv: f64,
) -> drive_emu::analysis::detector::DetectorReport {
    let (defaults, rotary) = PdoConfig::drive_defaults(NODE, preset).unwrap();
    let log = decode(
        &c.log,
        "loop.log",
        &DecodeOptions {
            node_id: NODE,
            defaults,
            sync_period_us: None,
        },
    )
    .unwrap();
    let tr = log.to_axis_trace(rotary).unwrap();
    analyze(&tr, &DetectorConfig::new(drive_kv))
}

#[test]
fn the_masters_loop_is_recognised_and_the_limit_cycle_judged_against_its_gain() {
    // cnc3's own k_v is 16.7 1/s; the master closes its loop at 30 and at 12 1/s.
    for (preset, backlash, kv, sync_us) in [
        ("cnc1", 0.05, 30.0, 1000),
        ("cnc3", 0.03, 30.0, 2000),
        ("cnc3", 0.03, 12.0, 1000),
        ("cnc4", 0.05, 40.0, 4000),
    ] {
        let c = capture(preset, backlash, kv, sync_us);
        let own_kv = AxisConfig::from_preset(preset).unwrap().kv_per_s;
        let rep = detect(&c, preset, own_kv);
        let truth = fundamental(&c.speed_uu_s, 1000.0, (1.0, 200.0)).unwrap();
        eprintln!(
            "{preset} k {kv} SYNC {sync_us} us: {} f {:?} (drive {:.2} Hz), loop {:?}\n  {}",
            rep.verdict.as_str(),
            rep.frequency_hz,
            truth.frequency_hz,
            rep.master_loop,
            rep.reasons[..2.min(rep.reasons.len())].join("\n  ")
        );
        let m = rep.master_loop.expect("the master's loop recognised");
        assert!(
            (m.kv_per_s - kv).abs() < 0.05 * kv,
            "k {} for {kv}",
            m.kv_per_s
        );
        assert_eq!(m.encoder, "direct");
        assert_eq!(rep.kv_per_s, m.kv_per_s, "the band is the master's loop's");
        assert_eq!(rep.verdict, Verdict::Backlash, "{:#?}", rep.reasons);
        assert!(rep.forced_windows.is_empty(), "{:#?}", rep.forced_windows);
        let f = rep.frequency_hz.unwrap();
        assert!(
            (f - truth.frequency_hz).abs() < 0.03 * truth.frequency_hz,
            "{f:.2} Hz, drive {:.2} Hz",
            truth.frequency_hz
        );
    }
}

#[test]
fn a_healthy_axis_under_the_masters_loop_is_ok_and_its_loop_still_seen() {
    let c = capture("cnc1", 0.0, 30.0, 1000);
    let rep = detect(&c, "cnc1", 30.0);
    assert_eq!(rep.verdict, Verdict::Ok, "{:#?}", rep.reasons);
    if let Some(m) = rep.master_loop {
        assert!((m.kv_per_s - 30.0).abs() < 1.5, "{m:?}");
    }
}

#[test]
fn an_open_loop_cruise_has_no_master_loop() {
    // The drive's own position loop (CSP targets of the reference master, no loop of its
    // own): nothing to fit, the drive's k_v stays.
    let mut tr = AxisTrace::default();
    for k in 0..4000 {
        let t = k as f64 * 1e-3;
        tr.t_s.push(t);
        tr.set_position.push((10_000.0 * t).round());
        tr.set_velocity.push(10_000.0);
        let x = 10_000.0 * t - 25.0 + 8.0 * (2.0 * std::f64::consts::PI * 18.0 * t).sin();
        tr.motor_position.push(x.round());
        tr.direct_position.push(x.round());
        tr.motor_velocity.push(
            10_000.0
                + 8.0
                    * 2.0
                    * std::f64::consts::PI
                    * 18.0
                    * (2.0 * std::f64::consts::PI * 18.0 * t).cos(),
        );
        tr.current.push(0.0);
    }
    tr.position_unit = "um".into();
    let rep = analyze(&tr, &DetectorConfig::new(30.0));
    assert_eq!(rep.master_loop, None);
    assert_eq!(rep.kv_per_s, 30.0);
    assert_eq!(rep.verdict, Verdict::Backlash, "{:#?}", rep.reasons);
}
