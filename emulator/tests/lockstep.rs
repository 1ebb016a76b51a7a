//! Lock-step mode: the drive's answers must not depend on how the frames were batched when it
//! read them. On a busy host (or inside user-mode Linux) the loop may find ten SYNC periods of
//! traffic queued at once; handled in bus order, each SYNC advancing time before the frames
//! after it are seen, that gives the same run as reading them one period at a time.

use drive_emu::bus::inproc::InProcBus;
use drive_emu::bus::{CanBus, CanFrame};
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::master::{Master, MasterConfig, Step, MODE_CSP, MODE_PP};
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::{AxisSlot, Runtime};
use drive_emu::session::OfflineRun;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

const NODE: u8 = 5;

fn axis() -> AxisSlot<AxisDrive> {
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("backlash_mm", "0.05")
        .unwrap();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node(&mut drive, NODE).unwrap();
    AxisSlot { node, drive }
}

/// What a master sends during a whole program (reset, remap, enable, PP move, CSP cruise),
/// split after each SYNC: group k ends with the k-th SYNC.
fn master_traffic() -> Vec<Vec<CanFrame>> {
    let program = vec![
        Step::Enable { mode: MODE_PP },
        Step::MoveTo {
            target_uu: 2_000,
            velocity_uu_s: 50_000,
            accel_uu_s2: 500_000,
        },
        Step::SetMode { mode: MODE_CSP },
        Step::Cruise {
            velocity_uu_s: 10_000.0,
            accel_uu_s2: 100_000.0,
            duration_s: 0.6,
        },
    ];
    let master = Master::new(MasterConfig::default(), program);
    let mut run = OfflineRun::new(vec![axis()], 1000, master);
    let mut monitor = run.take_monitor().unwrap();
    run.run_program(20_000_000);
    assert!(run.master.finished(), "{:?}", run.master.error());
    let n = u32::from(NODE);
    let from_master = |id: u32| {
        id == 0
            || id == 0x80
            || id == 0x200 + n
            || id == 0x300 + n
            || id == 0x600 + n
            || id == 0x77F
    };
    let mut groups = vec![Vec::new()];
    while let Ok(Some(f)) = monitor.recv() {
        if from_master(f.id) {
            groups.last_mut().unwrap().push(f);
            if f.id == 0x80 {
                groups.push(Vec::new());
            }
        }
    }
    groups.pop(); // frames after the last SYNC: no time passes for them
    groups
}

/// Replay the master's frames into a lock-step drive, `batch` SYNC periods at a time, and
/// return everything the drive sent.
fn replay(groups: &[Vec<CanFrame>], batch: usize) -> Vec<(u32, Vec<u8>)> {
    let mut eps = InProcBus::endpoints(2, 1 << 16);
    let mut peer = eps.pop().unwrap();
    let mut rt = Runtime::new(eps.pop().unwrap(), vec![axis()], 1000);
    rt.boot();
    let mut out = Vec::new();
    let mut syncs = 0u64;
    for chunk in groups.chunks(batch) {
        for f in chunk.iter().flatten() {
            peer.send(f).unwrap();
        }
        syncs += chunk.len() as u64;
        let end_us = syncs * 1000;
        let stop = AtomicBool::new(false);
        rt.run_lockstep(1000, &stop, |rt| {
            if rt.sim_time_us >= end_us {
                stop.store(true, Ordering::Relaxed);
            }
        });
        assert_eq!(rt.sim_time_us, end_us, "one SYNC period per SYNC");
        while let Ok(Some(f)) = peer.recv() {
            out.push((f.id, f.data[..usize::from(f.len)].to_vec()));
        }
    }
    out
}

#[test]
fn batched_frames_give_the_same_run_as_one_period_at_a_time() {
    let groups = master_traffic();
    assert!(groups.len() > 400, "{} SYNC periods", groups.len());
    let one = replay(&groups, 1);
    let tpdo_with_motion = one
        .iter()
        .filter(|(id, d)| *id == 0x280 + u32::from(NODE) && d[..4] != [0, 0, 0, 0])
        .count();
    assert!(tpdo_with_motion > 200, "the axis moved: {tpdo_with_motion}");
    for batch in [7, 64] {
        let many = replay(&groups, batch);
        assert_eq!(one.len(), many.len(), "batch {batch}: frame count");
        let first_diff = one.iter().zip(&many).position(|(a, b)| a != b);
        assert_eq!(
            first_diff, None,
            "batch {batch}: the drive answered differently at frame {first_diff:?}"
        );
    }
}

