//! The spectrum analyzer recovers a known sine from a noisy, trending signal.

use drive_emu::analysis::spectrum::{fundamental, SpectrumAnalyzer};
use drive_emu::axis::XorShift64;

#[test]
fn recovers_frequency_and_amplitude_of_a_noisy_sine() {
    // 1 kHz sampling, 3 s, 18.3 Hz sine of amplitude 2.5 (off-bin: bins are 1/3 Hz), plus a
    // linear trend, an offset, a weaker 55 Hz line and Gaussian-like noise of std 0.5.
    // Tolerances: frequency within 0.05 Hz (0.15 bin), amplitude within 3 %.
    let rate = 1000.0;
    let n = 3000;
    let mut rng = XorShift64::new(9);
    let (f0, a0) = (18.3, 2.5);
    let x: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / rate;
            7.0 + 0.8 * t
                + a0 * (2.0 * std::f64::consts::PI * f0 * t + 0.4).sin()
                + 0.6 * (2.0 * std::f64::consts::PI * 55.0 * t).sin()
                + 0.5 * rng.normal()
        })
        .collect();
    let p = fundamental(&x, rate, (1.0, 200.0)).unwrap();
    assert!((p.frequency_hz - f0).abs() < 0.05, "{p:?}");
    assert!((p.amplitude - a0).abs() < 0.03 * a0, "{p:?}");
    // Band limits are honoured: searching 40-100 Hz finds the 55 Hz line.
    let q = fundamental(&x, rate, (40.0, 100.0)).unwrap();
    assert!((q.frequency_hz - 55.0).abs() < 0.05, "{q:?}");
    assert!((q.amplitude - 0.6).abs() < 0.1 * 0.6, "{q:?}");
}

#[test]
fn on_bin_and_between_bins() {
    let rate = 500.0;
    let n = 1000; // 0.5 Hz bins
    let mut an = SpectrumAnalyzer::new(n);
    for f0 in [10.0, 10.25, 33.1] {
        let x: Vec<f64> = (0..n)
            .map(|i| 1.0 * (2.0 * std::f64::consts::PI * f0 * i as f64 / rate).cos())
            .collect();
        let p = an.fundamental(&x, rate, (2.0, 100.0)).unwrap();
        assert!((p.frequency_hz - f0).abs() < 0.02, "{f0}: {p:?}");
        assert!((p.amplitude - 1.0).abs() < 0.02, "{f0}: {p:?}");
    }
    // A constant signal has no line.
    assert!(an.fundamental(&vec![3.0; n], rate, (2.0, 100.0)).is_none());
}
