//! Proof that the real-time path does not allocate: a counting global allocator watches
//! `Runtime::tick` (receive -> node -> drive -> physics -> send), the statistics recording,
//! their publication to the node and the loop's hook (publish on the observation bus, apply
//! the injections: the detector's results, the panel's), with every reader of the bus on
//! (trace recorder, detector thread, status line, panel), while the drive runs CSP at constant
//! speed with backlash, answers SDO requests and consumes the master's heartbeat.

use drive_emu::analysis::detector::Verdict;
use drive_emu::bus::CanFrame;
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::drive::AxisParam;
use drive_emu::master::{Master, MasterConfig, Step, MODE_CSP};
use drive_emu::monitor::{verdict_code, DetectResult, DetectResults};
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::{AxisSlot, SimulatedDrive};
use drive_emu::session::OfflineRun;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::{Read, Write};

struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // try_with: the thread-locals may be gone while a thread shuts down.
        if COUNTING.try_with(Cell::get).unwrap_or(false) {
            let _ = ALLOCS.try_with(|a| a.set(a.get() + 1));
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.try_with(Cell::get).unwrap_or(false) {
            let _ = ALLOCS.try_with(|a| a.set(a.get() + 1));
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn counted<R>(f: impl FnOnce() -> R) -> R {
    COUNTING.with(|c| c.set(true));
    let r = f();
    COUNTING.with(|c| c.set(false));
    r
}

#[test]
fn the_counter_sees_an_allocation() {
    ALLOCS.with(|a| a.set(0));
    let v = counted(|| std::hint::black_box(vec![1u8; 16]));
    assert_eq!(ALLOCS.with(Cell::get), 1);
    drop(v);
}

#[test]
fn the_runtime_tick_does_not_allocate() {
    runtime_tick_allocations(None, "cnc1", 0.0);
}

/// The same on a twin pinion (two motors, two contacts, the preload split), its preload
/// written over SDO (0x200E) while it runs.
#[test]
fn the_runtime_tick_of_a_twin_pinion_does_not_allocate() {
    runtime_tick_allocations(None, "cnc4", 20.0);
}

/// The same with a vendor profile and more switches on (docs/quirks.md): the switches' hooks
/// on the tick (controlword hold, SDO delay queue, SYNC watchdog and lateness, the PDO rules)
/// allocate nothing either.
#[test]
fn the_runtime_tick_with_vendor_switches_on_does_not_allocate() {
    use drive_emu::drive::quirk_profile::{Overlay, QuirkProfile};
    let switches: Vec<String> = [
        "enable_requires_mode",
        "sdo_response_delay.delay_ms=1",
        "sdo_response_delay.late_every=3",
        "sdo_response_delay.late_delay_ms=2",
        // not tpdo_rtr_unsupported: the reference master writes TPDO COB-IDs without bit 30
        // and trips over it, as python canopen did before its PR 228
        "late_sync_statusword_bit15",
        "sync_watchdog.missed_periods=100",
        "sync_watchdog.period_from=\"0x1006\"",
        "homing_method_zero.zero=\"ignore\"",
        "unmappable_objects.objects=[\"0x6063:0\"]",
        "sdo_silent_objects.objects=[\"0x1800-0x1803:6\"]",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let overlay = Overlay::from_args(&switches, &[]).unwrap();
    let b = QuirkProfile::resolve(Some("technosoft-ipos"), None, &[&overlay]).unwrap();
    assert_eq!(b.quirks.on().count(), 8);
    runtime_tick_allocations(Some(b), "cnc1", 0.0);
}

/// `preload_pct`: 0 on a single-contact preset, else the twin pinion's preload at the start
/// (written again over SDO while the axis runs).
fn runtime_tick_allocations(
    quirk_profile: Option<drive_emu::drive::quirk_profile::QuirkProfile>,
    preset: &str,
    preload_pct: f64,
) {
    let cfg = AxisConfig::from_preset(preset)
        .unwrap()
        .with_override("backlash_mm", "0.05")
        .unwrap()
        .with_override("preload_pct", &format!("{preload_pct}"))
        .unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let opts = drive_emu::drive::NodeOptions {
        quirk_profile: quirk_profile.map(std::sync::Arc::new),
        ..drive_emu::drive::NodeOptions::new(5)
    };
    let node = drive_emu::drive::build_node(&mut drive, &opts).unwrap();
    let program = vec![
        Step::Enable { mode: MODE_CSP },
        Step::Cruise {
            velocity_uu_s: 10_000.0,
            accel_uu_s2: 100_000.0,
            duration_s: 30.0,
        },
    ];
    let mut run = OfflineRun::new(
        vec![AxisSlot { node, drive }],
        1000,
        Master::new(MasterConfig::default(), program),
    );
    // Warm up: boot, PDO mapping, enable, reach constant speed.
    while run.now_us() < 2_000_000 {
        run.step();
    }
    assert_eq!(
        run.runtime.axes[0].node.statusword() & 0x6F,
        0x27,
        "operation enabled ({:?})",
        run.master.error()
    );
    let sdo_read = CanFrame::new(0x605, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]);
    let sdo_write_backlash = CanFrame::new(0x605, &[0x23, 0x00, 0x20, 0, 0, 0, 0, 0]);
    let sdo_write_preload = CanFrame::new(0x605, &[0x23, 0x0E, 0x20, 0, 0, 0, 0, 0]);
    // The loop publishes every tick on the observation bus (`run --trace` and `--detect`
    // read it on their own threads) ...
    let (mut observer, obs) = drive_emu::observe::channel(1, 1 << 14);
    // ... and applies the detector's results to the drive's objects and as an EMCY (the
    // detector thread's side played here: a result offered now and then, backlash, then ok,
    // then backlash again).
    let detect = DetectResults::new(1);
    let result = |verdict: Verdict, analyses: u32| DetectResult {
        verdict: verdict_code(verdict),
        frequency_hz: 18.5,
        amplitude: 7.2,
        kv_per_s: 30.0,
        analyses,
    };
    ALLOCS.with(|a| a.set(0));
    for k in 0..5000u32 {
        run.master_send();
        if k % 100 == 0 {
            run.inject(&sdo_read);
        }
        match k {
            1000 => detect.offer(0, result(Verdict::Backlash, 1)),
            2000 => detect.offer(0, result(Verdict::Ok, 2)),
            3000 => detect.offer(0, result(Verdict::Backlash, 3)),
            _ => {}
        }
        if k % 1000 == 500 {
            // REAL32 0.06 mm of backlash: wear injected over SDO while the axis runs.
            let mut f = sdo_write_backlash;
            f.data[4..8].copy_from_slice(&0.06f32.to_le_bytes());
            run.inject(&f);
        }
        if k % 1000 == 700 && preload_pct > 0.0 {
            {
                let mut f = sdo_write_preload;
                let pct = preload_pct - (k / 1000) as f64;
                f.data[4..8].copy_from_slice(&(pct as f32).to_le_bytes());
                run.inject(&f);
            }
        }
        counted(|| {
            run.runtime.tick();
            run.runtime.stats.record_tick(3, 40);
            observer.publish(&mut run.runtime);
            detect.apply(&mut run.runtime);
            if k % 256 == 0 {
                run.runtime.publish_stats();
            }
        });
        run.master_receive();
    }
    let allocs = ALLOCS.with(Cell::get);
    assert!(run.master.error().is_none(), "{:?}", run.master.error());
    // The detector's path ran: published, warned twice (raised, cleared, raised).
    assert_eq!(detect.published(0), verdict_code(Verdict::Backlash));
    let warnings = run
        .master
        .emcys()
        .iter()
        .filter(|e| e.code == drive_emu::drive::objects::EMCY_BACKLASH)
        .count();
    assert_eq!(warnings, 2, "{:?}", run.master.emcys());
    assert_eq!(
        run.runtime.axes[0].node.statusword() & 0x6F,
        0x27,
        "still enabled"
    );
    let backlash = run.runtime.axes[0].drive.param(AxisParam::Backlash);
    assert!(
        (backlash - 0.06e-3).abs() < 1e-9,
        "the SDO write reached the axis: {backlash}"
    );
    if preload_pct > 0.0 {
        let preload = run.runtime.axes[0].drive.param(AxisParam::Preload);
        assert!(
            (preload - (preload_pct - 4.0) / 100.0).abs() < 1e-6,
            "the SDO write reached the twin pinion: {preload}"
        );
    }
    assert_eq!(
        obs.board.ticks.load(std::sync::atomic::Ordering::Relaxed),
        5000
    );
    assert_eq!(
        allocs, 0,
        "{allocs} allocations in 5000 ticks of the real-time path"
    );
}

/// The event-driven real-time path: `Runtime::realtime_wake` (wait, receive, ticks due before
/// each frame, on-arrival handling and send, the SYNC phase lock placing the next deadline) on
/// a virtual clock, with the master's SYNC and set-points every millisecond and SDO traffic.
#[test]
fn the_realtime_wake_does_not_allocate() {
    use drive_emu::runtime::pll::LockState;
    use drive_emu::runtime::RealtimeLoop;
    use drive_emu::time::{Clock, VirtualClock};
    let cfg = AxisConfig::from_preset("cnc1").unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node(&mut drive, 5).unwrap();
    let program = vec![
        Step::Enable { mode: MODE_CSP },
        Step::Cruise {
            velocity_uu_s: 10_000.0,
            accel_uu_s2: 100_000.0,
            duration_s: 30.0,
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
    let mut clock = VirtualClock::new();
    clock.advance_to(run.now_us());
    let mut state = RealtimeLoop::new(clock.now_us(), 1000);
    let mut hook = |_: &mut _| {};
    let sdo_read = CanFrame::new(0x605, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]);
    let ticks_before = run.runtime.stats.ticks;
    ALLOCS.with(|a| a.set(0));
    for k in 0..5000u32 {
        // The master's SYNC (and set-point) goes out at its own millisecond, between the
        // drive's ticks: the wake handles it on arrival.
        run.master_send();
        if k % 100 == 0 {
            run.inject(&sdo_read);
        }
        counted(|| run.runtime.realtime_wake(&mut state, &mut clock, &mut hook));
        run.master_receive();
    }
    let allocs = ALLOCS.with(Cell::get);
    assert!(run.master.error().is_none(), "{:?}", run.master.error());
    assert_eq!(run.runtime.axes[0].node.statusword() & 0x6F, 0x27);
    let ticks = run.runtime.stats.ticks - ticks_before;
    assert!(
        (4000..=6000).contains(&ticks),
        "{ticks} ticks in 5000 wakes"
    );
    assert_ne!(
        state.pll.state(),
        LockState::FreeRunning,
        "SYNCs reached the lock"
    );
    assert_eq!(allocs, 0, "{allocs} allocations in 5000 real-time wakes");
}

#[test]
fn supervision_trip_fault_reset_and_reset_node_do_not_allocate() {
    // A runaway (10 kN on an axis nobody holds) trips overspeed supervision; the master
    // resets the fault, then resets the node: all on the real-time path, none allocating.
    let mut drive = AxisDrive::from_config(&AxisConfig::from_preset("cnc1").unwrap()).unwrap();
    let mut slot = AxisSlot {
        node: drive_emu::drive::node(&mut drive, 5).unwrap(),
        drive,
    };
    slot.node.boot(0);
    let mut load = CanFrame::new(0x605, &[0x23, 0x06, 0x20, 0, 0, 0, 0, 0]);
    load.data[4..8].copy_from_slice(&1e4f32.to_le_bytes());
    let fault_reset = CanFrame::new(0x605, &[0x2B, 0x40, 0x60, 0, 0x80, 0, 0, 0]);
    let reset_node = CanFrame::new(0x000, &[0x81, 5]);
    let mut now = 0u64;
    let mut emcy = Vec::with_capacity(64);
    ALLOCS.with(|a| a.set(0));
    for k in 0..6000u32 {
        counted(|| {
            let f = match k {
                10 => Some(&load),
                3000 => Some(&fault_reset),
                4000 => Some(&reset_node),
                _ => None,
            };
            if let Some(f) = f {
                slot.node.handle(f, now, &mut slot.drive);
            }
            slot.node.poll(now, &mut slot.drive);
            slot.drive.advance(1000);
            now += 1000;
        });
        while let Some(f) = slot.node.pop_tx() {
            if f.id == 0x85 {
                emcy.push(u16::from_le_bytes([f.data[0], f.data[1]]));
            }
        }
    }
    let allocs = ALLOCS.with(Cell::get);
    assert_eq!(emcy.first(), Some(&0x8400), "overspeed EMCY: {emcy:x?}");
    assert_eq!(
        slot.drive.supervision_fault(),
        None,
        "cleared by the resets"
    );
    assert_eq!(allocs, 0, "{allocs} allocations on the supervision paths");
}

#[test]
fn i2t_heating_trip_and_cooling_do_not_allocate() {
    // The axis enabled in PP holds its position against a load that needs twice its rated
    // current: the I2t monitor heats every position cycle and trips (EMCY 0x2310), then the
    // motor cools while the drive is in FAULT. A short thermal time constant (2 s) keeps it
    // short; the path is the same.
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("motor_thermal_time_constant_s", "2")
        .unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let force = drive.peak_load_force() * 2.0 * cfg.rated_current_a / cfg.max_current_a;
    let mut slot = AxisSlot {
        node: drive_emu::drive::node(&mut drive, 5).unwrap(),
        drive,
    };
    slot.node.boot(0);
    let start = CanFrame::new(0x000, &[0x01, 5]);
    let mode_pp = CanFrame::new(0x605, &[0x2F, 0x60, 0x60, 0, 1, 0, 0, 0]);
    let cw = |v: u8| CanFrame::new(0x605, &[0x2B, 0x40, 0x60, 0, v, 0, 0, 0]);
    let (shutdown, switch_on, enable) = (cw(0x06), cw(0x07), cw(0x0F));
    let mut load = CanFrame::new(0x605, &[0x23, 0x06, 0x20, 0, 0, 0, 0, 0]);
    load.data[4..8].copy_from_slice(&(force as f32).to_le_bytes());
    let mut now = 0u64;
    let mut emcy = Vec::with_capacity(64);
    let mut peak_heat = 0.0f64;
    ALLOCS.with(|a| a.set(0));
    for k in 0..4000u32 {
        counted(|| {
            let f = match k {
                300 => Some(&start),
                301 => Some(&mode_pp),
                302 => Some(&shutdown),
                303 => Some(&switch_on),
                304 => Some(&enable),
                310 => Some(&load),
                _ => None,
            };
            if let Some(f) = f {
                slot.node.handle(f, now, &mut slot.drive);
            }
            slot.node.poll(now, &mut slot.drive);
            slot.drive.advance(1000);
            now += 1000;
        });
        peak_heat = peak_heat.max(slot.drive.motor_thermal_load());
        while let Some(f) = slot.node.pop_tx() {
            if f.id == 0x85 {
                emcy.push(u16::from_le_bytes([f.data[0], f.data[1]]));
            }
        }
    }
    let allocs = ALLOCS.with(Cell::get);
    assert_eq!(emcy.first(), Some(&0x2310), "I2t EMCY: {emcy:x?}");
    assert_eq!(slot.node.statusword() & 0x4F, 0x08, "FAULT");
    assert!(
        slot.drive.motor_thermal_load() < peak_heat * 0.9,
        "cooling in FAULT: {} after a peak of {peak_heat}",
        slot.drive.motor_thermal_load()
    );
    assert_eq!(allocs, 0, "{allocs} allocations on the I2t paths");
}

/// `run --panel` with 5 stream clients reading: the loop's half of the panel (publishing the
/// snapshot into the fan-out, applying the panel's injections) does not allocate either, while
/// the panel's threads build and send messages beside it (they allocate on their own threads,
/// which the counter does not count). An injection posted over HTTP during the counted ticks
/// reaches the drive there.
#[test]
fn the_tick_with_the_panel_open_and_five_clients_does_not_allocate() {
    use drive_emu::bus::fault::FaultyBus;
    use drive_emu::panel::{self, PanelAxis, PanelSetup};
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("backlash_mm", "0.05")
        .unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node(&mut drive, 5).unwrap();
    let program = vec![
        Step::Enable { mode: MODE_CSP },
        Step::Cruise {
            velocity_uu_s: 10_000.0,
            accel_uu_s2: 100_000.0,
            duration_s: 60.0,
        },
    ];
    let mut run = OfflineRun::with_drive_bus(
        vec![AxisSlot { node, drive }],
        1000,
        Master::new(MasterConfig::default(), program),
        |ep| FaultyBus::new(ep, 1),
    );
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let setup = PanelSetup {
        bus: drive_emu::panel::PanelBus::Can,
        axes: vec![PanelAxis {
            node_id: 5,
            preset: "cnc1".into(),
            config: cfg.clone(),
            overrides: vec![],
        }],
        iface: None,
        tick_hz: 1000,
        lockstep: false,
        master_id: 0x7F,
        json_stdout: false,
    };
    let dir = std::env::temp_dir().join(format!("drive-emu-alloc-panel-{}", std::process::id()));
    // The observation bus with every reader on: the panel, the trace recorder, the detector
    // thread (whose results the loop applies), and a status-line reader.
    let (mut observer, obs) = drive_emu::observe::channel(1, 1 << 14);
    let (panel, mut panel_loop) =
        panel::start_on(listener, None, dir.clone(), setup, obs.clone()).unwrap();
    let trace_path = dir.join("alloc-trace.csv");
    let recorder =
        drive_emu::observe::trace::Recorder::start(obs.clone(), vec![trace_path.clone()]).unwrap();
    let results = std::sync::Arc::new(DetectResults::new(1));
    let detector = drive_emu::monitor::Detector::start(
        obs.clone(),
        results.clone(),
        vec![drive_emu::monitor::AxisFacts {
            rotary: false,
            kv_per_s: cfg.kv_per_s,
            gap: None,
        }],
        drive_emu::monitor::DetectOptions {
            history_s: 2.0,
            interval_s: 0.5,
        },
    )
    .unwrap();
    let status_stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let status = {
        let (obs, stop) = (obs.clone(), status_stop.clone());
        std::thread::spawn(move || {
            let mut seen = 0u64;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                if let Some(s) = obs.latest(0) {
                    seen = seen.max(s.t_us);
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            seen
        })
    };
    while run.now_us() < 2_000_000 {
        run.step();
        observer.publish(&mut run.runtime);
        panel_loop.on_tick(&mut run.runtime);
        results.apply(&mut run.runtime);
    }
    // Five clients, each reading its stream in a thread of its own.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let clients: Vec<_> = (0..5)
        .map(|_| {
            let stop = std::sync::Arc::clone(&stop);
            let mut c = std::net::TcpStream::connect(addr).unwrap();
            write!(c, "GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n").unwrap();
            c.set_read_timeout(Some(std::time::Duration::from_millis(200)))
                .unwrap();
            std::thread::spawn(move || {
                let (mut text, mut buf) = (Vec::new(), [0u8; 8192]);
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    if let Ok(n) = c.read(&mut buf) {
                        text.extend_from_slice(&buf[..n]);
                    }
                }
                String::from_utf8_lossy(&text)
                    .matches("event: samples")
                    .count()
            })
        })
        .collect();
    let mut poster = None;
    ALLOCS.with(|a| a.set(0));
    for k in 0..5000u32 {
        if k == 1000 {
            // An injection from the page, while the loop runs.
            poster = Some(std::thread::spawn(move || {
                let body = r#"{"set": "backlash_mm", "value": 0.07}"#;
                let mut c = std::net::TcpStream::connect(addr).unwrap();
                write!(
                    c,
                    "POST /api/inject HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
                    body.len()
                )
                .unwrap();
                let mut answer = String::new();
                let _ = c.read_to_string(&mut answer);
                answer
            }));
        }
        run.master_send();
        counted(|| {
            run.runtime.tick();
            run.runtime.stats.record_tick(3, 40);
            observer.publish(&mut run.runtime);
            panel_loop.on_tick(&mut run.runtime);
            results.apply(&mut run.runtime);
            if k % 256 == 0 {
                run.runtime.publish_stats();
            }
        });
        run.master_receive();
        // About the wall clock's pace, so the panel reads while the loop runs.
        std::thread::sleep(std::time::Duration::from_micros(300));
    }
    let allocs = ALLOCS.with(Cell::get);
    let answer = poster.unwrap().join().unwrap();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let seen: Vec<usize> = clients.into_iter().map(|c| c.join().unwrap()).collect();
    status_stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let status_t_us = status.join().unwrap();
    let trace = recorder.finish().unwrap();
    let (reports, detector_lost) = detector.finish().unwrap();
    panel.stop();
    std::fs::remove_file(&trace_path).unwrap();
    std::fs::remove_dir(&dir).ok();
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    // Every reader read the bus while the loop ran: the trace has every tick, the detector
    // analysed, the status line saw the loop's time move.
    let ticks = obs.board.ticks.load(std::sync::atomic::Ordering::Relaxed);
    assert_eq!(trace.samples + trace.lost, ticks, "{trace:?}");
    assert!(reports[0].is_some() && detector_lost == 0);
    assert!(status_t_us > 2_000_000, "{status_t_us}");
    let backlash = run.runtime.axes[0].drive.param(AxisParam::Backlash);
    assert!(
        (backlash - 0.07e-3).abs() < 1e-9,
        "the panel's injection reached the axis: {backlash}"
    );
    assert!(
        seen.iter().all(|&n| n > 5),
        "every client received samples while the loop ran: {seen:?}"
    );
    assert_eq!(
        allocs, 0,
        "{allocs} allocations in 5000 ticks with the panel open and 5 clients"
    );
}

/// `run --ethercat --panel`: the panel's loop half after each EtherCAT drive cycle (every
/// slave published from its node beside its drive, the panel's injections applied to the first
/// slave and the port's faults) allocates nothing, with a stream client reading. A parameter
/// and an EtherCAT fault posted over HTTP during the counted cycles reach the drive and the
/// port there.
#[test]
fn the_ethercat_cycle_with_the_panel_open_does_not_allocate() {
    use drive_emu::bus::ethercat::EcatFaults;
    use drive_emu::panel::{self, PanelAxis, PanelBus, PanelSetup};
    use drive_protocol::Clocks;
    let cfg = AxisConfig::from_preset("cnc1").unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let node_cfg =
        drive_emu::drive::node_config(&mut drive, &drive_emu::drive::NodeOptions::new(1)).unwrap();
    let slave = drive_ethercat::Slave::new(node_cfg, &mut drive).unwrap();
    let mut seg = drive_ethercat::Segment::new(vec![slave]);
    let mut drives = vec![drive];
    let mut faults = EcatFaults::new(1);
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let setup = PanelSetup {
        bus: PanelBus::Ethercat,
        axes: vec![PanelAxis {
            node_id: 1,
            preset: "cnc1".into(),
            config: cfg.clone(),
            overrides: vec![],
        }],
        iface: None,
        tick_hz: 1000,
        lockstep: false,
        master_id: 0x7F,
        json_stdout: false,
    };
    let dir = std::env::temp_dir().join(format!("drive-emu-alloc-ecat-{}", std::process::id()));
    let (mut observer, obs) = drive_emu::observe::channel(1, 1 << 14);
    let (panel, mut panel_loop) = panel::start_on(listener, None, dir, setup, obs).unwrap();
    let mut t_us = 0u64;
    let mut cycle = |seg: &mut drive_ethercat::Segment,
                     drives: &mut Vec<AxisDrive>,
                     faults: &mut EcatFaults,
                     panel_loop: &mut panel::PanelLoop| {
        seg.cycle(
            Clocks {
                app_us: t_us,
                comm_us: t_us,
            },
            drives,
        );
        for d in drives.iter_mut() {
            d.advance(1000);
        }
        observer.publish_axes(
            t_us,
            seg.slaves
                .iter_mut()
                .map(|s| s.node_mut())
                .zip(drives.iter()),
        );
        panel_loop.on_ethercat_cycle(seg, drives, faults, t_us);
        t_us += 1000;
    };
    for _ in 0..500 {
        cycle(&mut seg, &mut drives, &mut faults, &mut panel_loop);
    }
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let client = {
        let stop = std::sync::Arc::clone(&stop);
        let mut c = std::net::TcpStream::connect(addr).unwrap();
        write!(c, "GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n").unwrap();
        c.set_read_timeout(Some(std::time::Duration::from_millis(200)))
            .unwrap();
        std::thread::spawn(move || {
            let (mut text, mut buf) = (Vec::new(), [0u8; 8192]);
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                if let Ok(n) = c.read(&mut buf) {
                    text.extend_from_slice(&buf[..n]);
                }
            }
            String::from_utf8_lossy(&text)
                .matches("event: samples")
                .count()
        })
    };
    let post = move |body: &'static str| {
        std::thread::spawn(move || {
            let mut c = std::net::TcpStream::connect(addr).unwrap();
            write!(
                c,
                "POST /api/inject HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
                body.len()
            )
            .unwrap();
            let mut answer = String::new();
            let _ = c.read_to_string(&mut answer);
            answer
        })
    };
    let mut posters = Vec::new();
    ALLOCS.with(|a| a.set(0));
    for k in 0..3000u32 {
        if k == 500 {
            posters.push(post(r#"{"set": "backlash_mm", "value": 0.07}"#));
            posters.push(post(r#"{"ethercat": "lost", "frames": 7}"#));
        }
        counted(|| cycle(&mut seg, &mut drives, &mut faults, &mut panel_loop));
        std::thread::sleep(std::time::Duration::from_micros(300));
    }
    let allocs = ALLOCS.with(Cell::get);
    let answers: Vec<String> = posters.into_iter().map(|p| p.join().unwrap()).collect();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let seen = client.join().unwrap();
    panel.stop();
    for a in &answers {
        assert!(a.starts_with("HTTP/1.1 200"), "{a}");
    }
    let backlash = drives[0].param(AxisParam::Backlash);
    assert!(
        (backlash - 0.07e-3).abs() < 1e-9,
        "the panel's injection reached the axis: {backlash}"
    );
    // The port's lost-frames fault: the next 7 frames are not admitted, the 8th is.
    let template =
        drive_ethercat::frame::build([2, 0, 0, 0, 0, 0], &[(4, 0x81, 0x1001_0130, &[0u8; 2])]);
    let admitted: Vec<bool> = (0..8).map(|_| faults.admit(&template, t_us)).collect();
    assert_eq!(
        admitted,
        [false, false, false, false, false, false, false, true]
    );
    assert!(
        seen > 5,
        "the client received samples while the loop ran: {seen}"
    );
    assert_eq!(
        allocs, 0,
        "{allocs} allocations in 3000 EtherCAT cycles with the panel open"
    );
}
