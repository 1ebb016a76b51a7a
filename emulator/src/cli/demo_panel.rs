//! `drive-emu demo --panel [ADDR]`: the demo's drive and reference master in real time, with
//! the live panel on them, so a newcomer sees the page in one command and no CAN bus.
//!
//! The master enables the drive in CSP and moves it back and forth at `--velocity` for
//! `--cruise-s` each way (the constant speed the detector needs), until Ctrl-C; the drive has
//! the backlash of the demo's worn run (`--backlash-mm`, `--backlash-deg`), which the page's
//! control changes live. One tick of the drive per millisecond of wall time, on the
//! in-process bus (lock-step: its time is the master's SYNCs).

use crate::bus::fault::FaultyBus;
use crate::bus::inproc::{InProcBus, InProcEndpoint};
use crate::bus::CanBus;
use crate::drive::axis_drive::AxisDrive;
use crate::master::{Master, MasterConfig, Step, MODE_CSP};
use crate::panel::{PanelAxis, PanelLoop, PanelSetup};
use crate::presets::AxisConfig;
use crate::runtime::{AxisSlot, Runtime};
use anyhow::{bail, Context, Result};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Ticks per second: 1 ms per tick, as the demo's master's SYNC period.
const TICK_HZ: u32 = 1000;
/// Back-and-forth legs the master's program holds (at 4 s each: hours; Ctrl-C ends it).
const LEGS: usize = 10_000;
/// Acceleration of each leg, per second of the leg's speed (reach it in 0.1 s).
const ACCEL_PER_S: f64 = 10.0;

/// The master's program: enable in CSP, then `v_uu` back and forth for `leg_s` each way.
fn program(v_uu: f64, leg_s: f64) -> Vec<Step> {
    let mut p = vec![Step::Enable { mode: MODE_CSP }];
    for k in 0..LEGS {
        let v = if k % 2 == 0 { v_uu } else { -v_uu };
        p.push(Step::Cruise {
            velocity_uu_s: v,
            accel_uu_s2: ACCEL_PER_S * v_uu.abs(),
            duration_s: leg_s,
        });
    }
    p
}

/// One tick of a drive on the in-process bus with the reference master beside it and the
/// panel watching: the master's frames in, the drive's tick, the loop's hook (publish on the
/// observation bus, the panel's injections), the drive's answers to the master. (The panel's
/// test rig runs the same.)
pub fn tick_with_master(
    master: &mut Master,
    master_bus: &mut InProcEndpoint,
    rt: &mut Runtime<FaultyBus<InProcEndpoint>, AxisDrive>,
    (observer, panel_loop): (&mut crate::observe::Observer, &mut PanelLoop),
) {
    master.poll(rt.sim_time_us);
    while let Some(f) = master.pop_tx() {
        let _ = master_bus.send(&f);
    }
    rt.tick();
    rt.stats.record_tick(0, 0);
    if rt.stats.ticks.is_multiple_of(256) {
        rt.publish_stats();
    }
    observer.publish(rt);
    panel_loop.on_tick(rt);
    while let Ok(Some(f)) = master_bus.recv() {
        master.handle(&f, rt.sim_time_us);
    }
}

/// What `demo --panel` runs, from the demo's flags (checked already).
pub struct PanelDemo<'a> {
    /// The preset's name.
    pub preset: &'a str,
    /// The drive's backlash, in the preset's unit (mm or deg).
    pub backlash: f64,
    /// The constant speed of each leg, mm/s or deg/s (as the user wrote it).
    pub velocity: f64,
    /// The same in the drive's user units per second.
    pub velocity_uu_s: f64,
    /// Duration of each leg, s.
    pub cruise_s: f64,
    /// The drive's node ID.
    pub node: u8,
    /// Where the panel listens, and its token.
    pub panel: &'a crate::panel::PanelArgs,
}

/// Run the demo with the panel until Ctrl-C / SIGTERM (or the master's program ends).
pub fn run(args: &PanelDemo) -> Result<()> {
    let base = AxisConfig::from_preset(args.preset)?;
    let (key, unit) = if base.backlash_deg.is_some() {
        ("backlash_deg", "deg")
    } else {
        ("backlash_mm", "mm")
    };
    let cfg = base.with_override(key, &args.backlash.to_string())?;
    let mut drive = AxisDrive::from_config(&cfg)?;
    let node = crate::drive::node(&mut drive, args.node)?;
    let mut eps = InProcBus::endpoints(2, 4096);
    let (Some(mut master_bus), Some(drive_end)) = (eps.pop(), eps.pop()) else {
        bail!("the in-process bus has no endpoints");
    };
    let mut rt = Runtime::new(
        FaultyBus::new(drive_end, 1),
        vec![AxisSlot { node, drive }],
        u64::from(1_000_000 / TICK_HZ),
    );
    rt.boot();
    let mcfg = MasterConfig {
        node_id: args.node,
        ..Default::default()
    };
    let setup = PanelSetup {
        bus: crate::panel::PanelBus::Can,
        axes: vec![PanelAxis {
            node_id: args.node,
            preset: args.preset.to_string(),
            config: cfg.clone(),
            overrides: vec![(key.to_string(), args.backlash.to_string())],
        }],
        iface: None,
        tick_hz: TICK_HZ,
        lockstep: true,
        master_id: mcfg.master_id,
        json_stdout: false,
    };
    let (mut observer, obs) = crate::observe::channel(1, crate::observe::ring_capacity(TICK_HZ));
    let Some((panel, mut panel_loop)) = crate::panel::start(args.panel, setup, obs)? else {
        bail!("demo --panel: no panel address");
    };
    let mut master = Master::new(mcfg, program(args.velocity_uu_s, args.cruise_s));
    println!("drive-emu demo: panel on {}", panel.url());
    println!(
        "(a {} drive with {} {unit} of backlash on an in-process bus, moved back and forth at \
         {} {unit}/s by the reference master, in real time; Ctrl-C stops)",
        args.preset, args.backlash, args.velocity
    );
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = Arc::clone(&stop);
        ctrlc::set_handler(move || stop.store(true, Ordering::Relaxed))
            .context("cannot install the Ctrl-C / SIGTERM handler")?;
    }
    let period = Duration::from_micros(u64::from(1_000_000 / TICK_HZ));
    let start = Instant::now();
    let mut ticks: u32 = 0;
    while !stop.load(Ordering::Relaxed) && !master.finished() && master.error().is_none() {
        tick_with_master(
            &mut master,
            &mut master_bus,
            &mut rt,
            (&mut observer, &mut panel_loop),
        );
        // Paced on the wall clock: tick k is due at start + k periods (a late tick is not
        // made up for by skipping: the drive's time is the master's, not the wall's).
        ticks += 1;
        let due = period * ticks;
        let now = start.elapsed();
        if due > now {
            std::thread::sleep(due - now);
        }
    }
    panel.stop();
    if let Some(e) = master.error() {
        bail!("the reference master failed: {e}");
    }
    println!(
        "drive-emu demo: stopped at {:.1} s of drive time",
        rt.sim_time_us as f64 * 1e-6
    );
    Ok(())
}
