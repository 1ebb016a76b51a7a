//! A tiny master (tests/common) walks what SOEM does against a segment of emulated slaves:
//! config_init (count, station addresses, SII identity), mailbox set-up and PRE-OP, CoE SDO
//! (expedited, normal, segmented, complete access, aborts, SDO information), PDO mapping,
//! SAFE-OP / OP with the working counters of a real line, a CSP move through the process
//! data, and the AL status codes of refused transitions.
mod common;
use common::*;
use drive_ethercat::AlState;
use drive_protocol::wire::sdo::abort;

#[test]
fn config_init_counts_addresses_and_reads_identity_from_sii() {
    let mut m = Master::new(3);
    assert_eq!(
        m.config_init(),
        3,
        "BRD working counter = slaves on the line"
    );
    // an auto-increment datagram comes back with ADP counted up once per slave
    let r = m
        .frame(&[(1, Master::addr(0xFFFF, 0x0010), &[0, 0])])
        .remove(0);
    assert_eq!((r.address & 0xFFFF, r.wkc), (2, 1), "APRD of position 1");
    assert_eq!(r.data, (NODE_OFFSET + 2).to_le_bytes());
    for k in 0..3 {
        let st = Master::station(k);
        let node = m.seg.slaves[k].node();
        let want: Vec<u32> = (1..=4)
            .map(|s| node.object_raw(0x1018, s).unwrap())
            .collect();
        let got = [
            m.eeprom32(st, 0x0008),
            m.eeprom32(st, 0x000A),
            m.eeprom32(st, 0x000C),
            m.eeprom32(st, 0x000E),
        ];
        assert_eq!(got.to_vec(), want, "SII identity of slave {k} = 0x1018");
        // mailbox offsets and sizes, CoE
        let mb = m.eeprom(st, 0x0018);
        assert_eq!(mb, [0x00, 0x10, 128, 0, 0x80, 0x10, 128, 0]);
        assert_eq!(m.eeprom(st, 0x001C)[0..2], [0x04, 0x00]);
        // ESC: type, FMMU / SM counts, DC, AL INIT, DL status communication on port 0
        let (t, _) = m.fprd(st, 0x0000, 8);
        assert_eq!((t[4], t[5]), (3, 4));
        assert_eq!(m.fprd16(st, 0x0008) & 0x04, 0x04);
        assert_eq!(m.fprd16(st, 0x0130), 1);
        assert_eq!(m.fprd16(st, 0x0012), 0);
    }
    // a configured-address datagram to nobody: no working counter
    assert_eq!(m.fprd(0x0999, 0x0130, 2).1, 0);
    // broadcast read ORs: AL status INIT of three slaves
    assert_eq!(m.brd(0x0130, 2), (vec![1, 0], 3));
}

#[test]
fn sii_categories_describe_the_slave() {
    let mut m = Master::new(1);
    m.config_init();
    let st = Master::station(0);
    let sii = m.seg.slaves[0].sii().to_vec();
    // what the master reads word by word is the image
    for w in (0..sii.len()).step_by(4) {
        let d = m.eeprom(st, w as u16);
        for k in 0..4 {
            let got = u16::from_le_bytes([d[2 * k], d[2 * k + 1]]);
            assert_eq!(got, *sii.get(w + k).unwrap_or(&0xFFFF));
        }
    }
    use drive_ethercat::sii::{category, find};
    let (g, _) = find(&sii, category::GENERAL).unwrap();
    assert_eq!(
        sii[g + 2] >> 8,
        0x2F,
        "CoE details: SDO, info, assign, config, CA"
    );
    let (s, len) = find(&sii, category::SYNCM).unwrap();
    assert_eq!(len, 16, "four sync managers");
    assert_eq!(sii[s + 4..s + 6], [0x1080, 128]);
    assert_eq!(sii[s + 9], 6, "SM2 outputs: controlword + target position");
    assert_eq!(sii[s + 13], 6, "SM3 inputs: statusword + position actual");
    let (p, _) = find(&sii, category::RXPDO).unwrap();
    assert_eq!(sii[p], 0x1601);
    let (p, _) = find(&sii, category::TXPDO).unwrap();
    assert_eq!(sii[p], 0x1A01);
    assert!(find(&sii, category::STRINGS).is_some());
    assert!(find(&sii, category::FMMU).is_some());
    assert_eq!(
        drive_ethercat::sii::crc8(
            &sii[..7]
                .iter()
                .flat_map(|w| w.to_le_bytes())
                .collect::<Vec<_>>()
        ),
        sii[7] as u8
    );
}

