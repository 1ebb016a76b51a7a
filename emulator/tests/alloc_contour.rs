//! No allocation in the master's per-cycle contour work: the circle interpolator
//! (`master::contour::CircleTest::sample`) and the backlash compensation
//! (`master::compensation::BacklashCompensation::apply`) run once per position cycle on a
//! master's real-time path and perform zero heap allocations.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use drive_emu::master::compensation::BacklashCompensation;
use drive_emu::master::contour::CircleTest;

struct Counting;

static ALLOCS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    // Count only on the test's own thread (the harness may allocate on others).
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

fn note() {
    if COUNTING.with(|c| c.get()) {
        ALLOCS.fetch_add(1, Ordering::SeqCst);
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn interpolating_and_compensating_do_not_allocate() {
    // a small fast circle: every phase (dwell, ramps, both passes) within the loop
    let test = CircleTest::new((0.0, 0.0), 0.01, 0.05);
    let mut comp = [
        BacklashCompensation::new(30e-6),
        BacklashCompensation::new(50e-6),
    ];
    let n = (test.duration_s() / 1e-3).ceil() as u32;
    let before = ALLOCS.load(Ordering::SeqCst);
    COUNTING.with(|c| c.set(true));
    let mut sum = 0.0;
    for i in 0..n {
        let s = test.sample(f64::from(i) * 1e-3);
        sum += comp[0].apply(s.x) + comp[1].apply(s.y);
    }
    COUNTING.with(|c| c.set(false));
    let after = ALLOCS.load(Ordering::SeqCst);
    assert!(sum.is_finite());
    // the loop went through both passes: each axis reversed at least four times
    assert!(comp[0].reversals() >= 4 && comp[1].reversals() >= 4);
    assert_eq!(after - before, 0, "allocations in {n} cycles");
}
