//! CiA 402 modes of operation against the simple drive model.
mod common;
use common::*;
use drive_protocol::{Cia402State, Setpoint};

fn demand(b: &Bench) -> f64 {
    match b.drive.last.unwrap().setpoint {
        Setpoint::Position { position_inc, .. } => position_inc,
        s => panic!("not a position set-point: {s:?}"),
    }
}

fn pp_bench() -> Bench {
    let mut b = Bench::new();
    b.start();
    b.w32(0x6081, 0, 10_000).unwrap(); // 10 mm/s
    b.w32(0x6083, 0, 100_000).unwrap(); // 100 mm/s^2
    b.w32(0x6084, 0, 100_000).unwrap();
    b.w32(0x6067, 0, 5).unwrap();
    b.enable(1);
    b
}

#[test]
fn pp_handshake_trapezoid_and_target_reached() {
    let mut b = pp_bench();
    b.w32(0x607A, 0, 5000).unwrap();
    b.cw(0x1F); // new set-point
    b.tick();
    let sw = b.node.statusword();
    assert!(sw & (1 << 12) != 0, "set-point acknowledged");
    assert!(sw & (1 << 10) == 0, "not yet reached");
    b.cw(0x0F);
    b.tick();
    assert!(
        b.node.statusword() & (1 << 12) == 0,
        "ack cleared with bit 4"
    );
    // 5 mm at 10 mm/s with 0.1 s ramps: ~0.6 s; check the speed never exceeds the profile
    let mut vmax: f64 = 0.0;
    let mut prev = demand(&b);
    for _ in 0..700 {
        b.tick();
        let d = demand(&b);
        vmax = vmax.max((d - prev) / 1e-3 / INC_PER_UU);
        prev = d;
    }
    assert!(
        vmax <= 10_000.0 * 1.01 && vmax > 9_000.0,
        "peak {vmax} um/s"
    );
    assert_eq!(b.node.position_actual(), 5000);
    assert!(b.node.statusword() & (1 << 10) != 0, "target reached");
    // relative move of -1000
    b.w32(0x607A, 0, (-1000i32) as u32).unwrap();
    b.cw(0x4F | 0x10);
    b.ticks(400);
    assert_eq!(b.node.position_actual(), 4000);
    // software limit clamps and shows bit 11
    b.w32(0x607D, 2, 4500).unwrap();
    b.w32(0x607D, 1, (-100i32) as u32).unwrap();
    b.cw(0x0F);
    b.tick();
    b.w32(0x607A, 0, 9000).unwrap();
    b.cw(0x1F);
    b.tick();
    assert!(
        b.node.statusword() & (1 << 11) != 0,
        "internal limit active"
    );
    b.ticks(400);
    assert_eq!(b.node.position_actual(), 4500);
}

#[test]
fn pp_internal_limit_bit_is_held_while_the_clamped_target_is_in_force() {
    // A master polling the statusword at any time during the clamped move (and after it
    // stops at the limit) sees bit 11; a target inside the limits clears it.
    let mut b = pp_bench();
    b.w32(0x607D, 2, 4500).unwrap();
    b.w32(0x607D, 1, (-100i32) as u32).unwrap();
    b.w32(0x607A, 0, 9000).unwrap();
    b.cw(0x1F);
    b.tick();
    b.cw(0x0F);
    for i in 0..1000 {
        b.tick();
        assert!(
            b.node.statusword() & (1 << 11) != 0,
            "bit 11 dropped {i} ticks after the clamped set-point"
        );
    }
    assert_eq!(b.node.position_actual(), 4500);
    b.w32(0x607A, 0, 1000).unwrap();
    b.cw(0x1F);
    b.tick();
    b.cw(0x0F);
    b.ticks(10);
    assert!(
        b.node.statusword() & (1 << 11) == 0,
        "a target inside the limits clears bit 11"
    );
}

#[test]
fn pp_change_set_immediately_vs_buffered() {
    let mut b = pp_bench();
    b.w32(0x607A, 0, 10_000).unwrap();
    b.cw(0x1F);
    b.ticks(100);
    b.cw(0x0F);
    b.tick();
    // buffered: the first target is finished first
    b.w32(0x607A, 0, 0).unwrap();
    b.cw(0x1F);
    b.tick();
    let mut max_pos = 0;
    for _ in 0..3000 {
        b.tick();
        max_pos = max_pos.max(b.node.position_actual());
    }
    assert!(
        max_pos >= 9_990,
        "first target reached before the buffered one: {max_pos}"
    );
    assert!(b.node.position_actual().abs() <= 5);
    // immediately: a new target replaces the running one
    b.cw(0x0F);
    b.tick();
    b.w32(0x607A, 0, 10_000).unwrap();
    b.cw(0x1F);
    b.ticks(100);
    b.cw(0x0F);
    b.tick();
    b.w32(0x607A, 0, 0).unwrap();
    b.cw(0x3F);
    let mut max_pos = 0;
    for _ in 0..2000 {
        b.tick();
        max_pos = max_pos.max(b.node.position_actual());
    }
    assert!(max_pos < 9_000, "turned around early: {max_pos}");
}