/// Lock-step with a boot delay: simulated time stands still without SYNC, yet the master
/// waits for the boot-up before it sends any. The delay passes on the wall clock, at power-on
/// and after each NMT reset, with no SYNC on the bus; a SYNC during the delay is not lost
/// time either (it advances the clock as ever).
#[test]
fn boot_delay_passes_on_the_wall_clock_without_sync() {
    use std::time::{Duration, Instant};
    const DELAY_US: u64 = 150_000;
    let mut eps = InProcBus::endpoints(2, 1 << 12);
    let mut peer = eps.pop().unwrap();
    let mut drive = axis().drive;
    let opts = drive_emu::drive::NodeOptions::new(NODE).with_boot_delay_us(DELAY_US);
    let node = drive_emu::drive::build_node(&mut drive, &opts).unwrap();
    let slot = AxisSlot { node, drive };
    let mut rt = Runtime::new(eps.pop().unwrap(), vec![slot], 1000);
    rt.boot();
    assert!(
        rt.axes[0].node.boot_pending(),
        "power-on boot waits for its delay"
    );
    let stop = std::sync::Arc::new(AtomicBool::new(false));
    let t_start = Instant::now();
    let runner = {
        let stop = std::sync::Arc::clone(&stop);
        std::thread::spawn(move || {
            rt.run_lockstep(1000, &stop, |_| {});
            rt
        })
    };
    let boot_up = u32::from(NODE) + 0x700;
    let wait_boot_up = |peer: &mut drive_emu::bus::inproc::InProcEndpoint| -> Instant {
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            if let Ok(Some(f)) = peer.recv() {
                if f.id == boot_up && f.data[0] == 0 {
                    return Instant::now();
                }
            }
            assert!(Instant::now() < deadline, "no boot-up within 60 s");
            std::thread::sleep(Duration::from_micros(200));
        }
    };
    let t = wait_boot_up(&mut peer);
    assert!(
        t - t_start >= Duration::from_micros(DELAY_US),
        "power-on: {:?}",
        t - t_start
    );
    for cs in [0x82u8, 0x81, 0x82] {
        let sent = Instant::now();
        peer.send(&CanFrame::new(0, &[cs, NODE])).unwrap();
        let t = wait_boot_up(&mut peer);
        assert!(
            t - sent >= Duration::from_micros(DELAY_US),
            "NMT {cs:#x}: boot-up after {:?}, before the delay",
            t - sent
        );
    }
    // SYNCs during a pending boot still advance the lock-step clock
    peer.send(&CanFrame::new(0, &[0x82, NODE])).unwrap();
    for _ in 0..10 {
        peer.send(&CanFrame::new(0x80, &[])).unwrap();
    }
    wait_boot_up(&mut peer);
    let deadline = Instant::now() + Duration::from_secs(60);
    while !runner.is_finished() && Instant::now() < deadline {
        stop.store(true, Ordering::Relaxed);
        std::thread::sleep(Duration::from_millis(5));
    }
    let rt = runner.join().unwrap();
    assert_eq!(rt.sim_time_us, 10_000, "10 SYNCs, 10 periods");
    assert!(!rt.axes[0].node.boot_pending());
}

#[test]
fn loop_statistics_are_live_in_lock_step() {
    // A master reading 0x2100 sub 1 (ticks) in the middle of a lock-step run sees the ticks
    // run so far, not 0 until the loop stops.
    let mut eps = InProcBus::endpoints(2, 1 << 16);
    let mut peer = eps.pop().unwrap();
    let mut rt = Runtime::new(eps.pop().unwrap(), vec![axis()], 1000);
    rt.boot();
    let syncs = 1000u64;
    for _ in 0..syncs {
        peer.send(&CanFrame::new(0x80, &[])).unwrap();
    }
    let n = u32::from(NODE);
    let stats_ticks = drive_protocol::wire::Mux::new(0x2100, 1);
    let upload = drive_protocol::wire::SdoRequest::InitiateUpload { mux: stats_ticks };
    peer.send(&CanFrame::new(0x600 + n, &upload.emit()))
        .unwrap();
    let stop = AtomicBool::new(false);
    rt.run_lockstep(1000, &stop, |rt| {
        if rt.sim_time_us >= syncs * 1000 {
            stop.store(true, Ordering::Relaxed);
        }
    });
    let mut ticks = None;
    while let Ok(Some(f)) = peer.recv() {
        if f.id != 0x580 + n {
            continue;
        }
        if let Ok(drive_protocol::wire::SdoResponse::InitiateUpload { mux, data }) =
            drive_protocol::wire::SdoResponse::parse(&f.data)
        {
            if mux == stats_ticks && data.bytes().len() == 4 {
                ticks = Some(u32::from_le_bytes(data.bytes().try_into().unwrap()));
            }
        }
    }
    let ticks = ticks.expect("no SDO answer for 0x2100 sub 1");
    // Refreshed every 256 ticks: within 256 of the 1000 run when the request came.
    assert!(
        ticks as u64 > syncs - 256 && ticks as u64 <= syncs,
        "0x2100:1 read {ticks} after {syncs} lock-step ticks"
    );
}

