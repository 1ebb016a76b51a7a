//! SDO server: expedited, segmented and block transfers, and every abort code it can give.
mod common;
use common::*;

fn abort_of(r: &[drive_protocol::CanFrame]) -> u32 {
    assert_eq!(r.len(), 1, "one response");
    assert_eq!(r[0].data[0], 0x80, "abort expected, got {:x?}", r[0].data);
    u32::from_le_bytes([r[0].data[4], r[0].data[5], r[0].data[6], r[0].data[7]])
}

#[test]
fn expedited_read_write() {
    let mut b = Bench::new();
    assert_eq!(b.r32(0x1000, 0), 0x0002_0192);
    b.w16(0x1017, 0, 250).unwrap();
    assert_eq!(b.r32(0x1017, 0), 250);
    assert_eq!(b.r32(0x1018, 4), ID as u32, "serial = node id");
    // expedited without size indication writes the object's size
    b.w32(0x6081, 0, 1).unwrap();
    let r = b.sdo_raw([0x22, 0x81, 0x60, 0, 0x34, 0x12, 0, 0]);
    assert_eq!(r[0].data[0], 0x60);
    assert_eq!(b.r32(0x6081, 0), 0x1234);
    // signed values round-trip
    b.w16(0x60B2, 0, (-300i16) as u16).unwrap();
    assert_eq!(b.ri32(0x60B2, 0), -300);
}

#[test]
fn segmented_upload_of_a_string() {
    let mut b = Bench::new();
    let v = b.sdo_read(0x1008, 0).unwrap();
    assert_eq!(String::from_utf8(v).unwrap(), "drive-emulator CiA402 servo");
}

fn seg_download(
    b: &mut Bench,
    index: u16,
    sub: u8,
    data: &[u8],
    size: Option<u32>,
) -> Result<(), u32> {
    let i = index.to_le_bytes();
    let mut req = [0x20 | size.is_some() as u8, i[0], i[1], sub, 0, 0, 0, 0];
    if let Some(s) = size {
        req[4..8].copy_from_slice(&s.to_le_bytes());
    }
    let r = b.sdo_raw(req);
    if r[0].data[0] == 0x80 {
        return Err(abort_of(&r));
    }
    assert_eq!(r[0].data[0], 0x60);
    let mut t = 0u8;
    let chunks: Vec<&[u8]> = data.chunks(7).collect();
    for (k, c) in chunks.iter().enumerate() {
        let last = k + 1 == chunks.len();
        let mut req = [0u8; 8];
        req[0] = t | (((7 - c.len()) as u8) << 1) | last as u8;
        req[1..1 + c.len()].copy_from_slice(c);
        let r = b.sdo_raw(req);
        if r[0].data[0] == 0x80 {
            return Err(abort_of(&r));
        }
        assert_eq!(r[0].data[0], 0x20 | t);
        t ^= 0x10;
    }
    Ok(())
}

#[test]
fn segmented_download() {
    let mut b = Bench::new();
    seg_download(&mut b, 0x607A, 0, &1234567i32.to_le_bytes(), Some(4)).unwrap();
    assert_eq!(b.ri32(0x607A, 0), 1234567);
    // size indicated but data differs: length mismatch
    assert_eq!(
        seg_download(&mut b, 0x607A, 0, &[1, 2, 3, 4, 5, 6, 7, 8], Some(4)),
        Err(0x0607_0010)
    );
    // no size, more data than the object: too long
    assert_eq!(
        seg_download(&mut b, 0x607A, 0, &[1, 2, 3, 4, 5, 6], None),
        Err(0x0607_0012)
    );
    // declared size too small / too big for the object
    assert_eq!(
        seg_download(&mut b, 0x607A, 0, &[1, 2], Some(2)),
        Err(0x0607_0013)
    );
    assert_eq!(
        seg_download(&mut b, 0x607A, 0, &[0; 8], Some(8)),
        Err(0x0607_0012)
    );
    // more data than the server buffer: out of memory
    assert_eq!(
        seg_download(&mut b, 0x607A, 0, &[0; 80], None),
        Err(0x0504_0005)
    );
}