#[test]
fn halt_decelerates_and_holds_then_resumes() {
    let mut b = pp_bench();
    b.w32(0x607A, 0, 20_000).unwrap();
    b.cw(0x1F);
    b.ticks(300);
    b.cw(0x10F | 0x10); // halt
    b.ticks(200);
    let held = b.node.position_actual();
    b.ticks(100);
    assert_eq!(b.node.position_actual(), held, "holding");
    assert!(
        b.node.statusword() & (1 << 10) != 0,
        "halt: target reached when standing"
    );
    assert!(held < 20_000);
    b.cw(0x1F);
    b.ticks(2500);
    assert_eq!(b.node.position_actual(), 20_000, "resumed");
}

#[test]
fn pv_ramp_window_and_speed_zero() {
    let mut b = Bench::new();
    b.start();
    b.w32(0x6083, 0, 50_000).unwrap();
    b.w32(0x6084, 0, 50_000).unwrap();
    b.w16(0x606D, 0, 100).unwrap();
    b.enable(3);
    b.tick();
    assert!(b.node.statusword() & (1 << 12) != 0, "speed zero");
    b.w32(0x60FF, 0, 20_000).unwrap();
    b.ticks(200);
    let v = b.r32(0x606C, 0) as i32;
    assert!((9_000..11_000).contains(&v), "ramping at 50 mm/s^2: {v}");
    assert!(b.node.statusword() & (1 << 10) == 0);
    assert!(b.node.statusword() & (1 << 12) == 0);
    b.ticks(300);
    assert!(
        b.node.statusword() & (1 << 10) != 0,
        "in the velocity window"
    );
    // halt ramps to zero
    b.cw(0x10F);
    b.ticks(500);
    assert!(b.drive.vel.abs() < 10.0);
    assert!(b.node.statusword() & (1 << 12) != 0);
}

#[test]
fn csp_interpolates_between_sync_targets() {
    let mut b = Bench::new();
    b.w8(0x60C2, 1, 4).unwrap(); // 4 ms
    b.w8(0x60C2, 2, (-3i8) as u8).unwrap();
    b.start();
    b.enable(8);
    // targets every 4 ms (SYNC), ticks every 1 ms
    let mut demands = Vec::new();
    for k in 1..=10 {
        b.send(f(0x300 + ID as u32, &{
            let mut d = [0x0F, 0, 0, 0, 0, 0];
            d[2..6].copy_from_slice(&(k * 400i32).to_le_bytes());
            d
        }));
        b.sync();
        for _ in 0..4 {
            b.tick();
            demands.push(demand(&b) / INC_PER_UU);
        }
    }
    // smooth: 100 um per 1 ms tick after the first segment
    let steps: Vec<f64> = demands.windows(2).map(|w| w[1] - w[0]).collect();
    for s in &steps[4..] {
        assert!((s - 100.0).abs() < 0.5, "step {s} in {steps:?}");
    }
    assert_eq!(
        b.node.statusword() & (1 << 12),
        1 << 12,
        "drive follows the command value"
    );
    // velocity feed-forward = slope, plus 0x60B1
    match b.drive.last.unwrap().setpoint {
        Setpoint::Position {
            velocity_ff_inc_per_s,
            ..
        } => {
            assert!(
                (velocity_ff_inc_per_s / INC_PER_UU - 100_000.0).abs() < 10.0
                    || velocity_ff_inc_per_s == 0.0
            )
        }
        _ => unreachable!(),
    }
}

#[test]
fn csp_target_wraps_around_i32() {
    let mut b = Bench::new();
    b.start();
    b.w32(0x6065, 0, u32::MAX).unwrap();
    b.enable(3);
    let near = i32::MAX - 100;
    // stand near the end of the I32 range, switch to CSP, cross the wrap
    b.drive.pos = near as f64 * INC_PER_UU;
    b.tick();
    b.w8(0x6060, 0, 8).unwrap();
    b.tick();
    let t0 = b.ri32(0x607A, 0);
    assert!(
        (t0 - near).abs() <= 1,
        "0x607A set to the position on entering CSP"
    );
    let before = demand(&b);
    b.w32(0x607A, 0, near.wrapping_add(200) as u32).unwrap();
    b.tick();
    let after = demand(&b);
    assert!(
        (after - before - 200.0 * INC_PER_UU).abs() < 2.0 * INC_PER_UU,
        "moved +200, not -2^32"
    );
}

