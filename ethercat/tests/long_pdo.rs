//! PDO mappings longer than one CAN frame on the EtherCAT front end: the master writes its
//! own 0x1600 / 0x1A00 in PRE-OP (11 and 13 bytes), assigns them, goes to OP and moves the
//! drive through them; the drive core's mapping limit is the front end's (8 bytes on CAN,
//! the sync manager buffer here), not a second mapping engine.
mod common;
use common::*;
use drive_ethercat::pdo::MAX_IMAGE;
use drive_protocol::{Cia402State, Node, NodeConfig};

/// 0x1600: controlword, target position, target velocity, modes of operation (11 bytes).
const RX: [u32; 4] = [0x6040_0010, 0x607A_0020, 0x60FF_0020, 0x6060_0008];
/// 0x1A00: statusword, position actual, velocity actual, torque actual, modes display
/// (13 bytes).
const TX: [u32; 5] = [
    0x6041_0010,
    0x6064_0020,
    0x606C_0020,
    0x6077_0010,
    0x6061_0008,
];

/// Write mapping `index` and assign it alone in `assign`, in PRE-OP, entry by entry as
/// SOEM's and TwinCAT's start-up lists do.
fn remap(m: &mut Master, k: usize, assign: u16, index: u16, entries: &[u32]) {
    m.sdo_write(k, assign, 0, false, &[0]).unwrap();
    m.sdo_write(k, index, 0, false, &[0]).unwrap();
    for (s, e) in entries.iter().enumerate() {
        m.sdo_write(k, index, s as u8 + 1, false, &e.to_le_bytes())
            .unwrap();
    }
    m.sdo_write(k, index, 0, false, &[entries.len() as u8])
        .unwrap();
    m.sdo_write(k, assign, 1, false, &index.to_le_bytes())
        .unwrap();
    m.sdo_write(k, assign, 0, false, &[1]).unwrap();
}

fn outputs_long(cw: u16, pos: i32, vel: i32, mode: i8) -> Vec<u8> {
    let mut v = cw.to_le_bytes().to_vec();
    v.extend_from_slice(&pos.to_le_bytes());
    v.extend_from_slice(&vel.to_le_bytes());
    v.push(mode as u8);
    v
}

#[test]
fn the_masters_own_long_mapping_in_pre_op_moves_the_drive_in_op() {
    let n = 2;
    let mut m = preop(n);
    for k in 0..n {
        remap(&mut m, k, 0x1C12, 0x1600, &RX);
        remap(&mut m, k, 0x1C13, 0x1A00, &TX);
        // read back as the master's config_map does
        let v = m.sdo_read(k, 0x1600, 0, true).unwrap();
        assert_eq!(v[0], 4);
        assert_eq!(
            u32::from_le_bytes([v[10], v[11], v[12], v[13]]),
            0x60FF_0020
        );
    }
    let (o, i) = (11usize, 13usize);
    for k in 0..n {
        let (so, si) = m.map_pdos(k, (o * k) as u32, (o * n + i * k) as u32);
        assert_eq!((so, si), (o, i), "SM sizes from the master's own mapping");
    }
    for k in 0..n {
        assert_eq!(m.request(k, 0x04), 0x04, "SAFE-OP of slave {k}");
        assert_eq!(m.seg.slaves[k].process_data().unwrap().outputs.len, o);
        assert_eq!(m.seg.slaves[k].process_data().unwrap().inputs.len, i);
    }
    let image = |cw: u16, pos: &dyn Fn(usize) -> i32| {
        let mut v = Vec::new();
        for k in 0..n {
            v.extend(outputs_long(cw, pos(k), 0, 8));
        }
        v.resize(o * n + i * n, 0);
        v
    };
    let (_, wkc) = m.lrw(&image(0, &|_| 0));
    assert_eq!(wkc as usize, 3 * n);
    for k in 0..n {
        assert_eq!(m.request(k, 0x08), 0x08, "OP of slave {k}");
    }
    // the mode comes from the process data (0x6060 in the outputs), then enable
    for cw in [0x06, 0x07, 0x0F] {
        let (_, wkc) = m.lrw(&image(cw, &|_| 0));
        assert_eq!(wkc as usize, 3 * n);
    }
    let mut last = Vec::new();
    for step in 1..=300 {
        let (back, wkc) = m.lrw(&image(0x0F, &|k| (k as i32 + 1) * step.min(200)));
        assert_eq!(wkc as usize, 3 * n, "working counter every cycle");
        last = back;
    }
    for k in 0..n {
        let node = m.seg.slaves[k].node();
        assert_eq!(node.cia402_state(), Cia402State::OperationEnabled);
        assert_eq!(node.object_raw(0x6060, 0), Some(8), "mode from the outputs");
        let at = o * n + i * k;
        let inp = &last[at..at + i];
        let sw = u16::from_le_bytes([inp[0], inp[1]]);
        let pos = i32::from_le_bytes([inp[2], inp[3], inp[4], inp[5]]);
        assert_eq!(sw & 0x6F, 0x27, "operation enabled in the inputs");
        assert_eq!(pos, node.position_actual());
        let want = 200 * (k as i32 + 1);
        assert!(
            (pos - want).abs() <= 2,
            "slave {k}: 0x6064 {pos}, want {want}"
        );
        // the 13th byte: modes of operation display, past what one CAN frame holds
        assert_eq!(inp[12] as i8, 8, "0x6061 in byte 12 of the inputs");
    }
}

