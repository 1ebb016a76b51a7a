//! The drive-core access seam a non-CAN front end uses (EtherCAT CoE): object reads and writes
//! with the SDO rules, PDO images through the mapping objects with the RPDO rules, one drive
//! cycle as a SYNC makes it. Each result is compared with what the CAN path does.
mod common;
use common::*;
use drive_protocol::wire::sdo::abort;
use drive_protocol::{Cia402State, Clocks};

fn read(b: &mut Bench, index: u16, sub: u8) -> Result<Vec<u8>, u32> {
    let mut out = [0u8; 64];
    let n = b.node.read_object(index, sub, &mut out, &mut b.drive)?;
    Ok(out[..n].to_vec())
}

fn write(b: &mut Bench, index: u16, sub: u8, data: &[u8]) -> Result<(), u32> {
    b.node.write_object(index, sub, data, &mut b.drive)
}

#[test]
fn read_object_matches_sdo_upload() {
    let mut b = Bench::new();
    for (index, sub) in [
        (0x1018, 1),
        (0x1018, 4),
        (0x1000, 0),
        (0x6041, 0),
        (0x1008, 0),
    ] {
        assert_eq!(
            read(&mut b, index, sub),
            b.sdo_read(index, sub),
            "0x{index:04X}:{sub}"
        );
    }
    // a value the drive keeps (handler) comes from the drive
    b.drive.params[1] = 0.25;
    assert_eq!(
        read(&mut b, HANDLER_INDEX, 1).unwrap(),
        0.25f32.to_le_bytes()
    );
}

#[test]
fn read_object_aborts() {
    let mut b = Bench::new();
    assert_eq!(read(&mut b, 0x2FFF, 0), Err(abort::NO_OBJECT));
    assert_eq!(read(&mut b, 0x1018, 9), Err(abort::NO_SUB));
    assert_eq!(read(&mut b, 0x2101, 0), Err(abort::WRITE_ONLY));
    // a buffer too short for the value is refused, not cut
    let mut two = [0u8; 2];
    assert_eq!(
        b.node.read_object(0x1018, 1, &mut two, &mut b.drive),
        Err(abort::OUT_OF_MEMORY)
    );
    let mut short = [0u8; 3];
    assert_eq!(
        b.node.read_object(0x1008, 0, &mut short, &mut b.drive),
        Err(abort::OUT_OF_MEMORY),
        "device name longer than 3 bytes"
    );
}

#[test]
fn write_object_takes_sdo_rules() {
    let mut b = Bench::new();
    write(&mut b, 0x607A, 0, &1234i32.to_le_bytes()).unwrap();
    assert_eq!(b.sdo_read(0x607A, 0).unwrap(), 1234i32.to_le_bytes());
    // refusals as an SDO download gets them, and the value stays
    assert_eq!(write(&mut b, 0x2FFF, 0, &[1]), Err(abort::NO_OBJECT));
    assert_eq!(write(&mut b, 0x1018, 9, &[1]), Err(abort::NO_SUB));
    assert_eq!(write(&mut b, 0x6041, 0, &[1, 0]), Err(abort::READ_ONLY));
    assert_eq!(
        write(&mut b, 0x1018, 1, &[1, 0, 0, 0]),
        Err(abort::READ_ONLY)
    );
    assert_eq!(write(&mut b, 0x607A, 0, &[1, 0]), Err(abort::TOO_SHORT));
    assert_eq!(
        write(&mut b, 0x607A, 0, &[1, 0, 0, 0, 0]),
        Err(abort::TOO_LONG)
    );
    // a mode the drive does not support: the drive's rule (the one SDO writes meet)
    assert_eq!(write(&mut b, 0x6060, 0, &[77]), Err(abort::VALUE_RANGE));
    assert_eq!(b.sdo_write(0x6060, 0, &[77]), Err(abort::VALUE_RANGE));
    // the dictionary's limits (0x6007 is 0..=3)
    assert_eq!(
        write(&mut b, 0x6007, 0, &9i16.to_le_bytes()),
        Err(abort::VALUE_HIGH)
    );
    assert_eq!(b.sdo_read(0x607A, 0).unwrap(), 1234i32.to_le_bytes());
    // the drive's own limits on a value it keeps
    assert!(write(&mut b, HANDLER_INDEX, 1, &2.0f32.to_le_bytes()).is_err());
    write(&mut b, HANDLER_INDEX, 1, &0.5f32.to_le_bytes()).unwrap();
    assert_eq!(b.drive.params[1], 0.5);
    // a PDO parameter's rules: mapping of an enabled RPDO is refused
    assert_eq!(
        write(&mut b, 0x1600, 0, &[0]),
        Err(abort::UNSUPPORTED_ACCESS)
    );
    assert_eq!(
        b.node.check_write_object(0x6041, 0, Some(2), &mut b.drive),
        Err(abort::READ_ONLY)
    );
    assert_eq!(
        b.node.check_write_object(0x607A, 0, Some(4), &mut b.drive),
        Ok(())
    );
}