#[test]
fn csv_and_cst_with_offsets() {
    let mut b = Bench::new();
    b.start();
    b.enable(9);
    b.w32(0x60FF, 0, 1000).unwrap();
    b.w32(0x60B1, 0, 500).unwrap();
    b.w16(0x60B2, 0, 50).unwrap();
    b.tick();
    match b.drive.last.unwrap().setpoint {
        Setpoint::Velocity {
            velocity_inc_per_s,
            torque_ff_permille,
        } => {
            assert!((velocity_inc_per_s - 1500.0 * INC_PER_UU).abs() < 1e-6);
            assert_eq!(torque_ff_permille, 50.0);
        }
        s => panic!("{s:?}"),
    }
    b.w8(0x6060, 0, 10).unwrap();
    b.w16(0x6071, 0, 200).unwrap();
    b.tick();
    assert_eq!(b.node.mode(), 10, "mode display follows at the next tick");
    match b.drive.last.unwrap().setpoint {
        Setpoint::Torque { torque_permille } => assert_eq!(torque_permille, 250.0),
        s => panic!("{s:?}"),
    }
    // limited by 0x6072
    b.w16(0x6072, 0, 100).unwrap();
    b.tick();
    assert!(b.node.statusword() & (1 << 11) != 0);
    match b.drive.last.unwrap().setpoint {
        Setpoint::Torque { torque_permille } => assert_eq!(torque_permille, 100.0),
        s => panic!("{s:?}"),
    }
}

#[test]
fn mode_switch_holds_position() {
    let mut b = Bench::new();
    b.start();
    b.enable(3);
    b.w32(0x60FF, 0, 5000).unwrap();
    b.ticks(300);
    b.w32(0x60FF, 0, 0).unwrap();
    b.ticks(300);
    let p = b.node.position_actual();
    b.w8(0x6060, 0, 1).unwrap();
    b.tick();
    assert_eq!(b.node.mode(), 1);
    b.ticks(100);
    assert!((b.node.position_actual() - p).abs() <= 2, "holds {p}");
    assert_eq!(b.r32(0x6061, 0) as i8, 1);
}

#[test]
fn homing_current_position_35_37() {
    for method in [35i8, 37] {
        let mut b = Bench::new();
        b.start();
        b.drive.pos = 12345.0;
        b.w32(0x607C, 0, 100).unwrap();
        b.w8(0x6098, 0, method as u8).unwrap();
        b.enable(6);
        b.cw(0x1F);
        b.tick();
        let sw = b.node.statusword();
        assert_eq!(sw & 0x3400, 0x1400, "attained + target reached: {sw:#x}");
        assert_eq!(b.node.position_actual(), 100);
    }
}

#[test]
fn homing_on_home_switch_19() {
    let mut b = Bench::new();
    b.start();
    b.drive.home_switch_above = Some(3000.0 * INC_PER_UU);
    b.w8(0x6098, 0, 19).unwrap();
    b.w32(0x6099, 1, 5000).unwrap();
    b.w32(0x609A, 0, 100_000).unwrap();
    b.enable(6);
    b.cw(0x1F);
    b.ticks(50);
    assert_eq!(b.node.statusword() & (1 << 12), 0, "not yet");
    b.ticks(1500);
    let sw = b.node.statusword();
    assert_eq!(sw & 0x3000, 0x1000, "{sw:#x}");
    // home offset 0: the switch edge is position 0; the axis stopped a little past it
    let p = b.node.position_actual();
    assert!((0..200).contains(&p), "{p}");
    // the direct encoder reads the same position
    let d = b.ri32(0x60E4, 1);
    assert!((d - p).abs() <= 1);
}

#[test]
fn homing_on_index_pulse_34_and_unsupported_method() {
    let mut b = Bench::new();
    b.start();
    b.drive.pos = 1000.0;
    b.w8(0x6098, 0, 34).unwrap();
    b.w32(0x6099, 2, 5000).unwrap();
    b.w32(0x609A, 0, 100_000).unwrap();
    b.enable(6);
    b.cw(0x1F);
    b.ticks(3000);
    assert_eq!(b.node.statusword() & 0x3000, 0x1000);
    // index at motor position 65536: position actual = (motor - 65536) / 6.5536
    let expect = ((b.drive.pos.round() - 65536.0) / INC_PER_UU).round() as i32;
    assert!((b.node.position_actual() - expect).abs() <= 1);
    b.cw(0x0F);
    b.w8(0x6098, 0, 99u8).unwrap();
    b.tick();
    b.cw(0x1F);
    b.tick();
    assert_eq!(b.node.statusword() & 0x3000, 0x2000, "homing error");
}

