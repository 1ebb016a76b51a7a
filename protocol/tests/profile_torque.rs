//! Profile torque mode (0x6060 = 4) against the simple drive model: the torque demand 0x6074
//! ramps to the target 0x6071 at the slope 0x6087 (measured from every tick's sample), target
//! reached when it is there, halt ramps it to 0, 0x6072 limits it, 0x6088 takes linear only.
mod common;
use common::*;
use drive_protocol::Setpoint;

const TARGET_REACHED: u16 = 1 << 10;
const INTERNAL_LIMIT: u16 = 1 << 11;

fn torque_setpoint(b: &Bench) -> f64 {
    match b.drive.last.unwrap().setpoint {
        Setpoint::Torque { torque_permille } => torque_permille,
        s => panic!("not a torque set-point: {s:?}"),
    }
}

fn demand_0x6074(b: &Bench) -> i32 {
    b.node.object_raw(0x6074, 0).expect("0x6074") as u16 as i16 as i32
}

fn pt_bench(slope_permille_per_s: u32) -> Bench {
    let mut b = Bench::new();
    b.start();
    b.w32(0x6087, 0, slope_permille_per_s).unwrap();
    b.enable(4);
    assert_eq!(b.node.mode(), 4, "mode display PT");
    b
}

/// Ticks until the demand stops moving; the samples (0x6074 and the set-point) of each tick.
fn ramp(b: &mut Bench, max_ticks: usize) -> Vec<(i32, f64)> {
    let mut v = Vec::new();
    for _ in 0..max_ticks {
        b.tick();
        v.push((demand_0x6074(b), torque_setpoint(b)));
        if b.node.statusword() & TARGET_REACHED != 0 {
            break;
        }
    }
    v
}

#[test]
fn the_demand_ramps_to_the_target_at_the_slope_over_a_sweep() {
    for slope in [2_000u32, 10_000, 50_000] {
        for target in [300i16, -150, 1000] {
            let mut b = pt_bench(slope);
            assert_eq!(demand_0x6074(&b), 0, "{slope} {target}: starts at 0");
            b.w16(0x6071, 0, target as u16).unwrap();
            let per_tick = slope as f64 * DT_US as f64 * 1e-6;
            let want_ticks = (f64::from(target).abs() / per_tick).ceil() as usize;
            let s = ramp(&mut b, want_ticks + 50);
            let at = |k: usize| s[k].1;
            // every tick on the way moves the demand by the slope times the tick, toward the
            // target, and not beyond it
            for k in 1..s.len() - 1 {
                let d = at(k) - at(k - 1);
                assert!(
                    (d.abs() - per_tick).abs() < 1e-9 && d.signum() == f64::from(target).signum(),
                    "{slope} {target}: tick {k} moved {d}, slope says {per_tick}"
                );
            }
            // the slope measured over the whole ramp
            let (first, last) = (s[0].1, s[s.len() - 2].1);
            let measured_permille_per_s =
                (last - first).abs() / ((s.len() - 2) as f64 * DT_US as f64 * 1e-6);
            assert!(
                (measured_permille_per_s - slope as f64).abs() < 1e-6 * slope as f64,
                "{slope} {target}: measured {measured_permille_per_s} per mille/s"
            );
            assert_eq!(s.last().unwrap().1, f64::from(target), "{slope} {target}");
            assert_eq!(s.last().unwrap().0, i32::from(target), "0x6074");
            assert!(
                s.len().abs_diff(want_ticks) <= 1,
                "{slope} {target}: reached after {} ticks, slope says {want_ticks}",
                s.len()
            );
            assert!(b.node.statusword() & TARGET_REACHED != 0, "target reached");
            // the axis accelerates with the torque's sign
            let v0 = b.drive.vel;
            b.ticks(20);
            assert_eq!(
                (b.drive.vel - v0).signum(),
                f64::from(target).signum(),
                "{slope} {target}: axis speed {v0} -> {}",
                b.drive.vel
            );
        }
    }
}

#[test]
fn target_reached_clears_while_the_demand_ramps() {
    let mut b = pt_bench(10_000);
    b.tick();
    assert!(
        b.node.statusword() & TARGET_REACHED != 0,
        "0 reached at once"
    );
    b.w16(0x6071, 0, 500).unwrap();
    b.tick();
    assert!(b.node.statusword() & TARGET_REACHED == 0, "ramping");
    assert_eq!(demand_0x6074(&b), 10);
}

#[test]
fn halt_ramps_the_demand_to_zero_and_release_resumes() {
    let mut b = pt_bench(20_000);
    b.w16(0x6071, 0, 400).unwrap();
    b.ticks(30);
    assert_eq!(torque_setpoint(&b), 400.0);
    b.cw(0x10F); // halt
    let s = ramp(&mut b, 100);
    for w in s.windows(2) {
        assert!(w[1].1 <= w[0].1, "halt: the demand only falls: {s:?}");
        assert!(w[0].1 - w[1].1 <= 20.0 + 1e-9, "at the slope: {s:?}");
    }
    assert_eq!(s.last().unwrap().1, 0.0, "halt: demand 0");
    assert_eq!(s.len(), 20, "400 per mille at 20 per tick");
    assert!(b.node.statusword() & TARGET_REACHED != 0, "halted");
    b.ticks(10);
    assert_eq!(torque_setpoint(&b), 0.0, "held at 0 while halted");
    b.cw(0x0F);
    b.ticks(30);
    assert_eq!(torque_setpoint(&b), 400.0, "resumed");
}

#[test]
fn max_torque_limits_the_target_and_a_zero_slope_is_a_step() {
    let mut b = pt_bench(0);
    b.w16(0x6072, 0, 250).unwrap();
    b.w16(0x6071, 0, (-600i16) as u16).unwrap();
    b.tick();
    assert_eq!(torque_setpoint(&b), -250.0, "a step to the limit");
    let sw = b.node.statusword();
    assert!(sw & INTERNAL_LIMIT != 0, "internal limit: {sw:#06x}");
    assert!(sw & TARGET_REACHED != 0, "{sw:#06x}");
}

#[test]
fn quick_stop_leaves_the_torque_mode_for_the_stop_ramp() {
    let mut b = pt_bench(50_000);
    b.w16(0x6071, 0, 300).unwrap();
    b.ticks(100);
    assert!(b.drive.vel > 0.0);
    b.cw(0x0B); // quick stop
    b.ticks(2000);
    assert!(
        b.drive.vel.abs() < 1.0,
        "stopped by the quick-stop ramp: {}",
        b.drive.vel
    );
    assert!(!matches!(
        b.drive.last.unwrap().setpoint,
        Setpoint::Torque { .. }
    ));
}

#[test]
fn pt_is_a_supported_mode_and_0x6088_takes_the_linear_ramp_only() {
    let mut b = Bench::new();
    assert_eq!(b.r32(0x6502, 0) & (1 << 3), 1 << 3, "0x6502 bit 3");
    assert_eq!(b.w16(0x6088, 0, 0), Ok(()));
    assert_eq!(
        b.w16(0x6088, 0, 1),
        Err(0x0609_0031),
        "sin^2 ramp: not offered"
    );
    assert_eq!(b.r32(0x6087, 0), 10_000, "default slope");
}
