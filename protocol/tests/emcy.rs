//! EMCY producer: frame layout, 0x1001, 0x1003 history, 0x1014, 0x1015 inhibit time.
mod common;
use common::*;

#[test]
fn fault_emcy_register_history_and_reset() {
    let mut b = Bench::new();
    b.start();
    b.take();
    b.drive.fault = Some(0x4310);
    b.tick();
    let e = b.sent(0x80 + ID as u32);
    assert_eq!(e.len(), 1);
    assert_eq!(e[0].len, 8);
    assert_eq!(u16::from_le_bytes([e[0].data[0], e[0].data[1]]), 0x4310);
    assert_eq!(e[0].data[2] & 0x09, 0x09, "generic + temperature");
    assert_eq!(b.r32(0x1001, 0) & 0x09, 0x09);
    assert_eq!(b.r32(0x1003, 0), 1);
    assert_eq!(b.r32(0x1003, 1) & 0xFFFF, 0x4310);
    assert_eq!(b.r32(0x603F, 0), 0x4310);
    // a second error pushes the first down
    b.drive.fault = None;
    b.cw(0x80);
    b.tick();
    b.take();
    b.tick();
    assert_eq!(b.emcys(), vec![]);
    b.w16(0x2101, 0, 0x7300).unwrap();
    b.tick();
    b.w16(0x2101, 0, 0).unwrap();
    assert_eq!(b.r32(0x1003, 0), 2);
    assert_eq!(b.r32(0x1003, 1) & 0xFFFF, 0x7300);
    assert_eq!(b.r32(0x1003, 2) & 0xFFFF, 0x4310);
    // fault reset: EMCY 0x0000, register cleared
    b.cw(0x00);
    b.tick();
    b.take();
    b.cw(0x80);
    b.tick();
    assert_eq!(b.emcys(), vec![0x0000]);
    assert_eq!(b.r32(0x1001, 0), 0);
    // history cleared by writing 0
    b.w8(0x1003, 0, 0).unwrap();
    assert_eq!(b.r32(0x1003, 0), 0);
    assert_eq!(b.r32(0x1003, 1), 0);
}

#[test]
fn inhibit_time_spaces_emcys() {
    let mut b = Bench::new();
    b.w16(0x1015, 0, 100).unwrap(); // 10 ms
    b.start();
    b.take();
    // two wrong-length RPDOs (too short, too long) on different PDOs in one tick
    b.send(f(0x200 + ID as u32, &[1]));
    b.send(f(0x300 + ID as u32, &[6, 0, 0, 0, 0, 0, 0, 0]));
    b.tick();
    assert_eq!(b.emcys().len(), 1, "second EMCY held back");
    b.ticks(5);
    assert_eq!(b.emcys().len(), 1);
    b.ticks(10);
    assert!(b.emcys().len() >= 2);
}

#[test]
fn emcy_cob_id_and_disable() {
    let mut b = Bench::new();
    b.w32(0x1014, 0, 0x8000_0000 | 0x85).unwrap();
    b.start();
    b.take();
    b.drive.fault = Some(0x7300);
    b.tick();
    assert!(
        b.take().iter().all(|f| f.id & 0x780 != 0x080),
        "EMCY disabled by bit 31"
    );
}

#[test]
fn drive_fault_survives_reset_communication_in_0x1001() {
    let mut b = Bench::new();
    b.start();
    b.drive.fault = Some(0x4310);
    b.drive.fault_persists = true;
    b.tick();
    b.tick();
    assert_eq!(b.r32(0x1001, 0) & 0x09, 0x09);
    b.take();
    b.nmt(0x82, ID);
    b.ticks(3);
    assert_eq!(
        b.emcys(),
        vec![],
        "reset communication sends no EMCY for an error already reported"
    );
    assert_eq!(b.node.statusword() & 0x4F, 0x08, "still FAULT");
    assert_eq!(b.r32(0x1001, 0) & 0x09, 0x09, "generic + temperature kept");
    assert_eq!(b.r32(0x1003, 1) & 0xFFFF, 0x4310);
    // the cause persists: a fault reset is refused and nothing clears
    b.cw(0x00);
    b.tick();
    b.cw(0x80);
    b.tick();
    assert!(b.emcys().is_empty(), "{:04X?}", b.emcys());
    assert_eq!(b.node.statusword() & 0x4F, 0x08);
    assert_eq!(b.r32(0x1001, 0) & 0x09, 0x09);
    // cause gone: the next fault reset clears it with one EMCY 0x0000
    b.drive.fault_persists = false;
    b.drive.fault = None;
    b.cw(0x00);
    b.tick();
    b.cw(0x80);
    b.tick();
    assert_eq!(b.emcys(), vec![0x0000]);
    assert_eq!(b.r32(0x1001, 0), 0);
}

#[test]
fn restricted_can_ids_are_refused_for_the_emcy_cob_id() {
    // The case: EMCY on COB-ID 0 is an NMT command to every node.
    let mut b = Bench::new();
    for bad in [
        0x000u32, 0x001, 0x07F, 0x101, 0x180, 0x585, 0x605, 0x6E0, 0x705, 0x7FF,
    ] {
        assert_eq!(b.w32(0x1014, 0, bad), Err(0x0609_0030), "{bad:#05x}");
    }
    assert_eq!(b.w32(0x1014, 0, 0x2000_0085), Err(0x0609_0030), "29-bit");
    assert_eq!(b.r32(0x1014, 0), 0x85, "unchanged");
    // a valid ID outside the ranges is taken; an invalid EMCY (bit 31) may hold any ID
    b.w32(0x1014, 0, 0x0FF).unwrap();
    b.w32(0x1014, 0, 0x8000_0000).unwrap();
    b.w32(0x1014, 0, 0x85).unwrap();
    b.start();
    b.take();
    b.drive.fault = Some(0x4310);
    b.tick();
    assert!(b.take().iter().any(|f| f.id == 0x85), "EMCY on 0x85");
}
