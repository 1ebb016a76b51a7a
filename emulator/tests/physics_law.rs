//! The paper's law over sweeps (issue 10): on every preset, measured from the simulated trace
//! (FFT of the measured motor speed at constant speed after a start disturbance, simulated
//! time only), the limit-cycle frequency follows the position gain k_v and not the gap.
//!
//! - f / k_v within 0.6 +- 0.1 and k_v/4 < f < k_v (eq. 11-13) from half to twice each preset's
//!   own k_v, and for CNC1 over 10..80 1/s, wherever the drag number `D / (m k_v^2 b)` is
//!   below the boundary the next test measures (docs/physics.md);
//! - the limit cycle's boundary: it lives below drag number 1.2 and dies above 2.5, whatever
//!   k_v, the gap or the drag (a sweep across the boundary on CNC1);
//! - f(2 k_v) / f(k_v) close to 2;
//! - f independent of the gap (spread <= 5 %) over 0.02-0.07 mm / 0.01-0.04 deg, amplitude
//!   growing with it;
//! - no sustained oscillation without backlash;
//! - the closed speed loop, measured by exciting the drive: -3 dB bandwidth in the paper's
//!   150-250 Hz, ~1 (|H| < 3 dB, phase lag < 20 deg) up to 40 Hz.

use drive_emu::presets::{preset_names, AxisConfig};
use drive_emu::study::response::{log_frequencies, speed_loop_response};
use drive_emu::study::{
    backlash_key, default_velocity, own_backlash, run_cases, Case, CaseRow,
    DRAG_NUMBER_CYCLE_BELOW, DRAG_NUMBER_NO_CYCLE_ABOVE, LIMIT_CYCLE_MIN_RELATIVE_AMPLITUDE,
};
const DURATION_S: f64 = 6.0;

fn preset(name: &str) -> AxisConfig {
    AxisConfig::from_preset(name).unwrap()
}

fn case(cfg: &AxisConfig, kv: f64, backlash: f64) -> (AxisConfig, Case) {
    (
        cfg.clone(),
        Case {
            preset: cfg.name.clone(),
            kv_per_s: kv,
            backlash,
            velocity: default_velocity(cfg),
            duration_s: DURATION_S,
        },
    )
}

fn run(cases: &[(AxisConfig, Case)]) -> Vec<CaseRow> {
    run_cases(cases, 0)
        .into_iter()
        .map(|r| r.expect("valid case"))
        .collect()
}

fn show(r: &CaseRow) -> String {
    format!(
        "{} k_v {:.1} backlash {} {}: f {:?} Hz, f/k_v {:?}, amplitude {:.4} {}/s, cycle {}, drag number {:.2}",
        r.preset,
        r.kv_per_s,
        r.backlash,
        r.unit,
        r.fundamental_hz.map(|f| (f * 100.0).round() / 100.0),
        r.f_over_kv.map(|x| (x * 1000.0).round() / 1000.0),
        r.load_velocity_amplitude,
        r.unit,
        r.limit_cycle,
        r.drag_number
    )
}

