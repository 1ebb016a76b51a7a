//! The drive core on its own (`DriveCore`: what a front end other than CAN holds) and the
//! CAN front end around it (`Node`): the core's outputs, the frames the node makes of them,
//! and the timer table behind `poll_at`.
mod common;
use common::*;
use drive_protocol::wire::lss::UNCONFIGURED_NODE_ID;
use drive_protocol::{ConfigError, CoreOutput, DriveCore, Node, NodeConfig, Timer};

fn cfg() -> NodeConfig {
    NodeConfig::new(ID, info()).with_od(od_with_handler())
}

fn outputs(core: &mut DriveCore) -> Vec<CoreOutput> {
    std::iter::from_fn(|| core.take_output()).collect()
}

/// Boot, a heartbeat producer of 100 ms, a condition raised: what the core says it has to
/// send, and what the CAN node sends for the same calls.
#[test]
fn the_core_says_what_to_send_and_the_node_frames_it_on_its_cob_ids() {
    let mut drive = SimDrive::default();
    let mut core = DriveCore::new(cfg()).unwrap();
    let mut node = Node::new(cfg()).unwrap();
    core.boot(0);
    node.boot(0);
    assert_eq!(outputs(&mut core), vec![CoreOutput::Bootup]);
    let boot: Vec<_> = std::iter::from_fn(|| node.pop_tx()).collect();
    assert_eq!(boot, vec![f(0x700 + ID as u32, &[0])]);

    let hb_ms = 100u16.to_le_bytes();
    core.write_object(0x1017, 0, &hb_ms, &mut drive).unwrap();
    node.write_object(0x1017, 0, &hb_ms, &mut drive).unwrap();
    core.raise_condition(0xFF01, [1, 2, 3, 4, 5]);
    node.raise_condition(0xFF01, [1, 2, 3, 4, 5]);
    core.poll(100_000, &mut drive);
    node.poll(100_000, &mut drive);
    let out = outputs(&mut core);
    let sent: Vec<_> = std::iter::from_fn(|| node.pop_tx()).collect();
    assert_eq!(out.len(), 2, "{out:?}");
    assert_eq!(out[0], CoreOutput::Heartbeat { state: 0x7F });
    let CoreOutput::Emcy(emcy) = out[1] else {
        panic!("an EMCY, not {:?}", out[1]);
    };
    assert_eq!(emcy[..2], 0xFF01u16.to_le_bytes());
    assert_eq!(emcy[3..], [1, 2, 3, 4, 5]);
    assert_eq!(
        sent,
        vec![f(0x700 + ID as u32, &[0x7F]), f(0x80 + ID as u32, &emcy)]
    );
    assert_eq!(core.tx_overflows(), 0);
    assert_eq!(node.tx_pending(), 0);
}

/// The core alone has no LSS: it needs a node-ID; the CAN node with LSS may start without.
#[test]
fn a_core_alone_needs_a_node_id() {
    let mut c = cfg();
    c.node_id = UNCONFIGURED_NODE_ID;
    assert_eq!(
        DriveCore::new(c.clone()).unwrap_err(),
        ConfigError::InvalidNodeId(UNCONFIGURED_NODE_ID)
    );
    assert!(Node::new(c).is_ok());
}

/// `poll_at` is the earliest slot of the timer table, and the table names the service.
#[test]
fn the_timer_table_names_the_service_due() {
    let mut drive = SimDrive::default();
    let mut node = Node::new(cfg().with_boot_delay_us(5_000)).unwrap();
    node.boot(1_000);
    let t = node.timers();
    assert_eq!(t.earliest(), Some((Timer::Boot, 6_000)));
    for s in Timer::ALL.into_iter().filter(|&s| s != Timer::Boot) {
        assert_eq!(t.get(s), None, "{s:?} armed while initialising");
    }
    assert_eq!(node.poll_at(), Some(6_000));
    node.poll(6_000, &mut drive);
    node.write_object(0x1017, 0, &250u16.to_le_bytes(), &mut drive)
        .unwrap();
    node.poll(7_000, &mut drive);
    let t = node.timers();
    assert_eq!(t.get(Timer::Boot), None);
    let (which, at) = t.earliest().unwrap();
    assert_eq!(which, Timer::HeartbeatProducer);
    assert!(at > 7_000);
    assert_eq!(node.poll_at(), Some(at));
    assert_eq!(node.poll_at_comm(), Some(at));
    assert_eq!(node.core().poll_at(), Some(at));
    // a SYNC not yet processed runs on the application clock: poll_at, not poll_at_comm
    node.handle(&f(0x80, &[]), 7_500, &mut drive);
    let t = node.timers();
    assert_eq!(t.get(Timer::PendingSync), Some(7_500));
    assert_eq!(node.poll_at(), Some(7_500));
    assert_eq!(node.poll_at_comm(), Some(at));
}
