//! No allocation in the master's per-cycle line work: the line interpolator
//! (`master::line::LineProgram`, its plan and `sample`) and the backlash compensation
//! (`master::compensation::BacklashCompensation::apply`) run once per position cycle on a
//! master's real-time path and perform zero heap allocations.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use drive_emu::master::compensation::BacklashCompensation;
use drive_emu::master::line::LineProgram;

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
fn line_interpolation_and_compensation_do_not_allocate() {
    // a square there and back on three axes, a short segment (a triangle) at the end
    let pts = [
        [0.0, 0.0, 0.0],
        [0.010, 0.0, 0.002],
        [0.010, 0.005, 0.0],
        [0.0, 0.0, 0.0],
        [0.0001, 0.0, 0.0],
    ];
    let before = ALLOCS.load(Ordering::SeqCst);
    COUNTING.with(|c| c.set(true));
    // the plan too: it lives in fixed arrays
    let plan = LineProgram::new(&pts, 3, 0.01, 0.1, 0.05).unwrap();
    let mut comp = [
        BacklashCompensation::new(30e-6),
        BacklashCompensation::new(50e-6),
        BacklashCompensation::new(20e-6),
    ];
    let n = (plan.duration_s() / 1e-3).ceil() as u32;
    let mut sum = 0.0;
    let mut last_segment = 0;
    for i in 0..n {
        let s = plan.sample(f64::from(i) * 1e-3);
        for (k, c) in comp.iter_mut().enumerate() {
            sum += c.apply(s.position[k]);
        }
        last_segment = s.segment;
    }
    COUNTING.with(|c| c.set(false));
    let after = ALLOCS.load(Ordering::SeqCst);
    assert!(sum.is_finite());
    // the loop ran the whole program: every segment, and X reversed twice, Y once
    assert_eq!(last_segment, 4);
    assert_eq!((comp[0].reversals(), comp[1].reversals()), (2, 1));
    assert_eq!(after - before, 0, "allocations in {n} cycles");
}