#[test]
fn following_error_faults_with_emcy_8611() {
    let mut b = Bench::new();
    b.start();
    b.w32(0x6065, 0, 100).unwrap();
    b.w16(0x6066, 0, 5).unwrap();
    b.enable(8);
    b.drive.stuck = true;
    b.w32(0x607A, 0, 1000).unwrap();
    b.tick();
    assert!(b.r32(0x60F4, 0) as i32 >= 900);
    b.ticks(3);
    assert_eq!(
        b.node.cia402_state(),
        Cia402State::OperationEnabled,
        "within the time-out"
    );
    b.ticks(5);
    assert!(b.emcys().contains(&0x8611));
    assert_eq!(b.node.cia402_state(), Cia402State::Fault);
    assert!(b.node.statusword() & (1 << 13) != 0, "following error bit");
    assert_eq!(b.r32(0x603F, 0), 0x8611);
}

#[test]
fn actual_values_use_the_factor_group() {
    let mut b = Bench::new();
    b.drive.pos = 65536.0 * 2.0;
    b.drive.vel = 65536.0;
    b.drive.direct_offset = 65.536;
    b.drive.stuck = true;
    b.tick();
    assert_eq!(b.ri32(0x6064, 0), 20_000);
    assert_eq!(b.ri32(0x6063, 0), 131_072);
    assert_eq!(b.ri32(0x606C, 0), 10_000);
    assert_eq!(b.ri32(0x6069, 0), 65_536);
    assert_eq!(b.ri32(0x60E4, 1), 20_010);
    // change the feed constant: 20 mm per rev
    b.w32(0x6092, 1, 20_000).unwrap();
    b.tick();
    assert_eq!(b.ri32(0x6064, 0), 40_000);
    assert_eq!(b.w32(0x6092, 1, 0), Err(0x0609_0032));
}

#[test]
fn one_drive_command_per_poll() {
    let mut b = Bench::new();
    b.ticks(10);
    assert_eq!(b.drive.commands, 10);
    b.start();
    b.enable(8);
    let c = b.drive.commands;
    b.ticks(7);
    assert_eq!(b.drive.commands, c + 7);
}

/// Interpolated position (7): with controlword bit 4 clear the drive holds and 0x60C1:1 follows
/// it; with bit 4 set ("enable ip mode", statusword bit 12 "ip mode active") it interpolates
/// linearly between the set-points written to 0x60C1:1 at each SYNC over 0x60C2.
#[test]
fn ip_interpolates_the_data_record_only_while_enabled() {
    let mut b = Bench::new();
    b.w8(0x60C2, 1, 4).unwrap(); // 4 ms
    b.w8(0x60C2, 2, (-3i8) as u8).unwrap();
    b.start();
    b.enable(7);
    assert_eq!(b.node.mode(), 7);
    let p0 = b.ri32(0x6064, 0);
    // bit 4 clear: a set-point written is not followed, bit 12 clear
    b.w32(0x60C1, 1, (p0 + 5000) as u32).unwrap();
    for _ in 0..5 {
        b.sync();
        b.ticks(4);
    }
    assert_eq!(b.node.statusword() & (1 << 12), 0, "ip mode not active");
    assert!((b.ri32(0x6064, 0) - p0).abs() < 5, "held");
    assert!(
        (b.ri32(0x60C1, 1) - p0).abs() < 5,
        "the set-point follows the axis"
    );
    // bit 4 set: 400 uu per 4 ms SYNC, smooth 100 uu per 1 ms tick
    b.cw(0x1F);
    let start = b.ri32(0x60C1, 1);
    let mut demands = Vec::new();
    for k in 1..=10 {
        b.w32(0x60C1, 1, (start + k * 400) as u32).unwrap();
        b.sync();
        for _ in 0..4 {
            b.tick();
            demands.push(demand(&b) / INC_PER_UU);
        }
    }
    let steps: Vec<f64> = demands.windows(2).map(|w| w[1] - w[0]).collect();
    for s in &steps[4..] {
        assert!((s - 100.0).abs() < 0.5, "step {s} in {steps:?}");
    }
    assert_eq!(b.node.statusword() & (1 << 12), 1 << 12, "ip mode active");
    // 0x60C0: linear interpolation (0) is the only sub-mode
    assert_eq!(b.w16(0x60C0, 0, 1), Err(0x0609_0031));
}
