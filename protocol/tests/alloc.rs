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

/// The LSS services (fastscan, configure, store, inquire, the switch to waiting that boots
/// the node with its new node-ID) do not allocate either: a master may run them while other
/// drives on the same loop are in motion.
#[test]
fn lss_services_do_not_allocate() {
    let mut node = Node::new(lss_config(255, 255, 0, 0, false)).unwrap();
    let mut drive = SimDrive::default();
    node.boot(0);
    let mut frames: Vec<[u8; 8]> = vec![[0x51, 0, 0, 0, 0, 0x80, 0, 0]];
    // python canopen's fastscan frames for this node's address (0, 0x402, 0x10000, 255)
    for (sub, part) in [0u32, 0x402, 0x0001_0000, 0xFF].into_iter().enumerate() {
        for bit in (0..32u8).rev() {
            // the bits above `bit` found so far, 0 from `bit` down
            let guess = (u64::from(part) >> (bit + 1) << (bit + 1)) as u32;
            let g = guess.to_le_bytes();
            frames.push([0x51, g[0], g[1], g[2], g[3], bit, sub as u8, sub as u8]);
        }
        let p = part.to_le_bytes();
        frames.push([
            0x51,
            p[0],
            p[1],
            p[2],
            p[3],
            0,
            sub as u8,
            (sub as u8 + 1) & 3,
        ]);
    }
    frames.extend([
        [0x5A, 0, 0, 0, 0, 0, 0, 0],
        [0x5E, 0, 0, 0, 0, 0, 0, 0],
        [0x11, 12, 0, 0, 0, 0, 0, 0],
        [0x13, 0, 2, 0, 0, 0, 0, 0],
        [0x17, 0, 0, 0, 0, 0, 0, 0],
        [0x46, 0, 0, 0, 0, 0, 0, 0],
        [0x04, 0, 0, 0, 0, 0, 0, 0],
    ]);
    let frames: Vec<CanFrame> = frames.iter().map(|b| CanFrame::new(0x7E5, b)).collect();
    let mut answers = 0;
    reset();
    ACTIVE.with(|a| a.set(true));
    for f in &frames {
        node.handle(f, 0, &mut drive);
        while let Some(f) = node.pop_tx() {
            answers += usize::from(f.id == 0x7E4);
        }
    }
    node.poll(1000, &mut drive);
    ACTIVE.with(|a| a.set(false));
    assert_eq!(allocs(), 0, "allocations in LSS services");
    // every fastscan frame but those probing a 1 bit (silent: the master sets the bit) and
    // the 5 services with an answer were answered; the node booted
    let ones: u32 = [0u32, 0x402, 0x0001_0000, 0xFF]
        .iter()
        .map(|p| p.count_ones())
        .sum();
    assert_eq!(answers, 1 + 4 * 33 - ones as usize + 5, "LSS answers");
    assert_eq!(node.node_id(), 12);
    assert_eq!(node.nmt_state(), drive_protocol::NmtState::PreOperational);
}

#[test]
fn steady_state_and_a_reset_with_every_switch_on_do_not_allocate() {
    let cfg = drive_protocol::NodeConfig::new(ID, info())
        .with_od(od_with_handler())
        .with_quirks(every_switch());
    let mut b = Bench::with_config(cfg);
    b.run_until(30_000); // ready
    let mut node = b.node;
    let mut drive = b.drive;
    let mut now = b.now;
    let mut sent = 0;
    let id = ID as u32;
    // the answers come late: each request, then time for its answer
    let sdo = |node: &mut Node, drive: &mut SimDrive, now: &mut u64, req: [u8; 8]| {
        node.handle(&CanFrame::new(0x600 + id, &req), *now, drive);
        for _ in 0..5 {
            *now += 1000;
            node.poll(*now, drive);
        }
        while let Some(f) = node.pop_tx() {
            assert!(f.id != 0x580 + id || f.data[0] != 0x80, "refused: {f:?}");
        }
    };
    for req in [
        [0x23, 0x06, 0x10, 0, 0xE8, 0x03, 0, 0], // 0x1006 = 1000 us
        [0x2F, 0xC2, 0x60, 1, 1, 0, 0, 0],       // 0x60C2 = 1 ms
        [0x2F, 0x60, 0x60, 0, 8, 0, 0, 0],       // CSP
    ] {
        sdo(&mut node, &mut drive, &mut now, req);
    }
    node.handle(&CanFrame::new(0, &[0x01, ID]), now, &mut drive);
    // enable in CSP through RPDO1, as a master does (each value held 2 ticks)
    let rpdo = |node: &mut Node, drive: &mut SimDrive, now: u64, cw: u16| {
        node.handle(&CanFrame::new(0x200 + id, &cw.to_le_bytes()), now, drive);
    };
    for cw in [0x06u16, 0x07, 0x0F] {
        rpdo(&mut node, &mut drive, now, cw);
        for _ in 0..2 {
            now += 1000;
            node.poll(now, &mut drive);
        }
    }
    for k in 0..100 {
        cycle(&mut node, &mut drive, &mut now, k, &mut sent);
    }
    assert_eq!(
        node.cia402_state(),
        drive_protocol::Cia402State::OperationEnabled
    );
    reset();
    sent = 0;
    ACTIVE.with(|a| a.set(true));
    for k in 100..2100 {
        cycle(&mut node, &mut drive, &mut now, k, &mut sent);
    }
    // a reset communication: not ready, 0x00 heartbeats, a dropped first upload, ready, the
    // early heartbeat, delayed answers
    node.handle(&CanFrame::new(0, &[0x82, ID]), now, &mut drive);
    for k in 0..60 {
        now += 1000;
        node.poll(now, &mut drive);
        if k % 5 == 0 {
            node.handle(
                &CanFrame::new(0x600 + id, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]),
                now,
                &mut drive,
            );
        }
        while node.pop_tx().is_some() {
            sent += 1;
        }
    }
    ACTIVE.with(|a| a.set(false));
    assert!(sent > 2000 * 2, "the node was busy: {sent} frames");
    assert_eq!(allocs(), 0, "allocations with every switch on");
}