#[test]
fn the_can_limit_stays_8_bytes_and_ethercat_takes_more() {
    // the same mapping (3 x 32 bits) on the CAN node: refused, 0x06040042
    let mut d = TestDrive::default();
    let mut cfg = NodeConfig::new(1, info()).with_od(od());
    cfg.lss = None;
    let mut can = Node::new(cfg).unwrap();
    can.boot(0);
    assert_eq!(can.pdo_max_len(), 8);
    let cob = can.object_raw(0x1801, 1).unwrap();
    can.write_object(0x1801, 1, &(cob | 0x8000_0000).to_le_bytes(), &mut d)
        .unwrap();
    can.write_object(0x1A01, 0, &[0], &mut d).unwrap();
    for s in 1..=3u8 {
        can.write_object(0x1A01, s, &0x6064_0020u32.to_le_bytes(), &mut d)
            .unwrap();
    }
    assert_eq!(can.write_object(0x1A01, 0, &[3], &mut d), Err(0x0604_0042));
    assert_eq!(can.pdo_image_len(0x1A01), Ok(0));
    // the front end's limit: 12 bytes pass, the mapping engine is the same
    can.set_pdo_max_len(MAX_IMAGE);
    assert_eq!(can.pdo_max_len(), MAX_IMAGE);
    can.write_object(0x1A01, 0, &[3], &mut d).unwrap();
    assert_eq!(can.pdo_image_len(0x1A01), Ok(12));
    let mut out = [0u8; 16];
    assert_eq!(can.tpdo_image(0x1A01, &mut out), Ok(12));
    assert_eq!(can.tpdo_image(0x1A01, &mut out[..11]), Err(0x0504_0005));
    // the entries still bound it: a ninth entry does not exist
    assert_eq!(can.write_object(0x1A01, 0, &[9], &mut d), Err(0x0609_0031));

    // and on the EtherCAT slave the limit is the sync manager's buffer
    let s = slave(1, &mut d);
    assert_eq!(s.node().pdo_max_len(), MAX_IMAGE);
}

#[test]
fn four_full_txpdos_fill_the_sm_buffer() {
    let mut m = preop(1);
    // four TxPDOs of 8 x 32 bits: 128 bytes, the whole buffer (every TxPDO 0x1C13 can list)
    let long = [0x6064_0020u32; 8];
    for n in 0..4u16 {
        m.sdo_write(0, 0x1A00 + n, 0, false, &[0]).unwrap();
        for (s, v) in long.iter().enumerate() {
            m.sdo_write(0, 0x1A00 + n, s as u8 + 1, false, &v.to_le_bytes())
                .unwrap();
        }
        m.sdo_write(0, 0x1A00 + n, 0, false, &[8]).unwrap();
        assert_eq!(m.seg.slaves[0].node().pdo_image_len(0x1A00 + n), Ok(32));
    }
    m.sdo_write(0, 0x1C13, 0, false, &[0]).unwrap();
    for n in 0..4u16 {
        m.sdo_write(0, 0x1C13, n as u8 + 1, false, &(0x1A00 + n).to_le_bytes())
            .unwrap();
    }
    m.sdo_write(0, 0x1C13, 0, false, &[4]).unwrap();
    let (o, i) = m.map_pdos(0, 0, 64);
    assert_eq!(i, MAX_IMAGE);
    assert_eq!(m.request(0, 0x04), 0x04, "128 bytes of inputs fit");
    assert_eq!(o, 6);
    m.lrw(&vec![0; 64 + i]);
    let (back, wkc) = m.lrw(&vec![0; 64 + i]);
    assert_eq!(wkc, 3);
    // every entry is 0x6064: the last 4 bytes of the image too
    let pos = m.seg.slaves[0].node().position_actual();
    assert_eq!(back[back.len() - 4..], pos.to_le_bytes());
}
