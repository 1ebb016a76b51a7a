//! The frame path and the cycle allocate nothing in OP: process-data frames (LRW), CoE SDO
//! requests through the mailbox and the drive's cycle, with a counting allocator (per
//! thread, so other tests of this binary cannot disturb the count).
mod common;
use common::*;
use drive_ethercat::frame;
use drive_protocol::Clocks;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;
thread_local! {
    static ACTIVE: Cell<bool> = const { Cell::new(false) };
    static ALLOCS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    if ACTIVE.try_with(|a| a.get()).unwrap_or(false) {
        let _ = ALLOCS.try_with(|n| n.set(n.get() + 1));
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn op_frame_path_and_cycle_allocate_nothing() {
    let n = 3;
    let (mut m, o, i) = op(n);
    for k in 0..n {
        m.sdo_write(k, 0x6060, 0, false, &[8]).unwrap();
    }
    // frames built before counting; the mailbox request with counter 0 (no repeat check)
    let mut image = vec![0u8; o + i];
    for k in 0..n {
        image[6 * k..6 * k + 6].copy_from_slice(&outputs(0x0F, 0));
    }
    let lrw = frame::build([1; 6], &[(12, 0, 0, &image)]);
    let mut req = vec![0u8; MBX];
    req[0] = 10;
    req[5] = 0x03;
    req[6..16].copy_from_slice(&[0x00, 0x20, 0x40, 0x41, 0x60, 0, 0, 0, 0, 0]);
    let st = Master::station(1);
    let sdo = frame::build(
        [1; 6],
        &[
            (5, 0, u32::from(st) | 0x1000 << 16, &req),
            (4, 1, u32::from(st) | 0x1080 << 16, &[0u8; MBX]),
        ],
    );
    let mut buf = vec![0u8; 1600];
    let mut now_us = m.now_ns / 1000;
    let mut wkcs = Vec::with_capacity(1000);
    let mut answers = 0usize;
    ACTIVE.with(|a| a.set(true));
    for k in 0..500u32 {
        now_us += 1000;
        let f = &mut buf[..lrw.len()];
        f.copy_from_slice(&lrw);
        m.seg.process(f, now_us * 1000, &mut m.drives).unwrap();
        wkcs.push(u16::from_le_bytes([f[f.len() - 2], f[f.len() - 1]]));
        if k % 10 == 0 {
            let f = &mut buf[..sdo.len()];
            f.copy_from_slice(&sdo);
            m.seg.process(f, now_us * 1000 + 10, &mut m.drives).unwrap();
            // the second datagram read the answer: wkc 1 and an expedited response
            let at = 16 + 10 + MBX + 2 + 10;
            answers += usize::from(f[at + 6 + 2] == 0x4B);
        }
        m.seg.cycle(Clocks::same(now_us), &mut m.drives);
    }
    ACTIVE.with(|a| a.set(false));
    let allocs = ALLOCS.with(|c| c.get());
    assert_eq!(allocs, 0, "allocations on the frame path and in the cycle");
    assert!(wkcs.iter().all(|&w| w == 3 * n as u16), "wkc every cycle");
    assert_eq!(answers, 50, "every SDO read answered in its frame");
}

#[test]
fn watchdog_expiry_and_the_0x6007_fault_reaction_allocate_nothing() {
    let (mut m, o, i) = op(1);
    m.sdo_write(0, 0x6060, 0, false, &[8]).unwrap();
    m.sdo_write(0, 0x6007, 0, false, &1i16.to_le_bytes())
        .unwrap();
    for cw in [0x06, 0x07, 0x0F] {
        let mut v = vec![0u8; o + i];
        v[..6].copy_from_slice(&outputs(cw, 0));
        for _ in 0..3 {
            m.lrw(&v);
        }
    }
    assert_eq!(
        m.seg.slaves[0].node().cia402_state(),
        drive_protocol::Cia402State::OperationEnabled
    );
    // the outputs stop: SAFE-OP 0x001B, EMCY 0x8250 into the mailbox, the fault reaction
    ALLOCS.with(|n| n.set(0));
    ACTIVE.with(|a| a.set(true));
    for _ in 0..300 {
        m.cycle();
    }
    ACTIVE.with(|a| a.set(false));
    let allocs = ALLOCS.with(|n| n.get());
    assert_eq!(m.seg.slaves[0].al_state(), drive_ethercat::AlState::SafeOp);
    assert_eq!(m.seg.slaves[0].al_status_code(), 0x001B);
    assert_eq!(
        m.seg.slaves[0].node().cia402_state(),
        drive_protocol::Cia402State::Fault
    );
    assert_eq!(allocs, 0, "allocations in the watchdog path");
}

#[test]
fn dc_sync0_frames_cycle_and_pulse_times_allocate_nothing() {
    // PRE-OP, mapped, DC SYNC0 at 1 ms as SOEM's ecx_dcsync0 writes it, SAFE-OP, OP
    let mut m = preop(1);
    let (o, i) = m.map_pdos(0, 0, 6);
    let st = Master::station(0);
    m.sdo_write(0, 0x1C32, 1, false, &2u16.to_le_bytes())
        .unwrap();
    m.sdo_write(0, 0x6060, 0, false, &[8]).unwrap();
    assert_eq!(m.fpwr(st, 0x0920, &5_000_000u64.to_le_bytes()), 1);
    assert_eq!(m.fpwr(st, 0x0981, &[0]), 1);
    let start = (m.now_ns + 5_000_000 + 100_000_000) / 1_000_000 * 1_000_000;
    assert_eq!(m.fpwr(st, 0x0990, &start.to_le_bytes()), 1);
    assert_eq!(m.fpwr(st, 0x09A0, &1_000_000u32.to_le_bytes()), 1);
    assert_eq!(m.fpwr(st, 0x0981, &[3]), 1);
    assert_eq!(m.request(0, 0x04), 0x04);
    m.lrw(&vec![0; o + i]);
    assert_eq!(m.request(0, 0x08), 0x08);
    // the process-data frame as SOEM sends it with DC: LRW and an FRMW of the system time
    let mut image = vec![0u8; o + i];
    image[..6].copy_from_slice(&outputs(0x0F, 0));
    let sys_time = [0u8; 8];
    let pd = frame::build(
        [1; 6],
        &[
            (14, 0, u32::from(st) | 0x0910 << 16, &sys_time),
            (12, 1, 0, &image),
            // and as a slave behind the reference gets it: written, drift control steers
            (14, 2, u32::from(st + 1) | 0x0910 << 16, &sys_time),
        ],
    );
    let mut buf = vec![0u8; 1600];
    m.seg.slaves[0].set_dc_drift_ppm(50.0);
    let mut now_ns = m.now_ns;
    let mut pulses = 0u64;
    ALLOCS.with(|n| n.set(0));
    ACTIVE.with(|a| a.set(true));
    for _ in 0..500 {
        now_ns += 1_000_000;
        let f = &mut buf[..pd.len()];
        f.copy_from_slice(&pd);
        m.seg.process(f, now_ns, &mut m.drives).unwrap();
        let s = &m.seg.slaves[0];
        if let Some(p) = s.next_sync0_ns(now_ns) {
            pulses += u64::from(p >= now_ns);
        }
        m.seg.cycle(Clocks::same(now_ns / 1000), &mut m.drives);
    }
    ACTIVE.with(|a| a.set(false));
    let allocs = ALLOCS.with(|n| n.get());
    assert_eq!(allocs, 0, "allocations with DC SYNC0 active");
    assert!(m.seg.slaves[0].dc_synchronised());
    assert_eq!(pulses, 500);
    assert_ne!(
        m.seg.slaves[0].dc_clock().freq_correction_ppb(),
        0,
        "steered"
    );
}

#[test]
fn a_drop_out_of_op_allocates_nothing() {
    let (mut m, o, i) = op(1);
    m.sdo_write(0, 0x6060, 0, false, &[8]).unwrap();
    for cw in [0x06, 0x07, 0x0F] {
        let mut v = vec![0u8; o + i];
        v[..6].copy_from_slice(&outputs(cw, 0));
        for _ in 0..3 {
            m.lrw(&v);
        }
    }
    ALLOCS.with(|n| n.set(0));
    ACTIVE.with(|a| a.set(true));
    let dropped = m.seg.slaves[0].drop_out_of_op(0x001A);
    m.cycle();
    let again = m.seg.slaves[0].drop_out_of_op(0x001A);
    ACTIVE.with(|a| a.set(false));
    assert!(
        dropped && !again,
        "dropped from OP once; not again from SAFE-OP"
    );
    assert_eq!(m.seg.slaves[0].al_state(), drive_ethercat::AlState::SafeOp);
    assert_eq!(m.seg.slaves[0].al_status_code(), 0x001A);
    assert_eq!(
        ALLOCS.with(|n| n.get()),
        0,
        "allocations in the drop out of OP"
    );
}
