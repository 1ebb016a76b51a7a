//! `run --detect` (issue 19, item 4): the detector on the drive's own samples while it runs,
//! off the loop thread, its result in the drive's objects (0x2102) and an EMCY warning 0xFF01
//! when backlash is confirmed; and what it says of a run is what `analyze` says of the same
//! run's trace. Offline (lock-step, the reference master on the in-process bus), the same loop
//! hook `run` uses: publish on the observation bus, then apply the detector's results.

use drive_emu::analysis::detector::{analyze, AxisTrace, DetectorConfig, Verdict};
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::drive::objects::{DETECTOR_OFFSET, EMCY_BACKLASH};
use drive_emu::master::{Master, MasterConfig, Step, MODE_CSP};
use drive_emu::monitor::{verdict_code, AxisFacts, DetectOptions, DetectResults, Detector};
use drive_emu::observe::{ring::Cursor, Observation, Observer};
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::AxisSlot;
use drive_emu::samples::{Sample, SampleSource};
use drive_emu::session::OfflineRun;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The loop's side: the bus's writer, the detector's results to apply, and (as `--trace`
/// would) every tick the bus carried, read through a cursor of the test's own.
struct Hook {
    observer: Observer,
    obs: Arc<Observation>,
    results: Arc<DetectResults>,
    cursor: Cursor,
    trace: Vec<Sample>,
}

fn run(backlash_mm: f64) -> (OfflineRun<AxisDrive>, Hook, Detector) {
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("backlash_mm", &backlash_mm.to_string())
        .unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node::node(&mut drive, 5).unwrap();
    let program = vec![
        Step::Enable { mode: MODE_CSP },
        Step::Cruise {
            velocity_uu_s: 10_000.0,
            accel_uu_s2: 1_000_000.0,
            duration_s: 60.0,
        },
    ];
    let run = OfflineRun::new(
        vec![AxisSlot { node, drive }],
        1000,
        Master::new(MasterConfig::default(), program),
    );
    let (observer, obs) = drive_emu::observe::channel(1, 1 << 16);
    let results = Arc::new(DetectResults::new(1));
    let detector = Detector::start(
        Arc::clone(&obs),
        Arc::clone(&results),
        vec![AxisFacts {
            rotary: false,
            kv_per_s: cfg.kv_per_s,
            gap: drive_emu::analysis::gap::GapModel::for_axis(
                &cfg,
                drive_emu::analysis::gap::CurrentUnit::Permille,
            ),
        }],
        DetectOptions {
            history_s: 60.0,
            interval_s: 2.0,
        },
    )
    .unwrap();
    let cursor = Cursor::at_end(&obs.rings[0]);
    let hook = Hook {
        observer,
        obs,
        results,
        cursor,
        trace: Vec::new(),
    };
    (run, hook, detector)
}

fn tick(run: &mut OfflineRun<AxisDrive>, h: &mut Hook) {
    run.master_send();
    run.runtime.tick();
    h.observer.publish(&mut run.runtime);
    h.results.apply(&mut run.runtime);
    while let Some(s) = h.obs.next(0, &mut h.cursor) {
        h.trace.push(s.sample);
    }
    run.master_receive();
}

