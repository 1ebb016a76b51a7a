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

/// Two slaves, the second's clock `drift_ppm` off; the offsets a master's `config_dc` writes
/// (the reference's system time less each one's local time, read in one frame).
fn drifting(drift_ppm: f64) -> Master {
    let mut m = preop(2);
    m.seg.slaves[1].set_dc_drift_ppm(drift_ppm);
    let r = m.frame(&[
        (4, Master::addr(Master::station(0), 0x0910), &[0; 8]),
        (4, Master::addr(Master::station(1), 0x0910), &[0; 8]),
    ]);
    let local = |k: usize| u64::from_le_bytes(r[k].data.clone().try_into().unwrap());
    for k in 0..2 {
        let off = OFFSET_NS.wrapping_add(local(0)).wrapping_sub(local(k));
        assert_eq!(m.fpwr(Master::station(k), 0x0920, &off.to_le_bytes()), 1);
    }
    m
}

/// One cycle of 1 ms: with `compensate`, the FRMW of the reference clock's system time (the
/// first slave reads it, the second gets it written), as SOEM and ethercrab send it with the
/// process data. Returns the second slave's 0x092C and its system time less the reference's,
/// read in one frame (the same instant).
fn dc_cycle(m: &mut Master, compensate: bool) -> (u32, i64) {
    m.now_ns += 1_000_000;
    if compensate {
        let (_, wkc) = m.one(14, Master::addr(Master::station(0), 0x0910), &[0; 8]);
        assert_eq!(wkc, 2, "FRMW: one read, one write");
    }
    let r = m.frame(&[
        (4, Master::addr(Master::station(0), 0x0910), &[0; 8]),
        (4, Master::addr(Master::station(1), 0x0910), &[0; 8]),
        (4, Master::addr(Master::station(1), 0x092C), &[0; 4]),
    ]);
    let t = |k: usize| u64::from_le_bytes(r[k].data.clone().try_into().unwrap());
    let diff_reg = u32::from_le_bytes(r[2].data.clone().try_into().unwrap());
    (diff_reg, t(1).wrapping_sub(t(0)) as i64)
}

fn signed(v: u32) -> i64 {
    let m = i64::from(v & 0x7FFF_FFFF);
    if v & 0x8000_0000 != 0 {
        -m
    } else {
        m
    }
}

#[test]
fn drift_control_holds_a_50_ppm_clock_to_the_reference() {
    // without drift compensation the difference grows at 50 ns per ms
    let mut m = drifting(50.0);
    let mut last = 0;
    for _ in 0..1000 {
        let (reg, d) = dc_cycle(&mut m, false);
        assert_eq!(reg, 0, "no write of 0x0910, no difference measured");
        last = d;
    }
    assert!(
        (49_000..=51_000).contains(&last),
        "after 1 s free: {last} ns apart"
    );

    // a master's FRMW every cycle: the loop brings the difference down and holds it
    let mut m = drifting(50.0);
    let (first, _) = dc_cycle(&mut m, true);
    assert_eq!(
        first & 0x8000_0000,
        0,
        "the local copy is ahead: bit 31 clear"
    );
    let mut worst = (0i64, 0i64);
    for k in 0..1000 {
        let (reg, d) = dc_cycle(&mut m, true);
        if k >= 100 {
            worst.0 = worst.0.max(signed(reg).abs());
            worst.1 = worst.1.max(d.abs());
        }
    }
    assert!(worst.0 <= 20, "|0x092C| after settling: {} ns", worst.0);
    assert!(worst.1 <= 20, "|system time difference|: {} ns", worst.1);
    let corr = m.seg.slaves[1].dc_clock().freq_correction_ppb();
    assert!(
        (-51_000..=-49_000).contains(&corr),
        "frequency correction {corr} ppb for a 50 ppm clock"
    );
    // the reference (nothing written to it) is not steered
    assert_eq!(m.seg.slaves[0].dc_clock().freq_correction_ppb(), 0);

    // the compensation stops: the difference grows again, at what is left of the drift
    // (now corrected), and a master resetting the loop (0x0930) loses the correction
    for _ in 0..200 {
        let (_, d) = dc_cycle(&mut m, false);
        assert!(d.abs() <= 200, "held by the frequency correction: {d} ns");
    }
    assert_eq!(
        m.fpwr(Master::station(1), 0x0930, &0x1000u16.to_le_bytes()),
        1
    );
    let (reg, before) = dc_cycle(&mut m, false);
    assert_eq!(reg, 0, "a reset loop has no difference");
    for _ in 0..100 {
        dc_cycle(&mut m, false);
    }
    let (_, after) = dc_cycle(&mut m, false);
    assert!(
        (4_500..=5_500).contains(&(after - before)),
        "100 ms at 50 ppm uncorrected: {} ns",
        after - before
    );
}

