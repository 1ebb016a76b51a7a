//! The object dictionary as a value: what a vendor's dictionary brings beyond the standard
//! objects reaches the bus as its entries say (long strings and DOMAINs through segmented
//! transfers, 24- and 64-bit integers with their limits and in PDOs, dummy entries in RPDOs),
//! a standard object the dictionary lacks is out of reach but still simulated, 0x6502 decides
//! which modes 0x6060 accepts, and the SDO buffer grows with the largest value.
mod common;
use common::*;
use drive_protocol::od::{Access, DataType, DefaultValue, Entry, ObjectDictionary};
use drive_protocol::{Cia402State, NodeConfig};

/// Segmented download of `data`; the abort code if refused.
fn write_segmented(b: &mut Bench, index: u16, sub: u8, data: &[u8]) -> Result<(), u32> {
    let i = index.to_le_bytes();
    let n = (data.len() as u32).to_le_bytes();
    let r = b.sdo_raw([0x21, i[0], i[1], sub, n[0], n[1], n[2], n[3]]);
    let abort = |d: [u8; 8]| u32::from_le_bytes([d[4], d[5], d[6], d[7]]);
    if r[0].data[0] == 0x80 {
        return Err(abort(r[0].data));
    }
    let mut toggle = 0u8;
    let chunks: Vec<&[u8]> = data.chunks(7).collect();
    for (k, c) in chunks.iter().enumerate() {
        let last = k + 1 == chunks.len();
        let mut req = [0u8; 8];
        req[0] = toggle | (((7 - c.len()) as u8) << 1) | u8::from(last);
        req[1..1 + c.len()].copy_from_slice(c);
        let r = b.sdo_raw(req);
        if r[0].data[0] == 0x80 {
            return Err(abort(r[0].data));
        }
        assert_eq!(r[0].data[0], 0x20 | toggle, "segment acknowledged");
        toggle ^= 0x10;
    }
    Ok(())
}

fn vendor_od() -> ObjectDictionary {
    let mut od = ObjectDictionary::standard(&info());
    for e in [
        Entry::var(0x2010, "Axis name", DataType::VisibleString, Access::Rw)
            .with_default(DefaultValue::Bytes(b"X axis".to_vec()))
            .with_capacity(100),
        Entry::var(0x2011, "Firmware", DataType::Domain, Access::Rw).with_capacity(300),
        Entry::var(0x2012, "Energy counter", DataType::U64, Access::Rw)
            .with_pdo(true)
            .with_default(DefaultValue::Value(0x0102_0304_0506_0708)),
        Entry::var(0x2013, "Trim", DataType::I24, Access::Rww)
            .with_pdo(true)
            .with_limits(Some(-5000), Some(5000)),
        Entry::var(0x2014, "Scale", DataType::Real64, Access::Rw)
            .with_default(DefaultValue::Value(2.5f64.to_bits())),
    ] {
        od.insert(e).unwrap();
    }
    od.device.dummy_usage[5] = true; // UNSIGNED8 dummies
    od
}

#[test]
fn long_values_and_wide_integers_travel_as_their_entries_say() {
    let mut b = Bench::with_config(NodeConfig::new(ID, info()).with_od(vendor_od()));
    assert_eq!(b.sdo_read(0x2010, 0).unwrap(), b"X axis");
    let name = b"a name longer than an expedited transfer carries";
    write_segmented(&mut b, 0x2010, 0, name).unwrap();
    assert_eq!(b.sdo_read(0x2010, 0).unwrap(), name);
    assert_eq!(
        write_segmented(&mut b, 0x2010, 0, &[b'x'; 101]),
        Err(0x0607_0012),
        "longer than the capacity"
    );
    let blob: Vec<u8> = (0..=255u8).chain(0..40).collect();
    write_segmented(&mut b, 0x2011, 0, &blob).unwrap();
    assert_eq!(
        b.sdo_read(0x2011, 0).unwrap(),
        blob,
        "a DOMAIN of 296 bytes"
    );
    assert_eq!(
        b.sdo_read(0x2012, 0).unwrap(),
        0x0102_0304_0506_0708u64.to_le_bytes()
    );
    assert_eq!(b.sdo_read(0x2014, 0).unwrap(), 2.5f64.to_le_bytes());
    // INTEGER24: three bytes, limits as numbers of the type
    b.sdo_write(0x2013, 0, &(-5000i32).to_le_bytes()[..3])
        .unwrap();
    assert_eq!(
        b.sdo_read(0x2013, 0).unwrap(),
        (-5000i32).to_le_bytes()[..3]
    );
    assert_eq!(
        b.sdo_write(0x2013, 0, &(-5001i32).to_le_bytes()[..3]),
        Err(0x0609_0032)
    );
    assert_eq!(b.sdo_write(0x2013, 0, &[0, 0, 0, 0]), Err(0x0607_0012));
}

