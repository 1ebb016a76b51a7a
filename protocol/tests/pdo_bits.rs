//! Bit-granular PDO mapping (issue 33, SEVCON's Gen4): on a device of granularity 1 a BOOLEAN
//! maps in 1 bit, and a device's own default map may map fewer bits of an object than it has;
//! the values then sit at continuous bit positions, LSB first (CiA 301), the PDO is its bits
//! rounded up to whole bytes, at most 64 bits on CAN. File: tests/eds/minimal/bit-pdo-map.eds.
mod common;
use common::*;
use drive_protocol::od::eds_parse::{decode_text, parse, EdsFile};
use drive_protocol::od::{BuildReport, ObjectDictionary};
use drive_protocol::NodeConfig;
use proptest::prelude::*;
use std::path::Path;

fn load() -> EdsFile {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/eds/minimal/bit-pdo-map.eds");
    parse(&decode_text(&std::fs::read(&p).unwrap())).unwrap()
}

fn bench(f: &EdsFile) -> (Bench, BuildReport) {
    let (od, report) = ObjectDictionary::from_eds(f, &info()).unwrap();
    (
        Bench::with_config(NodeConfig::new(ID, info()).with_od(od)),
        report,
    )
}

/// The objects of the file: BOOLEAN 0x2000+k, UNSIGNED8 0x2010+k, INTEGER16 0x2020+k,
/// UNSIGNED32 0x2030+k; (base, bits).
const KINDS: [(u16, u32); 4] = [(0x2000, 1), (0x2010, 8), (0x2020, 16), (0x2030, 32)];

/// `fields` (bits, value) packed from bit 0, LSB first: the reference the drive must match.
fn reference(fields: &[(u32, u64)]) -> Vec<u8> {
    let mut acc = 0u128;
    let mut pos = 0;
    for &(n, v) in fields {
        acc |= u128::from(v & ((1u64 << n) - 1)) << pos;
        pos += n;
    }
    acc.to_le_bytes()[..pos.div_ceil(8) as usize].to_vec()
}

/// Map `entries` in RPDO1 and TPDO1 (as a master remaps: invalid, count 0, entries, count,
/// valid).
fn remap(b: &mut Bench, entries: &[u32]) -> Result<(), u32> {
    for (comm, map, base) in [(0x1400u16, 0x1600u16, 0x200u32), (0x1800, 0x1A00, 0x180)] {
        let cob = base + u32::from(ID);
        b.w32(comm, 1, cob | 0x8000_0000)?;
        b.w8(map, 0, 0)?;
        for (k, e) in entries.iter().enumerate() {
            b.w32(map, k as u8 + 1, *e)?;
        }
        b.w8(map, 0, entries.len() as u8)?;
        b.w32(comm, 1, cob)?;
    }
    Ok(())
}

/// The RPDO1 frame `data` is applied, and the TPDO1 of the next SYNC sends it back.
fn loop_back(b: &mut Bench, data: &[u8]) -> Vec<u8> {
    b.send(f(0x200 + u32::from(ID), data));
    b.take();
    b.sync();
    let t = b.sent(0x180 + u32::from(ID));
    assert_eq!(t.len(), 1, "{t:?}");
    t[0].data[..t[0].len as usize].to_vec()
}

#[test]
fn the_default_map_carries_booleans_in_one_bit_each_and_the_next_values_at_bit_positions() {
    let (mut b, report) = bench(&load());
    assert!(
        !report
            .notes
            .iter()
            .any(|n| n.contains("cannot be mapped") || n.contains("maps 1 of the 8 bits")),
        "granularity 1: a 1-bit BOOLEAN maps by the rule, no note: {:?}",
        report.notes
    );
    b.start();
    // 1, 0, -2 (INTEGER16 at bit 2), 0x89ABCDEF (UNSIGNED32 at bit 18): 50 bits, 7 bytes;
    // the frame's 6 bits after them set, which the drive ignores
    let fields = [(1, 1), (1, 0), (16, 0xFFFE), (32, 0x89AB_CDEF)];
    let mut data = reference(&fields);
    assert_eq!(data.len(), 7);
    data[6] |= 0xFC;
    let back = loop_back(&mut b, &data);
    assert_eq!(b.sdo_read(0x2000, 0).unwrap(), vec![1]);
    assert_eq!(b.sdo_read(0x2001, 0).unwrap(), vec![0]);
    assert_eq!(
        b.sdo_read(0x2020, 0).unwrap(),
        (-2i16).to_le_bytes().to_vec()
    );
    assert_eq!(
        b.sdo_read(0x2030, 0).unwrap(),
        0x89AB_CDEFu32.to_le_bytes().to_vec()
    );
    assert_eq!(
        back,
        reference(&fields),
        "the TPDO's bits after the values are 0"
    );
    assert_eq!(back[6] & 0xFC, 0);
    // a frame one byte short of the 50 bits is not applied
    let other = reference(&[(1, 0), (1, 1), (16, 7), (32, 9)]);
    b.send(f(0x200 + u32::from(ID), &other[..6]));
    b.tick();
    assert_eq!(b.sdo_read(0x2000, 0).unwrap(), vec![1]);
    assert_eq!(
        b.sdo_read(0x2030, 0).unwrap(),
        0x89AB_CDEFu32.to_le_bytes().to_vec()
    );
    // the whole frame is
    b.send(f(0x200 + u32::from(ID), &other));
    b.tick();
    assert_eq!(b.sdo_read(0x2001, 0).unwrap(), vec![1]);
    assert_eq!(b.sdo_read(0x2030, 0).unwrap(), 9u32.to_le_bytes().to_vec());
}

