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
    assert_eq!(
        b.w32(0x1005, 0, 0x4000_0080),
        Err(0x0609_0030),
        "we do not produce SYNC"
    );
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
    // SYNC resumes: the communication error is cleared
    b.sync();
    b.tick();
    assert!(b.r32(0x1001, 0) & 0x10 == 0);
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