#[test]
fn a_lock_step_drive_that_lost_syncs_on_receive_says_so() {
    // The drive's receive queue holds 64 frames; a master sends 200 SYNCs before the drive
    // reads any (a stalled host): 136 are lost before the drive could see them. Lock-step
    // time then advances by 64 SYNCs only, and the drive reports the loss in 0x2100:13 and
    // on its statistics line instead of silently running slow.
    const QUEUE: usize = 64;
    const SENT: u64 = 200;
    let mut eps = InProcBus::endpoints(2, QUEUE);
    let mut peer = eps.pop().unwrap();
    let mut rt = Runtime::new(eps.pop().unwrap(), vec![axis()], 1000);
    rt.boot();
    while let Ok(Some(_)) = peer.recv() {}
    for _ in 0..SENT {
        peer.send(&CanFrame::new(0x80, &[])).unwrap();
    }
    let stop = AtomicBool::new(false);
    rt.run_lockstep(1000, &stop, |rt| {
        if rt.sim_time_us >= QUEUE as u64 * 1000 {
            stop.store(true, Ordering::Relaxed);
        }
    });
    let lost = SENT - QUEUE as u64;
    assert_eq!(rt.stats.syncs, QUEUE as u64, "SYNCs the drive read");
    assert_eq!(rt.stats.rx_overflows, lost);
    assert_eq!(
        rt.axes[0].node.object_raw(0x2100, 13),
        Some(lost as u32),
        "0x2100:13 rx_overflows"
    );
    let line = rt.stats.summary().to_string();
    assert!(line.contains(&format!("rx overflow {lost},")), "{line}");
}

/// Lock-step times what a master measures on its own clock on the wall clock (issue 22): a
/// drive whose 0x1017 says 50 ms sends heartbeats while no SYNC comes, its heartbeat consumer
/// (0x1016) reports a master that went silent (EMCY 0x8130), and TPDO1's event timer sends
/// the statusword; the simulated time, which moves only with SYNC, stays where it was.
#[test]
fn communication_timers_run_on_the_wall_clock_between_syncs() {
    use std::time::{Duration, Instant};
    let mut eps = InProcBus::endpoints(2, 1 << 14);
    let mut peer = eps.pop().unwrap();
    let mut rt = Runtime::new(eps.pop().unwrap(), vec![axis()], 1000);
    rt.boot();
    let stop = std::sync::Arc::new(AtomicBool::new(false));
    let runner = {
        let stop = std::sync::Arc::clone(&stop);
        std::thread::spawn(move || {
            rt.run_lockstep_with(drive_emu::runtime::Lockstep::default(), &stop, |_| {});
            rt
        })
    };
    let id = u32::from(NODE);
    let sdo = |peer: &mut drive_emu::bus::inproc::InProcEndpoint, req: [u8; 8]| {
        peer.send(&CanFrame::new(0x600 + id, &req)).unwrap();
    };
    // the master's heartbeat (node 0x7F) consumed with 200 ms, the drive's own every 50 ms
    sdo(&mut peer, [0x23, 0x16, 0x10, 1, 200, 0, 0x7F, 0]);
    sdo(&mut peer, [0x2B, 0x17, 0x10, 0, 50, 0, 0, 0]);
    peer.send(&CanFrame::new(0, &[0x01, NODE])).unwrap();
    peer.send(&CanFrame::new(0x77F, &[0x05])).unwrap();
    let (mut heartbeats, mut emcy, mut tpdo1) = (0, false, 0);
    let deadline = Instant::now() + Duration::from_secs(60);
    while (heartbeats < 3 || !emcy || tpdo1 < 2) && Instant::now() < deadline {
        match peer.recv() {
            Ok(Some(f)) if f.id == 0x700 + id && f.data[0] == 0x05 => heartbeats += 1,
            Ok(Some(f)) if f.id == 0x80 + id && f.data[..2] == [0x30, 0x81] => emcy = true,
            Ok(Some(f)) if f.id == 0x180 + id => tpdo1 += 1,
            _ => std::thread::sleep(Duration::from_micros(200)),
        }
    }
    let deadline = Instant::now() + Duration::from_secs(60);
    while !runner.is_finished() && Instant::now() < deadline {
        stop.store(true, Ordering::Relaxed);
        std::thread::sleep(Duration::from_millis(5));
    }
    let rt = runner.join().unwrap();
    assert!(heartbeats >= 3, "{heartbeats} heartbeats without SYNC");
    assert!(
        emcy,
        "a silent master is reported without SYNC (EMCY 0x8130)"
    );
    assert!(tpdo1 >= 2, "TPDO1's event timer: {tpdo1} without SYNC");
    assert_eq!(rt.sim_time_us, 0, "no SYNC, no simulated time");
}

