//! `drive-emu analyze` on a candump log: the reference master runs against the drive offline,
//! every frame on the in-process bus is written as `candump -L` would (virtual-clock timestamps
//! plus a few microseconds of deterministic jitter), and the decoded log must give what the
//! master itself received: the same samples, the same detector verdict, frequency and amplitude.

use drive_emu::analysis::candump::{self, DecodeOptions, DriveDefaults, PdoConfig, PeriodSource};
use drive_emu::analysis::detector::{analyze, AxisTrace, DetectorConfig, DetectorReport, Verdict};
use drive_emu::bus::inproc::InProcEndpoint;
use drive_emu::bus::{CanBus, CanFrame};
use drive_emu::cli::analyze::{run, AnalyzeArgs};
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::master::{Master, MasterConfig, Step, MODE_CSP, MODE_PP};
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::AxisSlot;
use drive_emu::samples::{Sample, SampleSource};
use drive_emu::session::OfflineRun;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::OnceLock;

const NODE: u8 = 5;
/// Epoch of the log's timestamps, s.
const EPOCH_S: u64 = 1_700_000_000;
const V_UU_S: f64 = 10_000.0;

/// Writes frames as `candump -L` lines.
#[derive(Default)]
struct CandumpWriter {
    text: String,
    frames: u64,
    last_us: u64,
}

impl CandumpWriter {
    /// One line at `t_us` plus jitter: frames of one burst follow each other a few us apart,
    /// each with 0..8 us of deterministic pseudo-random jitter; timestamps never go backwards.
    fn write(&mut self, f: &CanFrame, t_us: u64, burst: u64) {
        let jitter = (self.frames.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) % 9;
        let t = (t_us + 3 * burst + jitter).max(self.last_us + 1);
        self.last_us = t;
        self.frames += 1;
        let hex: String = f.payload().iter().map(|b| format!("{b:02X}")).collect();
        let _ = writeln!(
            self.text,
            "({}.{:06}) vcan0 {:03X}#{hex}",
            EPOCH_S + t / 1_000_000,
            t % 1_000_000,
            f.id
        );
    }

    fn drain(&mut self, monitor: &mut InProcEndpoint, now_us: u64) {
        let mut burst = 0;
        while let Ok(Some(f)) = monitor.recv() {
            self.write(&f, now_us, burst);
            burst += 1;
        }
    }
}

struct Logged {
    samples: Vec<Sample>,
    log: String,
    kv_per_s: f64,
}

/// The demo's program: enable, PP move, CSP cruise at constant speed, stop.
fn program(cruise_s: f64) -> Vec<Step> {
    vec![
        Step::Enable { mode: MODE_PP },
        Step::MoveTo {
            target_uu: 20_000,
            velocity_uu_s: (5.0 * V_UU_S) as u32,
            accel_uu_s2: (50.0 * V_UU_S) as u32,
        },
        Step::SetMode { mode: MODE_CSP },
        Step::Cruise {
            velocity_uu_s: V_UU_S,
            accel_uu_s2: 10.0 * V_UU_S,
            duration_s: cruise_s,
        },
        Step::Cruise {
            velocity_uu_s: 0.0,
            accel_uu_s2: 10.0 * V_UU_S,
            duration_s: 0.5,
        },
        Step::Disable,
    ]
}

/// Run the reference master against a CNC1 drive offline and record the bus.
fn run_logged(backlash_mm: f64) -> Logged {
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("backlash_mm", &backlash_mm.to_string())
        .unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node(&mut drive, NODE).unwrap();
    let master = Master::new(MasterConfig::default(), program(6.0));
    let mut run = OfflineRun::new(vec![AxisSlot { node, drive }], 1000, master);
    let mut monitor = run.take_monitor().unwrap();
    let mut w = CandumpWriter::default();
    while !run.master.finished() && run.now_us() < 60_000_000 {
        run.master_send();
        w.drain(&mut monitor, run.now_us());
        run.runtime.tick();
        w.drain(&mut monitor, run.now_us());
        run.master_receive();
    }
    assert_eq!(run.master.error(), None);
    assert_eq!(monitor.rx_overruns(), 0);
    Logged {
        samples: run.master.samples().to_vec(),
        log: w.text,
        kv_per_s: cfg.kv_per_s,
    }
}