#[test]
fn more_than_64_bits_are_refused_and_64_are_taken() {
    let (mut b, _) = bench(&load());
    assert_eq!(
        remap(&mut b, &[0x2030_0020, 0x2031_0020, 0x2000_0001]),
        Err(0x0604_0042)
    );
    let (mut b, _) = bench(&load());
    let entries: Vec<u32> = (0..8)
        .map(|k| 0x2000_0001 + (k << 16))
        .chain([0x2030_0020, 0x2020_0010, 0x2010_0008])
        .take(8)
        .collect();
    // 8 BOOLEANs: 8 bits, one byte
    remap(&mut b, &entries).unwrap();
    b.start();
    let data = [0b1010_0101u8];
    assert_eq!(loop_back(&mut b, &data), data.to_vec());
    for k in 0..8u16 {
        let want = (data[0] >> k) & 1;
        assert_eq!(
            b.sdo_read(0x2000 + k, 0).unwrap(),
            vec![want],
            "0x{:04X}",
            0x2000 + k
        );
    }
    let (mut b, _) = bench(&load());
    // 1 + 7 x 8 + ... : 1 bit, then UNSIGNED32, INTEGER16, UNSIGNED8 and 7 bits: 64 bits
    let entries = [
        0x2000_0001,
        0x2030_0020,
        0x2020_0010,
        0x2010_0008,
        0x2001_0001,
        0x2002_0001,
        0x2003_0001,
        0x2004_0001,
    ];
    remap(&mut b, &entries).unwrap();
}

#[test]
fn a_bit_entry_is_taken_where_the_file_allows_it_only() {
    // granularity 1: a 1-bit BOOLEAN anywhere; a BOOLEAN of 2 bits, or 8 bits of an
    // UNSIGNED32 its default map does not ship, are refused
    let (mut b, _) = bench(&load());
    remap(&mut b, &[0x2005_0001]).unwrap();
    for bad in [0x2005_0002u32, 0x2031_0008, 0x2021_0001] {
        let (mut b, _) = bench(&load());
        assert_eq!(remap(&mut b, &[bad]), Err(0x0604_0041), "0x{bad:08X}");
    }
    // the same file saying granularity 8: the 1-bit entries of its own default map are
    // taken (shipped, said in the notes), another 1-bit BOOLEAN is refused, 8 bits are taken
    let mut f = load();
    f.device_info.granularity = Some(8);
    let (mut b, report) = bench(&f);
    for entry in [0x2000_0001u32, 0x2001_0001] {
        assert!(
            report.notes.iter().any(|n| n.starts_with("RPDO1")
                && n.contains(&format!("0x{entry:08X} maps 1 of the 8 bits"))
                && n.contains("the value's low bit, at a bit position")),
            "{entry:08X}: {:?}",
            report.notes
        );
    }
    remap(&mut b, &[0x2000_0001, 0x2001_0001, 0x2020_0010]).unwrap();
    let (mut b, _) = bench(&f);
    assert_eq!(remap(&mut b, &[0x2005_0001]), Err(0x0604_0041));
    let (mut b, _) = bench(&f);
    remap(&mut b, &[0x2005_0008]).unwrap();
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// A sweep of layouts: up to 8 entries of any of the four kinds in any order (at most 64
    /// bits), random values: an RPDO packed by the reference is unpacked into the objects
    /// (SDO reads them back) and the TPDO of the same map packs what the reference packs.
    #[test]
    fn an_rpdo_unpacked_and_a_tpdo_packed_give_the_values_back(
        layout in prop::collection::vec((0usize..4, any::<u64>()), 1..=8),
    ) {
        let mut total = 0;
        let layout: Vec<(usize, u64)> = layout
            .into_iter()
            .take_while(|(kind, _)| {
                total += KINDS[*kind].1;
                total <= 64
            })
            .collect();
        let entries: Vec<u32> = layout
            .iter()
            .enumerate()
            .map(|(k, (kind, _))| {
                let (base, bits) = KINDS[*kind];
                (u32::from(base) + k as u32) << 16 | bits
            })
            .collect();
        let fields: Vec<(u32, u64)> =
            layout.iter().map(|(kind, v)| (KINDS[*kind].1, *v)).collect();
        let (mut b, _) = bench(&load());
        remap(&mut b, &entries).unwrap();
        b.start();
        let data = reference(&fields);
        let back = loop_back(&mut b, &data);
        for (k, (kind, v)) in layout.iter().enumerate() {
            let (base, bits) = KINDS[*kind];
            let index = base + k as u16;
            let size = (bits as usize).div_ceil(8);
            let want = (v & ((1u64 << bits) - 1)).to_le_bytes()[..size].to_vec();
            prop_assert_eq!(b.sdo_read(index, 0).unwrap(), want, "0x{:04X}", index);
        }
        prop_assert_eq!(back, data);
    }
}
