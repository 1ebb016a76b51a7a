//! Property: any sequence of frames (any ID, DLC 0-8, any bytes, RTR, extended) and time
//! steps never panics, keeps the TX queue bounded, and the node still answers a valid SDO.
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

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

    #[test]
    fn arbitrary_frames_never_break_the_node(frames in proptest::collection::vec(frame_strategy(), 1..200)) {
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