fn worn() -> &'static Logged {
    static L: OnceLock<Logged> = OnceLock::new();
    L.get_or_init(|| run_logged(0.05))
}

fn healthy() -> &'static Logged {
    static L: OnceLock<Logged> = OnceLock::new();
    L.get_or_init(|| run_logged(0.0))
}

fn opts() -> DecodeOptions {
    DecodeOptions {
        node_id: NODE,
        defaults: PdoConfig::drive_defaults(NODE, "cnc1").unwrap().0,
        sync_period_us: None,
    }
}

fn detect(tr: &AxisTrace, kv: f64) -> DetectorReport {
    analyze(tr, &DetectorConfig::new(kv))
}

fn frequency(r: &DetectorReport) -> Option<f64> {
    r.frequency_hz.or(r.dominant_hz)
}

#[test]
fn the_decoded_log_is_what_the_master_received_and_gives_the_same_verdict() {
    let l = worn();
    let (tr, bus) =
        candump::trace_from_candump(Path::new("worn.log"), &l.log, NODE, "cnc1", None, false)
            .unwrap();
    eprintln!("{}", bus.summary());
    // The master remapped the PDOs over SDO: only by following the remap are the values right.
    assert!(
        bus.stats.pdo_config_writes >= 20,
        "{}",
        bus.stats.pdo_config_writes
    );
    assert_eq!(bus.stats.sdo_writes_aborted, 0);
    assert_eq!(bus.stats.pdo_length_errors, 0);
    assert!(bus.stats.unknown_frames > 0, "the master's heartbeat");
    assert_eq!(bus.period_us, 1000);
    assert_eq!(bus.period_source, PeriodSource::Object1006);
    let measured = bus.measured_period_us.unwrap();
    assert!(measured.abs_diff(1000) <= 3, "{measured}");
    assert_eq!(bus.samples.len(), l.samples.len());
    assert_eq!(bus.stats.syncs, l.samples.len());
    for (k, (b, m)) in bus.samples.iter().zip(&l.samples).enumerate() {
        let got = (
            b.statusword,
            b.mode_display,
            b.position_uu,
            b.direct_position_uu,
            b.velocity_uu_s,
            b.torque_permille,
            b.current_permille,
            b.following_error_uu,
        );
        let want = (
            m.statusword,
            m.mode_display,
            m.position_uu,
            m.direct_position_uu,
            m.velocity_uu_s,
            m.torque_permille,
            m.current_permille,
            m.following_error_uu,
        );
        assert_eq!(got, want, "sample {k}");
        assert_eq!(
            b.target_position_uu,
            Some(m.target_uu.round() as i32),
            "sample {k}"
        );
    }

    let from_log = detect(&tr, l.kv_per_s);
    let from_samples = detect(
        &AxisTrace::from_sample_log(&l.samples, SampleSource::Master, false),
        l.kv_per_s,
    );
    let (fl, fs) = (
        frequency(&from_log).unwrap(),
        frequency(&from_samples).unwrap(),
    );
    eprintln!(
        "worn: candump {} {fl:.3} Hz {:.3} um, samples {} {fs:.3} Hz {:.3} um, windows {} / {}",
        from_log.verdict.as_str(),
        from_log.amplitude,
        from_samples.verdict.as_str(),
        from_samples.amplitude,
        from_log.windows.len(),
        from_samples.windows.len()
    );
    assert_ne!(from_samples.verdict, Verdict::Ok, "0.05 mm must be flagged");
    assert_eq!(from_log.verdict, from_samples.verdict);
    assert!((fl - fs).abs() <= 0.01 * fs, "{fl} vs {fs} Hz");
    assert!(
        (from_log.amplitude - from_samples.amplitude).abs() <= 0.05 * from_samples.amplitude,
        "{} vs {}",
        from_log.amplitude,
        from_samples.amplitude
    );
    // The set velocity derived from the 0x607A targets finds the same cruise windows, at the
    // same speed, starting at most one derivative span (0.2 s) later than the master's own
    // interpolator velocity says.
    assert_eq!(from_log.windows.len(), from_samples.windows.len());
    let span = (drive_emu::analysis::windows::DEMAND_SPAN_S * 1e3) as usize;
    for (a, b) in from_log.windows.iter().zip(&from_samples.windows) {
        assert!((a.set_velocity - V_UU_S).abs() < 0.01, "{}", a.set_velocity);
        assert!(
            a.start >= b.start
                && a.start - b.start <= span
                && (a.end - a.start).abs_diff(b.end - b.start) <= 2 * span,
            "{a:?} {b:?}"
        );
    }
}

