//! The typed live run (`drive_emu::api::LiveRequest`, what `drive-emu run` does on CAN): a
//! request on an in-process bus, started, driven by the reference master on the other end of
//! the bus, ended by its scenario or by `stop()`; the outcome's fields are checked against what
//! happened. A request the command line would refuse is refused with its flag named and the
//! error's kind.

use drive_emu::api::live::{LiveBusSpec, LiveRequest};
use drive_emu::api::ApiError;
use drive_emu::bus::inproc::{InProcBus, InProcEndpoint};
use drive_emu::bus::CanBus;
use drive_emu::master::{Master, MasterConfig, Step, MODE_CSP};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Half a second of simulated time: the wear event at 0.2 s, the master enables the drive.
const SCENARIO: &str = r#"
name = "api-live"
duration = "0.5 s"
[machine]
preset = "cnc1"
[[event]]
id = "wear"
at = "0.2 s"
set = "backlash_mm"
value = 0.05
[[expect]]
state = "operation_enabled"
[[expect]]
no_emcy = true
"#;

/// A request on an in-process bus, cheap to run on a busy machine: no boot delay, normal
/// scheduling, no locked memory. Returns the request and the master's end of the bus.
fn request() -> (LiveRequest, InProcEndpoint) {
    let mut ends = InProcBus::endpoints(2, 4096);
    let master_end = ends.pop().unwrap();
    let req = LiveRequest {
        bus: LiveBusSpec::InProcess(ends.pop().unwrap()),
        boot_delay_ms: 0,
        rt_priority: 0,
        lock_memory: false,
        ..LiveRequest::default()
    };
    (req, master_end)
}

