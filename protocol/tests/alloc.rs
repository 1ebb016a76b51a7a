//! Steady state (SYNC, RPDOs, TPDOs, heartbeat producer and consumer, expedited SDO, CiA 402
//! in CSP) does not allocate: a counting global allocator proves it. The counter is per
//! thread (the test harness runs tests on parallel threads), so another test in this binary
//! allocating at the same time cannot disturb the count.
mod common;
use common::*;
use drive_protocol::{CanFrame, Node};

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;
thread_local! {
    /// Counting on this thread.
    static ACTIVE: Cell<bool> = const { Cell::new(false) };
    /// Allocations counted on this thread (const-initialised: touching it never allocates).
    static ALLOCS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    if ACTIVE.try_with(|a| a.get()).unwrap_or(false) {
        let _ = ALLOCS.try_with(|n| n.set(n.get() + 1));
    }
}

fn allocs() -> usize {
    ALLOCS.with(|n| n.get())
}

fn reset() {
    ALLOCS.with(|n| n.set(0));
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

fn cycle(node: &mut Node, drive: &mut SimDrive, now: &mut u64, k: u32, sent: &mut usize) {
    let id = ID as u32;
    let target = (k as i32 * 10).to_le_bytes();
    node.handle(
        &CanFrame::new(
            0x300 + id,
            &[0x0F, 0, target[0], target[1], target[2], target[3]],
        ),
        *now,
        drive,
    );
    node.handle(&CanFrame::new(0x80, &[]), *now, drive);
    if k.is_multiple_of(10) {
        node.handle(&CanFrame::new(0x77F, &[0x05]), *now, drive);
        node.handle(
            &CanFrame::new(0x600 + id, &[0x2B, 0x40, 0x60, 0, 0x0F, 0, 0, 0]),
            *now,
            drive,
        );
        node.handle(
            &CanFrame::new(0x600 + id, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]),
            *now,
            drive,
        );
    }
    *now += 1000;
    node.poll(*now, drive);
    // the event-driven caller's path: deadline and events
    assert!(node.poll_at().is_some());
    while node.poll_event().is_some() {}
    while node.pop_tx().is_some() {
        *sent += 1;
    }
}

#[test]
fn steady_state_does_not_allocate() {
    let mut b = Bench::new();
    b.w16(0x1017, 0, 10).unwrap();
    b.w32(0x1016, 1, (0x7F << 16) | 100).unwrap();
    b.w8(0x1802, 2, 254).unwrap(); // one event-driven TPDO too
    b.start();
    b.enable(8);
    let mut node = b.node;
    let mut drive = b.drive;
    let mut now = b.now;
    let mut sent = 0;
    for k in 0..100 {
        cycle(&mut node, &mut drive, &mut now, k, &mut sent);
    }
    reset();
    sent = 0;
    ACTIVE.with(|a| a.set(true));
    for k in 100..2100 {
        cycle(&mut node, &mut drive, &mut now, k, &mut sent);
    }
    ACTIVE.with(|a| a.set(false));
    assert!(sent > 2000 * 2, "the node was busy: {sent} frames");
    assert_eq!(allocs(), 0, "allocations in steady state");
    assert_eq!(
        node.cia402_state(),
        drive_protocol::Cia402State::OperationEnabled
    );
}

#[test]
fn the_counter_counts() {
    reset();
    ACTIVE.with(|a| a.set(true));
    let v: Vec<u8> = Vec::with_capacity(10);
    ACTIVE.with(|a| a.set(false));
    drop(v);
    assert!(allocs() >= 1);
}