#[test]
fn a_worn_drive_says_backlash_in_its_objects_and_an_emcy_and_agrees_with_analyze() {
    let (mut run, mut h, detector) = run(0.05);
    // 6 s of drive time: boot, enable, cruise.
    while run.now_us() < 6_000_000 {
        tick(&mut run, &mut h);
    }
    // The detector thread analyses as the samples come; the loop publishes what it says.
    let t0 = Instant::now();
    while h.results.published(0) != verdict_code(Verdict::Backlash) {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "no backlash published (last {})",
            h.results.published(0)
        );
        std::thread::sleep(Duration::from_millis(20));
        for _ in 0..20 {
            tick(&mut run, &mut h);
        }
    }
    // A few more ticks for the EMCY to go out and reach the master.
    for _ in 0..20 {
        tick(&mut run, &mut h);
    }
    let node = &run.runtime.axes[0].node;
    let base = run.runtime.axes[0].drive.objects.unwrap().base;
    let obj = |sub: u8| node.object_raw(base + DETECTOR_OFFSET, sub).unwrap();
    assert_eq!(obj(1), u32::from(verdict_code(Verdict::Backlash)));
    let f_obj = f32::from_bits(obj(2));
    let a_obj = f32::from_bits(obj(3));
    assert!((7.5..=30.0).contains(&f_obj), "frequency object {f_obj} Hz");
    assert!(a_obj >= 3.0, "amplitude object {a_obj} um");
    assert_eq!(f32::from_bits(obj(4)), 30.0);
    assert!(obj(5) >= 1);
    assert!(node.error_active(EMCY_BACKLASH));
    // The master saw the warning, the drive stayed in OPERATION ENABLED.
    let e = run
        .master
        .emcys()
        .iter()
        .find(|e| e.code == EMCY_BACKLASH)
        .expect("EMCY 0xFF01 on the bus");
    assert_eq!(e.error_register & 0x80, 0x80, "manufacturer-specific bit");
    assert_eq!(node.statusword() & 0x6F, 0x27, "still operation enabled");
    // Stop: the last analysis of the whole run against `analyze` of the run's trace.
    let (reports, lost) = detector.finish().unwrap();
    let live = reports[0].as_ref().unwrap();
    let samples = std::mem::take(&mut h.trace);
    let offline = analyze(
        &AxisTrace::from_sample_log(&samples, SampleSource::Drive, false),
        &DetectorConfig::new(30.0),
    );
    eprintln!(
        "live: {} {:?} Hz {:.2} um; offline: {} {:?} Hz {:.2} um; {} samples",
        live.verdict.as_str(),
        live.frequency_hz,
        live.amplitude,
        offline.verdict.as_str(),
        offline.frequency_hz,
        offline.amplitude,
        samples.len()
    );
    assert_eq!(lost, 0, "the detector thread read every tick");
    assert_eq!(h.cursor.lost, 0);
    assert_eq!(live.verdict, offline.verdict);
    assert_eq!(live.frequency_hz, offline.frequency_hz);
    assert_eq!(live.amplitude, offline.amplitude);
    // Issue 31: the gap in mm from the limit cycle, within 30 %.
    let gap = live.backlash_estimate.value().expect("a gap estimate");
    let [lo, hi] = live.backlash_estimate.range().unwrap();
    assert!((gap - 0.05).abs() <= 0.3 * 0.05, "gap {gap} mm");
    assert!(lo <= 0.05 && 0.05 <= hi, "range {lo}..{hi} mm");
    let json = serde_json::to_value(live).unwrap();
    assert_eq!(json["backlash_estimate_mm"].as_f64(), Some(gap));
    // 0x6064 follows the direct encoder (cnc1 closes its loop on it): one encoder in the
    // samples, the estimate from the amplitude.
    assert_eq!(json["backlash_estimate_method"], "amplitude");
}

#[test]
fn a_healthy_drive_stays_ok_without_an_emcy() {
    let (mut run, mut h, detector) = run(0.0);
    while run.now_us() < 6_000_000 {
        tick(&mut run, &mut h);
    }
    let t0 = Instant::now();
    while h.results.published(0) == 0 {
        assert!(t0.elapsed() < Duration::from_secs(60), "nothing published");
        std::thread::sleep(Duration::from_millis(20));
        for _ in 0..20 {
            tick(&mut run, &mut h);
        }
    }
    assert_eq!(h.results.published(0), verdict_code(Verdict::Ok));
    assert!(!run.runtime.axes[0].node.error_active(EMCY_BACKLASH));
    assert!(run.master.emcys().iter().all(|e| e.code != EMCY_BACKLASH));
    let (live, _) = detector.finish().unwrap();
    let live = live[0].as_ref().unwrap();
    assert_eq!(live.verdict, Verdict::Ok);
    // No gap on a healthy axis: null in the JSON.
    assert_eq!(live.backlash_estimate.value(), None);
    let json = serde_json::to_value(live).unwrap();
    assert!(json["backlash_estimate_mm"].is_null() && json["backlash_estimate_range_mm"].is_null());
}
