//! A vendor's ESI with its own object dictionary and padding entries
//! (`tests/data/vendor_dictionary.xml`, a small file of our own), served by the sans-IO slave
//! as `--esi` serves it: the objects the drive lacks (a VAR of each direction, a record, an
//! array) answer over CoE with the file's defaults, access and PDO mapping flag; an object of a
//! type the dictionary cannot hold is skipped and said so; objects the drive has stay the
//! drive's; the PDOs' padding entries (`Index` #x0) are gaps in the process data (zeros out,
//! ignored in), read back over CoE as a master sums them, and exported again in the ESI.
mod common;
use common::*;

use drive_ethercat::esi;
use drive_ethercat::{Segment, Slave};
use drive_protocol::NodeConfig;

const FILE: &str = include_str!("data/vendor_dictionary.xml");

fn served() -> Master {
    let dev = esi::parse(FILE).unwrap();
    let mut drive = TestDrive::default();
    let mut cfg = NodeConfig::new(1, info()).with_od(od());
    cfg.lss = None;
    let slave = Slave::with_esi(cfg, &mut drive, &dev).unwrap();
    let mut m = Master {
        seg: Segment::new(vec![slave]),
        drives: vec![drive],
        now_ns: 0,
        counter: 0,
        last_counter: vec![0],
        returned: 0,
    };
    assert_eq!(m.config_init(), 1);
    assert_eq!(m.go_preop(0), 0x02);
    m
}

fn u(v: &[u8]) -> u64 {
    let mut b = [0u8; 8];
    b[..v.len()].copy_from_slice(v);
    u64::from_le_bytes(b)
}

#[test]
fn the_dictionary_is_read_with_what_it_cannot_hold_said() {
    let dev = esi::parse(FILE).unwrap();
    let d = &dev.dictionary;
    let idx: Vec<u16> = d.objects.iter().map(|o| o.index).collect();
    assert_eq!(idx, [0x2001, 0x2002, 0x2003, 0x2004, 0x6040, 0x1C12]);
    assert_eq!(d.skipped.len(), 1, "{:?}", d.skipped);
    let (line, why) = &d.skipped[0];
    assert_eq!(*line, 84, "the <Object> of 0x2005");
    assert!(why.contains("BITARR8"), "{why}");
    let rec = &d.objects[2];
    assert_eq!(rec.subs.len(), 3);
    assert_eq!(rec.subs[2].name, "Offset");
    let arr = &d.objects[3];
    let subs: Vec<u8> = arr.subs.iter().map(|s| s.sub).collect();
    assert_eq!(subs, [0, 1, 2, 3]);
}

#[test]
fn objects_the_drive_lacks_answer_over_coe_with_the_files_defaults_and_access() {
    let mut m = served();
    assert_eq!(u(&m.sdo_read(0, 0x2001, 0, false).unwrap()), 7);
    assert_eq!(u(&m.sdo_read(0, 0x2002, 0, false).unwrap()), 0x1234);
    assert_eq!(
        m.sdo_write(0, 0x2002, 0, false, &[0, 0]),
        Err(SdoError::Abort(0x0601_0002)),
        "read only"
    );
    // the record: sub 0, the gain, the offset (-5, sign-extended), writable
    assert_eq!(u(&m.sdo_read(0, 0x2003, 0, false).unwrap()), 2);
    assert_eq!(u(&m.sdo_read(0, 0x2003, 1, false).unwrap()), 1000);
    let off = m.sdo_read(0, 0x2003, 2, false).unwrap();
    assert_eq!(i32::from_le_bytes(off.try_into().unwrap()), -5);
    m.sdo_write(0, 0x2003, 1, false, &2500u32.to_le_bytes())
        .unwrap();
    assert_eq!(u(&m.sdo_read(0, 0x2003, 1, false).unwrap()), 2500);
    // the array, whole (complete access): count, then 10, 20, 30
    let all = m.sdo_read(0, 0x2004, 0, true).unwrap();
    assert_eq!(all[0], 3);
    let vals: Vec<u16> = all[2..8]
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    assert_eq!(vals, [10, 20, 30]);
    // skipped: not there; the drive's own 0x6040 and the slave's 0x1C12 stay theirs
    assert_eq!(
        m.sdo_read(0, 0x2005, 0, false),
        Err(SdoError::Abort(0x0602_0000))
    );
    let n = m.seg.slaves[0].node();
    let (_, cw) = n.od().get(0x6040, 0).unwrap();
    assert!(!cw.name.contains("vendor"), "{}", cw.name);
    assert_eq!(u(&m.sdo_read(0, 0x1C12, 0, false).unwrap()), 1);
}

#[test]
fn padding_entries_are_gaps_in_the_process_data() {
    let mut m = served();
    // the mapping as a master reads it: the gap's entry is index 0 with its bits
    let map = m.sdo_read(0, 0x1600, 0, true).unwrap();
    assert_eq!(map[0], 3);
    assert_eq!(u(&map[6..10]), 0x0000_0008, "padding of 8 bits");
    let (o, i) = m.map_pdos(0, 0, 4);
    assert_eq!((o, i), (4, 10), "2 + 1 gap + 1 out; 2 + 2 gap + 4 + 2 in");
    assert_eq!(m.request(0, 0x04), 0x04, "SAFE-OP with the gaps");
    let mut image = vec![0u8; o + i];
    m.lrw(&image);
    assert_eq!(m.request(0, 0x08), 0x08, "OP");
    // outputs: controlword 0x0006, a gap byte the slave ignores, 0x2001 = 0x42
    image[..4].copy_from_slice(&[0x06, 0x00, 0xFF, 0x42]);
    let mut back = Vec::new();
    for _ in 0..3 {
        let (r, wkc) = m.lrw(&image);
        assert_eq!(wkc, 3);
        back = r;
    }
    assert_eq!(u(&m.sdo_read(0, 0x2001, 0, false).unwrap()), 0x42);
    let inputs = &back[o..];
    assert_eq!(&inputs[2..4], &[0, 0], "the gap is zeros");
    assert_eq!(
        &inputs[8..10],
        &[0x34, 0x12],
        "0x2002 after the gap and 0x6064"
    );
    // the ESI exported again has the padding entries, and reads back the same
    let xml = m.seg.slaves[0].esi_xml().unwrap();
    assert!(xml.contains("<Index>#x0</Index>\n            <BitLen>16</BitLen>"));
    let again = esi::parse(&xml).unwrap();
    let entries: Vec<(u16, u8)> = again.config.tx_pdos[0]
        .entries
        .iter()
        .map(|e| (e.index, e.bits))
        .collect();
    assert_eq!(entries, [(0x6041, 16), (0, 16), (0x6064, 32), (0x2002, 16)]);
}

#[test]
fn a_padding_of_bits_is_refused_with_its_line() {
    let bad = FILE.replace(
        "<Entry><Index>#x0</Index><BitLen>8</BitLen></Entry>",
        "<Entry><Index>#x0</Index><BitLen>4</BitLen></Entry>",
    );
    let e = esi::parse(&bad).unwrap_err();
    assert_eq!(e.line, 118, "{e}");
    assert!(e.why.contains("whole bytes"), "{e}");
}
