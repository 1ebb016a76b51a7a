//! The LSS slave inside the node (the minimal integration, issue 18 item 4): a node built
//! with node-ID 255 is silent but for LSS, gets its node-ID by LSS and boots with it; a
//! configured node answers LSS in every NMT state; store configuration in memory or handed to
//! the emulator; NMT reset node loads the stored node-ID.
mod common;
use common::*;
use drive_protocol::cia305::LssState;
use drive_protocol::{CanFrame, FrameEvent, LssStore, NmtState, Node, NodeConfig};

const TO_CONFIG: [u8; 8] = [0x04, 0x01, 0, 0, 0, 0, 0, 0];
const TO_WAITING: [u8; 8] = [0x04, 0x00, 0, 0, 0, 0, 0, 0];

struct Lss {
    node: Node,
    drive: SimDrive,
    now: u64,
}

impl Lss {
    fn new(node_id: u8) -> Lss {
        Lss::with(lss_config(node_id, node_id as u32, 0, 0, false))
    }

    fn with(cfg: drive_protocol::NodeConfig) -> Lss {
        let mut node = Node::new(cfg).unwrap();
        node.boot(0);
        Lss {
            node,
            drive: SimDrive::default(),
            now: 0,
        }
    }

    /// Hand a frame to the node; every frame it sends back.
    fn frame(&mut self, f: CanFrame) -> (FrameEvent, Vec<CanFrame>) {
        let ev = self.node.handle(&f, self.now, &mut self.drive);
        let mut out = Vec::new();
        while let Some(f) = self.node.pop_tx() {
            out.push(f);
        }
        (ev, out)
    }

    fn lss(&mut self, bytes: [u8; 8]) -> Vec<CanFrame> {
        let (ev, out) = self.frame(CanFrame::new(0x7E5, &bytes));
        assert_eq!(ev, FrameEvent::Handled);
        out
    }

    /// Poll for `ms` milliseconds, 1 ms per tick; every frame sent.
    fn run_ms(&mut self, ms: u64) -> Vec<CanFrame> {
        let mut out = Vec::new();
        for _ in 0..ms {
            self.now += 1000;
            self.node.poll(self.now, &mut self.drive);
            while let Some(f) = self.node.pop_tx() {
                out.push(f);
            }
        }
        out
    }

    fn sdo_read(&mut self, id: u8, index: u16, sub: u8) -> Vec<CanFrame> {
        let i = index.to_le_bytes();
        self.frame(CanFrame::new(
            0x600 + u32::from(id),
            &[0x40, i[0], i[1], sub, 0, 0, 0, 0],
        ))
        .1
    }
}

fn lss_answer(out: &[CanFrame]) -> Option<[u8; 8]> {
    assert!(out.len() <= 1, "{out:?}");
    out.first().map(|f| {
        assert_eq!((f.id, f.len), (0x7E4, 8));
        f.data
    })
}

#[test]
fn a_non_configured_node_is_silent_but_for_lss() {
    let mut b = Lss::new(255);
    assert_eq!(b.node.node_id(), 255);
    assert_eq!(b.node.nmt_state(), NmtState::Initialising);
    assert!(!b.node.boot_pending());
    // no boot-up, no heartbeat, nothing in a second
    assert!(b.run_ms(1000).is_empty());
    // NMT start (to all and to 255), SDO, SYNC, heartbeat of others: ignored, unanswered
    for f in [
        CanFrame::new(0, &[0x01, 0]),
        CanFrame::new(0, &[0x01, 255]),
        CanFrame::new(0x67F, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]),
        CanFrame::new(0x600 + 5, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]),
        CanFrame::new(0x80, &[]),
        CanFrame::new(0x701, &[0x05]),
    ] {
        assert_eq!(b.frame(f), (FrameEvent::Ignored, vec![]), "{f:?}");
    }
    assert_eq!(b.node.nmt_state(), NmtState::Initialising);
    assert!(b.run_ms(100).is_empty());
    // the drive is kept disabled
    assert!(matches!(
        b.drive.last.as_ref().map(|c| c.setpoint),
        Some(drive_protocol::Setpoint::Disabled)
    ));
    // LSS answers: identify non-configured, fastscan's reset frame
    assert_eq!(
        lss_answer(&b.lss([0x4C, 0, 0, 0, 0, 0, 0, 0])),
        Some([0x50, 0, 0, 0, 0, 0, 0, 0])
    );
    assert_eq!(
        lss_answer(&b.lss([0x51, 0, 0, 0, 0, 0x80, 0, 0])),
        Some([0x4F, 0, 0, 0, 0, 0, 0, 0])
    );
}