#[test]
fn a_healthy_axis_is_ok_from_the_log_too() {
    let l = healthy();
    let (tr, _) =
        candump::trace_from_candump(Path::new("healthy.log"), &l.log, NODE, "cnc1", None, false)
            .unwrap();
    let from_log = detect(&tr, l.kv_per_s);
    let from_samples = detect(
        &AxisTrace::from_sample_log(&l.samples, SampleSource::Master, false),
        l.kv_per_s,
    );
    eprintln!(
        "healthy: candump {} {:.3} um, samples {} {:.3} um",
        from_log.verdict.as_str(),
        from_log.amplitude,
        from_samples.verdict.as_str(),
        from_samples.amplitude
    );
    assert!(!from_log.windows.is_empty());
    assert_eq!(from_log.verdict, Verdict::Ok);
    assert_eq!(from_samples.verdict, Verdict::Ok);
}

#[test]
fn the_cli_reads_a_candump_log_by_content_and_writes_the_report() {
    let l = worn();
    let dir = std::env::temp_dir().join(format!("drive-emu-candump-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // No .log extension: the format is told by the content.
    let path = dir.join("bus.txt");
    std::fs::write(&path, &l.log).unwrap();
    let out = dir.join("report");
    let code = run(&AnalyzeArgs {
        trace: path,
        kv: Some(l.kv_per_s),
        out: Some(out.clone()),
        fail_on_backlash: true,
        ..Default::default()
    })
    .unwrap();
    assert_eq!(
        code,
        std::process::ExitCode::from(1),
        "backlash found: exit 1"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("detector.json")).unwrap()).unwrap();
    let from_samples = detect(
        &AxisTrace::from_sample_log(&l.samples, SampleSource::Master, false),
        l.kv_per_s,
    );
    assert_eq!(json["verdict"], from_samples.verdict.as_str());
    assert_eq!(json["position_unit"], "um");
    let _ = std::fs::remove_dir_all(&dir);
}

/// What the master wrote to remap TPDO1/2 and RPDO1/2 (a subset of its configuration):
/// (index, sub, value, len).
fn remap_writes() -> Vec<(u16, u8, u32, u8)> {
    let n = u32::from(NODE);
    let mut w = Vec::new();
    for (comm, map, cob, entries) in [
        (
            0x1400u16,
            0x1600u16,
            0x200 + n,
            &[0x6040_0010u32, 0x607A_0020][..],
        ),
        (0x1401, 0x1601, 0x300 + n, &[0x60FF_0020, 0x6071_0010]),
        (0x1800, 0x1A00, 0x180 + n, &[0x6041_0010, 0x6064_0020]),
        (
            0x1801,
            0x1A01,
            0x280 + n,
            &[0x606C_0020, 0x6077_0010, 0x6061_0008],
        ),
    ] {
        w.push((comm, 1, cob | 0x8000_0000, 4));
        w.push((map, 0, 0, 1));
        for (i, e) in entries.iter().enumerate() {
            w.push((map, i as u8 + 1, *e, 4));
        }
        w.push((map, 0, entries.len() as u32, 1));
        w.push((comm, 1, cob, 4));
    }
    w
}

/// A log of the same motion as the drive's *default* mapping sends it: RPDO2 0x305 with
/// controlword and target position; TPDO1 with statusword and mode display, TPDO2-4 with
/// statusword and position / velocity / direct encoder. `aborted`: the master tried the remap
/// and every write was aborted.
fn default_mapped_log(samples: &[Sample], aborted: bool) -> String {
    let mut w = CandumpWriter::default();
    let n = u32::from(NODE);
    w.write(&CanFrame::new(0x000, &[0x82, NODE]), 0, 0);
    w.write(&CanFrame::new(0x700 + n, &[0x00]), 1000, 0);
    let mut t = 2000;
    if aborted {
        for (index, sub, value, len) in remap_writes() {
            let [i0, i1] = index.to_le_bytes();
            let v = value.to_le_bytes();
            let cmd = 0x23 | ((4 - len) << 2);
            w.write(
                &CanFrame::new(0x600 + n, &[cmd, i0, i1, sub, v[0], v[1], v[2], v[3]]),
                t,
                0,
            );
            // Abort 0x06040041: object cannot be mapped to the PDO.
            w.write(
                &CanFrame::new(0x580 + n, &[0x80, i0, i1, sub, 0x41, 0x00, 0x04, 0x06]),
                t,
                1,
            );
            t += 1000;
        }
    }
    w.write(&CanFrame::new(0x000, &[0x01, NODE]), t, 0);
    t += 1000;
    for (k, s) in samples.iter().enumerate() {
        let now = t + 1000 * k as u64;
        let mut r2 = [0x0F, 0x00, 0, 0, 0, 0];
        r2[2..].copy_from_slice(&(s.target_uu.round() as i32).to_le_bytes());
        w.write(&CanFrame::new(0x300 + n, &r2), now, 0);
        w.write(&CanFrame::new(0x080, &[]), now, 1);
        // What the drive answers to this SYNC, which the master records at the next one.
        let Some(next) = samples.get(k + 1) else {
            break;
        };
        let sw = next.statusword.to_le_bytes();
        let with_sw = |v: i32| {
            let mut d = [0u8; 6];
            d[..2].copy_from_slice(&sw);
            d[2..].copy_from_slice(&v.to_le_bytes());
            d
        };
        w.write(
            &CanFrame::new(0x180 + n, &[sw[0], sw[1], next.mode_display as u8]),
            now + 500,
            0,
        );
        w.write(
            &CanFrame::new(0x280 + n, &with_sw(next.position_uu)),
            now + 500,
            1,
        );
        w.write(
            &CanFrame::new(0x380 + n, &with_sw(next.velocity_uu_s)),
            now + 500,
            2,
        );
        w.write(
            &CanFrame::new(0x480 + n, &with_sw(next.direct_position_uu)),
            now + 500,
            3,
        );
    }
    w.text
}

#[test]
fn without_a_confirmed_remap_the_default_mapping_is_used() {
    let l = worn();
    let writes = remap_writes().len();
    for aborted in [false, true] {
        let log = default_mapped_log(&l.samples, aborted);
        let bus = candump::decode(&log, "default.log", &opts()).unwrap();
        assert_eq!(bus.stats.pdo_config_writes, 0);
        assert_eq!(
            bus.stats.sdo_writes_aborted,
            if aborted { writes } else { 0 }
        );
        assert_eq!(bus.stats.pdo_length_errors, 0, "aborted {aborted}");
        // No 0x1006 in this log: the median SYNC interval of the jittered timestamps.
        assert_eq!(bus.period_source, PeriodSource::MedianSyncInterval);
        assert!(bus.period_us.abs_diff(1000) <= 3, "{}", bus.period_us);
        assert_eq!(bus.samples.len(), l.samples.len());
        for (k, (b, m)) in bus.samples.iter().zip(&l.samples).enumerate().skip(1) {
            assert_eq!(
                (
                    b.statusword,
                    b.mode_display,
                    b.position_uu,
                    b.velocity_uu_s,
                    b.direct_position_uu
                ),
                (
                    m.statusword,
                    m.mode_display,
                    m.position_uu,
                    m.velocity_uu_s,
                    m.direct_position_uu
                ),
                "aborted {aborted}, sample {k}"
            );
        }
        // No current in the default mapping: speed alone still finds the limit cycle.
        assert!(
            bus.notes.iter().any(|n| n.contains("0x6078")),
            "{:?}",
            bus.notes
        );
        let from_log = detect(&bus.to_axis_trace(false).unwrap(), l.kv_per_s);
        let from_samples = detect(
            &AxisTrace::from_sample_log(&l.samples, SampleSource::Master, false),
            l.kv_per_s,
        );
        assert_eq!(from_log.verdict, from_samples.verdict);
        let (fl, fs) = (
            frequency(&from_log).unwrap(),
            frequency(&from_samples).unwrap(),
        );
        assert!((fl - fs).abs() <= 0.01 * fs, "{fl} vs {fs} Hz");
    }
}

#[test]
fn a_malformed_line_is_reported_with_its_number() {
    let l = healthy();
    let mut lines: Vec<&str> = l.log.lines().take(40).collect();
    lines[6] = "(1700000000.006000) vcan0 185#01020";
    let e = candump::decode(&lines.join("\n"), "bad.log", &opts())
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("bad.log:7: "), "{e}");
    assert!(e.contains("odd number of hex digits"), "{e}");
}

