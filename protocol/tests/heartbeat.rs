//! Heartbeat producer (0x1017) and consumer (0x1016) with the 0x6007 reaction.
mod common;
use common::*;
use drive_protocol::Cia402State;

#[test]
fn producer_sends_state_every_period() {
    let mut b = Bench::new();
    b.w16(0x1017, 0, 100).unwrap();
    b.take();
    b.run_until(1_000_000);
    let hb = b.sent(0x700 + ID as u32);
    assert!(
        (9..=11).contains(&hb.len()),
        "{} heartbeats in 1 s",
        hb.len()
    );
    assert!(hb.iter().all(|f| f.len == 1 && f.data[0] == 0x7F));
    b.start();
    b.take();
    b.run_until(1_200_000);
    assert!(b.sent(0x700 + ID as u32).iter().all(|f| f.data[0] == 0x05));
    b.nmt(0x02, ID);
    b.take();
    b.run_until(1_400_000);
    let hb = b.sent(0x700 + ID as u32);
    assert!(
        !hb.is_empty() && hb.iter().all(|f| f.data[0] == 0x04),
        "heartbeat continues in stopped"
    );
}

fn lose_master(option: u16) -> Bench {
    let mut b = Bench::new();
    b.start();
    b.w16(0x6007, 0, option).unwrap();
    b.w32(0x1016, 1, (0x7F << 16) | 50).unwrap();
    b.enable(1);
    // master heartbeats for a while, then stops
    for _ in 0..10 {
        b.send(f(0x77F, &[0x05]));
        b.ticks(20);
    }
    assert!(!b.emcys().contains(&0x8130));
    b.ticks(60);
    b
}

#[test]
fn lost_master_raises_emcy_and_fault() {
    let mut b = lose_master(1);
    assert!(b.emcys().contains(&0x8130), "EMCY 0x8130");
    assert_eq!(b.node.cia402_state(), Cia402State::Fault);
    // One event, one EMCY: the fault reaction to the loss must not report it again.
    assert_eq!(
        b.emcys().iter().filter(|&&c| c == 0x8130).count(),
        1,
        "{:04X?}",
        b.emcys()
    );
    assert_eq!(b.r32(0x1003, 0), 1, "one history entry");
    assert_eq!(
        b.r32(0x1001, 0) & 0x11,
        0x11,
        "generic + communication bits"
    );
}

#[test]
fn lost_master_with_option_0_does_nothing_to_the_drive() {
    let mut b = lose_master(0);
    assert!(b.emcys().contains(&0x8130));
    assert_eq!(b.node.cia402_state(), Cia402State::OperationEnabled);
    // heartbeat comes back: error cleared with EMCY 0x0000
    b.send(f(0x77F, &[0x05]));
    b.tick();
    assert_eq!(*b.emcys().last().unwrap(), 0x0000);
}

#[test]
fn lost_master_option_2_disables_voltage_and_3_quick_stops() {
    let b = lose_master(2);
    assert_eq!(b.node.cia402_state(), Cia402State::SwitchOnDisabled);
    let mut b = lose_master(3);
    // quick stop (option 2 of 0x605A by default) ends in switch on disabled once standing
    assert_eq!(b.node.cia402_state(), Cia402State::SwitchOnDisabled);
    // with 0x605A = 6 the drive stays in quick stop and the master's 0x0F does not re-enable it
    let mut b2 = Bench::new();
    b2.start();
    b2.w16(0x6007, 0, 3).unwrap();
    b2.w16(0x605A, 0, 6).unwrap();
    b2.w32(0x1016, 1, (0x7F << 16) | 50).unwrap();
    b2.enable(1);
    b2.send(f(0x77F, &[0x05]));
    b2.ticks(100);
    assert_eq!(b2.node.cia402_state(), Cia402State::QuickStopActive);
    b2.ticks(10);
    assert_eq!(b2.node.cia402_state(), Cia402State::QuickStopActive);
    b.tick();
}

#[test]
fn monitoring_starts_with_the_first_heartbeat() {
    let mut b = Bench::new();
    b.start();
    b.w32(0x1016, 1, (0x7F << 16) | 50).unwrap();
    b.ticks(500);
    assert!(!b.emcys().contains(&0x8130));
}

