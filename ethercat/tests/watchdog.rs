//! The process-data watchdog (SM2's): outputs that stop in OP take the slave to SAFE-OP with
//! AL status 0x001B, and the drive reacts as 0x6007 says (0 none, 1 fault, 2 disable
//! voltage, 3 quick stop) with EMCY 0x8250 over CoE; the master acknowledges, goes back to
//! OP, resets the fault (controlword bit 7) and enables the drive again.
mod common;
use common::*;
use drive_protocol::Cia402State;

/// The CoE emergencies waiting in the slave's mailbox, their error codes.
fn emergencies(m: &mut Master) -> Vec<u16> {
    let mut codes = Vec::new();
    while let Some((kind, b)) = m.mbx_receive(0) {
        if kind == 3 && b[1] >> 4 == 1 {
            codes.push(u16::from_le_bytes([b[2], b[3]]));
        }
    }
    codes
}

fn enable(m: &mut Master, image: usize) {
    for cw in [0x80, 0x00, 0x06, 0x07, 0x0F] {
        let mut v = vec![0u8; image];
        v[..6].copy_from_slice(&outputs(cw, 0));
        for _ in 0..3 {
            let (_, wkc) = m.lrw(&v);
            assert_eq!(wkc, 3);
        }
    }
    assert_eq!(
        m.seg.slaves[0].node().cia402_state(),
        Cia402State::OperationEnabled
    );
}

#[test]
fn outputs_lost_in_op_safe_op_0x001b_and_the_0x6007_reaction() {
    for (option, want) in [
        (1i16, Cia402State::Fault),
        (2, Cia402State::SwitchOnDisabled),
        (3, Cia402State::QuickStopActive),
        (0, Cia402State::OperationEnabled),
    ] {
        let (mut m, o, i) = op(1);
        m.sdo_write(0, 0x6060, 0, false, &[8]).unwrap();
        m.sdo_write(0, 0x6007, 0, false, &option.to_le_bytes())
            .unwrap();
        enable(&mut m, o + i);
        emergencies(&mut m);
        // the master stops: drive cycles go on (1 ms each), no process data for 150 ms
        for _ in 0..150 {
            m.cycle();
        }
        let st = m.fprd16(Master::station(0), 0x0130);
        assert_eq!(st, 0x14, "0x6007={option}: SAFE-OP with the error flag");
        assert_eq!(m.al_code(0), 0x001B, "SM watchdog");
        let state = m.seg.slaves[0].node().cia402_state();
        // a quick stop may already have ended in SWITCH ON DISABLED (0x605A)
        let ok = state == want || (option == 3 && state == Cia402State::SwitchOnDisabled);
        assert!(ok, "0x6007={option}: {state:?}, want {want:?}");
        assert!(
            emergencies(&mut m).contains(&0x8250),
            "0x6007={option}: EMCY 0x8250 over CoE"
        );
        if option == 1 {
            assert_eq!(
                m.sdo_read(0, 0x603F, 0, false).unwrap(),
                0x8250u16.to_le_bytes()
            );
        }
        // acknowledge, OP again (the watchdog starts over), fault reset, enable
        assert_eq!(m.request(0, 0x14), 0x04, "acknowledged");
        assert_eq!(m.lrw(&vec![0; o + i]).1, 3);
        assert_eq!(m.request(0, 0x08), 0x08, "0x6007={option}: OP again");
        enable(&mut m, o + i);
        assert_eq!(m.al_code(0), 0);
        assert_eq!(m.seg.slaves[0].watchdog_expiries, 1);
    }
}

#[test]
fn no_watchdog_while_the_outputs_keep_coming() {
    let (mut m, o, i) = op(1);
    enable(&mut m, o + i);
    let mut v = vec![0u8; o + i];
    v[..6].copy_from_slice(&outputs(0x0F, 0));
    for _ in 0..500 {
        assert_eq!(m.lrw(&v).1, 3);
    }
    assert_eq!(m.fprd16(Master::station(0), 0x0130), 0x08);
    assert_eq!(m.seg.slaves[0].watchdog_expiries, 0);
}