#[test]
fn a_log_without_the_node_says_so() {
    let l = healthy();
    let mut o = opts();
    o.node_id = 9;
    o.defaults = PdoConfig::drive_defaults(9, "cnc1").unwrap().0;
    let e = candump::decode(&l.log, "other.log", &o)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no frame of node 9"), "{e}");
    assert!(e.contains("0x185") && e.contains("--node"), "{e}");
}

#[test]
fn a_log_without_set_points_takes_the_constant_speed_from_the_actual_position() {
    // The set-points are not in the capture (RPDOs filtered out): the windows come from the
    // actual position (the paper's criterion on what the axis did), and the report says so;
    // the healthy axis is still measured and ok.
    let l = healthy();
    let log: String = l
        .log
        .lines()
        .filter(|x| !x.contains(" 205#") && !x.contains(" 305#"))
        .map(|x| format!("{x}\n"))
        .collect();
    let bus = candump::decode(&log, "nosp.log", &opts()).unwrap();
    let tr = bus.to_axis_trace(false).unwrap();
    assert!(
        tr.set_velocity_source.contains("actual values"),
        "{}",
        tr.set_velocity_source
    );
    let rep = detect(&tr, l.kv_per_s);
    assert!(!rep.windows.is_empty(), "{:?}", rep.reasons);
    assert_eq!(rep.verdict, Verdict::Ok, "{:?}", rep.reasons);
}