#[test]
fn a_node_id_given_by_lss_boots_when_switched_to_waiting_and_serves_sdo_there() {
    let mut b = Lss::new(255);
    assert!(b.lss(TO_CONFIG).is_empty());
    assert_eq!(b.node.lss_state(), Some(LssState::Configuration));
    // the LSS address is 0x1018 (serial number = the power-on $NODEID, 255 here)
    let vendor = lss_answer(&b.lss([0x5A, 0, 0, 0, 0, 0, 0, 0])).unwrap();
    let product = lss_answer(&b.lss([0x5B, 0, 0, 0, 0, 0, 0, 0])).unwrap();
    let serial = lss_answer(&b.lss([0x5D, 0, 0, 0, 0, 0, 0, 0])).unwrap();
    assert_eq!(vendor, [0x5A, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(product, [0x5B, 0x02, 0x04, 0, 0, 0, 0, 0]);
    assert_eq!(serial, [0x5D, 0xFF, 0, 0, 0, 0, 0, 0]);
    assert_eq!(
        lss_answer(&b.lss([0x11, 12, 0, 0, 0, 0, 0, 0])),
        Some([0x11, 0, 0, 0, 0, 0, 0, 0])
    );
    assert_eq!(
        lss_answer(&b.lss([0x17, 0, 0, 0, 0, 0, 0, 0])),
        Some([0x17, 0, 0, 0, 0, 0, 0, 0])
    );
    assert_eq!(b.node.node_id(), 255, "pending until the switch to waiting");
    // back to waiting: NMT reset communication, boot-up on 0x70C
    let out = b.lss(TO_WAITING);
    assert_eq!(out, vec![CanFrame::new(0x70C, &[0x00])]);
    assert_eq!(b.node.node_id(), 12);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    // SDO on 0x60C: 0x1000 and the identity's serial number, unchanged by the new ID
    let r = b.sdo_read(12, 0x1000, 0);
    assert_eq!(r.len(), 1);
    assert_eq!((r[0].id, r[0].data[0]), (0x58C, 0x43));
    let r = b.sdo_read(12, 0x1018, 4);
    assert_eq!(r[0].data, [0x43, 0x18, 0x10, 0x04, 0xFF, 0, 0, 0]);
    // COB-IDs follow the new node-ID: TPDO1 0x18C, EMCY 0x8C
    assert_eq!(b.node.object_raw(0x1800, 1).map(|v| v & 0x7FF), Some(0x18C));
    assert_eq!(b.node.object_raw(0x1014, 0).map(|v| v & 0x7FF), Some(0x8C));
    // and LSS now reports it
    b.lss(TO_CONFIG);
    assert_eq!(
        lss_answer(&b.lss([0x5E, 0, 0, 0, 0, 0, 0, 0])),
        Some([0x5E, 12, 0, 0, 0, 0, 0, 0])
    );
}

#[test]
fn the_lss_boot_waits_the_boot_delay_and_is_deaf_meanwhile() {
    let mut node = Node::new(lss_config(255, 255, 200_000, 0, false)).unwrap();
    node.boot(0);
    let mut b = Lss {
        node,
        drive: SimDrive::default(),
        now: 0,
    };
    // booting: LSS is not served yet
    assert_eq!(
        b.frame(CanFrame::new(0x7E5, &[0x4C, 0, 0, 0, 0, 0, 0, 0])),
        (FrameEvent::Ignored, vec![])
    );
    assert!(b.run_ms(250).is_empty());
    b.lss(TO_CONFIG);
    b.lss([0x11, 7, 0, 0, 0, 0, 0, 0]);
    assert!(b.lss(TO_WAITING).is_empty(), "boot-up after the delay");
    assert!(b.node.boot_pending());
    assert!(b.run_ms(150).is_empty());
    assert_eq!(b.run_ms(100), vec![CanFrame::new(0x707, &[0x00])]);
}

#[test]
fn a_configured_node_answers_lss_in_every_nmt_state() {
    let mut b = Lss::new(5);
    b.run_ms(1);
    let id = [0u32, 0x402, 0x0001_0000, 5];
    let selective = |b: &mut Lss| {
        let mut last = vec![];
        for (k, v) in id.iter().enumerate() {
            let x = v.to_le_bytes();
            last = b.lss([0x40 + k as u8, x[0], x[1], x[2], x[3], 0, 0, 0]);
        }
        last
    };
    for (cmd, state) in [
        (0x80u8, NmtState::PreOperational),
        (0x01, NmtState::Operational),
        (0x02, NmtState::Stopped),
    ] {
        b.frame(CanFrame::new(0, &[cmd, 5]));
        assert_eq!(b.node.nmt_state(), state);
        assert_eq!(
            lss_answer(&selective(&mut b)),
            Some([0x44, 0, 0, 0, 0, 0, 0, 0]),
            "{state:?}"
        );
        assert_eq!(
            lss_answer(&b.lss([0x5E, 0, 0, 0, 0, 0, 0, 0])),
            Some([0x5E, 5, 0, 0, 0, 0, 0, 0])
        );
        // a configured node takes no part in fastscan
        b.lss(TO_WAITING);
        assert!(b.lss([0x51, 0, 0, 0, 0, 0x80, 0, 0]).is_empty());
        assert_eq!(b.node.nmt_state(), state, "LSS leaves the NMT state alone");
    }
    // a new node-ID waits for the master's NMT reset communication
    b.lss(TO_CONFIG);
    b.lss([0x11, 9, 0, 0, 0, 0, 0, 0]);
    assert!(b.lss(TO_WAITING).is_empty());
    assert_eq!(b.node.node_id(), 5);
    assert_eq!(b.node.lss_pending_node_id(), Some(9));
    let (_, out) = b.frame(CanFrame::new(0, &[0x82, 5]));
    assert_eq!(out, vec![CanFrame::new(0x709, &[0x00])]);
    assert_eq!(b.node.node_id(), 9);
    // not stored: an NMT reset node goes back to the stored (power-on) node-ID
    let (_, out) = b.frame(CanFrame::new(0, &[0x81, 9]));
    assert_eq!(out, vec![CanFrame::new(0x705, &[0x00])]);
    assert_eq!(b.node.node_id(), 5);
}

#[test]
fn stored_node_id_survives_reset_node_and_unconfigure_takes_a_broadcast_reset() {
    let mut b = Lss::new(5);
    b.lss(TO_CONFIG);
    b.lss([0x11, 33, 0, 0, 0, 0, 0, 0]);
    b.lss([0x17, 0, 0, 0, 0, 0, 0, 0]);
    b.lss(TO_WAITING);
    b.frame(CanFrame::new(0, &[0x81, 0]));
    assert_eq!(b.node.node_id(), 33);
    // unconfigure: 0xFF pending, reset communication -> silent, LSS only
    b.lss(TO_CONFIG);
    b.lss([0x11, 0xFF, 0, 0, 0, 0, 0, 0]);
    b.lss(TO_WAITING);
    let (_, out) = b.frame(CanFrame::new(0, &[0x82, 33]));
    assert!(out.is_empty(), "no boot-up without a node-ID: {out:?}");
    assert_eq!(b.node.node_id(), 255);
    assert!(b.run_ms(500).is_empty());
    // a broadcast NMT reset node loads the stored 33 again
    let (ev, out) = b.frame(CanFrame::new(0, &[0x81, 0]));
    assert_eq!(ev, FrameEvent::Handled);
    assert_eq!(out, vec![CanFrame::new(0x721, &[0x00])]);
}

#[test]
fn store_configuration_handed_to_the_emulator() {
    let mut b = Lss::with(lss_config(255, 255, 0, 0, true));
    b.lss(TO_CONFIG);
    b.lss([0x11, 12, 0, 0, 0, 0, 0, 0]);
    b.lss([0x13, 0, 2, 0, 0, 0, 0, 0]);
    assert!(
        b.lss([0x17, 0, 0, 0, 0, 0, 0, 0]).is_empty(),
        "answered once written"
    );
    assert_eq!(
        b.node.take_lss_store(),
        Some(LssStore {
            node_id: Some(12),
            bit_timing_index: 2
        })
    );
    assert_eq!(b.node.take_lss_store(), None);
    b.node.lss_store_done(true);
    let mut out = Vec::new();
    while let Some(f) = b.node.pop_tx() {
        out.push(f);
    }
    assert_eq!(lss_answer(&out), Some([0x17, 0, 0, 0, 0, 0, 0, 0]));
    // a failed write: error 2
    b.lss([0x17, 0, 0, 0, 0, 0, 0, 0]);
    assert!(b.node.take_lss_store().is_some());
    b.node.lss_store_done(false);
    assert_eq!(
        b.node.pop_tx().map(|f| f.data),
        Some([0x17, 2, 0, 0, 0, 0, 0, 0])
    );
    // activate bit timing is handed out too
    assert!(b.lss([0x15, 100, 0, 0, 0, 0, 0, 0]).is_empty());
    assert_eq!(b.node.take_lss_bit_timing_activation(), Some((2, 100)));
    assert_eq!(b.node.take_lss_bit_timing_activation(), None);
}

#[test]
fn power_on_values_from_non_volatile_memory() {
    // non-volatile memory says node-ID 40, bit timing 3; the serial number stays the drive's
    let mut node = Node::new(lss_config(40, 255, 0, 3, false)).unwrap();
    for (id, bt) in [(0u8, 3u8), (128, 3), (200, 3), (254, 3)] {
        assert!(
            Node::new(lss_config(id, 255, 0, bt, false)).is_err(),
            "{id}"
        );
    }
    assert_eq!(
        Node::new(lss_config(255, 255, 0, 5, false)).err(),
        Some(drive_protocol::ConfigError::InvalidBitTiming(5))
    );
    node.boot(0);
    let mut b = Lss {
        node,
        drive: SimDrive::default(),
        now: 0,
    };
    assert_eq!(b.node.pop_tx(), Some(CanFrame::new(0x728, &[0])));
    assert_eq!(b.node.node_id(), 40);
    assert_eq!(b.node.object_raw(0x1800, 1).map(|v| v & 0x7FF), Some(0x1A8));
    // the LSS address keeps the power-on serial number (255)
    b.lss(TO_CONFIG);
    assert_eq!(
        lss_answer(&b.lss([0x5D, 0, 0, 0, 0, 0, 0, 0])),
        Some([0x5D, 0xFF, 0, 0, 0, 0, 0, 0])
    );
    // without LSS, 255 is refused too
    let mut no_lss = NodeConfig::new(255, info());
    no_lss.lss = None;
    assert!(Node::new(no_lss).is_err());
}

#[test]
fn the_eds_says_lss_is_supported() {
    let eds = Node::new(NodeConfig::new(5, info()).with_od(od_with_handler()))
        .unwrap()
        .export_eds(
            &mut SimDrive::default(),
            &drive_protocol::od::eds::EdsMeta::default(),
        );
    assert!(eds.contains("\nLSS_Supported=1\n"), "{eds}");
    assert!(!eds.contains("LSS_Supported=0"));
}