#[test]
fn block_download_with_crc() {
    let mut b = Bench::new();
    let data = 0x0BAD_F00Du32.to_le_bytes();
    let crc = canopen_rs::sdo::block::crc16(&data);
    // initiate: client CRC, size indicated
    let r = b.sdo_raw([0xC6, 0x7A, 0x60, 0, 4, 0, 0, 0]);
    assert_eq!(r[0].data[0] & 0xFB, 0xA0, "initiate response");
    let blksize = r[0].data[4];
    assert!(blksize >= 1);
    let r = b.sdo_raw([0x81, data[0], data[1], data[2], data[3], 0, 0, 0]);
    assert_eq!(&r[0].data[..3], &[0xA2, 1, blksize]);
    // end: 3 unused bytes in the last segment
    let c = crc.to_le_bytes();
    let r = b.sdo_raw([0xC1 | (3 << 2), c[0], c[1], 0, 0, 0, 0, 0]);
    assert_eq!(r[0].data[0], 0xA1);
    assert_eq!(b.r32(0x607A, 0), 0x0BAD_F00D);
}

#[test]
fn block_download_bad_crc_and_bad_sequence() {
    let mut b = Bench::new();
    b.sdo_raw([0xC6, 0x7A, 0x60, 0, 4, 0, 0, 0]);
    b.sdo_raw([0x81, 1, 2, 3, 4, 0, 0, 0]);
    let r = b.sdo_raw([0xC1 | (3 << 2), 0xEE, 0xEE, 0, 0, 0, 0, 0]);
    assert_eq!(abort_of(&r), 0x0504_0004);
    // sequence number 0 is invalid
    b.sdo_raw([0xC6, 0x7A, 0x60, 0, 4, 0, 0, 0]);
    let r = b.sdo_raw([0x00, 1, 2, 3, 4, 0, 0, 0]);
    assert_eq!(abort_of(&r), 0x0504_0003);
}

#[test]
fn block_upload() {
    let mut b = Bench::new();
    let r = b.sdo_raw([0xA4, 0x08, 0x10, 0, 127, 0, 0, 0]);
    assert_eq!(r[0].data[0], 0xC6, "initiate response with CRC and size");
    let size =
        u32::from_le_bytes([r[0].data[4], r[0].data[5], r[0].data[6], r[0].data[7]]) as usize;
    let segs = b.sdo_raw([0xA3, 0, 0, 0, 0, 0, 0, 0]);
    let mut data = Vec::new();
    for (k, s) in segs.iter().enumerate() {
        assert_eq!(s.data[0] & 0x7F, k as u8 + 1);
        data.extend_from_slice(&s.data[1..8]);
    }
    assert!(segs.last().unwrap().data[0] & 0x80 != 0);
    let r = b.sdo_raw([0xA2, segs.len() as u8, 127, 0, 0, 0, 0, 0]);
    assert_eq!(r[0].data[0] & 0xE3, 0xC1);
    let unused = ((r[0].data[0] >> 2) & 7) as usize;
    data.truncate(data.len() - unused);
    assert_eq!(data.len(), size);
    assert_eq!(
        canopen_rs::sdo::block::crc16(&data),
        u16::from_le_bytes([r[0].data[1], r[0].data[2]])
    );
    assert_eq!(
        String::from_utf8(data).unwrap(),
        "drive-emulator CiA402 servo"
    );
    assert!(b.sdo_raw([0xA1, 0, 0, 0, 0, 0, 0, 0]).is_empty());
    // the server is idle again
    assert_eq!(b.r32(0x1000, 0), 0x0002_0192);
}

#[test]
fn block_upload_invalid_block_size() {
    let mut b = Bench::new();
    assert_eq!(
        abort_of(&b.sdo_raw([0xA4, 0x08, 0x10, 0, 0, 0, 0, 0])),
        0x0504_0002
    );
    assert_eq!(
        abort_of(&b.sdo_raw([0xA4, 0x08, 0x10, 0, 128, 0, 0, 0])),
        0x0504_0002
    );
}