#[test]
fn a_u64_maps_into_a_tpdo_and_a_dummy_pads_an_rpdo() {
    let mut b = Bench::with_config(NodeConfig::new(ID, info()).with_od(vendor_od()));
    let n = ID as u32;
    // TPDO4 = the 64-bit counter alone
    b.w32(0x1803, 1, 0x8000_0480 + n).unwrap();
    b.w8(0x1A03, 0, 0).unwrap();
    b.w32(0x1A03, 1, 0x2012_0040).unwrap();
    b.w8(0x1A03, 0, 1).unwrap();
    b.w32(0x1803, 1, 0x480 + n).unwrap();
    // RPDO4 = a dummy byte, then the 24-bit trim
    b.w32(0x1403, 1, 0x8000_0500 + n).unwrap();
    b.w8(0x1603, 0, 0).unwrap();
    b.w32(0x1603, 1, 0x0005_0008).unwrap();
    b.w32(0x1603, 2, 0x2013_0018).unwrap();
    b.w8(0x1603, 0, 2).unwrap();
    b.w8(0x1403, 2, 255).unwrap();
    b.w32(0x1403, 1, 0x500 + n).unwrap();
    // a dummy of a type DummyUsage does not allow, or in a TPDO, is not mappable
    b.w32(0x1402, 1, 0x8000_0400 + n).unwrap();
    b.w8(0x1602, 0, 0).unwrap();
    assert_eq!(b.w32(0x1602, 1, 0x0006_0010), Err(0x0604_0041));
    b.w32(0x1802, 1, 0x8000_0380 + n).unwrap();
    b.w8(0x1A02, 0, 0).unwrap();
    assert_eq!(b.w32(0x1A02, 1, 0x0005_0008), Err(0x0604_0041));
    b.start();
    b.take();
    b.sync();
    let tx = b.take();
    let t4: Vec<_> = tx.iter().filter(|f| f.id == 0x480 + n).collect();
    assert_eq!(t4.len(), 1, "{tx:?}");
    assert_eq!(t4[0].len, 8);
    assert_eq!(t4[0].data, 0x0102_0304_0506_0708u64.to_le_bytes());
    b.send(f(0x500 + n, &[0xEE, 0x18, 0xFC, 0xFF])); // dummy 0xEE, trim -1000
    b.tick();
    assert_eq!(
        b.sdo_read(0x2013, 0).unwrap(),
        (-1000i32).to_le_bytes()[..3]
    );
}

/// A standard object the vendor's dictionary does not have is out of reach of SDO and PDO,
/// yet the drive still runs with its standard value (here: the position window in PP).
#[test]
fn a_standard_object_the_dictionary_lacks_is_hidden_but_still_simulated() {
    let mut od = ObjectDictionary::standard(&info());
    assert!(od.remove(0x6067, 0));
    let mut b = Bench::with_config(NodeConfig::new(ID, info()).with_od(od));
    assert_eq!(b.sdo_read(0x6067, 0), Err(0x0602_0000));
    assert_eq!(b.w32(0x6067, 0, 5), Err(0x0602_0000));
    b.w32(0x1A00, 1, 0x6067_0020).unwrap_err();
    b.start();
    b.enable(1);
    b.w32(0x607A, 0, 1000).unwrap();
    b.cw(0x1F);
    b.ticks(2000);
    assert_ne!(
        b.statusword() & 0x0400,
        0,
        "target reached with the hidden window"
    );
}

/// 0x6502 of the dictionary decides: a drive without CST refuses 0x6060 = 10 over SDO and
/// RPDO, and never shows it.
#[test]
fn supported_modes_come_from_0x6502() {
    let mut od = ObjectDictionary::standard(&info());
    od.remove(0x6502, 0);
    od.insert(
        Entry::var(0x6502, "Supported drive modes", DataType::U32, Access::Ro)
            .with_default(DefaultValue::Value(0x1A5)), // PP, PV, HM, CSP, CSV
    )
    .unwrap();
    let mut b = Bench::with_config(NodeConfig::new(ID, info()).with_od(od));
    assert_eq!(b.w8(0x6060, 0, 10), Err(0x0609_0030));
    b.w8(0x6060, 0, 9).unwrap();
    b.start();
    b.enable(9);
    assert_eq!(b.node.cia402_state(), Cia402State::OperationEnabled);
    assert_eq!(b.node.mode(), 9);
}

/// The SDO server's buffer is as large as the largest value: a block download of a large
/// DOMAIN announces a block size that fits it.
#[test]
fn the_transfer_buffer_grows_with_the_largest_value() {
    let mut od = ObjectDictionary::standard(&info());
    od.insert(Entry::var(0x2F00, "Big", DataType::Domain, Access::Rw).with_capacity(4000))
        .unwrap();
    let mut b = Bench::with_config(NodeConfig::new(ID, info()).with_od(od));
    let data: Vec<u8> = (0..3000u32).map(|i| (i * 7) as u8).collect();
    write_segmented(&mut b, 0x2F00, 0, &data).unwrap();
    assert_eq!(b.sdo_read(0x2F00, 0).unwrap(), data);
    // block download initiate: the server's blksize is 127 (its buffer holds 127 segments)
    let r = b.sdo_raw([0xC6, 0x00, 0x2F, 0, 0xB8, 0x0B, 0, 0]);
    assert_eq!(r[0].data[0] & 0xE0, 0xA0, "{:?}", r[0].data);
    assert_eq!(r[0].data[4], 127);
}
