//! Set-points with noise quench the backlash limit cycle (dither), and the gap estimate says
//! so (`amplitude_lower_bound`, its range reaching `gap::DITHER_QUENCH` times higher) instead
//! of a number that is only a lower bound (docs/scenarios.md, "How large is the gap").
//!
//! Over presets cnc1 and cnc2 x k_v 0.7, 1, 1.4 x the preset's, 0.05 mm, 10 mm/s, the axis
//! run twice by the simulator's cascade with a master's CSP set-points every 4 ms, linearly
//! interpolated in between with their slope as the velocity feed-forward, as the drive does: exact, and each sampled up to +-5 % of the
//! period off its time (uniform, a fixed seed: the python master of the capture corpus,
//! whose set-points jitter so). Physical claim: the limit cycle is smaller with the jitter,
//! in every case. The estimate, from the limit cycle's amplitude (one
//! encoder): with exact set-points within 30 % and method `amplitude`; with noise a lower
//! bound whose range holds the truth.

use drive_emu::analysis::detector::{analyze, AxisTrace, DetectorConfig, Verdict};
use drive_emu::analysis::gap::{CurrentUnit, GapMethod, GapModel};
use drive_emu::control::{Command, Servo, Setpoint};
use drive_emu::presets::AxisConfig;

const GAP_MM: f64 = 0.05;
const SPEED_MM_S: f64 = 10.0;
/// The master's set-point period, s, and how far off its time a set-point is sampled, share
/// of the period.
const PERIOD_S: f64 = 0.004;
const JITTER: f64 = 0.05;

/// A run at constant speed with a knock after the ramp (the limit cycle is a hard
/// excitation), the set-points every [`PERIOD_S`] sampled up to `jitter` x the period off
/// their time and interpolated in between; the detector's trace of the part after the knock,
/// with the direct encoder as the only encoder.
fn run(cfg: &AxisConfig, jitter: f64) -> AxisTrace {
    let built = cfg.build().unwrap();
    let mut servo = Servo::new(built.axis, built.control).unwrap();
    let dt = servo.cycle_time();
    let v = SPEED_MM_S * 1e-3;
    let accel = v / 0.1;
    let settle = 0.1 + 5.0 / cfg.kv_per_s;
    // the master's profile: ramp, then cruise
    let t_ramp = v / accel;
    let profile = |t: f64| {
        let t = t.max(0.0);
        if t < t_ramp {
            0.5 * accel * t * t
        } else {
            0.5 * accel * t_ramp * t_ramp + v * (t - t_ramp)
        }
    };
    let n = (4.0 / dt).round() as usize;
    let kick_at = (settle / dt).ceil() as usize;
    let kick_cycles = (0.005 / dt).round().max(1.0) as usize;
    let kick_force = built.axis.mech.load_mass * 0.6 * v / (kick_cycles as f64 * dt);
    let first = kick_at + (0.2 / dt) as usize;
    // xorshift: the same noise on every run
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut uniform = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let (mut t, mut sp, mut x, mut rpm, mut amps) = (vec![], vec![], vec![], vec![], vec![]);
    let per_period = (PERIOD_S / dt).round() as usize;
    let (mut from, mut to) = (0.0, profile(PERIOD_S));
    for i in 0..n {
        if i % per_period == 0 {
            let k = (i / per_period + 1) as f64;
            from = to;
            to = profile((k + jitter * uniform()) * PERIOD_S);
        }
        let on = i >= kick_at && i < kick_at + kick_cycles;
        servo
            .axis
            .set_external_load(if on { kick_force } else { 0.0 });
        let position = from + (to - from) * (i % per_period) as f64 / per_period as f64;
        // the drive's CSP: the set-point's slope as the velocity feed-forward
        // (protocol/src/cia402/csp.rs)
        servo.set_command(Command::new(Setpoint::Position {
            position,
            velocity_ff: (to - from) / PERIOD_S,
            torque_ff: 0.0,
        }));
        servo.step();
        if i >= first {
            t.push(servo.time());
            sp.push(position * 1e3);
            x.push(servo.direct_encoder_position() * 1e3);
            rpm.push(servo.motor_velocity() * 30.0 / std::f64::consts::PI);
            amps.push(servo.current());
        }
    }
    AxisTrace::from_sim(&t, &sp, &x, &x, &rpm, &amps, false)
}

#[test]
fn noisy_set_points_quench_the_limit_cycle_and_the_estimate_says_it_is_a_lower_bound() {
    let mut table = String::new();
    let mut failures = Vec::new();
    for preset in ["cnc1", "cnc2"] {
        for kv_factor in [0.7, 1.0, 1.4] {
            let base = AxisConfig::from_preset(preset).unwrap();
            let kv = base.kv_per_s * kv_factor;
            let cfg = base
                .with_override("backlash_mm", &GAP_MM.to_string())
                .unwrap()
                .with_override("kv_per_s", &kv.to_string())
                .unwrap();
            let mut dc = DetectorConfig::new(kv);
            dc.windows.settle_s = 0.2;
            dc.windows.min_len_s = 1.0;
            dc.gap = GapModel::for_axis(&cfg, CurrentUnit::Ampere);
            let clean = analyze(&run(&cfg, 0.0), &dc);
            let noisy = analyze(&run(&cfg, JITTER), &dc);
            let amp = |r: &drive_emu::analysis::detector::DetectorReport| {
                r.windows
                    .iter()
                    .map(|w| w.displacement_amplitude)
                    .fold(0.0, f64::max)
            };
            let (a0, a1) = (amp(&clean), amp(&noisy));
            let e0 = clean.backlash_estimate.estimate;
            let e1 = noisy.backlash_estimate.estimate;
            table += &format!(
                "{preset} k_v {kv:5.1}: amplitude {a0:.2} -> {a1:.2} um ({:.2}); estimate {:?} -> {:?}\n",
                a1 / a0,
                e0.map(|e| (e.value / 1e3, e.method)),
                e1.map(|e| (e.value / 1e3, e.lo / 1e3, e.hi / 1e3, e.method)),
            );
            let case = format!("{preset} k_v {kv}");
            if clean.verdict < Verdict::BacklashSuspected {
                failures.push(format!("{case}: no limit cycle with exact set-points"));
                continue;
            }
            // the physical claim: the noise makes the limit cycle smaller
            if a1 >= 0.9 * a0 {
                failures.push(format!(
                    "{case}: amplitude {a0:.2} -> {a1:.2} um with noise"
                ));
            }
            match e0 {
                Some(e) if e.method == GapMethod::Amplitude => {
                    if (e.value / 1e3 - GAP_MM).abs() > 0.3 * GAP_MM {
                        failures.push(format!("{case}: exact set-points, estimate {e:?}"));
                    }
                }
                other => failures.push(format!("{case}: exact set-points, estimate {other:?}")),
            }
            if noisy.verdict >= Verdict::BacklashSuspected {
                match e1 {
                    Some(e) if e.method == GapMethod::AmplitudeLowerBound => {
                        if !(e.lo / 1e3 <= GAP_MM && GAP_MM <= e.hi / 1e3) {
                            failures.push(format!("{case}: noisy, truth outside {e:?}"));
                        }
                    }
                    other => failures.push(format!("{case}: noisy, estimate {other:?}")),
                }
            } else if e1.is_some() {
                failures.push(format!("{case}: an estimate without a flagged window"));
            }
        }
    }
    println!("{table}");
    assert!(failures.is_empty(), "{failures:#?}\n{table}");
}