#[test]
fn toggle_bit_error() {
    let mut b = Bench::new();
    b.sdo_raw([0x40, 0x08, 0x10, 0, 0, 0, 0, 0]);
    let r = b.sdo_raw([0x70, 0, 0, 0, 0, 0, 0, 0]); // toggle 1 first: wrong
    assert_eq!(abort_of(&r), 0x0503_0000);
}

#[test]
fn timeout_of_a_stalled_transfer() {
    let mut b = Bench::new();
    b.sdo_raw([0x40, 0x08, 0x10, 0, 0, 0, 0, 0]);
    b.run_until(900_000);
    assert!(b.sent(0x580 + ID as u32).is_empty(), "no abort before 1 s");
    b.run_until(1_100_000);
    let r = b
        .take()
        .into_iter()
        .filter(|f| f.id == 0x580 + ID as u32)
        .collect::<Vec<_>>();
    assert_eq!(abort_of(&r), 0x0504_0000);
}

#[test]
fn bad_command_specifier() {
    let mut b = Bench::new();
    assert_eq!(
        abort_of(&b.sdo_raw([0xE0, 0, 0x10, 0, 0, 0, 0, 0])),
        0x0504_0001
    );
    // a segment without a transfer
    assert_eq!(
        abort_of(&b.sdo_raw([0x60, 0, 0, 0, 0, 0, 0, 0])),
        0x0504_0001
    );
    assert_eq!(
        abort_of(&b.sdo_raw([0x00, 0, 0, 0, 0, 0, 0, 0])),
        0x0504_0001
    );
}

#[test]
fn access_and_existence_aborts() {
    let mut b = Bench::new();
    assert_eq!(b.w32(0x1000, 0, 1), Err(0x0601_0002), "write of read-only");
    assert_eq!(
        b.sdo_read(0x2101, 0),
        Err(0x0601_0001),
        "read of write-only"
    );
    assert_eq!(b.sdo_read(0x5555, 0), Err(0x0602_0000));
    assert_eq!(b.sdo_read(0x1018, 9), Err(0x0609_0011));
    assert_eq!(b.w8(0x6081, 0, 1), Err(0x0607_0013), "too short");
    // too long: expedited 4 bytes into a U16
    assert_eq!(b.w32(0x1017, 0, 1), Err(0x0607_0012));
    // mapping entries may not change while the PDO is valid: unsupported access
    assert_eq!(b.w32(0x1A00, 1, 0x6064_0020), Err(0x0601_0000));
}

#[test]
fn value_aborts() {
    let mut b = Bench::new();
    assert_eq!(b.w16(0x605A, 0, 9), Err(0x0609_0031), "above high limit");
    assert_eq!(b.w16(0x605D, 0, 0), Err(0x0609_0032), "below low limit");
    assert_eq!(b.w8(0x6060, 0, 5), Err(0x0609_0030), "unsupported mode");
    assert_eq!(
        b.w8(0x1003, 0, 3),
        Err(0x0609_0030),
        "only 0 clears the history"
    );
    assert_eq!(
        b.w8(0x1800, 2, 245),
        Err(0x0609_0030),
        "reserved transmission type"
    );
    // software limits: max < min
    b.w32(0x607D, 1, 1000).unwrap();
    assert_eq!(b.w32(0x607D, 2, 500), Err(0x0609_0036));
    b.w32(0x607D, 2, 2000).unwrap();
    assert_eq!(b.w32(0x607D, 1, 3000), Err(0x0609_0036));
}

