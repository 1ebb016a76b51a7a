//! `Node::poll_event` (what happened) and `Node::poll_at` (when the node next needs a poll).
mod common;
use common::*;
use drive_protocol::{Cia402State, NmtState, NodeEvent, SdoDirection, SdoTransfer, EVENT_QUEUE};

fn events(b: &mut Bench) -> Vec<NodeEvent> {
    std::iter::from_fn(|| b.node.poll_event()).collect()
}

#[test]
fn state_changes_sync_and_sdo_transfers_are_reported_in_order() {
    let mut b = Bench::new();
    events(&mut b);
    b.start();
    assert_eq!(
        events(&mut b),
        vec![NodeEvent::NmtState {
            from: NmtState::PreOperational,
            to: NmtState::Operational
        }]
    );
    b.enable(1);
    let ev = events(&mut b);
    let states: Vec<_> = ev
        .iter()
        .filter_map(|e| match e {
            NodeEvent::Cia402State { to, .. } => Some(*to),
            _ => None,
        })
        .collect();
    assert_eq!(
        states,
        vec![
            Cia402State::ReadyToSwitchOn,
            Cia402State::SwitchedOn,
            Cia402State::OperationEnabled
        ]
    );
    let writes = ev
        .iter()
        .filter(|e| {
            matches!(
                e,
                NodeEvent::SdoTransfer(SdoTransfer {
                    index: 0x6040,
                    direction: SdoDirection::Download,
                    abort: None,
                    ..
                })
            )
        })
        .count();
    assert_eq!(writes, 3, "{ev:?}");
    assert_eq!(b.sdo_read(0x1234, 0), Err(0x0602_0000));
    assert_eq!(
        events(&mut b),
        vec![NodeEvent::SdoTransfer(SdoTransfer {
            index: 0x1234,
            sub: 0,
            direction: SdoDirection::Upload,
            abort: Some(0x0602_0000)
        })]
    );
    b.sync();
    assert_eq!(events(&mut b), vec![NodeEvent::Sync { counter: None }]);
}

/// A repeated error is reported every time, also after the 0x1003 history (8 entries) is
/// full: what scraping 0x1003 missed.
#[test]
fn emcy_raised_and_cleared_every_time_beyond_the_history() {
    let mut b = Bench::new();
    b.w32(0x1006, 0, 2000).unwrap();
    b.start();
    events(&mut b);
    let mut ev = Vec::new();
    for _ in 0..12 {
        b.sync();
        b.ticks(5); // > 1.5 periods without SYNC
        b.sync();
        b.tick();
        ev.extend(events(&mut b));
    }
    let raised = ev
        .iter()
        .filter(|e| **e == NodeEvent::EmcyRaised { code: 0x8100 })
        .count();
    let cleared = ev
        .iter()
        .filter(|e| **e == NodeEvent::EmcyCleared { code: 0x8100 })
        .count();
    assert_eq!((raised, cleared), (12, 12), "{ev:?}");
    assert_eq!(b.r32(0x1003, 0), 8, "history saturates at 8");
}

#[test]
fn a_full_event_queue_drops_and_counts_never_blocks() {
    let mut b = Bench::new();
    b.start();
    events(&mut b);
    for _ in 0..EVENT_QUEUE + 10 {
        b.sync();
    }
    assert_eq!(events(&mut b).len(), EVENT_QUEUE);
    assert_eq!(b.node.events_dropped(), 10);
}

/// A caller that polls only at `poll_at()` still gets every timed frame: heartbeats on their
/// period and the SDO timeout abort; and nothing is due before the deadline.
#[test]
fn polling_only_at_poll_at_keeps_heartbeat_and_sdo_timeout() {
    let mut b = Bench::new();
    b.w16(0x1017, 0, 100).unwrap();
    b.take();
    // a segmented download (size not indicated) that the client abandons
    b.send(f(0x600 + b.id(), &[0x20, 0x40, 0x60, 0, 0, 0, 0, 0]));
    assert_eq!(b.take()[0].data[0], 0x60, "segmented download started");
    let mut polls = 0;
    let mut sent = Vec::new();
    while b.now < 1_500_000 {
        let at = b.node.poll_at().expect("heartbeat and SDO deadlines");
        assert!(
            at > b.now,
            "deadline {at} not after the last poll {}",
            b.now
        );
        // nothing is due just before the deadline
        b.now = at - 1;
        b.node.poll(b.now, &mut b.drive);
        let early = b.take();
        assert!(
            early.is_empty(),
            "frame before the deadline {at}: {early:?}"
        );
        b.now = at;
        b.node.poll(b.now, &mut b.drive);
        sent.extend(b.take());
        polls += 1;
    }
    b.tx = sent;
    let hb = b.sent(0x700 + b.id());
    assert!(
        (14..=15).contains(&hb.len()),
        "{} heartbeats in 1.5 s",
        hb.len()
    );
    let aborts: Vec<_> = b
        .sent(0x580 + b.id())
        .into_iter()
        .filter(|f| f.data[0] == 0x80)
        .collect();
    assert_eq!(aborts.len(), 1);
    assert_eq!(&aborts[0].data[4..8], &0x0504_0000u32.to_le_bytes());
    assert!(
        polls < 40,
        "{polls} polls for 15 heartbeats and one timeout"
    );
}