#[test]
fn a_log_without_the_speed_names_the_missing_object() {
    let l = healthy();
    // TPDO2 carries velocity, torque and mode display after the remap.
    let log: String = l
        .log
        .lines()
        .filter(|x| !x.contains(" 285#"))
        .map(|x| format!("{x}\n"))
        .collect();
    let bus = candump::decode(&log, "nospeed.log", &opts()).unwrap();
    let e = bus.to_axis_trace(false).unwrap_err().to_string();
    assert!(
        e.contains("node 5: 0x606C velocity actual value never in a PDO"),
        "{e}"
    );
    assert!(!e.contains("and 0x6078"), "current is in TPDO3: {e}");
}

/// `(ts) vcan0 185#0102` -> ` (ts)  vcan0  185   [2]  01 02` (candump -ta).
fn to_columns(line: &str) -> String {
    let mut it = line.split(' ');
    let (ts, iface, frame) = (it.next().unwrap(), it.next().unwrap(), it.next().unwrap());
    let (id, hex) = frame.split_once('#').unwrap();
    let bytes: Vec<&str> = (0..hex.len() / 2).map(|k| &hex[2 * k..2 * k + 2]).collect();
    format!(
        " {ts}  {iface}  {id}   [{}]  {}",
        bytes.len(),
        bytes.join(" ")
    )
}

