//! Twin-pinion drives with electrical preload (issue 31, item 1): two motors, each with its
//! own pinion, on one load, the drive's torque split `T/2 +- T_p`.
//!
//! - With the preload at 0 (and the one gap) the two motors move exactly as the lumped one:
//!   the twin model reduces to the single-contact axis bit for bit, over a start ramp, a knock
//!   on the load, a reversal and a stop.
//! - The preload threshold against the deceleration torque: a deceleration whose load torque
//!   per pinion stays below `T_p` keeps pinion A on its flank (no lost motion between the
//!   motor encoder and the direct encoder beyond the elastic wind-up); one above it makes A
//!   cross its gap (lost motion of about the gap at the direct encoder).
//! - A single-contact preset refuses a preload with a clear error; the drive disabled gives
//!   neither motor any torque, the preload included.

use std::f64::consts::PI;

use drive_physics::control::cascade::{Command, Servo, Setpoint};
use drive_physics::presets::{AxisConfig, AxisKind};

const TWINS: [&str; 3] = ["cnc3", "cnc4", "cnc5"];

fn preset(name: &str, sets: &[&str]) -> AxisConfig {
    AxisConfig::from_preset(name)
        .unwrap()
        .with_overrides(sets.iter().copied())
        .unwrap()
}

fn servo(cfg: &AxisConfig) -> Servo {
    let built = cfg.build().unwrap();
    Servo::new(built.axis, built.control).unwrap()
}

/// Cruise velocity at the load, m/s or rad/s: 20 mm/s or the paper's 0.026 r/s.
fn cruise(cfg: &AxisConfig) -> f64 {
    match cfg.kind {
        AxisKind::Linear => 0.020,
        AxisKind::Rotary => 0.026 * 2.0 * PI,
    }
}

fn gap(cfg: &AxisConfig) -> f64 {
    cfg.build().unwrap().axis.mech.contact.backlash
}

#[test]
fn preload_zero_reduces_to_the_single_contact_axis_bit_for_bit() {
    for name in TWINS {
        let twin_cfg = preset(name, &[]);
        assert!(twin_cfg.twin_pinion, "{name} ships as a twin pinion");
        assert_eq!(twin_cfg.preload_pct, 0.0);
        let mut twin = servo(&twin_cfg);
        let mut single = servo(&preset(name, &["twin_pinion=false"]));
        assert!(twin.axis.is_twin_pinion() && !single.axis.is_twin_pinion());
        let v = cruise(&twin_cfg);
        let dt = twin.cycle_time();
        let mass = twin_cfg.build().unwrap().axis.mech.load_mass;
        let (mut pos, mut vel) = (0.0, 0.0);
        let (mut lo, mut hi) = (0.0f64, 0.0f64);
        // 0-0.1 s ramp up, cruise, knock at 1 s, reverse at 2 s, stop at 3 s, hold to 3.5 s.
        let n = (3.5 / dt).round() as usize;
        for i in 0..n {
            let t = i as f64 * dt;
            let target = if t < 2.0 {
                v
            } else if t < 3.0 {
                -v
            } else {
                0.0
            };
            let a = 10.0 * v;
            vel += (target - vel).clamp(-a * dt, a * dt);
            pos += vel * dt;
            let knock = if (1.0..1.005).contains(&t) {
                mass * 0.6 * v / 0.005
            } else {
                0.0
            };
            for s in [&mut twin, &mut single] {
                s.axis.set_external_load(knock);
                s.set_command(Command::new(Setpoint::Position {
                    position: pos,
                    velocity_ff: 0.0,
                    torque_ff: 0.0,
                }));
                s.step();
            }
            let (a, b) = (twin.axis.mech.state, single.axis.mech.state);
            assert_eq!(a.motor, b.motor, "{name}: motor A at {t} s");
            assert_eq!(a.load, b.load, "{name}: load at {t} s");
            assert_eq!(a.motor_b, a.motor, "{name}: motor B apart from A at {t} s");
            assert_eq!(twin.torque(), single.torque(), "{name}: torque at {t} s");
            assert_eq!(twin.current(), single.current(), "{name}: current at {t} s");
            assert_eq!(
                twin.direct_encoder_position(),
                single.direct_encoder_position()
            );
            let d = single.axis.mech.deflection();
            lo = lo.min(d);
            hi = hi.max(d);
        }
        // The run pressed both flanks (it crossed the gap at the reversal).
        let b = gap(&twin_cfg);
        assert!(
            hi > 0.5 * b && lo < -0.5 * b,
            "{name}: {lo} .. {hi}, gap {b}"
        );
    }
}