/// A lock-step drive whose master wrote the SDOs `writes` (index, sub, little-endian value)
/// and then sent three SYNCs: the simulated time per SYNC it took.
fn period_per_sync_after(writes: &[(u16, u8, &[u8])]) -> u64 {
    use drive_protocol::wire::{Initiate, Mux, SdoRequest, SdoResponse};
    let mut eps = InProcBus::endpoints(2, 1 << 16);
    let mut peer = eps.pop().unwrap();
    let mut rt = Runtime::new(eps.pop().unwrap(), vec![axis()], 1000);
    rt.boot();
    let n = u32::from(NODE);
    for &(index, sub, value) in writes {
        let req = SdoRequest::InitiateDownload {
            mux: Mux::new(index, sub),
            data: Initiate::expedited(value),
        };
        peer.send(&CanFrame::new(0x600 + n, &req.emit())).unwrap();
    }
    const SYNCS: u64 = 3;
    for _ in 0..SYNCS {
        peer.send(&CanFrame::new(0x80, &[])).unwrap();
    }
    let stop = Arc::new(AtomicBool::new(false));
    // Only against a hang: the run stops itself once the SYNCs are used up.
    let guard = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_secs(30));
            stop.store(true, Ordering::Relaxed);
        })
    };
    let cfg = drive_emu::runtime::Lockstep::default();
    let mut ticks = 0u64;
    let mut wanted = u64::MAX;
    rt.run_lockstep_with(cfg, &stop, |rt| {
        ticks += 1;
        wanted = SYNCS * rt.lockstep_period_us / 1000;
        if ticks >= wanted {
            stop.store(true, Ordering::Relaxed);
        }
    });
    drop(guard);
    let mut answers = 0;
    while let Ok(Some(f)) = peer.recv() {
        if f.id == 0x580 + n {
            let r = SdoResponse::parse(&f.data);
            assert!(
                matches!(r, Ok(SdoResponse::InitiateDownload { .. })),
                "a write was not accepted: {r:?}"
            );
            answers += 1;
        }
    }
    assert_eq!(answers, writes.len(), "every write answered");
    assert_eq!(ticks, wanted, "the SYNCs ran the drive {ticks} ticks");
    assert_eq!(rt.sim_time_us, SYNCS * rt.lockstep_period_us);
    rt.lockstep_period_us
}

#[test]
fn the_time_per_sync_is_the_period_the_master_configured() {
    // Nothing written: 1 ms per SYNC.
    assert_eq!(period_per_sync_after(&[]), 1000);
    // Lely and ros2_canopen write no 0x1006, but a CSP set-up writes the interpolation time
    // period 0x60C2 (10 x 10^-3 s): the time between set-points, one per SYNC.
    assert_eq!(
        period_per_sync_after(&[(0x60C2, 1, &[10]), (0x60C2, 2, &[(-3i8) as u8])]),
        10_000
    );
    // 0x60C2 = 25 x 10^-4 s: 2.5 ms, in whole 1 ms ticks (rounded half up).
    assert_eq!(
        period_per_sync_after(&[(0x60C2, 1, &[25]), (0x60C2, 2, &[(-4i8) as u8])]),
        3000
    );
    // The communication cycle period 0x1006 comes first.
    assert_eq!(
        period_per_sync_after(&[
            (0x60C2, 1, &[10]),
            (0x60C2, 2, &[(-3i8) as u8]),
            (0x1006, 0, &4000u32.to_le_bytes()),
        ]),
        4000
    );
}

