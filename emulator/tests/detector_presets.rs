//! The backlash detector on simulated axes: quiet on every preset without backlash, flags worn
//! backlash, and its frequency agrees with an independent DFT of the same samples.

use drive_emu::analysis::detector::{analyze, AxisTrace, DetectorConfig, Verdict};
use drive_emu::analysis::{constant_velocity_run, RunOptions};
use drive_emu::presets::{preset_names, AxisConfig, AxisKind};

fn run(preset: &str, backlash: f64) -> (AxisTrace, f64) {
    let cfg = AxisConfig::from_preset(preset).unwrap();
    let rotary = cfg.kind == AxisKind::Rotary;
    let key = if rotary {
        "backlash_deg"
    } else {
        "backlash_mm"
    };
    let cfg = cfg.with_override(key, &format!("{backlash}")).unwrap();
    let opts = RunOptions {
        velocity: if rotary { 10.0 } else { 1000.0 / 60.0 },
        duration: 4.0,
        accel: 0.0,
        record: true,
        kick: None,
    };
    let r = constant_velocity_run(&cfg, &opts).unwrap();
    let t = &r.trace;
    let tr = AxisTrace::from_sim(
        &t.time_s,
        &t.position_setpoint,
        &t.motor_position,
        &t.direct_position,
        &t.motor_velocity_rpm,
        &t.current_a,
        rotary,
    );
    (tr, cfg.kv_per_s)
}

/// Plain DFT magnitude at frequency f (Hz) of x sampled at times t, mean removed, Hann window.
fn dft_mag(t: &[f64], x: &[f64], f: f64) -> f64 {
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let (mut re, mut im) = (0.0, 0.0);
    for i in 0..n {
        let w = 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos();
        let ph = 2.0 * std::f64::consts::PI * f * t[i];
        re += (x[i] - mean) * w * ph.cos();
        im -= (x[i] - mean) * w * ph.sin();
    }
    (re * re + im * im).sqrt()
}

/// The strongest frequency in lo..hi on a 0.05 Hz grid.
fn dft_peak(t: &[f64], x: &[f64], lo: f64, hi: f64) -> f64 {
    let mut best = (lo, 0.0);
    let mut f = lo;
    while f <= hi {
        let m = dft_mag(t, x, f);
        if m > best.1 {
            best = (f, m);
        }
        f += 0.05;
    }
    best.0
}

#[test]
fn quiet_on_every_preset_without_backlash() {
    for p in preset_names() {
        let (tr, kv) = run(p, 0.0);
        let rep = analyze(&tr, &DetectorConfig::new(kv));
        assert!(!rep.windows.is_empty(), "{p}: no constant-velocity window");
        assert_eq!(
            rep.verdict,
            Verdict::Ok,
            "{p}: {:?}",
            rep.windows
                .iter()
                .map(|w| (w.speed_hz, w.displacement_amplitude, w.prominence))
                .collect::<Vec<_>>()
        );
    }
}

#[test]
fn flags_worn_cnc1_and_the_frequency_matches_an_independent_dft() {
    let (tr, kv) = run("cnc1", 0.05);
    let rep = analyze(&tr, &DetectorConfig::new(kv));
    assert_ne!(rep.verdict, Verdict::Ok, "{rep:#?}");
    let f = rep.frequency_hz.expect("a frequency");
    let ratio = f / kv;
    assert!((0.25..=1.0).contains(&ratio), "f/kv {ratio}");
    // Independent check on the same window's samples.
    let w = rep.windows.last().unwrap();
    let fw = w.speed_hz.unwrap();
    let fd = dft_peak(
        &tr.t_s[w.start..w.end],
        &tr.motor_velocity[w.start..w.end],
        0.5 * kv / 4.0,
        2.0 * kv,
    );
    assert!(
        (fw - fd).abs() <= 0.05 * fd,
        "detector {fw} Hz, DFT {fd} Hz"
    );
}

#[test]
fn amplitude_grows_with_the_gap_and_the_frequency_does_not_move() {
    let mut last = 0.0;
    let mut freqs = Vec::new();
    for b in [0.02, 0.04, 0.07] {
        let (tr, kv) = run("cnc1", b);
        let rep = analyze(&tr, &DetectorConfig::new(kv));
        assert!(
            rep.amplitude > last,
            "gap {b}: amplitude {} <= {last}",
            rep.amplitude
        );
        last = rep.amplitude;
        freqs.push(rep.dominant_hz.unwrap());
    }
    let (lo, hi) = freqs
        .iter()
        .fold((f64::MAX, 0.0f64), |(l, h), f| (l.min(*f), h.max(*f)));
    assert!(hi / lo < 1.1, "frequency moved with the gap: {freqs:?}");
}