#[test]
fn tpdo_image_packs_the_mapping() {
    let mut b = Bench::new();
    b.drive.pos = INC_PER_UU * 3000.0;
    b.tick();
    // 0x1A01: statusword + position actual, 6 bytes
    let mut out = [0u8; 16];
    assert_eq!(b.node.pdo_image_len(0x1A01), Ok(6));
    let n = b.node.tpdo_image(0x1A01, &mut out).unwrap();
    assert_eq!(n, 6);
    assert_eq!(u16::from_le_bytes([out[0], out[1]]), b.node.statusword());
    assert_eq!(i32::from_le_bytes([out[2], out[3], out[4], out[5]]), 3000);
    // a buffer too short, a mapping that does not exist, an RPDO mapping
    assert_eq!(
        b.node.tpdo_image(0x1A01, &mut out[..5]),
        Err(abort::OUT_OF_MEMORY)
    );
    assert_eq!(b.node.tpdo_image(0x1A40, &mut out), Err(abort::NO_OBJECT));
    assert_eq!(
        b.node.tpdo_image(0x1601, &mut out),
        Err(abort::NOT_MAPPABLE)
    );
    assert_eq!(
        b.node.tpdo_image(0x6041, &mut out),
        Err(abort::NOT_MAPPABLE)
    );
    // remapped (the CAN procedure: PDO off, count 0, entries, count): the image follows,
    // whether or not the PDO is valid on CAN
    write(&mut b, 0x1801, 1, &0x8000_0285u32.to_le_bytes()).unwrap();
    write(&mut b, 0x1A01, 0, &[0]).unwrap();
    write(&mut b, 0x1A01, 1, &0x6064_0020u32.to_le_bytes()).unwrap();
    write(&mut b, 0x1A01, 0, &[1]).unwrap();
    assert_eq!(b.node.tpdo_image(0x1A01, &mut out), Ok(4));
    assert_eq!(i32::from_le_bytes([out[0], out[1], out[2], out[3]]), 3000);
}

#[test]
fn rpdo_image_takes_rpdo_rules() {
    let mut b = Bench::new();
    // 0x1601: controlword + target position
    let mut img = [0u8; 6];
    img[..2].copy_from_slice(&6u16.to_le_bytes());
    img[2..].copy_from_slice(&(-500i32).to_le_bytes());
    assert_eq!(b.node.apply_rpdo_image(0x1601, &img), Ok(true));
    assert_eq!(b.sdo_read(0x6040, 0).unwrap(), 6u16.to_le_bytes());
    assert_eq!(b.sdo_read(0x607A, 0).unwrap(), (-500i32).to_le_bytes());
    // too short: nothing written
    assert_eq!(
        b.node.apply_rpdo_image(0x1601, &[7, 0, 1]),
        Err(abort::TOO_SHORT)
    );
    assert_eq!(b.sdo_read(0x6040, 0).unwrap(), 6u16.to_le_bytes());
    assert_eq!(
        b.node.apply_rpdo_image(0x1A01, &img),
        Err(abort::NOT_MAPPABLE)
    );
    assert_eq!(b.node.apply_rpdo_image(0x1640, &img), Err(abort::NO_OBJECT));
    // a value the drive refuses: the object keeps its value, EMCY 0x6320 held until a good one
    write(&mut b, 0x1600, 0, &[0]).ok();
    write(&mut b, 0x1400, 1, &0x8000_0205u32.to_le_bytes()).unwrap();
    write(&mut b, 0x1600, 0, &[0]).unwrap();
    write(&mut b, 0x1600, 1, &0x6060_0008u32.to_le_bytes()).unwrap();
    write(&mut b, 0x1600, 0, &[1]).unwrap();
    b.take();
    assert_eq!(b.node.apply_rpdo_image(0x1600, &[77]), Ok(false));
    assert!(b.node.error_active(0x6320));
    assert_eq!(b.sdo_read(0x6060, 0).unwrap(), [0]);
    assert_eq!(b.node.apply_rpdo_image(0x1600, &[8]), Ok(true));
    assert!(!b.node.error_active(0x6320));
    assert_eq!(b.sdo_read(0x6060, 0).unwrap(), [8]);
}

#[test]
fn cycle_runs_the_drive_as_sync_does() {
    let mut b = Bench::new();
    let mut t = 0u64;
    let mut cycle = |b: &mut Bench, img: &[u8]| {
        t += DT_US;
        b.node.apply_rpdo_image(0x1601, img).unwrap();
        b.node.cycle(Clocks::same(t), &mut b.drive);
        b.take();
    };
    let cw = |c: u16, p: i32| {
        let mut v = [0u8; 6];
        v[..2].copy_from_slice(&c.to_le_bytes());
        v[2..].copy_from_slice(&p.to_le_bytes());
        v
    };
    write(&mut b, 0x6060, 0, &[8]).unwrap(); // CSP
    let before = b.drive.commands;
    for c in [0x06u16, 0x07, 0x0F] {
        cycle(&mut b, &cw(c, 0));
    }
    assert_eq!(b.drive.commands - before, 3, "one drive command per cycle");
    assert_eq!(b.node.cia402_state(), Cia402State::OperationEnabled);
    // CSP: the target moves 1 um per cycle; the position actual follows
    for k in 1..=400 {
        cycle(&mut b, &cw(0x0F, k));
    }
    for _ in 0..50 {
        cycle(&mut b, &cw(0x0F, 400));
    }
    let pos = b.node.position_actual();
    assert!((pos - 400).abs() <= 2, "position actual {pos}");
    let mut out = [0u8; 8];
    b.node.tpdo_image(0x1A01, &mut out).unwrap();
    assert_eq!(i32::from_le_bytes([out[2], out[3], out[4], out[5]]), pos);
}

#[test]
fn mappings_listed() {
    let b = Bench::new();
    let mut v = Vec::new();
    b.node.for_each_pdo_mapping(|tx, i| v.push((tx, i)));
    assert_eq!(
        v,
        [
            (false, 0x1600),
            (false, 0x1601),
            (false, 0x1602),
            (false, 0x1603),
            (true, 0x1A00),
            (true, 0x1A01),
            (true, 0x1A02),
            (true, 0x1A03)
        ]
    );
}