#[test]
fn coe_sdo_read_write_and_aborts() {
    let mut m = preop(2);
    for k in 0..2 {
        let id = m.sdo_read(k, 0x1018, 1, false).unwrap();
        let want = m.seg.slaves[k].node().object_raw(0x1018, 1).unwrap();
        assert_eq!(id, want.to_le_bytes());
        assert_eq!(
            m.sdo_read(k, 0x1018, 4, false).unwrap(),
            m.eeprom(Master::station(k), 0x0E)[..4]
        );
    }
    m.sdo_write(1, 0x607A, 0, false, &(-4321i32).to_le_bytes())
        .unwrap();
    assert_eq!(
        m.sdo_read(1, 0x607A, 0, false).unwrap(),
        (-4321i32).to_le_bytes()
    );
    assert_eq!(
        m.sdo_read(0, 0x607A, 0, false).unwrap(),
        0i32.to_le_bytes(),
        "the other slave's own"
    );
    // aborts with their CiA 301 codes
    assert_eq!(
        m.sdo_read(0, 0x2FFF, 0, false),
        Err(SdoError::Abort(abort::NO_OBJECT))
    );
    assert_eq!(
        m.sdo_read(0, 0x1018, 9, false),
        Err(SdoError::Abort(abort::NO_SUB))
    );
    assert_eq!(
        m.sdo_write(0, 0x2FFF, 0, false, &[1]),
        Err(SdoError::Abort(abort::NO_OBJECT))
    );
    assert_eq!(
        m.sdo_write(0, 0x6041, 0, false, &[1, 0]),
        Err(SdoError::Abort(abort::READ_ONLY))
    );
    assert_eq!(
        m.sdo_write(0, 0x6060, 0, false, &[99]),
        Err(SdoError::Abort(abort::VALUE_RANGE))
    );
    // the slave still answers after the aborts
    assert_eq!(m.sdo_read(0, 0x6060, 0, false).unwrap(), [0]);
}

#[test]
fn coe_normal_and_segmented_transfers() {
    let mut m = preop(1);
    let text = m.sdo_read(0, LONG_INDEX, 0, false).unwrap();
    assert_eq!(text.len(), 300, "segmented upload");
    assert_eq!(&text[..3], b"abc");
    let name = m.sdo_read(0, 0x1008, 0, false).unwrap();
    let mut buf = [0u8; 64];
    let mut d = TestDrive::default();
    let n = m.seg.slaves[0]
        .node_mut()
        .read_object(0x1008, 0, &mut buf, &mut d)
        .unwrap();
    assert_eq!(name, buf[..n]);
    let new: Vec<u8> = (0..250u32).map(|k| b'A' + (k % 26) as u8).collect();
    m.sdo_write(0, LONG_INDEX, 0, false, &new).unwrap();
    assert_eq!(m.sdo_read(0, LONG_INDEX, 0, false).unwrap(), new);
    let short = b"hello world".to_vec();
    m.sdo_write(0, LONG_INDEX, 0, false, &short).unwrap();
    assert_eq!(m.sdo_read(0, LONG_INDEX, 0, false).unwrap(), short);
    // too long for the object: refused before any data moves
    let huge = vec![b'x'; 500];
    assert_eq!(
        m.sdo_write(0, LONG_INDEX, 0, false, &huge),
        Err(SdoError::Abort(abort::TOO_LONG))
    );
}

