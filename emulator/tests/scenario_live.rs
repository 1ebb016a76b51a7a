//! A scenario's timeline injected into a running drive (what `drive-emu run --scenario` and
//! `drive-emu scenario --iface` do), with the loop on the wall clock and the scenario on its own
//! thread, talking through the lock-free LiveLink. The motion comes from a controller on the
//! bus: here the reference master on an in-process bus.

use drive_emu::bus::fault::FaultyBus;
use drive_emu::bus::inproc::InProcBus;
use drive_emu::bus::CanBus;
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::drive::AxisParam;
use drive_emu::master::{Master, MasterConfig, Step, MODE_CSP};
use drive_emu::runtime::{AxisSlot, Lockstep, Runtime};
use drive_emu::scenario::live::{run_timeline, LiveEnd, LiveLink, LoopInjector};
use drive_emu::time::{Clock, MonotonicClock};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

const SCENARIO: &str = r#"
name = "live-test"
duration = "2.5 s"
[machine]
preset = "cnc1"
backlash_mm = 0.02
[[motion]]
step = "enable"
mode = "csp"
[[event]]
id = "wear"
at = "0.3 s"
set = "backlash_mm"
value = 0.06
[[event]]
id = "loss"
at = "1.5 s"
sensor = "direct_encoder_loss"
[[expect]]
emcy = "0x7300"
after = "loss"
within = "100 ms"
[[expect]]
state = "fault"
[[expect]]
no_emcy = true
until = "1.4 s"
"#;

