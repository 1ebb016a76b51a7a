//! Proof that the EtherCAT fault injector allocates nothing on the frame path: a counting
//! global allocator watches `EcatFaults` start, admit, answer (working counters restored,
//! frames held, frames corrupted), release held frames and end every wire fault over
//! thousands of frames.
//! (The slave's drop out of OP is counted in ethercat/tests/alloc.rs.)

use drive_emu::bus::ethercat::{Answer, EcatFault, EcatFaults, HELD_FRAMES};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.try_with(Cell::get).unwrap_or(false) {
            let _ = ALLOCS.try_with(|a| a.set(a.get() + 1));
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.try_with(Cell::get).unwrap_or(false) {
            let _ = ALLOCS.try_with(|a| a.set(a.get() + 1));
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn counted<R>(f: impl FnOnce() -> R) -> R {
    COUNTING.with(|c| c.set(true));
    let r = f();
    COUNTING.with(|c| c.set(false));
    r
}

#[test]
fn the_counter_sees_an_allocation() {
    ALLOCS.with(|a| a.set(0));
    let v = counted(|| std::hint::black_box(vec![1u8; 16]));
    assert_eq!(ALLOCS.with(Cell::get), 1);
    drop(v);
}

#[test]
fn every_wire_fault_on_the_frame_path_allocates_nothing() {
    // an LRW and an FPRD in one frame, as a master's cycle sends them
    let template = drive_ethercat::frame::build(
        [2, 0, 0, 0, 0, 0],
        &[
            (12, 0x80, 0x1000, &[0u8; 12]),
            (4, 0x81, 0x1001_0130, &[0u8; 2]),
        ],
    );
    let mut faults = EcatFaults::new(5);
    let mut buf = [0u8; 1600];
    let n = template.len();
    let mut counts = [0u64; 4]; // passed, sent at once, kept, sent late
    ALLOCS.with(|a| a.set(0));
    counted(|| {
        let schedule = [
            (EcatFault::Lost {
                frames: 20,
                share: 0.0,
            }),
            (EcatFault::Lost {
                frames: 0,
                share: 0.3,
            }),
            (EcatFault::BadWkc { share: 1.0 }),
            (EcatFault::Late { hold_us: 20_000 }),
            (EcatFault::LinkDown),
            (EcatFault::Corrupt {
                frames: 20,
                share: 0.0,
            }),
            (EcatFault::Corrupt {
                frames: 0,
                share: 0.3,
            }),
        ];
        let mut now_us = 0u64;
        for fault in schedule {
            faults.start(fault, Some(50_000), now_us);
            for _ in 0..2000 {
                now_us += 100;
                let f = &mut buf[..n];
                f.copy_from_slice(&template);
                if faults.admit(f, now_us) {
                    counts[0] += 1;
                    // the slaves' working counter of the second datagram (the frame is padded
                    // to 60 bytes after it)
                    f[14 + 2 + 10 + 12 + 2 + 10 + 2] = 3;
                    if faults.answer(f, now_us) == Answer::Send {
                        counts[1] += 1;
                    } else {
                        counts[2] += 1;
                    }
                }
                faults.due(now_us, |_| counts[3] += 1);
            }
        }
        faults.start(EcatFault::LinkDown, None, now_us);
        faults.clear();
    });
    assert_eq!(ALLOCS.with(Cell::get), 0, "allocations on the frame path");
    let st = faults.stats();
    assert!(st.lost >= 20 + 500, "{st:?}");
    assert!(st.bad_wkc >= 400, "{st:?}");
    // 20, then about 0.3 of the 500 frames of 50 ms
    assert!(
        st.corrupted >= 20 + 100 && st.corrupted <= 20 + 250,
        "{st:?}"
    );
    assert!(st.held >= HELD_FRAMES as u64 && st.held <= 500, "{st:?}");
    assert_eq!(counts[3], st.held, "every held frame went out");
    assert_eq!(counts[2], st.held + st.hold_full);
}
