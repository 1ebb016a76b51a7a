//! SYNC consumer: counter, FrameEvent, supervision of 0x1006 with the 0x6007 reaction.
mod common;
use common::*;
use drive_protocol::{Cia402State, FrameEvent};

#[test]
fn sync_event_and_counter() {
    let mut b = Bench::new();
    assert_eq!(b.sync(), FrameEvent::Sync { counter: None });
    b.w8(0x1019, 0, 5).unwrap();
    b.start();
    assert_eq!(b.send(f(0x80, &[3])), FrameEvent::Sync { counter: Some(3) });
    assert!(!b.emcys().contains(&0x8240));
    // a SYNC without the counter byte while 0x1019 > 1: EMCY 0x8240 once
    b.sync();
    b.tick();
    b.sync();
    b.tick();
    assert_eq!(b.emcys().iter().filter(|&&c| c == 0x8240).count(), 1);
    // a different SYNC COB-ID
    b.w32(0x1005, 0, 0x81).unwrap();
    assert_eq!(b.send(f(0x81, &[1])), FrameEvent::Sync { counter: Some(1) });
    assert_ne!(b.send(f(0x80, &[1])), FrameEvent::Sync { counter: Some(1) });
    // bit 30 makes the node the producer (protocol/tests/sync_producer.rs); its CAN-ID then
    // stays until it stops producing
    assert_eq!(b.w32(0x1005, 0, 0x4000_0081), Ok(()));
    assert_eq!(
        b.w32(0x1005, 0, 0x4000_0082),
        Err(0x0609_0030),
        "the CAN-ID of a running producer"
    );
    assert_eq!(b.w32(0x1005, 0, 0x81), Ok(()));
    assert_eq!(b.w32(0x1005, 0, 0x82), Ok(()));
}

#[test]
fn missing_sync_gives_emcy_and_reaction() {
    let mut b = Bench::new();
    b.w32(0x1006, 0, 4000).unwrap();
    b.w16(0x6007, 0, 1).unwrap();
    b.start();
    b.enable(8);
    for _ in 0..10 {
        b.sync();
        b.ticks(4);
    }
    assert!(!b.emcys().contains(&0x8100));
    assert_eq!(b.node.cia402_state(), Cia402State::OperationEnabled);
    b.ticks(3); // 7 ms > 1.5 x 4 ms
    assert!(b.emcys().contains(&0x8100), "SYNC loss EMCY");
    b.ticks(2);
    assert_eq!(b.node.cia402_state(), Cia402State::Fault);
    // SYNC resumes: the drive is still in FAULT for it, so the error stays active (0x1001,
    // no EMCY 0x0000) until the fault reset
    b.take();
    b.sync();
    b.tick();
    assert!(!b.emcys().contains(&0x0000), "{:04X?}", b.emcys());
    assert_eq!(b.node.cia402_state(), Cia402State::Fault);
    assert_eq!(b.r32(0x1001, 0) & 0x11, 0x11);
    b.cw(0x00);
    b.tick();
    b.cw(0x80);
    b.sync();
    b.tick();
    assert_eq!(b.emcys(), vec![0x0000]);
    assert_eq!(b.node.cia402_state(), Cia402State::SwitchOnDisabled);
    assert_eq!(b.r32(0x1001, 0), 0);
}

#[test]
fn sync_back_without_a_fault_clears_the_error() {
    // 0x6007 = 0: SYNC loss is only reported; when SYNC returns, EMCY 0x0000 and 0x1001 = 0
    let mut b = Bench::new();
    b.w32(0x1006, 0, 4000).unwrap();
    b.start();
    for _ in 0..3 {
        b.sync();
        b.ticks(4);
    }
    b.ticks(10);
    assert!(b.emcys().contains(&0x8100));
    assert_eq!(b.r32(0x1001, 0) & 0x11, 0x11);
    b.take();
    b.sync();
    b.tick();
    assert_eq!(b.emcys(), vec![0x0000]);
    assert_eq!(b.r32(0x1001, 0), 0);
}

#[test]
fn sync_loss_not_reported_at_1_4_periods() {
    let mut b = Bench::new();
    b.w32(0x1006, 0, 10_000).unwrap();
    b.start();
    for _ in 0..20 {
        b.sync();
        b.ticks(14);
    }
    assert!(!b.emcys().contains(&0x8100));
}

#[test]
fn restricted_can_ids_are_refused_for_the_sync_cob_id() {
    // The case: SYNC = 0x605 (our SDO request ID) silenced SDO until reset.
    let mut b = Bench::new();
    let id = ID as u32;
    for bad in [
        0x000,
        0x001,
        0x07F,
        0x101,
        0x180,
        0x581,
        0x5FF,
        0x600 + id,
        0x6E0,
        0x701,
        0x7FF,
    ] {
        assert_eq!(b.w32(0x1005, 0, bad), Err(0x0609_0030), "{bad:#05x}");
    }
    assert_eq!(b.w32(0x1005, 0, 0x2000_0080), Err(0x0609_0030), "29-bit");
    assert_eq!(b.r32(0x1005, 0), 0x80, "unchanged");
    // SDO still answers, SYNC still works
    assert_eq!(b.r32(0x1000, 0), 0x0002_0192);
    b.start();
    assert!(matches!(b.sync(), drive_protocol::FrameEvent::Sync { .. }));
}