#[test]
fn a_slow_clock_reads_back_with_the_sign_bit_and_is_corrected_too() {
    let mut m = drifting(-50.0);
    let (first, d) = dc_cycle(&mut m, true);
    assert_ne!(
        first & 0x8000_0000,
        0,
        "the local copy is behind: bit 31 set"
    );
    assert!((1..=0x7FFF_FFFF).contains(&(first & 0x7FFF_FFFF)));
    assert!(d < 0);
    for _ in 0..300 {
        dc_cycle(&mut m, true);
    }
    let (reg, d) = dc_cycle(&mut m, true);
    assert!(signed(reg).abs() <= 20 && d.abs() <= 20, "{reg:#x} {d}");
    assert!(m.seg.slaves[1].dc_clock().freq_correction_ppb() > 49_000);
}

#[test]
fn sync0_follows_the_steered_clock() {
    // the drifting slave's SYNC0 pulses are on its own (steered) system time: with drift
    // control they stay within nanoseconds of the reference's pulses
    let mut m = drifting(50.0);
    for k in 0..2 {
        let (o, i) = m.map_pdos(k, 6 * k as u32, 12 + 6 * k as u32);
        assert_eq!((o, i), (6, 6));
        m.sdo_write(k, 0x1C32, 1, false, &2u16.to_le_bytes())
            .unwrap();
    }
    let start = dc_sync0(&mut m, 0, CYCLE_NS);
    let st = Master::station(1);
    assert_eq!(m.fpwr(st, 0x0990, &start.to_le_bytes()), 1);
    assert_eq!(m.fpwr(st, 0x09A0, &CYCLE_NS.to_le_bytes()), 1);
    assert_eq!(m.fpwr(st, 0x0981, &[3]), 1);
    for k in 0..2 {
        assert_eq!(m.request(k, 0x04), 0x04, "SAFE-OP with DC SYNC0");
    }
    for _ in 0..300 {
        dc_cycle(&mut m, true);
    }
    let at = m.now_ns;
    let p0 = m.seg.slaves[0].next_sync0_ns(at).unwrap();
    let p1 = m.seg.slaves[1].next_sync0_ns(at).unwrap();
    assert!(p0.abs_diff(p1) <= 20, "pulses {p0} and {p1}");
    // without compensation for 1 s of frames the second slave's pulses come 50 us early
    // (its clock runs fast; the correction is kept, so reset the loop first)
    assert_eq!(m.fpwr(st, 0x0930, &0x1000u16.to_le_bytes()), 1);
    m.now_ns += 1_000_000_000;
    let at = m.now_ns;
    let p0 = m.seg.slaves[0].next_sync0_ns(at).unwrap();
    let p1 = m.seg.slaves[1].next_sync0_ns(at).unwrap();
    let early = (p0 as i64 - p1 as i64).rem_euclid(i64::from(CYCLE_NS));
    assert!((49_000..=51_000).contains(&early), "{early} ns early");
}