/// A temporary directory of this test, removed on drop.
struct TempDir(std::path::PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let p = std::env::temp_dir().join(format!("api-live-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn a_live_request_runs_its_scenario_with_a_master_on_the_bus_and_reports_what_happened() {
    let s = drive_emu::scenario::parse(SCENARIO, std::path::Path::new("api-live.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    let dir = TempDir::new("scenario");
    let trace = dir.0.join("trace.csv");
    let (req, mut bus) = request();
    let run = LiveRequest {
        scenario: Some(s),
        trace: Some(trace.clone()),
        ..req
    }
    .start()
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(run.bus_label(), "in-process");
    assert_eq!(run.machine().axes[0].node_id, 5, "--node's default");
    // The reference master on the other end: enable in CSP, then hold; it follows the drive's
    // simulated time as the observation bus has it. The test thread is paced by a busy
    // machine, not by a real-time loop: the drive's SYNC and heartbeat supervision are turned
    // off first (0x1006 = 0, 0x1016:1 = 0), so that a late SYNC from this thread is not a
    // fault of the drive's.
    let mut master = Master::new(
        MasterConfig {
            sync_period_us: 10_000,
            heartbeat_ms: 200,
            ..MasterConfig::default()
        },
        vec![
            Step::WriteSdo {
                index: 0x1006,
                sub: 0,
                value: 0,
                len: 4,
            },
            Step::WriteSdo {
                index: 0x1016,
                sub: 1,
                value: 0,
                len: 4,
            },
            Step::Enable { mode: MODE_CSP },
            Step::Dwell { duration_s: 60.0 },
        ],
    );
    let obs = run.observation().clone();
    let give_up = Instant::now() + Duration::from_secs(120);
    while !run.is_finished() && Instant::now() < give_up {
        let now_us = obs.board.sim_time_us.load(Ordering::Acquire);
        master.poll(now_us);
        while let Some(f) = master.pop_tx() {
            bus.send(&f).unwrap();
        }
        while let Ok(Some(f)) = bus.recv() {
            master.handle(&f, now_us);
        }
        // pacing only: the master answers within a tick or two of the drive's 1 ms
        std::thread::sleep(Duration::from_micros(300));
    }
    assert!(run.is_finished(), "the scenario's end stops the run");
    let out = run.wait().unwrap_or_else(|e| panic!("{e}"));
    let o = out.scenario.as_ref().expect("a scenario outcome");
    for e in &o.expectations {
        eprintln!("{e}");
    }
    assert!(o.unfinished().is_none(), "{:?}", o.unfinished());
    assert!(o.passed(), "{:?}", o.expectations);
    assert_eq!(o.expectations.len(), 2);
    // The event fired at its time on the drive's clock, and the run ended at the file's end.
    assert_eq!(o.fired.len(), 1, "{:?}", o.fired);
    assert!((200_000..300_000).contains(&o.fired[0].0), "{:?}", o.fired);
    assert!(o.record.end_us >= 500_000, "{}", o.record.end_us);
    // Samples: the scenario's and the trace's come from the loop's ticks.
    let samples = o.record.samples.len() as u64;
    assert!(samples >= 400, "{samples} samples for 0.5 s at 1 kHz");
    assert!(samples + o.samples_lost <= out.stats.ticks + 1);
    assert!(out.stats.ticks >= 500, "{:?}", out.stats);
    let t = out.trace.as_ref().expect("--trace");
    assert_eq!(t.paths, std::slice::from_ref(&trace));
    assert!(t.samples > 0 && t.samples + t.lost <= out.stats.ticks + 1);
    let rows = std::fs::read_to_string(&trace).unwrap().lines().count() as u64;
    assert!(
        rows > t.samples,
        "{rows} rows in the file, {} samples",
        t.samples
    );
    assert!(out.detector.is_empty(), "no --detect");
    assert_eq!(out.lockstep_period_us, None);
    assert!(
        master.emcys().is_empty(),
        "the master saw no EMCY: {:?}",
        master.emcys()
    );
}

#[test]
fn a_run_without_an_end_stops_when_asked_and_its_detector_reports_per_axis() {
    let (req, _bus) = request();
    let run = LiveRequest {
        node_id: 12,
        detect: true,
        ..req
    }
    .start()
    .unwrap_or_else(|e| panic!("{e}"));
    let obs = run.observation().clone();
    let give_up = Instant::now() + Duration::from_secs(120);
    while obs.board.ticks.load(Ordering::Acquire) < 50 && Instant::now() < give_up {
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(run.booted());
    assert!(
        !run.is_finished(),
        "no duration, no scenario: it runs until stopped"
    );
    run.stop();
    let out = run.wait().unwrap_or_else(|e| panic!("{e}"));
    assert!(out.stats.ticks >= 50, "{:?}", out.stats);
    assert!(out.scenario.is_none() && out.trace.is_none());
    assert_eq!(out.detector.len(), 1);
    assert_eq!(out.detector[0].0, 12, "the detector's axis is node 12");
}

#[test]
fn a_request_the_command_line_would_refuse_is_refused_with_its_flag_and_kind() {
    let invalid = |req: LiveRequest, flag: &str| {
        let e = req
            .start()
            .err()
            .unwrap_or_else(|| panic!("{flag}: started"));
        assert!(matches!(e, ApiError::Invalid(_)), "{flag}: {e:?}");
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().starts_with(flag), "{flag}: {e}");
    };
    let (r, _b) = request();
    invalid(LiveRequest { node_id: 0, ..r }, "--node 0:");
    let (r, _b) = request();
    invalid(
        LiveRequest {
            duration_s: Some(-1.0),
            ..r
        },
        "--duration -1:",
    );
    let (r, _b) = request();
    invalid(
        LiveRequest {
            sync_period_us: Some(50),
            ..r
        },
        "--sync-period-us 50:",
    );
    let (r, _b) = request();
    invalid(
        LiveRequest {
            lockstep: true,
            sync_period_us: Some(1500),
            ..r
        },
        "--sync-period-us 1500:",
    );
    let (r, _b) = request();
    invalid(
        LiveRequest {
            detect_history_s: 0.0,
            ..r
        },
        "--detect-history 0:",
    );
    let (r, _b) = request();
    invalid(
        LiveRequest {
            sets: vec!["backlash_mm".into()],
            ..r
        },
        "--set backlash_mm:",
    );
    // A machine file that is not there: unreadable (exit 4), the file's error kept.
    let (r, _b) = request();
    let e = LiveRequest {
        machine_file: Some("/nonexistent/drive-emu-api-live.toml".into()),
        ..r
    }
    .start()
    .err()
    .expect("a missing --config");
    assert!(matches!(e, ApiError::Unreadable(_)), "{e:?}");
    assert_eq!(e.exit_code(), 4);
    assert!(e.input_error().is_some(), "{e:?}");
}