/// What a deceleration did on a twin pinion.
struct Decel {
    /// Largest force pinion B transmitted to the load while decelerating it, in motor torque
    /// (N m at the motor: the force over the ratio).
    peak_pinion_torque: f64,
    /// The preload torque per motor, N m.
    preload_torque: f64,
    /// Smallest force pinion A pressed the load's positive flank with during the
    /// deceleration, in motor torque (N m; 0 or less: it left that flank).
    min_force_a: f64,
    /// Largest change of `motor encoder at the load - direct encoder` (both as the cascade
    /// sampled them) from its cruise value, m or rad: the lost motion the encoders see.
    lost_motion: f64,
}

/// Cruise at the preset's velocity with `preload_pct`, then decelerate to rest with a smooth
/// (raised-cosine) deceleration whose peak torque per pinion on the load is `share` x the
/// preload torque. Each motor decelerates its own rotor with its own torque: what a pinion
/// transmits is the load's share, `m a / 2` (in motor torque `m a / (2 r)`), and that is what
/// the preload must exceed (docs/physics.md, "Twin pinion").
fn decelerate(name: &str, preload_pct: f64, share: f64) -> Decel {
    let cfg = preset(name, &[&format!("preload_pct={preload_pct}")]);
    let built = cfg.build().unwrap();
    let mech = built.axis.mech;
    let tp = mech.twin.unwrap().preload_torque;
    let mut s = servo(&cfg);
    let dt = s.cycle_time();
    let v = cruise(&cfg);
    // Peak deceleration at the load: m a / (2 r) = share x T_p.
    let a_peak = 2.0 * share * tp * mech.ratio / mech.load_mass;
    // Raised cosine: a(t) = a_peak sin^2(pi t / T), mean a_peak / 2, so T = 2 v / a_peak.
    let t_dec = 2.0 * v / a_peak;
    // Start gently (a third of the preload's acceleration), cruise, then decelerate.
    let a_start = a_peak * 0.33 / share;
    let t_acc = 2.0 * v / a_start;
    let t_cruise_end = t_acc + 1.0;
    let t_end = t_cruise_end + t_dec + 0.5;
    let (mut pos, mut vel) = (0.0, 0.0);
    let mut cruise_between = None;
    let mut out = Decel {
        peak_pinion_torque: 0.0,
        preload_torque: tp,
        min_force_a: f64::INFINITY,
        lost_motion: 0.0,
    };
    let n = (t_end / dt).round() as usize;
    for i in 0..n {
        let t = i as f64 * dt;
        let acc = if t < t_acc {
            a_start * (PI * t / t_acc).sin().powi(2)
        } else if t >= t_cruise_end && t < t_cruise_end + t_dec {
            -a_peak * (PI * (t - t_cruise_end) / t_dec).sin().powi(2)
        } else {
            0.0
        };
        let v_next = vel + acc * dt;
        pos += 0.5 * (vel + v_next) * dt;
        vel = v_next;
        s.set_command(Command::new(Setpoint::Position {
            position: pos,
            velocity_ff: vel,
            torque_ff: 0.0,
        }));
        s.step();
        // Both encoders as the cascade sampled them at the same instant (the motor encoder's
        // own reading is a speed cycle later: a skew of a speed cycle's travel).
        let (motor_counts, direct_counts) = s.cascade.sampled_counts();
        let between =
            motor_counts as f64 / s.axis.motor_encoder.params.counts_per_unit / mech.ratio
                - direct_counts as f64 / s.axis.direct_encoder.params.counts_per_unit;
        if t >= t_cruise_end - 0.2 {
            let c = *cruise_between.get_or_insert(between);
            out.lost_motion = out.lost_motion.max((between - c).abs());
        }
        if t >= t_cruise_end {
            let (fa, fb) = s.axis.mech.pinion_forces();
            out.min_force_a = out.min_force_a.min(fa / mech.ratio);
            out.peak_pinion_torque = out.peak_pinion_torque.max(-fb / mech.ratio);
        }
    }
    out
}