#[test]
fn store_restore_and_device_state() {
    let mut b = Bench::new();
    assert_eq!(
        b.w32(0x1010, 1, 0x1234),
        Err(0x0800_0020),
        "wrong signature"
    );
    assert_eq!(b.w32(0x1011, 1, 0x1234), Err(0x0800_0020));
    b.w16(0x1017, 0, 123).unwrap();
    b.w32(0x1010, 1, 0x6576_6173).unwrap(); // "save"
    b.w16(0x1017, 0, 7).unwrap();
    b.nmt(0x82, ID); // reset communication loads the saved values
    assert_eq!(b.r32(0x1017, 0), 123);
    b.w32(0x1011, 1, 0x6461_6F6C).unwrap(); // "load" defaults at the next reset
    b.nmt(0x81, ID);
    assert_eq!(b.r32(0x1017, 0), 0);
    // 0x1019 may only change while 0x1006 is 0
    b.w32(0x1006, 0, 1000).unwrap();
    assert_eq!(b.w8(0x1019, 0, 10), Err(0x0800_0022));
    b.w32(0x1006, 0, 0).unwrap();
    b.w8(0x1019, 0, 10).unwrap();
}

#[test]
fn heartbeat_consumer_duplicate_is_incompatible() {
    let mut b = Bench::new();
    b.w32(0x1016, 1, (1 << 16) | 100).unwrap();
    assert_eq!(b.w32(0x1016, 2, (1 << 16) | 200), Err(0x0604_0043));
    b.w32(0x1016, 2, (2 << 16) | 200).unwrap();
}

/// An object the drive keeps itself (a handler): SDO reads and writes reach the drive, which
/// applies its own range with its own abort codes; a NaN passes the node (no limits) and the
/// drive refuses it.
#[test]
fn handler_objects_are_read_and_written_by_the_drive() {
    let mut b = Bench::new();
    b.w32(HANDLER_INDEX, 1, 0.5f32.to_bits()).unwrap();
    assert_eq!(b.drive.params[1], 0.5);
    assert_eq!(f32::from_bits(b.r32(HANDLER_INDEX, 1)), 0.5);
    b.drive.params[3] = 0.75;
    assert_eq!(f32::from_bits(b.r32(HANDLER_INDEX, 3)), 0.75);
    assert_eq!(b.w32(HANDLER_INDEX, 2, 2.0f32.to_bits()), Err(0x0609_0031));
    assert_eq!(
        b.w32(HANDLER_INDEX, 2, (-1.0f32).to_bits()),
        Err(0x0609_0032)
    );
    assert_eq!(
        b.w32(HANDLER_INDEX, 2, f32::NAN.to_bits()),
        Err(0x0609_0032)
    );
    assert_eq!(b.drive.params[2], 0.0, "refused values change nothing");
    assert_eq!(
        b.w16(HANDLER_INDEX, 1, 1),
        Err(0x0607_0013),
        "the node checks the size"
    );
    assert_eq!(b.sdo_read(HANDLER_INDEX, 4), Err(0x0609_0011));
}

/// A stored read-only object the application sets (as the emulator publishes its loop
/// statistics): SDO reads see the value, writes are refused.
#[test]
fn application_values_are_set_by_the_application_and_read_only_on_the_bus() {
    use drive_protocol::od::{Access, DataType, Entry, Lookup};
    let mut od = od_with_handler();
    let slot = od
        .insert(Entry::var(0x2300, "ticks", DataType::U32, Access::Ro).with_pdo(true))
        .unwrap();
    let mut b = Bench::with_config(drive_protocol::NodeConfig::new(ID, info()).with_od(od));
    assert_eq!(b.node.od().find(0x2300, 0), Lookup::Found(slot));
    b.node.set_value(slot, 42);
    assert_eq!(b.r32(0x2300, 0), 42);
    assert_eq!(b.node.value(slot), Some(42));
    assert_eq!(b.w32(0x2300, 0, 0), Err(0x0601_0002));
}

#[test]
fn client_abort_resets_the_server_and_short_frames_are_ignored() {
    let mut b = Bench::new();
    b.sdo_raw([0x40, 0x08, 0x10, 0, 0, 0, 0, 0]);
    assert!(b.sdo_raw([0x80, 0x08, 0x10, 0, 0, 0, 0, 0x08]).is_empty());
    let id = 0x600 + b.id();
    b.send(f(id, &[0x40, 0x00, 0x10]));
    assert!(b.take().is_empty(), "DLC < 8 is not an SDO request");
    assert_eq!(b.r32(0x1000, 0), 0x0002_0192);
}