#[test]
fn complete_access_of_the_pdo_assignment() {
    let mut m = preop(1);
    let v = m.sdo_read(0, 0x1C12, 0, true).unwrap();
    assert_eq!(
        &v[..4],
        &[1, 0, 0x01, 0x16],
        "sub 0 as 16 bits, then 0x1601"
    );
    let v = m.sdo_read(0, 0x1C13, 0, true).unwrap();
    assert_eq!(&v[..4], &[1, 0, 0x01, 0x1A]);
    // written in PRE-OP as SOEM / pysoem do: count, entries
    m.sdo_write(0, 0x1C12, 0, true, &[2, 0, 0x01, 0x16, 0x00, 0x16])
        .unwrap();
    assert_eq!(
        &m.sdo_read(0, 0x1C12, 0, true).unwrap()[..6],
        &[2, 0, 0x01, 0x16, 0x00, 0x16]
    );
    assert_eq!(m.sdo_read(0, 0x1C12, 0, false).unwrap(), [2]);
    // an entry that is no RxPDO mapping: refused with the limit's code; nothing is lost
    assert_eq!(
        m.sdo_write(0, 0x1C12, 0, true, &[2, 0, 0x02, 0x16, 0x00, 0x60]),
        Err(SdoError::Abort(abort::VALUE_HIGH))
    );
    assert_eq!(
        &m.sdo_read(0, 0x1C12, 0, true).unwrap()[..6],
        &[2, 0, 0x01, 0x16, 0x00, 0x16]
    );
    // complete access to a missing object
    assert_eq!(
        m.sdo_read(0, 0x2FFF, 0, true),
        Err(SdoError::Abort(abort::NO_OBJECT))
    );
    // the mapping itself over complete access: count, then 32-bit entries
    let map = m.sdo_read(0, 0x1601, 0, true).unwrap();
    assert_eq!(
        &map[..10],
        &[2, 0, 0x10, 0x00, 0x40, 0x60, 0x20, 0x00, 0x7A, 0x60]
    );
}

#[test]
fn sdo_information_lists_and_describes_objects() {
    let mut m = preop(1);
    let list = m.od_list(0, 1);
    let want = m.seg.slaves[0].node().od().indices();
    assert!(want.len() > 60, "several fragments");
    assert_eq!(list, want);
    // entry description of the statusword
    m.mbx_send(0, 3, &[0x00, 0x80, 0x05, 0, 0, 0, 0x41, 0x60, 0, 0]);
    let (_, b) = m.mbx_receive(0).unwrap();
    assert_eq!(b[2], 0x06);
    assert_eq!(u16::from_le_bytes([b[10], b[11]]), 0x0006, "UNSIGNED16");
    assert_eq!(u16::from_le_bytes([b[12], b[13]]), 16);
    assert_eq!(
        u16::from_le_bytes([b[14], b[15]]) & 0x87,
        0x87,
        "readable, TxPDO"
    );
    assert_eq!(&b[16..], b"Statusword");
    // object description of 0x1018 (record, 4 subs)
    m.mbx_send(0, 3, &[0x00, 0x80, 0x03, 0, 0, 0, 0x18, 0x10]);
    let (_, b) = m.mbx_receive(0).unwrap();
    assert_eq!((b[2], b[10], b[11]), (0x04, 4, 9));
    // a missing object: an SDO information error with the abort code
    m.mbx_send(0, 3, &[0x00, 0x80, 0x03, 0, 0, 0, 0xFF, 0x2F]);
    let (_, b) = m.mbx_receive(0).unwrap();
    assert_eq!(b[2], 0x07);
    assert_eq!(
        u32::from_le_bytes([b[6], b[7], b[8], b[9]]),
        abort::NO_OBJECT
    );
}

#[test]
fn mailbox_errors_for_unknown_protocols_and_garbage() {
    let mut m = preop(1);
    m.mbx_send(0, 5, &[1, 2, 3, 4]); // FoE: not supported
    let (kind, b) = m.mbx_receive(0).unwrap();
    assert_eq!((kind, u16::from_le_bytes([b[2], b[3]])), (0, 0x0002));
    // a header whose length runs past the mailbox
    let st = Master::station(0);
    let mut raw = vec![0u8; MBX];
    raw[0..2].copy_from_slice(&500u16.to_le_bytes());
    raw[5] = 0x03 | 0x70;
    assert_eq!(m.fpwr(st, 0x1000, &raw), 1);
    let (kind, b) = m.mbx_receive(0).unwrap();
    assert_eq!((kind, u16::from_le_bytes([b[2], b[3]])), (0, 0x0005));
    // a write into a full mailbox is refused (no working counter) until the slave reads it:
    // the slave reads at once, so write twice in one frame to the SM1 area instead
    assert_eq!(
        m.fpwr(st, 0x1080, &[0; MBX]),
        0,
        "SM1 is the slave's: master writes refused"
    );
    assert!(m.sdo_read(0, 0x1018, 1, false).is_ok());
}

