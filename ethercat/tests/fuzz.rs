//! Bad input on the wire: arbitrary bytes as frames, well-framed datagrams with arbitrary
//! commands, addresses and data (a storm of them), and mailbox garbage never panic; the
//! slaves still take a master's configuration and answer a CoE read afterwards.
mod common;
use common::*;
use drive_ethercat::frame;
use proptest::prelude::*;

/// After anything: a master configures the line again and reads 0x1018:1 of every slave.
fn still_answers(m: &mut Master, n: usize) {
    assert_eq!(m.config_init(), n);
    for k in 0..n {
        assert_eq!(m.go_preop(k), 0x02);
        let want = m.seg.slaves[k].node().object_raw(0x1018, 1).unwrap();
        // a reply may still wait in SM1 from the storm: drain it first
        while m.mbx_receive(k).is_some() {}
        assert_eq!(m.sdo_read(k, 0x1018, 1, false).unwrap(), want.to_le_bytes());
    }
}

fn datagram() -> impl Strategy<Value = (u8, u32, Vec<u8>)> {
    (
        0u8..20,
        prop_oneof![
            any::<u32>(),
            // registers of the first slaves, where a storm does harm
            (0u16..4, 0u16..0x1200)
                .prop_map(|(adp, ado)| u32::from(0u16.wrapping_sub(adp)) | u32::from(ado) << 16),
        ],
        proptest::collection::vec(any::<u8>(), 0..160),
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(frames in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..1600), 1..20)) {
        let mut m = Master::new(2);
        for mut f in frames {
            let _ = m.seg.process(&mut f, 1, &mut m.drives);
            // an EtherCAT type and length field on random bytes: the deeper paths
            if f.len() >= 16 {
                f[12] = 0x88;
                f[13] = 0xA4;
                let _ = m.seg.process(&mut f, 2, &mut m.drives);
            }
        }
        still_answers(&mut m, 2);
    }

    #[test]
    fn datagram_storm_never_panics(frames in proptest::collection::vec(proptest::collection::vec(datagram(), 1..12), 1..40)) {
        let mut m = preop(2);
        for dgs in frames {
            let list: Vec<(u8, u8, u32, &[u8])> = dgs.iter().map(|(c, a, d)| (*c, 0, *a, d.as_slice())).collect();
            let mut f = frame::build([1; 6], &list);
            prop_assert!(m.seg.process(&mut f, m.now_ns, &mut m.drives).is_ok());
            m.cycle();
        }
        still_answers(&mut m, 2);
    }

    #[test]
    fn mailbox_garbage_never_panics(bodies in proptest::collection::vec((any::<u8>(), proptest::collection::vec(any::<u8>(), 0..122)), 1..30)) {
        let mut m = preop(1);
        let st = Master::station(0);
        let mut last_counter = 0;
        for (kind, body) in bodies {
            last_counter = (kind >> 4) & 7;
            let mut raw = vec![0u8; MBX];
            raw[0..2].copy_from_slice(&(body.len() as u16).to_le_bytes());
            raw[5] = kind;
            raw[6..6 + body.len()].copy_from_slice(&body);
            m.fpwr(st, 0x1000, &raw);
            // the master reads whatever came back
            while m.mbx_receive(0).is_some() {}
        }
        while m.mbx_receive(0).is_some() {}
        // the next request's counter differs from the last garbage's (else it is a repeat,
        // which a slave rightly ignores)
        m.counter = last_counter;
        let want = m.seg.slaves[0].node().object_raw(0x1018, 1).unwrap();
        prop_assert_eq!(m.sdo_read(0, 0x1018, 1, false).unwrap(), want.to_le_bytes().to_vec());
    }
}

#[test]
fn malformed_frames_are_refused_with_their_reason() {
    use drive_ethercat::frame::FrameError;
    let mut m = Master::new(1);
    let good = frame::build([1; 6], &[(7, 0, 0x0130_0000, &[0, 0])]);
    let run = |m: &mut Master, f: &mut Vec<u8>| m.seg.process(f, 1, &mut m.drives);
    let mut f = good.clone();
    assert!(run(&mut m, &mut f).is_ok());
    let mut f = good[..10].to_vec();
    assert_eq!(run(&mut m, &mut f), Err(FrameError::TooShort));
    let mut f = good.clone();
    f[12] = 0x08;
    f[13] = 0x00;
    assert_eq!(run(&mut m, &mut f), Err(FrameError::NotEtherCat(0x0800)));
    let mut f = good.clone();
    f[15] = (f[15] & 0x0F) | 0x40;
    assert_eq!(run(&mut m, &mut f), Err(FrameError::UnsupportedType(4)));
    let mut f = good.clone();
    f[14] = 0xFF;
    f[15] = 0x17;
    assert_eq!(run(&mut m, &mut f), Err(FrameError::LengthBeyondFrame));
    // a datagram length past the EtherCAT length
    let mut f = good.clone();
    f[16 + 6] = 100;
    assert_eq!(
        run(&mut m, &mut f),
        Err(FrameError::DatagramBeyondLength(16))
    );
    // a "more follows" flag with nothing after it
    let mut f = good.clone();
    f[16 + 7] |= 0x80;
    assert!(matches!(
        run(&mut m, &mut f),
        Err(FrameError::DatagramBeyondLength(_))
    ));
    assert_eq!(
        m.seg.bad_frames, 4,
        "EtherCAT frames refused (the other two are not EtherCAT)"
    );
    // unknown commands pass untouched, working counter 0
    let r = m.frame(&[(0x2A, 0, &[1, 2, 3]), (7, 0x0130_0000, &[0, 0])]);
    assert_eq!((r[0].data.clone(), r[0].wkc), (vec![1, 2, 3], 0));
    assert_eq!(r[1].wkc, 1);
    still_answers(&mut m, 1);
}
