//! NMT slave: boot-up, state changes, broadcast, resets.
mod common;
use common::*;
use drive_protocol::{Cia402State, FrameEvent, NmtState, NodeConfig};

#[test]
fn boot_up_message_and_pre_operational() {
    let mut node = drive_protocol::Node::new(NodeConfig::new(9, info())).unwrap();
    assert_eq!(node.nmt_state(), NmtState::Initialising);
    node.boot(0);
    let f = node.pop_tx().unwrap();
    assert_eq!((f.id, f.len, f.data[0]), (0x709, 1, 0x00));
    assert_eq!(node.nmt_state(), NmtState::PreOperational);
    assert!(drive_protocol::Node::new(NodeConfig::new(0, info())).is_err());
    assert!(drive_protocol::Node::new(NodeConfig::new(128, info())).is_err());
}

#[test]
fn start_stop_pre_operational_and_broadcast() {
    let mut b = Bench::new();
    b.nmt(0x01, ID);
    assert_eq!(b.node.nmt_state(), NmtState::Operational);
    b.nmt(0x02, 0); // broadcast stop
    assert_eq!(b.node.nmt_state(), NmtState::Stopped);
    // no SDO in stopped
    assert!(b.sdo_raw([0x40, 0, 0x10, 0, 0, 0, 0, 0]).is_empty());
    b.nmt(0x80, ID);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    // other nodes' commands are ignored
    assert_eq!(b.nmt(0x01, ID + 1), FrameEvent::Ignored);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    // unknown command specifier and short frames are ignored
    assert_eq!(b.nmt(0x55, ID), FrameEvent::Ignored);
    assert_eq!(b.send(f(0, &[0x01])), FrameEvent::Ignored);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
}

#[test]
fn pdos_only_in_operational() {
    let mut b = Bench::new();
    b.take();
    b.sync();
    b.tick();
    assert!(
        b.take()
            .iter()
            .all(|f| !(0x180..0x500).contains(&(f.id & !0x7F))),
        "no TPDO in pre-op"
    );
    b.send(f(0x200 + ID as u32, &[0x06, 0]));
    assert_eq!(b.r32(0x6040, 0), 0, "RPDO ignored in pre-op");
    b.start();
    b.send(f(0x200 + ID as u32, &[0x06, 0]));
    assert_eq!(b.r32(0x6040, 0), 6, "RPDO1 applied in operational");
    b.take();
    b.sync();
    let tx = b.take();
    assert!(
        tx.iter().any(|f| f.id == 0x280 + ID as u32),
        "TPDO2 on SYNC"
    );
}

#[test]
fn reset_communication_and_reset_node() {
    let mut b = Bench::new();
    b.start();
    b.w16(0x1017, 0, 100).unwrap();
    b.w32(0x6081, 0, 777).unwrap();
    b.enable(1);
    b.take();
    b.nmt(0x82, ID);
    let tx = b.take();
    assert!(
        tx.iter()
            .any(|f| f.id == 0x700 + ID as u32 && f.data[0] == 0),
        "boot-up after reset comm"
    );
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    assert_eq!(b.r32(0x1017, 0), 0, "communication objects reset");
    assert_eq!(b.r32(0x6081, 0), 777, "application objects kept");
    assert_eq!(
        b.node.cia402_state(),
        Cia402State::OperationEnabled,
        "drive state kept"
    );
    b.take();
    b.nmt(0x81, 0);
    assert!(b
        .take()
        .iter()
        .any(|f| f.id == 0x700 + ID as u32 && f.data[0] == 0));
    assert_ne!(b.r32(0x6081, 0), 777, "reset node resets everything");
    b.tick();
    assert_eq!(b.node.cia402_state(), Cia402State::SwitchOnDisabled);
}

#[test]
fn frames_for_other_nodes_and_extended_ids_are_ignored() {
    let mut b = Bench::new();
    b.take();
    let mut ext = f(0x600 + ID as u32, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]);
    ext.extended = true;
    assert_eq!(b.send(ext), FrameEvent::Ignored);
    assert_eq!(
        b.send(f(0x600 + ID as u32 + 1, &[0x40, 0, 0x10, 0, 0, 0, 0, 0])),
        FrameEvent::Ignored
    );
    assert!(b.take().is_empty());
}

#[test]
fn two_nodes_share_a_bus() {
    let mut a = Bench::with_id(3);
    let mut b = Bench::with_id(4);
    a.take();
    b.take();
    for fr in [
        f(0, &[0x01, 0]),
        f(0x603, &[0x40, 0x18, 0x10, 4, 0, 0, 0, 0]),
    ] {
        a.send(fr);
        b.send(fr);
    }
    assert_eq!(a.node.nmt_state(), NmtState::Operational);
    assert_eq!(b.node.nmt_state(), NmtState::Operational);
    let ta = a.take();
    assert_eq!(ta.len(), 1);
    assert_eq!((ta[0].id, ta[0].data[4]), (0x583, 3));
    assert!(b.take().is_empty(), "node 4 ignores node 3's SDO");
}