#[test]
fn a_live_timeline_changes_the_running_drive_and_its_expectations_are_checked() {
    let s = drive_emu::scenario::parse(SCENARIO, std::path::Path::new("live-test.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    let cfg = s.machine.configs[0].clone();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let snapshot = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node(&mut drive, 5).unwrap();
    let mut eps = InProcBus::endpoints(2, 4096);
    let mut master_bus = eps.pop().unwrap();
    let bus = FaultyBus::new(eps.pop().unwrap(), 1);
    let mut rt = Runtime::new(bus, vec![AxisSlot { node, drive }], 1000);
    rt.boot();
    let mut master = Master::new(
        MasterConfig::default(),
        vec![
            Step::Enable { mode: MODE_CSP },
            Step::Cruise {
                velocity_uu_s: 10_000.0,
                accel_uu_s2: 100_000.0,
                duration_s: 10.0,
            },
        ],
    );
    let link = Arc::new(LiveLink::new());
    // The observation bus the loop publishes into and the scenario thread reads.
    let (mut observer, obs) = drive_emu::observe::channel(1, 1 << 14);
    let stop = Arc::new(AtomicBool::new(false));
    let scenario_thread = {
        let (s, cfg, link, stop) = (s.clone(), cfg.clone(), link.clone(), stop.clone());
        let obs = Arc::clone(&obs);
        std::thread::spawn(move || {
            let end = LiveEnd::for_scenario(&s, None);
            let o = run_timeline(&s, &cfg, &snapshot, (&link, &obs), &stop, end);
            stop.store(true, Ordering::Relaxed);
            o
        })
    };
    let mut injector = LoopInjector::new(0x7F);
    let mut clock = MonotonicClock::new();
    let mut deadline = clock.now_us();
    let mut backlash_at_1s = None;
    while !stop.load(Ordering::Relaxed) && rt.sim_time_us < 10_000_000 {
        clock.sleep_until(deadline);
        deadline += 1000;
        master.poll(rt.sim_time_us);
        while let Some(f) = master.pop_tx() {
            master_bus.send(&f).unwrap();
        }
        rt.tick();
        observer.publish(&mut rt);
        injector.on_tick(&link, &mut rt);
        while let Ok(Some(f)) = master_bus.recv() {
            master.handle(&f, rt.sim_time_us);
        }
        if rt.sim_time_us == 1_000_000 {
            backlash_at_1s = Some(rt.axes[0].drive.param(AxisParam::Backlash));
        }
    }
    let outcome = scenario_thread.join().unwrap();
    for e in &outcome.expectations {
        eprintln!(
            "{} line {}: {} ({})",
            e.passed, e.line, e.expectation, e.detail
        );
    }
    assert_eq!(
        backlash_at_1s,
        Some(0.06e-3),
        "the set event reached the running drive"
    );
    assert!(outcome.fired.len() == 2, "{:?}", outcome.fired);
    assert!(outcome.record.samples.len() > 2000, "samples from the loop");
    assert!(outcome.passed(), "expectations: {:?}", outcome.expectations);
    assert!(
        master.emcys().iter().any(|e| e.code == 0x7300),
        "the controller saw the EMCY too"
    );
}

/// The shipped SYNC-loss scenario live, with the drive in lock-step: the scenario cuts the
/// SYNCs, so the drive's simulated time would stand still for ever. One second (here 0.2 s) of
/// wall time after the last SYNC the drive's own clock takes over: its SYNC supervision
/// reports the loss (EMCY 0x8100), and the run ends by itself, once the event has run its
/// course, with the event at the time the drive applied it and every expectation checked.
#[test]
fn a_lockstep_live_scenario_whose_sync_stops_ends_by_itself_with_the_sync_loss_reported() {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/sync-loss.toml");
    let s = drive_emu::scenario::load(&file).unwrap_or_else(|e| panic!("{e}"));
    let cfg = s.machine.configs[0].clone();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let snapshot = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node(&mut drive, 5).unwrap();
    let mut eps = InProcBus::endpoints(2, 4096);
    let mut master_bus = eps.pop().unwrap();
    let bus = FaultyBus::new(eps.pop().unwrap(), 1);
    let mut rt = Runtime::new(bus, vec![AxisSlot { node, drive }], 1000);
    let link = Arc::new(LiveLink::new());
    // The observation bus the loop publishes into and the scenario thread reads.
    let (mut observer, obs) = drive_emu::observe::channel(1, 1 << 14);
    let stop = Arc::new(AtomicBool::new(false));
    let scenario_thread = {
        let (s, cfg, link, stop) = (s.clone(), cfg.clone(), link.clone(), stop.clone());
        let obs = Arc::clone(&obs);
        std::thread::spawn(move || {
            let end = LiveEnd::for_scenario(&s, None);
            assert_eq!(end, LiveEnd::EventsDone, "the file has no duration");
            let o = run_timeline(&s, &cfg, &snapshot, (&link, &obs), &stop, end);
            stop.store(true, Ordering::Relaxed);
            o
        })
    };
    let loop_thread = {
        let (link, stop) = (link.clone(), stop.clone());
        std::thread::spawn(move || {
            let mut injector = LoopInjector::new(0x7F);
            rt.boot();
            let cfg = Lockstep {
                // From 0x1006, which the master writes.
                sync_period_us: None,
                free_run_after_us: Some(200_000),
            };
            rt.run_lockstep_with(cfg, &stop, |rt| {
                observer.publish(rt);
                injector.on_tick(&link, rt)
            });
            rt
        })
    };
    // The controller: the reference master on its own virtual clock, one SYNC period per
    // round, waiting a little for the drive's answers.
    let mut master = Master::new(
        MasterConfig::default(),
        vec![
            Step::Enable { mode: MODE_CSP },
            Step::Cruise {
                velocity_uu_s: 10_000.0,
                accel_uu_s2: 100_000.0,
                duration_s: 600.0,
            },
        ],
    );
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    let mut t_us = 0;
    while !stop.load(Ordering::Relaxed) {
        assert!(
            std::time::Instant::now() < deadline,
            "the live run did not end after SYNC stopped reaching the drive"
        );
        master.poll(t_us);
        while let Some(f) = master.pop_tx() {
            master_bus.send(&f).unwrap();
        }
        std::thread::sleep(std::time::Duration::from_micros(300));
        while let Ok(Some(f)) = master_bus.recv() {
            master.handle(&f, t_us);
        }
        t_us += 1000;
    }
    let outcome = scenario_thread.join().unwrap();
    let rt = loop_thread.join().unwrap();
    for e in &outcome.expectations {
        eprintln!("{e}");
    }
    eprintln!("{} | {:?}", outcome.end_reason, outcome.fired);
    assert_eq!(rt.lockstep_period_us, 1000, "SYNC period from 0x1006");
    assert!(
        rt.lockstep_free_ticks > 0,
        "the drive's clock ran without SYNC"
    );
    assert_eq!(outcome.fired.len(), 1, "{:?}", outcome.fired);
    assert!(
        outcome.fired[0].1.contains("SYNC lost"),
        "{:?}",
        outcome.fired
    );
    assert!(outcome.not_fired.is_empty());
    let (t_event, _) = outcome.fired[0];
    let sync_loss = outcome
        .record
        .emcys
        .iter()
        .find(|(_, c)| *c == 0x8100)
        .unwrap_or_else(|| panic!("no EMCY 0x8100: {:?}", outcome.record.emcys));
    // Supervision fires 1.5 SYNC periods after the last SYNC the drive saw, which came
    // before the event was applied: a few ms at most.
    assert!(
        sync_loss.0 > t_event && sync_loss.0 <= t_event + 5_000,
        "EMCY 0x8100 at {} us, event applied at {t_event} us",
        sync_loss.0
    );
    assert!(outcome.passed(), "{:?}", outcome.expectations);
    // The run ended about the settle time (1 s) after the event, not much later.
    assert!(
        outcome.record.end_us >= t_event + 1_000_000 && outcome.record.end_us < t_event + 1_500_000,
        "ended at {} us, event at {t_event} us",
        outcome.record.end_us
    );
}

/// A live run that ends (here at `--duration`'s 1 s) before every event of the timeline has
/// fired did not run the scenario: it fails and says which events had not fired, even when
/// every expectation it could check held (as `drive-emu scenario` fails a program that does
/// not finish).
#[test]
fn a_live_run_that_ends_before_its_timeline_finishes_fails_and_says_so() {
    let text = r#"
name = "unfinished"
[machine]
preset = "cnc1"
[[motion]]
step = "enable"
mode = "csp"
[[event]]
at = "0.2 s"
set = "backlash_mm"
value = 0.03
[[event]]
at = "5 s"
sensor = "direct_encoder_loss"
[[expect]]
no_emcy = true
"#;
    let s = drive_emu::scenario::parse(text, std::path::Path::new("unfinished.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    let cfg = s.machine.configs[0].clone();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let snapshot = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node(&mut drive, 5).unwrap();
    let mut eps = InProcBus::endpoints(2, 4096);
    let _master_bus = eps.pop().unwrap();
    let bus = FaultyBus::new(eps.pop().unwrap(), 1);
    let mut rt = Runtime::new(bus, vec![AxisSlot { node, drive }], 1000);
    rt.boot();
    let link = Arc::new(LiveLink::new());
    // The observation bus the loop publishes into and the scenario thread reads.
    let (mut observer, obs) = drive_emu::observe::channel(1, 1 << 14);
    let stop = Arc::new(AtomicBool::new(false));
    let scenario_thread = {
        let (s, cfg, link, stop) = (s.clone(), cfg.clone(), link.clone(), stop.clone());
        let obs = Arc::clone(&obs);
        std::thread::spawn(move || {
            // --duration 1
            let end = LiveEnd::for_scenario(&s, Some(1_000_000));
            let o = run_timeline(&s, &cfg, &snapshot, (&link, &obs), &stop, end);
            stop.store(true, Ordering::Relaxed);
            o
        })
    };
    let mut injector = LoopInjector::new(0x7F);
    let mut clock = MonotonicClock::new();
    let mut deadline = clock.now_us();
    while !stop.load(Ordering::Relaxed) && rt.sim_time_us < 600_000_000 {
        clock.sleep_until(deadline);
        deadline += 1000;
        rt.tick();
        observer.publish(&mut rt);
        injector.on_tick(&link, &mut rt);
    }
    let o = scenario_thread.join().unwrap();
    assert!(
        o.expectations.iter().all(|e| e.passed),
        "{:?}",
        o.expectations
    );
    assert_eq!(o.fired.len(), 1, "{:?}", o.fired);
    assert_eq!(o.not_fired.len(), 1, "{:?}", o.not_fired);
    assert!(!o.passed(), "an unfinished timeline passed");
    let why = o.unfinished().expect("says why");
    assert!(
        why.contains("did not finish")
            && why.contains("line 12")
            && why.contains("1 event had not fired"),
        "{why}"
    );
}
