//! The EtherCAT loop's SYNC0 lock allocates nothing: `Sync0Lock` fed SYNC0 pulses, ticking,
//! and its 0x2100 values, for 2000 cycles (acquisition, lock, a late loop), and lock-step's
//! ticks and 0x2100 values per SYNC0 event, under a counting allocator (per thread).

use drive_emu::runtime::ethercat::{lockstep_ticks, lockstep_values, Sync0Lock};
use drive_emu::runtime::pll::LockState;
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
fn sync0_lock_pulses_ticks_and_stats_allocate_nothing() {
    let mut lock = Sync0Lock::new(0, 1000);
    // SYNC0 every 1 ms from 20.3 ms on (slave clock, ns)
    let pulses = |t: u64| {
        let first = 20_300_000u64;
        Some(if t <= first {
            first
        } else {
            first + (t - first).div_ceil(1_000_000) * 1_000_000
        })
    };
    let mut sum = 0u64;
    let mut lockstep_period_us = 0u64;
    ACTIVE.with(|a| a.set(true));
    for k in 0..2000u64 {
        let now = lock.deadline_us() + if k % 7 == 0 { 40 } else { 0 };
        lock.pulses(now, pulses);
        lock.ticked(now, pulses);
        sum += u64::from(lock.stats_values()[8]);
        let ticks = lockstep_ticks(Some(1_000_000), 250);
        lockstep_period_us += u64::from(lockstep_values(&lock, k * ticks, Some(1_000_000))[9]);
    }
    ACTIVE.with(|a| a.set(false));
    assert_eq!(ALLOCS.with(|n| n.get()), 0, "allocations in the SYNC0 lock");
    assert_eq!(lock.state(), LockState::Locked);
    assert!(sum > 0, "a late loop shows in the phase error");
    assert_eq!(
        lockstep_period_us,
        2000 * 1000,
        "lock-step: the SYNC0 period"
    );
}