#[test]
fn preload_holds_below_the_deceleration_threshold_and_is_lost_above_it() {
    for name in TWINS {
        let b = gap(&preset(name, &[]));
        for (share, holds) in [(0.7, true), (1.4, false)] {
            let d = decelerate(name, 20.0, share);
            println!(
                "{name}: decel at {share} x T_p: peak torque through pinion B {:.3} N m vs \
                 preload {:.3} N m; pinion A's least force {:.3} N m; lost motion {:.3} of the gap",
                d.peak_pinion_torque,
                d.preload_torque,
                d.min_force_a,
                d.lost_motion / b,
            );
            if holds {
                assert!(
                    d.min_force_a > 0.0,
                    "{name}: pinion A left its flank below the threshold"
                );
                assert!(
                    d.lost_motion < 0.5 * b,
                    "{name}: lost motion {} with the preload holding (gap {b})",
                    d.lost_motion
                );
            } else {
                assert!(
                    d.min_force_a <= 0.0,
                    "{name}: pinion A never left its flank"
                );
                assert!(
                    d.lost_motion > 0.8 * b,
                    "{name}: lost motion {} only with the preload exceeded (gap {b})",
                    d.lost_motion
                );
            }
        }
    }
}

#[test]
fn single_contact_refuses_a_preload_and_twin_takes_it_live() {
    let e = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("preload_pct", "20")
        .unwrap_err();
    assert_eq!(e.key, "preload_pct");
    assert!(e.reason.contains("single-contact"), "{e}");
    let e = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("twin_pinion", "true")
        .unwrap_err();
    assert_eq!(e.key, "twin_pinion");
    assert!(e.reason.contains("lead screw"), "{e}");
    for bad in ["-1", "101", "nan"] {
        let e = preset("cnc3", &[])
            .with_override("preload_pct", bad)
            .unwrap_err();
        assert_eq!(e.key, "preload_pct", "{bad}: {e}");
    }
    // Live: the single-contact axis refuses and keeps nothing; the twin takes it.
    let mut one = servo(&preset("cnc1", &[]));
    assert!(one.axis.set_preload(0.2).is_err());
    assert_eq!(one.axis.preload(), None);
    let cfg = preset("cnc3", &["preload_pct=20"]);
    let mut two = servo(&cfg);
    assert!((two.axis.preload().unwrap() - 0.2).abs() < 1e-12);
    assert!(two.axis.set_preload(-0.1).is_err());
    two.axis.set_preload(0.05).unwrap();
    assert!((two.axis.preload().unwrap() - 0.05).abs() < 1e-12);
    let tp = two.axis.mech.params().twin.unwrap().preload_torque;
    assert!((tp - 0.05 * 0.5 * cfg.rated_torque_nm).abs() < 1e-12);
}

#[test]
fn preload_presses_both_flanks_at_rest_and_nothing_pushes_while_disabled() {
    let cfg = preset("cnc4", &["preload_pct=20"]);
    let b = gap(&cfg);
    let mut s = servo(&cfg);
    let dt = s.cycle_time();
    // Disabled: no torque at all, the motors stay at the centre of their gaps.
    for _ in 0..200 {
        s.set_command(Command::DISABLED);
        s.step();
    }
    assert_eq!(s.axis.motor_torques(), (0.0, 0.0));
    assert_eq!(s.torque(), 0.0);
    assert!(s.axis.mech.deflection().abs() < 0.5 * b);
    // Enabled at rest: A on the positive flank, B on the negative one, the load still.
    for _ in 0..(0.5 / dt) as usize {
        s.set_command(Command::new(Setpoint::Position {
            position: 0.0,
            velocity_ff: 0.0,
            torque_ff: 0.0,
        }));
        s.step();
    }
    let (ta, tb) = s.axis.motor_torques();
    let tp = s.axis.mech.params().twin.unwrap().preload_torque;
    assert!(ta > 0.8 * tp && tb < -0.8 * tp, "{ta} {tb} (T_p {tp})");
    assert!(s.axis.mech.deflection() > 0.5 * b, "A not on its flank");
    assert!(s.axis.mech.deflection_b() < -0.5 * b, "B not on its flank");
    assert!(s.axis.load_velocity().abs() < 1e-9);
    // The drive's torque is the sum: the bias cancels, what is left is the speed loop's
    // quantisation jitter at rest.
    assert!(
        (s.torque() - (ta + tb)).abs() < 1e-12 && s.torque().abs() < 0.25 * tp,
        "{} (T_p {tp})",
        s.torque()
    );
}
