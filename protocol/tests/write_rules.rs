//! One rule per object, whichever way a value comes (issue 29: the services own their write
//! rules). An SDO download, an RPDO frame and a front end's RxPDO image
//! (`Node::apply_rpdo_image`, EtherCAT's path) all pass the rule of the service that owns the
//! object: a value the SDO write refuses is refused by the RPDO too (the object keeps its
//! value, EMCY 0x6320 tells the master), and a value it takes, the RPDO takes.
//!
//! The software position limits 0x607D are not PDO-mappable in the standard dictionary; some
//! vendors' files map them, so the dictionary here does, as an EDS would.

mod common;
use common::*;
use drive_protocol::od::ObjectDictionary;
use drive_protocol::wire::sdo::abort;
use drive_protocol::NodeConfig;

/// The test's dictionary with 0x607D:1 and 0x607D:2 mappable.
fn od_with_mappable_limits() -> ObjectDictionary {
    let mut od = od_with_handler();
    for sub in [1u8, 2] {
        let e = od.get(0x607D, sub).unwrap().1.clone().with_pdo(true);
        assert!(od.remove(0x607D, sub));
        od.insert(e).unwrap();
    }
    od
}

/// RPDO2 (event-driven) carries the controlword and then object (`index`, `sub`) of `bits`.
fn map_rpdo2(b: &mut Bench, index: u16, sub: u8, bits: u8) {
    let cob = 0x300 + b.id();
    b.w32(0x1401, 1, 0x8000_0000 | cob).unwrap();
    b.w8(0x1601, 0, 0).unwrap();
    b.w32(0x1601, 1, 0x6040_0010).unwrap();
    let entry = (u32::from(index) << 16) | (u32::from(sub) << 8) | u32::from(bits);
    b.w32(0x1601, 2, entry).unwrap();
    b.w8(0x1601, 0, 2).unwrap();
    b.w8(0x1401, 2, 255).unwrap();
    b.w32(0x1401, 1, cob).unwrap();
}

/// The object's value as read back by SDO, sign-extended from its `bits`.
fn value(b: &mut Bench, index: u16, sub: u8, bits: u8) -> i64 {
    let raw = b.r32(index, sub);
    match bits {
        8 => i64::from(raw as u8 as i8),
        _ => i64::from(raw as i32),
    }
}

/// The RPDO's bytes: controlword 0 (a CiA 402 "disable voltage" that changes nothing here),
/// then the value in `bits`.
fn image(v: i64, bits: u8) -> Vec<u8> {
    let mut d = vec![0, 0];
    d.extend_from_slice(&v.to_le_bytes()[..bits as usize / 8]);
    d
}

#[test]
fn an_rpdo_value_passes_the_rule_an_sdo_write_passes() {
    let cfg = NodeConfig::new(ID, info()).with_od(od_with_mappable_limits());
    let mut b = Bench::with_config(cfg);
    b.w32(0x607D, 1, (-1000i32) as u32).unwrap();
    b.w32(0x607D, 2, 1000).unwrap();
    // (object, bits, value, what the SDO write answers)
    type Case = (u16, u8, u8, i64, Result<(), u32>);
    let cases: [Case; 7] = [
        (0x607D, 1, 32, 2000, Err(abort::MAX_LT_MIN)), // min above max
        (0x607D, 1, 32, -500, Ok(())),
        (0x607D, 2, 32, -2000, Err(abort::MAX_LT_MIN)), // max below min
        (0x607D, 2, 32, 500, Ok(())),
        (0x6060, 0, 8, 2, Err(abort::VALUE_RANGE)), // velocity mode: not supported
        (0x6060, 0, 8, 11, Err(abort::VALUE_RANGE)), // no such mode
        (0x6060, 0, 8, 8, Ok(())),
    ];
    for (index, sub, bits, v, sdo_expected) in cases {
        let what = format!("0x{index:04X}:{sub} = {v}");
        let before = value(&mut b, index, sub, bits);
        let restore = |b: &mut Bench| {
            let bytes = before.to_le_bytes();
            b.sdo_write(index, sub, &bytes[..bits as usize / 8])
                .unwrap_or_else(|e| panic!("{what}: restoring {before}: {e:#010x}"));
        };
        let taken = sdo_expected.is_ok();

        // 1. an RPDO frame in operational
        b.nmt(0x80, ID);
        map_rpdo2(&mut b, index, sub, bits);
        b.start();
        b.tick();
        b.take();
        b.send(f(0x300 + b.id(), &image(v, bits)));
        b.tick();
        let emcy = b.emcys(); // before an SDO read takes the frames
        let got = value(&mut b, index, sub, bits);
        assert_eq!(got, if taken { v } else { before }, "{what} by RPDO");
        if taken {
            assert!(!emcy.contains(&0x6320), "{what} by RPDO: {emcy:04X?}");
        } else {
            assert_eq!(emcy, vec![0x6320], "{what} by RPDO: EMCY parameter error");
            assert!(b.node.error_active(0x6320), "{what}: held while it lasts");
        }
        restore(&mut b);

        // 2. the front end's RxPDO image (EtherCAT's path): the same rule
        assert_eq!(
            b.node.apply_rpdo_image(0x1601, &image(v, bits)),
            Ok(taken),
            "{what} by RxPDO image"
        );
        let got = value(&mut b, index, sub, bits);
        assert_eq!(got, if taken { v } else { before }, "{what} by image");
        assert_eq!(b.node.error_active(0x6320), !taken, "{what} by image");
        restore(&mut b);

        // 3. an SDO download: the abort code the rule gives
        let bytes = v.to_le_bytes();
        assert_eq!(
            b.sdo_write(index, sub, &bytes[..bits as usize / 8]),
            sdo_expected,
            "{what} by SDO"
        );
        let got = value(&mut b, index, sub, bits);
        assert_eq!(got, if taken { v } else { before }, "{what} by SDO");
        restore(&mut b);
    }
}
