//! Physics speed: nanoseconds per physics substep (axis only) and one simulated second of one
//! axis with the full cascade (real-time factor = 1 s / measured time).
//!
//! cargo bench -p drive-emu --bench physics -- --warm-up-time 1 --measurement-time 3

use criterion::{black_box, criterion_group, criterion_main, Criterion};

use drive_emu::axis::Axis;
use drive_emu::control::{Command, Servo, Setpoint};
use drive_emu::presets::AxisConfig;

fn bench(c: &mut Criterion) {
    let built = AxisConfig::from_preset("cnc1").unwrap().build().unwrap();

    let mut axis = Axis::new(built.axis).unwrap();
    axis.motor.set_demand(0.5);
    c.bench_function("axis_substep_1000", |b| {
        b.iter(|| {
            for _ in 0..1000 {
                axis.substep();
            }
            black_box(axis.load_position())
        })
    });

    let mut servo = Servo::new(built.axis, built.control).unwrap();
    let v = 0.0167;
    let dt = servo.cycle_time();
    let cycles = (1.0 / dt).round() as usize;
    let mut pos = 0.0;
    c.bench_function("servo_cascade_1_simulated_second", |b| {
        b.iter(|| {
            for _ in 0..cycles {
                pos += v * dt;
                servo.set_command(Command::new(Setpoint::Position {
                    position: pos,
                    velocity_ff: 0.0,
                    torque_ff: 0.0,
                }));
                servo.step();
            }
            black_box(servo.axis.load_position())
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