#[test]
fn op_with_working_counter_and_a_csp_move() {
    let n = 3;
    let (mut m, o, i) = op(n);
    for k in 0..n {
        m.sdo_write(k, 0x6060, 0, false, &[8]).unwrap();
    }
    let image = |cw: u16, target: &dyn Fn(usize) -> i32| {
        let mut v = vec![0u8; o + i];
        for k in 0..n {
            v[6 * k..6 * k + 6].copy_from_slice(&outputs(cw, target(k)));
        }
        v
    };
    for cw in [0x06, 0x07, 0x0F] {
        let (_, wkc) = m.lrw(&image(cw, &|_| 0));
        assert_eq!(wkc, 3 * n as u16);
    }
    for k in 0..n {
        assert_eq!(
            m.seg.slaves[k].node().cia402_state(),
            drive_protocol::Cia402State::OperationEnabled
        );
    }
    // each slave its own target: 100 um per slave number, ramped
    let mut last = Vec::new();
    for step in 1..=400 {
        let (back, wkc) = m.lrw(&image(0x0F, &|k| {
            (k as i32 + 1) * step.min(100 * (k as i32 + 1))
        }));
        assert_eq!(wkc, 3 * n as u16, "working counter every cycle");
        last = back;
    }
    for k in 0..n {
        let at = o + 6 * k;
        let sw = u16::from_le_bytes([last[at], last[at + 1]]);
        let pos = i32::from_le_bytes([last[at + 2], last[at + 3], last[at + 4], last[at + 5]]);
        assert_eq!(sw & 0x6F, 0x27, "operation enabled in the inputs");
        let want = 100 * (k as i32 + 1) * (k as i32 + 1);
        assert!(
            (pos - want).abs() <= 2,
            "slave {k}: 0x6064 {pos}, target {want}"
        );
        assert_eq!(pos, m.seg.slaves[k].node().position_actual());
    }
    // LRD reads the inputs only (+1 per slave), LWR writes the outputs only (+1 per slave)
    assert_eq!(m.one(10, 0, &vec![0; o + i]).1, n as u16);
    assert_eq!(m.one(11, 0, &vec![0; o + i]).1, n as u16);
}

#[test]
fn refused_transitions_carry_al_status_codes() {
    let mut m = Master::new(1);
    m.config_init();
    // INIT -> OP directly: invalid requested state change
    assert_eq!(m.request(0, 0x08), 0x11, "INIT with the error flag");
    assert_eq!(m.al_code(0), 0x0011);
    // without the acknowledge bit nothing happens while the error stands
    assert_eq!(m.request(0, 0x02), 0x11);
    // PRE-OP with the mailbox SMs not set: invalid mailbox configuration
    assert_eq!(m.request(0, 0x12), 0x11);
    assert_eq!(m.al_code(0), 0x0016);
    // SM0 of the wrong length
    let st = Master::station(0);
    m.fpwr(
        st,
        0x0800,
        &[
            0x00, 0x10, 64, 0, 0x26, 0, 1, 0, 0x80, 0x10, 128, 0, 0x22, 0, 1, 0,
        ],
    );
    assert_eq!(m.request(0, 0x12), 0x11);
    assert_eq!(m.al_code(0), 0x0016);
    // acknowledged, with the mailbox as the SII says: PRE-OP
    assert_eq!(m.go_preop(0), 0x02);
    assert_eq!(m.al_code(0), 0);
    // SAFE-OP with SM2 of the wrong length: invalid output configuration
    m.map_pdos(0, 0, 6);
    m.fpwr(st, 0x0812, &4u16.to_le_bytes());
    assert_eq!(m.request(0, 0x04), 0x12);
    assert_eq!(m.al_code(0), 0x001D);
    m.fpwr(st, 0x0812, &6u16.to_le_bytes());
    // SM3 wrong: invalid input configuration
    m.fpwr(st, 0x081A, &2u16.to_le_bytes());
    assert_eq!(m.request(0, 0x14), 0x12);
    assert_eq!(m.al_code(0), 0x001E);
    m.fpwr(st, 0x081A, &6u16.to_le_bytes());
    assert_eq!(m.request(0, 0x14), 0x04);
    // PDO assignment is written in PRE-OP only
    assert_eq!(
        m.sdo_write(0, 0x1C12, 0, false, &[0]),
        Err(SdoError::Abort(abort::DEVICE_STATE))
    );
    m.lrw(&[0; 12]);
    assert_eq!(m.request(0, 0x08), 0x08);
    // outputs stop: the SM watchdog (100 ms) takes the slave to SAFE-OP with 0x001B
    for _ in 0..150 {
        m.cycle();
    }
    assert_eq!(m.seg.slaves[0].al_state(), AlState::SafeOp);
    assert_eq!(m.fprd16(st, 0x0130), 0x14);
    assert_eq!(m.al_code(0), 0x001B);
    // back to INIT always works (acknowledged)
    assert_eq!(m.request(0, 0x11), 0x01);
    // SAFE-OP from INIT: invalid
    assert_eq!(m.request(0, 0x04), 0x11);
    assert_eq!(m.al_code(0), 0x0011);
    // an unknown state
    assert_eq!(m.request(0, 0x17), 0x11);
    assert_eq!(m.al_code(0), 0x0012);
    // BOOT from INIT and back
    assert_eq!(m.request(0, 0x13), 0x03);
    assert_eq!(m.request(0, 0x01), 0x01);
}