/// The drive in FAULT because its master was lost (0x6007 = 1), as a master finds it.
fn faulted_by_lost_master() -> Bench {
    let mut b = lose_master(1);
    assert_eq!(b.node.cia402_state(), Cia402State::Fault);
    assert_eq!(b.r32(0x603F, 0), 0x8130);
    b.take();
    b
}

/// Fault reset by SDO; returns the EMCY codes sent from the rising edge on.
fn fault_reset(b: &mut Bench) -> Vec<u16> {
    b.cw(0x00);
    b.tick();
    b.cw(0x80);
    b.tick();
    b.emcys()
}

#[test]
fn heartbeat_back_while_in_fault_keeps_the_error_active() {
    let mut b = faulted_by_lost_master();
    // the master's heartbeat returns, the drive is still in FAULT for it
    for _ in 0..5 {
        b.send(f(0x77F, &[0x05]));
        b.ticks(20);
    }
    // (EMCYs checked first: an SDO exchange drains what the bench collected)
    assert!(
        !b.emcys().contains(&0x0000),
        "no 'error reset' EMCY while in FAULT: {:04X?}",
        b.emcys()
    );
    assert_eq!(b.node.cia402_state(), Cia402State::Fault);
    assert_eq!(b.statusword() & 0x4F, 0x08, "statusword FAULT");
    assert_eq!(b.r32(0x603F, 0), 0x8130);
    assert_eq!(
        b.r32(0x1001, 0) & 0x11,
        0x11,
        "0x1001 still flags the error"
    );
    // the fault reset (cause gone) clears it: one EMCY 0x0000, register 0
    assert_eq!(fault_reset(&mut b), vec![0x0000]);
    assert_eq!(b.node.cia402_state(), Cia402State::SwitchOnDisabled);
    assert_eq!(b.r32(0x1001, 0), 0);
    assert_eq!(b.r32(0x603F, 0), 0);
}

/// CiA 402: a fault reset is refused while a fault is present. The master resets by SDO but
/// its heartbeat is still missing (0x6007 = 1 makes the loss a fault): the drive stays in
/// FAULT, no EMCY 0000, no second 0x1003 entry; once the heartbeat is back the reset is
/// accepted with one EMCY 0000.
#[test]
fn fault_reset_while_the_master_is_still_lost_is_refused() {
    let mut b = faulted_by_lost_master();
    let history = b.r32(0x1003, 0);
    for _ in 0..3 {
        let e = fault_reset(&mut b);
        assert!(e.is_empty(), "nothing sent for a refused reset: {e:04X?}");
        assert_eq!(b.node.cia402_state(), Cia402State::Fault);
        assert_eq!(b.statusword() & 0x4F, 0x08, "statusword FAULT");
    }
    assert_eq!(b.r32(0x1003, 0), history, "no new history entry");
    assert_eq!(
        b.r32(0x1001, 0) & 0x11,
        0x11,
        "heartbeat error still active"
    );
    // its heartbeat comes back: the reset is accepted, nothing is active
    b.send(f(0x77F, &[0x05]));
    b.tick();
    assert_eq!(fault_reset(&mut b), vec![0x0000]);
    assert_eq!(b.node.cia402_state(), Cia402State::SwitchOnDisabled);
    assert_eq!(b.r32(0x1001, 0), 0);
}

#[test]
fn reset_communication_in_fault_keeps_the_error_register() {
    let mut b = faulted_by_lost_master();
    b.nmt(0x82, ID);
    b.ticks(5);
    assert!(!b.emcys().contains(&0x0000), "{:04X?}", b.emcys());
    assert_eq!(
        b.node.cia402_state(),
        Cia402State::Fault,
        "CiA 402 state kept"
    );
    assert_eq!(b.r32(0x603F, 0), 0x8130);
    assert_eq!(b.r32(0x1001, 0) & 0x11, 0x11, "0x1001 reflects the fault");
    assert_eq!(b.r32(0x1003, 0), 1, "the active error is in the history");
    assert_eq!(b.r32(0x1003, 1) & 0xFFFF, 0x8130);
    // 0x1016 is back to its default (no monitoring): the fault reset clears everything
    assert_eq!(fault_reset(&mut b), vec![0x0000]);
    assert_eq!(b.r32(0x1001, 0), 0);
}
