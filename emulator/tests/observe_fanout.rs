//! The tick's observation fan-out on a running drive: what one snapshot holds (in SI-derived
//! units, checked against the physics of a cruise), the node events drained into it, and a
//! reader that stops: it loses the oldest snapshots and counts them, while the loop goes on
//! publishing and a reader that keeps up loses nothing.

use drive_emu::drive::axis_drive::{AxisDrive, Encoder};
use drive_emu::master::{Master, MasterConfig, Step, MODE_CSP};
use drive_emu::observe::{self, ring::Cursor, AxisSnapshot};
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::AxisSlot;
use drive_emu::session::OfflineRun;

fn cruise(velocity_uu_s: f64) -> (OfflineRun<AxisDrive>, AxisConfig) {
    let cfg = AxisConfig::from_preset("cnc1").unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node(&mut drive, 5).unwrap();
    let program = vec![
        Step::Enable { mode: MODE_CSP },
        Step::Cruise {
            velocity_uu_s,
            accel_uu_s2: 100_000.0,
            duration_s: 60.0,
        },
    ];
    let run = OfflineRun::new(
        vec![AxisSlot { node, drive }],
        1000,
        Master::new(MasterConfig::default(), program),
    );
    (run, cfg)
}

#[test]
fn snapshots_hold_the_axis_in_its_units_and_a_stopped_reader_only_loses_the_oldest() {
    let (mut run, cfg) = cruise(10_000.0);
    let (mut observer, obs) = observe::channel(1, 1024);
    let ring = &obs.rings[0];
    let mut fast = Cursor::at_end(ring);
    let mut slow = Cursor::at_end(ring);
    let mut seen: Vec<AxisSnapshot> = Vec::new();
    const TICKS: u64 = 10_000;
    for k in 0..TICKS {
        run.step();
        observer.publish(&mut run.runtime);
        if k % 7 == 0 {
            while let Some(s) = obs.next(0, &mut fast) {
                seen.push(s);
            }
        }
        if k == 8000 {
            // An encoder fault: its EMCY goes through the fan-out.
            run.runtime.axes[0]
                .drive
                .set_signal_lost(Encoder::Direct, true);
        }
    }
    while let Some(s) = obs.next(0, &mut fast) {
        seen.push(s);
    }
    // The reader that kept up: every tick, in order, nothing lost.
    assert_eq!(fast.lost, 0);
    assert_eq!(seen.len() as u64, TICKS);
    assert!(seen.windows(2).all(|w| w[1].t_us == w[0].t_us + 1000));
    // The last snapshot is the node as a master reads it.
    let node = &run.runtime.axes[0].node;
    let last = seen.last().unwrap();
    assert_eq!(last.sample.statusword, node.statusword());
    assert_eq!(last.sample.position_uu, node.position_actual());
    assert_eq!(last.t_us, run.runtime.sim_time_us);
    // At constant speed (3..7 s), the load moves at the commanded 10 mm/s = 10000 uu/s and
    // the motor turns at v / pitch * gear ratio.
    let cruise: Vec<&AxisSnapshot> = seen
        .iter()
        .filter(|s| (3_000_000..7_000_000).contains(&s.t_us))
        .collect();
    let mean = |f: &dyn Fn(&AxisSnapshot) -> f64| {
        cruise.iter().map(|s| f(s)).sum::<f64>() / cruise.len() as f64
    };
    let load = mean(&|s| s.load_speed_uu_per_s);
    assert!((load - 10_000.0).abs() < 100.0, "load speed {load} uu/s");
    let rpm_expected = 0.010 / (cfg.pitch_mm.unwrap() * 1e-3) * cfg.gear_ratio * 60.0;
    let rpm = mean(&|s| s.motor_speed_rpm);
    assert!(
        (rpm / rpm_expected - 1.0).abs() < 0.01,
        "{rpm} rpm, expected {rpm_expected}"
    );
    let cw = cruise.last().unwrap().controlword;
    assert_eq!(cw & 0x0F, 0x0F, "enable operation: {cw:#06x}");
    assert_eq!(cruise.last().unwrap().nmt, 0x05);
    let current = mean(&|s| s.current_a.abs());
    assert!(
        current > 0.0 && current < cfg.rated_current_a,
        "{current} A"
    );
    // The EMCY of the encoder fault: raised once, with its code, after the fault.
    let raised: Vec<(u64, u16)> = seen
        .iter()
        .flat_map(|s| {
            s.emcys()
                .filter(|e| e.raised)
                .map(move |e| (s.t_us, e.code))
        })
        .collect();
    assert_eq!(raised.len(), 1, "{raised:?}");
    assert_eq!(raised[0].1, 0x7300);
    assert!(raised[0].0 > 8_000_000);
    // The reader that stopped: it gets the newest snapshots the ring holds, in order, ending
    // at the last tick, and counts the rest as lost; nothing in between is missing.
    let mut got = Vec::new();
    while let Some(s) = obs.next(0, &mut slow) {
        got.push(s.t_us);
    }
    assert!(!got.is_empty() && got.len() <= ring.capacity());
    assert_eq!(*got.last().unwrap(), last.t_us);
    assert!(got.windows(2).all(|w| w[1] == w[0] + 1000));
    assert_eq!(slow.lost + got.len() as u64, TICKS);
    assert_eq!(ring.written(), TICKS, "the loop published every tick");
}