#[test]
fn poll_at_names_sync_supervision_and_heartbeat_consumer_deadlines() {
    let mut b = Bench::new();
    b.w16(0x1800, 5, 0).unwrap(); // no TPDO1 event timer: its deadline would come first
    b.w32(0x1006, 0, 4000).unwrap();
    b.w32(0x1016, 1, (0x7F << 16) | 50).unwrap();
    b.start();
    b.now = 10_000;
    b.sync();
    b.node.poll(b.now, &mut b.drive);
    assert_eq!(
        b.node.poll_at(),
        Some(10_000 + 6000 + 1),
        "1.5 SYNC periods"
    );
    b.send(f(0x77F, &[0x05]));
    assert_eq!(b.node.poll_at(), Some(10_000 + 6000 + 1));
    b.now = 12_000;
    b.send(f(0x77F, &[0x05]));
    assert_eq!(
        b.node.poll_at(),
        Some(12_000 + 50_000 + 1).min(Some(16_001))
    );
    b.take();
    b.now = 16_001;
    b.node.poll(b.now, &mut b.drive);
    b.drain();
    assert!(b.emcys().contains(&0x8100), "SYNC loss at the deadline");
    assert_eq!(
        b.node.poll_at(),
        Some(62_001),
        "then the heartbeat consumer"
    );
    b.now = 62_001;
    b.node.poll(b.now, &mut b.drive);
    b.drain();
    assert!(
        b.emcys().contains(&0x8130),
        "heartbeat loss at the deadline"
    );
}

/// The `poll_at` contract: right after `poll(now)` the next deadline is later than `now`.
fn assert_poll_at_after(b: &Bench, what: &str) {
    if let Some(at) = b.node.poll_at() {
        assert!(at > b.now, "{what}: poll_at() = {at} <= now = {}", b.now);
    }
}

/// A poll that comes exactly one heartbeat period late (the loop stalled for a period) sends
/// one heartbeat and schedules the next a period on: it used to keep the grid and leave the
/// next heartbeat due at `now`, so `poll_at()` said "now" right after the poll.
#[test]
fn a_poll_one_period_late_leaves_the_next_heartbeat_in_the_future() {
    for late_periods in [1u64, 2, 5] {
        let mut b = Bench::new();
        b.w16(0x1017, 0, 100).unwrap();
        b.take();
        // due at 100 ms; polled at 100 ms + k periods
        b.now = 100_000 + late_periods * 100_000;
        b.node.poll(b.now, &mut b.drive);
        assert_eq!(
            b.take().iter().filter(|f| f.id == 0x700 + b.id()).count(),
            1
        );
        assert_poll_at_after(&b, &format!("{late_periods} periods late"));
        assert_eq!(b.node.poll_at(), Some(b.now + 100_000), "one period on");
        // polling again at the same instant sends nothing
        b.node.poll(b.now, &mut b.drive);
        assert!(b.take().is_empty());
    }
}

/// Two monitored producers that time out in the same poll are both handled by it (one EMCY
/// 0x8130): the second used to stay due until the next poll.
#[test]
fn heartbeat_consumers_timing_out_together_are_handled_in_one_poll() {
    let mut b = Bench::new();
    b.w16(0x1800, 5, 0).unwrap(); // no TPDO1 event timer
    b.w32(0x1016, 1, (0x7E << 16) | 50).unwrap();
    b.w32(0x1016, 2, (0x7F << 16) | 50).unwrap();
    b.send(f(0x77E, &[0x05]));
    b.send(f(0x77F, &[0x05]));
    b.take();
    b.now = 50_001;
    b.node.poll(b.now, &mut b.drive);
    assert_poll_at_after(&b, "both consumers timed out");
    b.drain();
    assert_eq!(
        b.emcys().iter().filter(|&&c| c == 0x8130).count(),
        1,
        "{:04X?}",
        b.emcys()
    );
}

/// Clocks near the end of the u64 range (584 542 years): nothing overflows (the test
/// profile checks overflow), deadlines that would lie beyond `u64::MAX` never come, and the
/// contract holds at every poll up to `u64::MAX` itself. With and without a communication
/// cycle period (without one, CSP takes the measured SYNC interval: here 2^62 us and more).
#[test]
fn clocks_at_the_end_of_the_range_neither_overflow_nor_spin() {
    let starts = [
        1u64 << 62,
        1 << 63,
        u64::MAX - 2_000_000,
        u64::MAX - 1000,
        u64::MAX,
    ];
    for (start, cycle_us) in starts.into_iter().flat_map(|s| [(s, 4000u32), (s, 0)]) {
        let what = format!("clock from {start:#x}, 0x1006 = {cycle_us}");
        let mut b = Bench::new();
        b.w16(0x1017, 0, 100).unwrap();
        b.w32(0x1006, 0, cycle_us).unwrap();
        b.w8(0x60C2, 1, 0).unwrap();
        b.w32(0x1016, 1, (0x7F << 16) | 50).unwrap();
        b.start();
        b.sync();
        b.take();
        b.now = start;
        b.send(f(0x77F, &[0x05]));
        b.sync();
        b.enable(8);
        let mut heartbeats = 0;
        for step in [0u64, 1, 999, 50_001, 100_000, 1_000_000, u64::MAX] {
            b.now = start.saturating_add(step);
            for again in [false, true] {
                b.sync();
                b.node.poll(b.now, &mut b.drive);
                assert_poll_at_after(&b, &format!("{what}: + {step} us, again: {again}"));
                heartbeats += b.take().iter().filter(|f| f.id == 0x700 + b.id()).count();
            }
        }
        assert_eq!(b.now, u64::MAX);
        if start <= u64::MAX - 2_000_000 {
            assert!(heartbeats >= 2, "{what}: {heartbeats} heartbeats");
        }
        // The next heartbeat would be due beyond u64::MAX: it never is, and polling at
        // u64::MAX sends none (instead of one per poll).
        for _ in 0..3 {
            b.node.poll(u64::MAX, &mut b.drive);
        }
        let hb = b.take().iter().filter(|f| f.id == 0x700 + b.id()).count();
        assert_eq!(hb, 0, "{what}: heartbeats polled at u64::MAX");
    }
}
