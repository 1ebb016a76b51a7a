//! SYNC producer (CiA 301 7.2.5: 0x1005 bit 30, 0x1006, 0x1019) on the sans-IO node with
//! simulated time: the node polled exactly at the deadlines it names (`poll_at`), SYNC frames
//! at those deadlines on 0x1005's CAN-ID, the counter 1..=0x1019, its own synchronous TPDOs
//! after each SYNC, silence in stopped, and CiA 301's rules for writing the three objects.
mod common;
use common::*;
use drive_protocol::{CanFrame, Timer};

/// Poll at the node's own deadlines until `until_us`; every frame with the time it was sent.
fn run_at_deadlines(b: &mut Bench, until_us: u64) -> Vec<(u64, CanFrame)> {
    let mut out = Vec::new();
    while let Some(at) = b.node.poll_at() {
        if at > until_us {
            break;
        }
        assert!(at >= b.now, "a deadline in the past: {at} < {}", b.now);
        b.now = at;
        b.node.poll(at, &mut b.drive);
        while let Some(f) = b.node.pop_tx() {
            out.push((at, f));
        }
        assert!(
            b.node.poll_at().is_none_or(|n| n > at),
            "poll_at after poll({at}) is not later"
        );
    }
    out
}

fn syncs(frames: &[(u64, CanFrame)], can_id: u32) -> Vec<(u64, Vec<u8>)> {
    frames
        .iter()
        .filter(|(_, f)| f.id == can_id)
        .map(|(t, f)| (*t, f.data[..f.len as usize].to_vec()))
        .collect()
}

/// A producer at 5 ms on `can_id`, written at t = 10 ms in pre-operational.
fn producer(can_id: u32, overflow: u8) -> Bench {
    let mut b = Bench::new();
    b.run_until(10_000);
    b.take();
    b.w8(0x1019, 0, overflow).unwrap();
    b.w32(0x1006, 0, 5_000).unwrap();
    b.w32(0x1005, 0, 0x4000_0000 | can_id).unwrap();
    assert_eq!(
        b.node.timers().get(Timer::SyncProducer),
        Some(b.now),
        "poll now"
    );
    b
}

#[test]
fn sync_frames_come_at_exactly_the_period_with_no_counter() {
    let mut b = producer(0x80, 0);
    let start = b.now;
    let s = syncs(&run_at_deadlines(&mut b, start + 50_000), 0x80);
    let times: Vec<u64> = s.iter().map(|(t, _)| *t).collect();
    let want: Vec<u64> = (1..=10).map(|k| start + 5_000 * k).collect();
    assert_eq!(times, want, "one SYNC per 0x1006 after it was set");
    assert!(s.iter().all(|(_, d)| d.is_empty()), "0x1019 = 0: no data");
}

#[test]
fn the_counter_runs_1_to_0x1019_and_wraps_for_several_overflow_values() {
    for overflow in [2u8, 3, 7, 240] {
        let mut b = producer(0x80, overflow);
        let start = b.now;
        let n = overflow as u64 * 2 + 3;
        let s = syncs(&run_at_deadlines(&mut b, start + 5_000 * n), 0x80);
        let counters: Vec<u8> = s.iter().map(|(_, d)| d[0]).collect();
        let want: Vec<u8> = (0..n).map(|k| (k % overflow as u64) as u8 + 1).collect();
        assert_eq!(counters, want, "0x1019 = {overflow}");
        assert!(s.iter().all(|(_, d)| d.len() == 1));
    }
}

#[test]
fn the_sync_cob_id_is_the_can_id_of_0x1005() {
    let mut b = producer(0x90, 0);
    let start = b.now;
    let all = run_at_deadlines(&mut b, start + 20_000);
    assert_eq!(syncs(&all, 0x90).len(), 4);
    assert!(syncs(&all, 0x80).is_empty());
}

#[test]
fn its_own_synchronous_tpdos_follow_each_sync() {
    let mut b = producer(0x80, 4);
    b.start();
    b.take();
    let start = b.now;
    let all = run_at_deadlines(&mut b, start + 30_000);
    // TPDO2 (statusword + position actual) is sent every SYNC (transmission type 1)
    let tpdo2 = 0x280 + ID as u32;
    let ids: Vec<u32> = all
        .iter()
        .map(|(_, f)| f.id)
        .filter(|&i| i == 0x80 || i == tpdo2)
        .collect();
    assert_eq!(ids.len(), 12, "{ids:x?}");
    for pair in ids.chunks(2) {
        assert_eq!(pair, [0x80, tpdo2], "the TPDO after its SYNC: {ids:x?}");
    }
    for (t, f) in all.iter().filter(|(_, f)| f.id == tpdo2) {
        assert!(
            all.iter().any(|(ts, s)| s.id == 0x80 && ts == t),
            "TPDO at {t} without a SYNC then ({:?})",
            f
        );
    }
}

