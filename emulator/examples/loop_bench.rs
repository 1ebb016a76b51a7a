//! Loop benchmark: N CiA 402 axes (cnc1) on the real-time loop at a given rate, fed a SYNC and a
//! CSP set-point per axis every tick, as a master on the bus would. Prints lateness and work
//! statistics as JSON. The bus is in-process: the loop's timing does not depend on it.
//!
//!     cargo run --release -p drive-emu --example loop_bench -- AXES HZ SECONDS [PRIORITY]

use drive_emu::bus::inproc::InProcBus;
use drive_emu::bus::{CanBus, CanFrame};
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::realtime::{self, RealtimeRequest};
use drive_emu::runtime::{AxisSlot, Runtime};
use drive_emu::time::{Clock, MonotonicClock};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let axes: u8 = args.first().map_or(Ok(1), |s| s.parse())?;
    let hz: u64 = args.get(1).map_or(Ok(1000), |s| s.parse())?;
    let seconds: f64 = args.get(2).map_or(Ok(5.0), |s| s.parse())?;
    let prio: i32 = args.get(3).map_or(Ok(80), |s| s.parse())?;
    let cfg = AxisConfig::from_preset("cnc1")?.with_override("backlash_mm", "0.05")?;
    let slots = (1..=axes)
        .map(|id| {
            let mut drive = AxisDrive::from_config(&cfg).unwrap();
            let node = drive_emu::drive::node(&mut drive, id).unwrap();
            AxisSlot { node, drive }
        })
        .collect();
    let mut eps = InProcBus::endpoints(2, 65536);
    let mut master = eps.pop().unwrap();
    let drive_bus = eps.pop().unwrap();
    let period_us = 1_000_000 / hz;
    let mut rt = Runtime::new(drive_bus, slots, period_us);
    let report = realtime::apply(&RealtimeRequest {
        fifo_priority: (prio > 0).then_some(prio),
        cpu: Some(1),
        lock_memory: true,
    });
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    eprintln!("{report}");
    rt.boot();
    // Operational, then switch on and enable every axis (RPDO1: controlword, applied at once).
    master.send(&CanFrame::new(0x000, &[0x01, 0])).unwrap();
    let mut clock = MonotonicClock::new();
    let ticks = (seconds * hz as f64) as u64;
    let stop = Arc::new(AtomicBool::new(false));
    let mut k = 0u64;
    let mut deadline = clock.now_us();
    while k < ticks && !stop.load(Ordering::Relaxed) {
        let woke = clock.sleep_until(deadline);
        // What the master sends this cycle: controlword steps, then CSP set-points + SYNC.
        for id in 1..=u32::from(axes) {
            match k {
                2 => master.send(&CanFrame::new(0x200 + id, &[0x06, 0])).unwrap(),
                4 => master.send(&CanFrame::new(0x200 + id, &[0x07, 0])).unwrap(),
                6 => master.send(&CanFrame::new(0x200 + id, &[0x0F, 0])).unwrap(),
                _ => {}
            }
        }
        master.send(&CanFrame::new(0x080, &[])).unwrap();
        rt.tick();
        while let Ok(Some(_)) = master.recv() {}
        let done = clock.now_us();
        rt.stats
            .record_tick(woke.saturating_sub(deadline), done.saturating_sub(woke));
        deadline += period_us;
        k += 1;
    }
    let enabled = rt
        .axes
        .iter()
        .filter(|a| a.node.statusword() & 0x6F == 0x27)
        .count();
    let s = rt.stats.summary();
    println!(
        "{}",
        serde_json::json!({
            "axes": axes, "hz": hz, "seconds": seconds, "enabled_axes": enabled,
            "stats": s, "realtime": report.to_string(),
        })
    );
    Ok(())
}