#[test]
fn the_column_format_decodes_like_the_log_format_and_skips_other_frames() {
    let l = healthy();
    let mut ta = String::new();
    for (k, line) in l.log.lines().enumerate() {
        let col = to_columns(line);
        ta.push_str(&col);
        ta.push('\n');
        if k == 10 {
            // Not CANopen traffic of the node: counted and skipped.
            let ts = line.split(' ').next().unwrap();
            ta.push_str(&format!(
                " {ts}  vcan0  20000004   [8]  00 04 00 00 00 00 00 00   ERRORFRAME\n\
                 \tcontroller-problem{{rx-error-warning}}\n \
                 {ts}  vcan0  185   [6]  remote request\n \
                 {ts}  vcan0  12345678   [2]  01 02   '..'\n"
            ));
        }
    }
    let a = candump::decode(&l.log, "l.log", &opts()).unwrap();
    let b = candump::decode(&ta, "ta.log", &opts()).unwrap();
    assert_eq!(a.samples, b.samples);
    assert_eq!(a.period_us, b.period_us);
    assert_eq!(
        (
            b.stats.error_frames,
            b.stats.remote_frames,
            b.stats.extended_frames
        ),
        (1, 1, 1)
    );
    assert_eq!(b.stats.frames, a.stats.frames);
    assert_eq!(b.stats.node_frames, a.stats.node_frames);
}

/// The worn run's log as a drive behind its master would give it (lock-step on a busy host):
/// now and then the drive stalls for 8..32 SYNC periods, and when it runs again it answers
/// every SYNC it missed, in order, right after the SYNC that ends the stall. Only stretches
/// without SDO traffic stall (a remap between a SYNC and its late answer would change what
/// the answer means). Returns the log and the number of answers that came late.
fn with_stalls(log: &str) -> (String, usize) {
    let lines: Vec<&str> = log.lines().collect();
    let id = |l: &str| {
        u32::from_str_radix(l.split(' ').nth(2).unwrap().split('#').next().unwrap(), 16).unwrap()
    };
    let syncs: Vec<usize> = (0..lines.len())
        .filter(|&i| id(lines[i]) == 0x080)
        .collect();
    let n = u32::from(NODE);
    let answer = |i: usize| [0x180 + n, 0x280 + n, 0x380 + n, 0x480 + n].contains(&id(lines[i]));
    let sdo = |i: usize| [0x600 + n, 0x580 + n].contains(&id(lines[i]));
    // For each line of an answer that is moved: the SYNC (index into `syncs`) it goes after.
    let mut moved_to = vec![None; lines.len()];
    let mut late = 0;
    let (mut k, mut stall) = (200, 0usize);
    while k + 40 < syncs.len() {
        let d = 8 + (stall * 7) % 25;
        let (from, to) = (syncs[k], syncs[k + d]);
        if !(from..to).any(sdo) {
            for (i, m) in moved_to.iter_mut().enumerate().take(to).skip(from) {
                if answer(i) {
                    *m = Some(k + d);
                }
            }
            late += d;
            stall += 1;
        }
        k += d + 40;
    }
    let mut out = String::new();
    for (i, l) in lines.iter().enumerate() {
        if moved_to[i].is_some() {
            continue;
        }
        out.push_str(l);
        out.push('\n');
        if let Ok(s) = syncs.binary_search(&i) {
            let ts = l.split(' ').next().unwrap();
            for (j, m) in moved_to.iter().enumerate() {
                if *m == Some(s) {
                    let rest = lines[j].split_once(' ').unwrap().1;
                    out.push_str(&format!("{ts} {rest}\n"));
                }
            }
        }
    }
    (out, late)
}

#[test]
fn a_drive_that_falls_behind_and_catches_up_decodes_to_what_the_master_received() {
    let l = worn();
    let (log, late) = with_stalls(&l.log);
    assert!(late > 100, "{late} answers late");
    let a = candump::decode(&l.log, "on-time.log", &opts()).unwrap();
    let b = candump::decode(&log, "behind.log", &opts()).unwrap();
    eprintln!("{}", b.summary());
    assert!(
        b.stats.answers_late >= late / 2,
        "{} late",
        b.stats.answers_late
    );
    // Each SYNC's row holds what answered it: the same as on time.
    assert_eq!(a.rows.len(), b.rows.len());
    let differ: Vec<usize> = (0..a.rows.len())
        .filter(|&k| {
            (
                a.rows[k].position_uu,
                a.rows[k].velocity_uu_s,
                a.answered[k],
            ) != (
                b.rows[k].position_uu,
                b.rows[k].velocity_uu_s,
                b.answered[k],
            )
        })
        .collect();
    assert!(
        differ.is_empty(),
        "{} of {} rows differ, the first at {:?}",
        differ.len(),
        a.rows.len(),
        differ.first()
    );
}
