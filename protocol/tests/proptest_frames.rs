//! Property: any sequence of frames (any ID, DLC 0-8, any bytes, RTR, extended; LSS requests
//! with valid command specifiers among them) and time steps never panics, keeps the TX queue
//! bounded, and the node still answers a valid SDO (once given back its node-ID by LSS if the
//! frames changed it).
mod common;
use common::*;
use drive_protocol::{CanFrame, Node};
use proptest::prelude::*;

fn frame_strategy() -> impl Strategy<Value = (CanFrame, u32, bool)> {
    let id = prop_oneof![
        Just(0u32),
        Just(0x80),
        Just(0x600 + ID as u32),
        Just(0x200 + ID as u32),
        Just(0x300 + ID as u32),
        Just(0x180 + ID as u32),
        Just(0x77F),
        Just(0x7E5),
        0u32..0x800,
        any::<u32>(),
    ];
    (
        id,
        any::<bool>(),
        any::<bool>(),
        0u8..=8,
        any::<[u8; 8]>(),
        0u32..20_000,
        any::<bool>(),
    )
        .prop_map(|(id, ext, rtr, len, data, dt, poll)| {
            // bias SDO/NMT bytes toward valid command specifiers
            (
                CanFrame {
                    id,
                    extended: ext && id % 7 == 0,
                    rtr: rtr && id % 5 == 0,
                    len,
                    data,
                },
                dt,
                poll,
            )
        })
}

/// LSS requests (0x7E5) with a defined command specifier and random data, so that the
/// slave's states, node-ID changes and NMT resets are reached.
fn lss_strategy() -> impl Strategy<Value = (CanFrame, u32, bool)> {
    let cs = prop_oneof![
        Just(0x04u8),
        Just(0x11),
        Just(0x13),
        Just(0x15),
        Just(0x17),
        0x40u8..=0x4C,
        Just(0x51),
        0x5Au8..=0x5E,
    ];
    (cs, any::<[u8; 8]>(), 0u8..=8, 0u32..2_000, any::<bool>()).prop_map(
        |(cs, mut data, len, dt, poll)| {
            data[0] = cs;
            // switch modes and node-IDs at and near their valid values
            match cs {
                0x04 => data[1] %= 3,
                0x11 => data[1] = [0, 1, ID, 0x7F, 0x80, 0xFF][usize::from(data[1] % 6)],
                _ => {}
            }
            (
                CanFrame {
                    id: 0x7E5,
                    extended: false,
                    rtr: false,
                    len,
                    data,
                },
                dt,
                poll,
            )
        },
    )
}

/// NMT reset node / communication to all nodes: what makes a node-ID given by LSS active.
fn nmt_reset_strategy() -> impl Strategy<Value = (CanFrame, u32, bool)> {
    (0x81u8..=0x82, 0u32..2_000).prop_map(|(cmd, dt)| (CanFrame::new(0, &[cmd, 0]), dt, true))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

    #[test]
    fn arbitrary_frames_never_break_the_node(frames in proptest::collection::vec(
        prop_oneof![6 => frame_strategy(), 3 => lss_strategy(), 1 => nmt_reset_strategy()],
        1..200)) {
        let mut node = Node::new(drive_protocol::NodeConfig::new(ID, info()).with_od(od_with_handler())).unwrap();
        let mut drive = SimDrive::default();
        let mut now = 0u64;
        node.boot(now);
        for (fr, dt, poll) in frames {
            now += dt as u64;
            let _ = node.handle(&fr, now, &mut drive);
            if poll {
                node.poll(now, &mut drive);
            }
            while node.pop_tx().is_some() {}
        }
        // the frames may have given the node another node-ID (or none) by LSS: the master
        // gives it back by LSS and resets its communication
        if node.node_id() != ID {
            for d in [[0x04, 1, 0, 0, 0, 0, 0, 0], [0x11, ID, 0, 0, 0, 0, 0, 0], [0x04, 0, 0, 0, 0, 0, 0, 0]] {
                node.handle(&CanFrame::new(0x7E5, &d), now, &mut drive);
            }
            node.handle(&CanFrame::new(0, &[0x82, 0]), now, &mut drive);
            node.poll(now, &mut drive);
            prop_assert_eq!(node.node_id(), ID);
        }
        // leave stopped / let any stalled transfer time out
        node.handle(&CanFrame::new(0, &[0x80, ID]), now, &mut drive);
        for _ in 0..3 {
            now += 1_000_000;
            node.poll(now, &mut drive);
        }
        while node.pop_tx().is_some() {}
        let r = node.handle(&CanFrame::new(0x600 + ID as u32, &[0x40, 0x00, 0x10, 0, 0, 0, 0, 0]), now, &mut drive);
        prop_assert_eq!(r, drive_protocol::FrameEvent::Handled);
        let mut got = None;
        while let Some(f) = node.pop_tx() {
            if f.id == 0x580 + ID as u32 { got = Some(f); }
        }
        let f = got.expect("SDO answered");
        prop_assert_eq!(&f.data[..8], &[0x43, 0x00, 0x10, 0, 0x92, 0x01, 0x02, 0x00][..]);
    }
}