#[test]
fn drive_emergency_becomes_a_coe_emergency() {
    let (mut m, o, i) = op(1);
    m.drives[0].fault = Some(0x7300);
    m.lrw(&vec![0; o + i]);
    let mut found = None;
    while let Some((kind, b)) = m.mbx_receive(0) {
        if kind == 3 && b[1] >> 4 == 1 {
            found = Some(b);
        }
    }
    let b = found.expect("a CoE emergency");
    assert_eq!(u16::from_le_bytes([b[2], b[3]]), 0x7300);
}

#[test]
fn dc_registers_answer_as_a_master_configures_them() {
    let mut m = preop(2);
    // BWR 0x0900 latches the receive times of every slave
    assert_eq!(m.bwr(0x0900, &[0; 4]), 2);
    let st = Master::station(1);
    let (t, w) = m.fprd(st, 0x0918, 8);
    assert_eq!(w, 1);
    assert!(u64::from_le_bytes(t.try_into().unwrap()) > 0);
    // the offset written shows in the system time
    m.fpwr(st, 0x0920, &1_000_000_000u64.to_le_bytes());
    let (t, _) = m.fprd(st, 0x0910, 8);
    assert!(u64::from_le_bytes(t.try_into().unwrap()) > 1_000_000_000);
    // ARMW: the first slave reads its time, the others are written: wkc = slaves
    let r = m.frame(&[(13, Master::addr(0, 0x0910), &[0; 8])]).remove(0);
    assert_eq!(r.wkc, 2);
    // SYNC0 cycle and activation are registers the master reads back
    m.fpwr(st, 0x09A0, &1_000_000u32.to_le_bytes());
    m.fpwr(st, 0x0981, &[3]);
    assert_eq!(m.fprd(st, 0x09A0, 4).0, 1_000_000u32.to_le_bytes());
    assert_eq!(m.fprd(st, 0x0981, 1).0, [3]);
}

#[test]
fn a_corrupted_frame_counts_in_each_slaves_rx_error_counters_and_a_write_clears_them() {
    let mut m = Master::new(3);
    assert_eq!(m.config_init(), 3);
    for _ in 0..4 {
        m.seg.frame_corrupted();
    }
    // the first slave saw a bad frame check sequence; the others got it marked as such
    let counters: Vec<(u8, u8)> = (0..3)
        .map(|k| {
            let (d, wkc) = m.fprd(Master::station(k), 0x0300, 12);
            assert_eq!(wkc, 1);
            (d[0], d[8])
        })
        .collect();
    assert_eq!(counters, [(4, 0), (0, 4), (0, 4)]);
    // a master clears them with a write (BWR to every slave, as diagnostics tools do)
    assert_eq!(m.bwr(0x0300, &[0]), 3);
    let (d, _) = m.fprd(Master::station(1), 0x0300, 12);
    assert_eq!(d, [0u8; 12]);
}