/// A bus whose frames all arrived while the drive was stalled: the first read finds the whole
/// queue, each frame kernel-stamped 1 ms after the one before, from the moment the stall
/// began; the read then finds the wall clock a second later than that. What the drive sends
/// is kept with the number of frames it had read by then.
struct StalledQueue {
    queue: std::collections::VecDeque<CanFrame>,
    first_stamp_ns: Option<i128>,
    read: usize,
    stamp_ns: Option<i128>,
    sent: Vec<(usize, CanFrame)>,
    stop: Arc<AtomicBool>,
}

impl CanBus for StalledQueue {
    fn send(&mut self, frame: &CanFrame) -> Result<(), drive_emu::bus::SendError> {
        self.sent.push((self.read, *frame));
        Ok(())
    }
    fn recv(&mut self) -> Result<Option<CanFrame>, drive_emu::bus::RecvError> {
        let first = *self.first_stamp_ns.get_or_insert_with(|| {
            let t = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_nanos() as i128;
            // The drive was stalled this long while the frames queued.
            std::thread::sleep(std::time::Duration::from_secs(1));
            t
        });
        let Some(f) = self.queue.pop_front() else {
            self.stop.store(true, Ordering::Relaxed);
            return Ok(None);
        };
        self.stamp_ns = Some(first + self.read as i128 * 1_000_000);
        self.read += 1;
        Ok(Some(f))
    }
    fn wait_readable(&mut self, _timeout_us: u64) {}
    fn last_rx_stamp_ns(&self) -> Option<i128> {
        self.stamp_ns
    }
}

/// A drive behind its master on a busy host reads a backlog longer than one batch
/// (`MAX_RX_PER_TICK`): the master's heartbeats in it arrived on time, by their stamps, so
/// the heartbeat consumer must not fault while the backlog is read (it once took the wall
/// clock after each batch: EMCY 0x8130 with the next heartbeat still in the queue).
#[test]
fn a_backlog_longer_than_a_batch_is_timed_by_its_stamps_not_the_wall_clock() {
    use drive_emu::runtime::MAX_RX_PER_TICK;
    const MASTER: u32 = 0x7F;
    let stop = Arc::new(AtomicBool::new(false));
    let mut queue = std::collections::VecDeque::new();
    // 0x1016:1 = master 0x7F, 150 ms (expedited download, 4 bytes).
    let consumer = (MASTER << 16) | 150;
    let b = consumer.to_le_bytes();
    queue.push_back(CanFrame::new(
        0x600 + u32::from(NODE),
        &[0x23, 0x16, 0x10, 0x01, b[0], b[1], b[2], b[3]],
    ));
    // 900 ms of traffic, 1 ms apart: a SYNC each, the master's heartbeat every 50 ms.
    for i in 0..900 {
        if i % 50 == 0 {
            queue.push_back(CanFrame::new(0x700 + MASTER, &[0x05]));
        } else {
            queue.push_back(CanFrame::new(0x80, &[]));
        }
    }
    let total = queue.len();
    assert!(total > 3 * MAX_RX_PER_TICK, "a backlog of several batches");
    let bus = StalledQueue {
        queue,
        first_stamp_ns: None,
        read: 0,
        stamp_ns: None,
        sent: Vec::new(),
        stop: Arc::clone(&stop),
    };
    let mut rt = Runtime::new(bus, vec![axis()], 1000);
    rt.boot();
    rt.finish_boots();
    rt.run_lockstep(1000, &stop, |_| {});
    let sdo_ok = rt
        .bus
        .sent
        .iter()
        .any(|(_, f)| f.id == 0x580 + u32::from(NODE) && f.data[0] == 0x60);
    assert!(sdo_ok, "0x1016 written");
    let emcy = u32::from(NODE) + 0x80;
    let heartbeat_emcy: Vec<usize> = rt
        .bus
        .sent
        .iter()
        .filter(|(_, f)| f.id == emcy && f.data[..2] == [0x30, 0x81])
        .map(|(read, _)| *read)
        .collect();
    assert!(
        heartbeat_emcy.iter().all(|&read| read == total),
        "EMCY 0x8130 after {heartbeat_emcy:?} of {total} frames read: the heartbeat was \
         taken for missed while it was still in the queue"
    );
}