#[test]
fn law_from_half_to_twice_kv_on_every_preset() {
    let mut cases = Vec::new();
    for name in preset_names() {
        let cfg = preset(name);
        let own = cfg.kv_per_s;
        let kvs: Vec<f64> = if name == "cnc1" {
            (1..=8).map(|i| 10.0 * i as f64).collect()
        } else {
            [0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0]
                .iter()
                .map(|m| m * own)
                .collect()
        };
        for kv in kvs {
            cases.push(case(&cfg, kv, own_backlash(&cfg)));
        }
    }
    let rows = run(&cases);
    let mut failures = Vec::new();
    for r in &rows {
        println!("{}", show(r));
        if !r.limit_cycle {
            if r.drag_number <= DRAG_NUMBER_CYCLE_BELOW {
                failures.push(format!(
                    "no limit cycle below the drag boundary: {}",
                    show(r)
                ));
            }
            continue;
        }
        let f = r.fundamental_hz.unwrap();
        if !(f > r.kv_per_s / 4.0 && f < r.kv_per_s) {
            failures.push(format!("outside k_v/4 < f < k_v: {}", show(r)));
        }
        if (r.f_over_kv.unwrap() - 0.6).abs() > 0.1 {
            failures.push(format!("f/k_v outside 0.6 +- 0.1: {}", show(r)));
        }
    }
    // The presets' own k_v and everything above always oscillate.
    let own_missing = rows
        .iter()
        .filter(|r| r.kv_per_s >= preset(&r.preset).kv_per_s && !r.limit_cycle)
        .count();
    assert_eq!(own_missing, 0, "no limit cycle at or above the own k_v");
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn limit_cycle_lives_below_the_drag_boundary() {
    // CNC1 with Coulomb drag only (viscous 0), set so that the drag number D / (m k_v^2 b)
    // takes values on both sides of the boundary, at three k_v and two gaps: the boundary is a
    // number, not a k_v or a gap.
    let base = preset("cnc1")
        .with_override("load_viscous_friction_n_per_m_per_s", "0")
        .unwrap();
    let mut cases = Vec::new();
    let mut expect = Vec::new();
    for kv in [10.0, 20.0, 40.0] {
        for gap_mm in [0.03, 0.06] {
            for pi in [0.5, 1.0, 3.0, 4.0] {
                let drag_n = pi * base.carriage_mass_kg.unwrap() * kv * kv * gap_mm * 1e-3;
                let cfg = base
                    .with_override("load_coulomb_friction_n", &format!("{drag_n}"))
                    .unwrap();
                cases.push(case(&cfg, kv, gap_mm));
                expect.push(pi);
            }
        }
    }
    let rows = run(&cases);
    let mut failures = Vec::new();
    for (r, pi) in rows.iter().zip(expect) {
        println!("{}", show(r));
        assert!((r.drag_number - pi).abs() < 1e-6 * pi, "{}", show(r));
        if pi <= DRAG_NUMBER_CYCLE_BELOW && !r.limit_cycle {
            failures.push(format!("no cycle below the boundary: {}", show(r)));
        }
        if pi >= DRAG_NUMBER_NO_CYCLE_ABOVE && r.limit_cycle {
            failures.push(format!("a cycle above the boundary: {}", show(r)));
        }
        if r.limit_cycle && (r.f_over_kv.unwrap() - 0.6).abs() > 0.1 {
            failures.push(format!("f/k_v outside 0.6 +- 0.1: {}", show(r)));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn doubling_kv_doubles_f() {
    let mut cases = Vec::new();
    for name in preset_names() {
        let cfg = preset(name);
        for m in [1.0, 2.0] {
            cases.push(case(&cfg, m * cfg.kv_per_s, own_backlash(&cfg)));
        }
    }
    let cfg = preset("cnc1");
    for kv in [20.0, 40.0] {
        cases.push(case(&cfg, kv, own_backlash(&cfg)));
    }
    let rows = run(&cases);
    for pair in rows.chunks(2) {
        let (a, b) = (&pair[0], &pair[1]);
        assert!(a.limit_cycle && b.limit_cycle, "{}\n{}", show(a), show(b));
        let ratio = b.fundamental_hz.unwrap() / a.fundamental_hz.unwrap();
        println!(
            "{} k_v {} -> {}: f ratio {ratio:.3}",
            a.preset, a.kv_per_s, b.kv_per_s
        );
        assert!(
            (1.75..=2.25).contains(&ratio),
            "f(2 k_v) / f(k_v) = {ratio:.3}\n{}\n{}",
            show(a),
            show(b)
        );
    }
}

#[test]
fn frequency_independent_of_gap_amplitude_grows() {
    let mut groups = Vec::new();
    for name in preset_names() {
        let cfg = preset(name);
        let gaps: Vec<f64> = if backlash_key(&cfg) == "backlash_mm" {
            vec![0.02, 0.03, 0.04, 0.05, 0.06, 0.07]
        } else {
            vec![0.01, 0.02, 0.03, 0.04]
        };
        let cases: Vec<_> = gaps.iter().map(|&b| case(&cfg, cfg.kv_per_s, b)).collect();
        groups.push(run(&cases));
    }
    for rows in &groups {
        for r in rows {
            println!("{}", show(r));
            assert!(r.limit_cycle, "{}", show(r));
        }
        let f: Vec<f64> = rows.iter().map(|r| r.fundamental_hz.unwrap()).collect();
        let (lo, hi) = f
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), &x| (l.min(x), h.max(x)));
        let mean = f.iter().sum::<f64>() / f.len() as f64;
        assert!(
            hi - lo <= 0.05 * mean,
            "{}: f spread {:.1} % over the gaps: {f:?}",
            rows[0].preset,
            100.0 * (hi - lo) / mean
        );
        for w in rows.windows(2) {
            assert!(
                w[1].load_velocity_amplitude > w[0].load_velocity_amplitude,
                "amplitude does not grow with the gap:\n{}\n{}",
                show(&w[0]),
                show(&w[1])
            );
        }
    }
}

#[test]
fn no_sustained_oscillation_without_backlash() {
    let mut cases = Vec::new();
    for name in preset_names() {
        let cfg = preset(name);
        for m in [0.5, 1.0, 2.0] {
            cases.push(case(&cfg, m * cfg.kv_per_s, own_backlash(&cfg)));
            cases.push(case(&cfg, m * cfg.kv_per_s, 0.0));
        }
    }
    let rows = run(&cases);
    for pair in rows.chunks(2) {
        let (worn, healthy) = (&pair[0], &pair[1]);
        println!("{}\n{}", show(worn), show(healthy));
        // The same bound that classifies a limit cycle at the preset's own gap.
        let bound = LIMIT_CYCLE_MIN_RELATIVE_AMPLITUDE * worn.kv_per_s * worn.backlash;
        assert!(
            healthy.load_velocity_amplitude < bound,
            "without backlash: {} (bound {bound})",
            show(healthy)
        );
        if worn.limit_cycle {
            assert!(
                healthy.load_velocity_amplitude < 0.05 * worn.load_velocity_amplitude,
                "{}\n{}",
                show(worn),
                show(healthy)
            );
        }
    }
}

#[test]
fn speed_loop_bandwidth_in_the_papers_band() {
    // The paper (section III, Fig. 3): closed speed loop -3 dB at about 180 Hz (the issue: 150 to
    // 250 Hz), and ~1 at the vibration frequencies ("less than 3 dB"; most vibrations below
    // 30 Hz). Measured by exciting the drive; the presets derive k_sp and T_si by the symmetric
    // optimum on the drive's small time constants (docs/physics.md), which peaks by about
    // 3.8 dB near 55 Hz: the magnitude is asserted within 3 dB up to 40 Hz, the peak below 4 dB.
    for name in preset_names() {
        let cfg = preset(name);
        let cfg = cfg.with_override(backlash_key(&cfg), "0").unwrap();
        let r = speed_loop_response(&cfg, &log_frequencies(5.0, 1000.0, 31), 300.0, 5.0).unwrap();
        let bw = r.bandwidth_3db_hz.expect("a -3 dB point below 1 kHz");
        let peak = r.points.iter().fold(f64::MIN, |m, p| m.max(p.magnitude_db));
        println!("{name}: closed speed loop -3 dB at {bw:.0} Hz, peak {peak:.2} dB");
        assert!((150.0..=250.0).contains(&bw), "{name}: -3 dB at {bw} Hz");
        assert!(peak < 4.0, "{name}: peak {peak} dB");
        for p in r.points.iter().filter(|p| p.frequency_hz <= 40.0) {
            assert!(
                p.magnitude_db.abs() < 3.0 && p.phase_deg > -20.0,
                "{name}: not ~1 at {:.1} Hz: {:.2} dB, {:.1} deg",
                p.frequency_hz,
                p.magnitude_db,
                p.phase_deg
            );
        }
    }
}
