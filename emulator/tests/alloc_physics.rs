//! No allocation in the physics hot path: after construction, stepping the axis with the full
//! cascade (all modes, encoder noise and faults) performs zero heap allocations, on a
//! single-contact axis and on a twin pinion with its preload changed while it runs.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use drive_emu::control::{Command, Servo, Setpoint, VelocityProfile};
use drive_emu::presets::AxisConfig;

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
fn stepping_does_not_allocate() {
    let single = AxisConfig::from_preset("cnc1").unwrap();
    steps_without_allocating(&single);
    let twin = AxisConfig::from_preset("cnc4")
        .unwrap()
        .with_override("preload_pct", "20")
        .unwrap();
    steps_without_allocating(&twin);
}

fn steps_without_allocating(cfg: &AxisConfig) {
    let built = cfg
        .with_overrides([
            "motor_encoder_noise_counts=2",
            "direct_encoder_noise_counts=1",
        ])
        .unwrap()
        .build()
        .unwrap();
    let mut servo = Servo::new(built.axis, built.control).unwrap();
    let mut profile = VelocityProfile::constant(0.0, 0.0167, 0.167);
    let dt = servo.cycle_time();
    let before = ALLOCS.load(Ordering::SeqCst);
    COUNTING.with(|c| c.set(true));
    for i in 0..20_000u32 {
        let s = profile.next(dt);
        let sp = match i / 4000 {
            0 | 1 => Setpoint::Position {
                position: s.position,
                velocity_ff: s.velocity,
                torque_ff: 0.0,
            },
            2 => Setpoint::Velocity {
                velocity: s.velocity,
                torque_ff: 0.0,
            },
            3 => Setpoint::Torque { torque: 1.0 },
            _ => Setpoint::Disabled,
        };
        servo.set_command(Command {
            setpoint: sp,
            torque_limit: 30.0,
            speed_limit: 200.0,
        });
        if i == 5000 {
            servo.axis.direct_encoder.inject_glitch(100);
            servo.axis.set_backlash(0.05e-3);
            servo.axis.set_external_load(500.0);
        }
        if i == 6000 {
            servo.axis.motor_encoder.set_signal_lost(true);
            if servo.axis.is_twin_pinion() {
                servo.axis.set_preload(0.05).unwrap();
            }
        }
        servo.step();
    }
    COUNTING.with(|c| c.set(false));
    let after = ALLOCS.load(Ordering::SeqCst);
    assert!(servo.time() > 19.0);
    assert_eq!(
        after - before,
        0,
        "{}: allocations while stepping",
        cfg.name
    );
    // The counter works: an allocation on this thread is seen.
    COUNTING.with(|c| c.set(true));
    let v: Vec<u64> = Vec::with_capacity(16);
    COUNTING.with(|c| c.set(false));
    drop(v);
    assert_eq!(ALLOCS.load(Ordering::SeqCst) - after, 1);
}