#[test]
fn full_tx_queue_is_counted_not_fatal() {
    let mut node = drive_protocol::Node::new(NodeConfig::new(ID, info())).unwrap();
    let mut drive = SimDrive::default();
    node.boot(0);
    for _ in 0..200 {
        node.handle(
            &f(0x600 + ID as u32, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]),
            0,
            &mut drive,
        );
    }
    assert_eq!(node.tx_pending(), drive_protocol::TX_QUEUE);
    assert_eq!(node.tx_overflows(), 201 - drive_protocol::TX_QUEUE as u32);
    while node.pop_tx().is_some() {}
    node.poll(1000, &mut drive);
}

/// With a boot delay the node is silent and deaf from power-on or a reset until the delay
/// has passed, then sends its boot-up: a master that sends the reset and only then starts
/// waiting for the boot-up (python canopen's `wait_for_bootup`) sees it.
#[test]
fn boot_delay_holds_the_boot_up_after_power_on_and_resets() {
    for delay_us in [1_000u64, 150_000, 300_000] {
        let mut b = Bench::with_boot_delay(delay_us);
        assert_eq!(b.node.boot_delay_us(), delay_us);
        for (what, cs) in [
            ("power-on", 0u8),
            ("reset node", 0x81),
            ("reset communication", 0x82),
        ] {
            b.take();
            let t0 = b.now;
            if cs == 0 {
                let cfg = NodeConfig::new(ID, info()).with_boot_delay_us(delay_us);
                b.node = drive_protocol::Node::new(cfg).unwrap();
                b.node.boot(t0);
            } else {
                b.nmt(cs, ID);
            }
            assert!(b.node.boot_pending(), "{what}: boot pending");
            assert_eq!(b.node.nmt_state(), NmtState::Initialising, "{what}");
            // deaf meanwhile: no SDO answer, no NMT start, no heartbeat
            assert!(b.sdo_raw([0x2B, 0x17, 0x10, 0, 10, 0, 0, 0]).is_empty());
            b.start();
            b.run_until(t0 + delay_us - 1);
            let early = b.take();
            assert!(
                early.is_empty(),
                "{what}, {delay_us} us: sent {early:?} while booting"
            );
            assert_eq!(b.node.nmt_state(), NmtState::Initialising, "{what}");
            b.run_until(t0 + delay_us + 2 * DT_US);
            let tx = b.take();
            let boot_ups: Vec<_> = tx.iter().filter(|f| f.id == 0x700 + ID as u32).collect();
            assert_eq!(boot_ups.len(), 1, "{what}, {delay_us} us: {tx:?}");
            assert_eq!(boot_ups[0].data[0], 0, "{what}: boot-up, not a heartbeat");
            assert_eq!(b.node.nmt_state(), NmtState::PreOperational, "{what}");
            assert_eq!(
                b.r32(0x1017, 0),
                0,
                "{what}: the write while booting was ignored"
            );
        }
    }
}

/// A lock-step runtime whose clock stands still completes the boot itself; SYNCs during the
/// delay are reported (time goes on) but not processed.
#[test]
fn finish_boot_completes_a_pending_boot_at_once() {
    let mut b = Bench::with_boot_delay(200_000);
    b.take();
    b.nmt(0x82, ID);
    assert_eq!(b.sync(), FrameEvent::Sync { counter: None });
    assert!(b.take().is_empty());
    b.node.finish_boot(b.now);
    let tx = b.take();
    assert_eq!(tx.len(), 1, "{tx:?}");
    assert_eq!((tx[0].id, tx[0].data[0]), (0x700 + ID as u32, 0));
    assert!(!b.node.boot_pending());
    // nothing pending: a no-op
    b.node.finish_boot(b.now);
    assert!(b.take().is_empty());
}

/// Reset communication keeps the application: an enabled drive stays enabled through the
/// boot delay (only the communication restarts), reset node disables it.
#[test]
fn reset_communication_keeps_the_drive_enabled_during_the_boot_delay() {
    let mut b = Bench::with_boot_delay(100_000);
    b.start();
    b.enable(1);
    assert_eq!(b.node.cia402_state(), Cia402State::OperationEnabled);
    b.nmt(0x82, ID);
    b.run_until(b.now + 50_000);
    assert_eq!(b.node.cia402_state(), Cia402State::OperationEnabled);
    b.run_until(b.now + 100_000);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    assert_eq!(b.node.cia402_state(), Cia402State::OperationEnabled);
    b.nmt(0x81, ID);
    b.run_until(b.now + 150_000);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    assert_ne!(b.node.cia402_state(), Cia402State::OperationEnabled);
}

/// NMT module control is exactly two bytes (CiA 301): longer frames are not commands.
#[test]
fn nmt_frames_of_other_lengths_are_ignored() {
    let mut b = Bench::new();
    for len in [3usize, 4, 8] {
        let mut d = [0u8; 8];
        d[0] = 0x81;
        d[1] = ID;
        assert_eq!(b.send(f(0, &d[..len])), FrameEvent::Ignored, "{len} bytes");
        assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    }
    assert_eq!(b.nmt(0x01, ID), FrameEvent::Handled);
}
