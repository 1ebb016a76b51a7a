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