#[test]
fn no_sync_in_stopped_and_the_counter_restarts_in_pre_operational() {
    let mut b = producer(0x80, 5);
    let start = b.now;
    let s = syncs(&run_at_deadlines(&mut b, start + 15_000), 0x80);
    assert_eq!(s.iter().map(|(_, d)| d[0]).collect::<Vec<_>>(), [1, 2, 3]);
    b.nmt(0x02, ID); // stop
    let t = b.now;
    assert_eq!(b.node.timers().get(Timer::SyncProducer), None);
    b.run_until(t + 30_000);
    assert!(syncs(&b.tx.iter().map(|f| (0, *f)).collect::<Vec<_>>(), 0x80).is_empty());
    b.nmt(0x80, ID); // pre-operational
    b.take();
    let t = b.now;
    let s = syncs(&run_at_deadlines(&mut b, t + 10_000), 0x80);
    assert_eq!(s.iter().map(|(_, d)| d[0]).collect::<Vec<_>>(), [1, 2]);
}

#[test]
fn writes_follow_cia_301() {
    let mut b = producer(0x80, 0);
    // 0x1019 only while 0x1006 = 0
    assert_eq!(b.w8(0x1019, 0, 4), Err(0x0800_0022));
    // the CAN-ID of a running producer stays; bit 30 cleared first, then it may change
    assert_eq!(b.w32(0x1005, 0, 0x4000_0081), Err(0x0609_0030));
    assert_eq!(b.w32(0x1005, 0, 0x4000_0601), Err(0x0609_0030));
    assert_eq!(b.w32(0x1005, 0, 0x0000_0081), Ok(()));
    assert_eq!(b.node.timers().get(Timer::SyncProducer), None, "stopped");
    assert_eq!(b.w32(0x1005, 0, 0x4000_0081), Ok(()));
    // stopped and started again between two polls: the counter starts from 1 again
    b.w32(0x1005, 0, 0x81).unwrap();
    b.w32(0x1006, 0, 0).unwrap();
    b.w8(0x1019, 0, 3).unwrap();
    b.w32(0x1006, 0, 5_000).unwrap();
    b.w32(0x1005, 0, 0x4000_0081).unwrap();
    let t = b.now;
    let s = syncs(&run_at_deadlines(&mut b, t + 20_000), 0x81);
    assert_eq!(
        s.iter().map(|(_, d)| d[0]).collect::<Vec<_>>(),
        [1, 2, 3, 1]
    );
    b.w32(0x1005, 0, 0x81).unwrap();
    b.w32(0x1005, 0, 0x4000_0081).unwrap();
    let t = b.now;
    let s = syncs(&run_at_deadlines(&mut b, t + 10_000), 0x81);
    assert_eq!(
        s.iter().map(|(_, d)| d[0]).collect::<Vec<_>>(),
        [1, 2],
        "restarted"
    );
    // a restricted CAN-ID is refused with bit 30 as without
    assert_eq!(b.w32(0x1005, 0, 0x81), Ok(()));
    assert_eq!(b.w32(0x1005, 0, 0x4000_0701), Err(0x0609_0030));
    // 0x1006 = 0 stops the producer; 0x1019 may then be written
    assert_eq!(b.w32(0x1005, 0, 0x4000_0080), Ok(()));
    b.w32(0x1006, 0, 0).unwrap();
    assert_eq!(b.node.timers().get(Timer::SyncProducer), None);
    assert_eq!(b.w8(0x1019, 0, 4), Ok(()));
    assert_eq!(
        b.w8(0x1019, 0, 1),
        Err(0x0609_0030),
        "1 is no overflow value"
    );
}

#[test]
fn a_new_period_takes_effect_from_the_write() {
    let mut b = producer(0x80, 0);
    let start = b.now;
    let s = syncs(&run_at_deadlines(&mut b, start + 12_000), 0x80);
    assert_eq!(s.len(), 2);
    b.now += 500;
    let t = b.now;
    b.w32(0x1006, 0, 2_000).unwrap();
    let s = syncs(&run_at_deadlines(&mut b, t + 8_000), 0x80);
    let times: Vec<u64> = s.iter().map(|(t, _)| *t).collect();
    assert_eq!(times, [t + 2_000, t + 4_000, t + 6_000, t + 8_000]);
}
