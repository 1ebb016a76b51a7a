//! Distributed clocks, sans-IO: SYNC0 configured as SOEM's `ecx_dcsync0` writes it (0x0981
//! off, 0x0910 read, 0x0990 start time, 0x09A0 cycle, 0x0981 = 3), with the offset 0x0920 a
//! master's `config_dc` writes; the SYNC0 times the slave computes from those registers, the
//! DC SYNC0 synchronisation type 0x1C32:1 = 2 accepted at SAFE-OP and refused with AL status
//! 0x0030 when SYNC0 is not active and 0x0036 when its cycle is below 0x1C32:5.
mod common;
use common::*;

const CYCLE_NS: u32 = 1_000_000;
const OFFSET_NS: u64 = 7_123_456_789;

/// `ecx_dcsync0(slave, TRUE, cycle, 0)`: the start time a whole number of cycles, at least
/// 100 ms after the slave's system time now. Returns the start time written.
fn dc_sync0(m: &mut Master, k: usize, cycle_ns: u32) -> u64 {
    let st = Master::station(k);
    assert_eq!(m.fpwr(st, 0x0981, &[0]), 1);
    assert_eq!(m.fpwr(st, 0x0980, &[0]), 1);
    let (t, w) = m.fprd(st, 0x0910, 8);
    assert_eq!(w, 1);
    let t1 = u64::from_le_bytes(t.try_into().unwrap());
    let c = u64::from(cycle_ns);
    let start = (t1 + 100_000_000) / c * c + c;
    assert_eq!(m.fpwr(st, 0x0990, &start.to_le_bytes()), 1);
    assert_eq!(m.fpwr(st, 0x09A0, &cycle_ns.to_le_bytes()), 1);
    assert_eq!(m.fpwr(st, 0x0981, &[3]), 1);
    start
}

/// PRE-OP with the process data mapped, the master's offset written (as config_dc).
fn mapped() -> Master {
    let mut m = preop(1);
    let (o, i) = m.map_pdos(0, 0, 6);
    assert_eq!((o, i), (6, 6));
    assert_eq!(
        m.fpwr(Master::station(0), 0x0920, &OFFSET_NS.to_le_bytes()),
        1
    );
    m
}

#[test]
fn sync0_times_come_from_start_cycle_and_offset() {
    let mut m = mapped();
    m.sdo_write(0, 0x1C32, 1, false, &2u16.to_le_bytes())
        .unwrap();
    let start = dc_sync0(&mut m, 0, CYCLE_NS);
    assert_eq!(m.request(0, 0x04), 0x04, "SAFE-OP with DC SYNC0");
    let s = &m.seg.slaves[0];
    assert!(s.dc_synchronised());
    // the slave's clock is the system time less the offset
    let first_local = start - OFFSET_NS;
    assert_eq!(s.next_sync0_ns(0), Some(first_local));
    assert_eq!(s.next_sync0_ns(first_local), Some(first_local));
    assert_eq!(
        s.next_sync0_ns(first_local + 1),
        Some(first_local + 1_000_000)
    );
    assert_eq!(
        s.next_sync0_ns(first_local + 2_500_000),
        Some(first_local + 3_000_000)
    );
    // 0x0990 read back while active: the next pulse in system time
    m.now_ns = first_local + 4_200_000;
    let (d, w) = m.fprd(Master::station(0), 0x0990, 8);
    assert_eq!(w, 1);
    assert_eq!(u64::from_le_bytes(d.try_into().unwrap()), start + 5_000_000);
    // the master switches SYNC0 off: no more pulses; back in PRE-OP the drive free-runs
    assert_eq!(m.fpwr(Master::station(0), 0x0981, &[0]), 1);
    assert_eq!(m.seg.slaves[0].next_sync0_ns(0), None);
    dc_sync0(&mut m, 0, CYCLE_NS);
    assert!(m.seg.slaves[0].next_sync0_ns(0).is_some());
    assert_eq!(m.request(0, 0x02), 0x02);
    assert!(!m.seg.slaves[0].dc_synchronised());
    assert_eq!(m.seg.slaves[0].next_sync0_ns(0), None);
}

#[test]
fn dc_sync0_without_sync0_is_refused_with_0x0030() {
    let mut m = mapped();
    m.sdo_write(0, 0x1C32, 1, false, &2u16.to_le_bytes())
        .unwrap();
    assert_eq!(m.request(0, 0x04), 0x12, "PRE-OP with the error flag");
    assert_eq!(m.al_code(0), 0x0030);
    // acknowledged, SYNC0 configured at 125 us (the minimum cycle): accepted
    dc_sync0(&mut m, 0, 125_000);
    assert_eq!(m.request(0, 0x14), 0x04);
    assert_eq!(m.al_code(0), 0);
    assert!(m.seg.slaves[0].dc_synchronised());
}

#[test]
fn a_sync0_cycle_below_the_minimum_is_refused_with_0x0036() {
    let mut m = mapped();
    m.sdo_write(0, 0x1C32, 1, false, &2u16.to_le_bytes())
        .unwrap();
    dc_sync0(&mut m, 0, 100_000);
    assert_eq!(m.request(0, 0x04), 0x12);
    assert_eq!(m.al_code(0), 0x0036);
}

#[test]
fn free_run_ignores_an_active_sync0() {
    let mut m = mapped();
    dc_sync0(&mut m, 0, CYCLE_NS);
    assert_eq!(m.request(0, 0x04), 0x04, "free run (0x1C32:1 = 0)");
    assert!(m.seg.slaves[0].sync0().active());
    assert!(!m.seg.slaves[0].dc_synchronised());
    assert_eq!(m.seg.slaves[0].next_sync0_ns(0), None);
}
