//! Fundamental frequency and amplitude of a sampled signal.
//!
//! Steps: remove the linear trend (mean and slope), Hann window, real FFT (realfft), peak
//! search within a band, quadratic interpolation of the log-magnitude around the peak bin
//! (Gaussian interpolation, accurate for a Hann window) for a sub-bin frequency and a
//! scalloping-corrected amplitude, then correction for the window's coherent gain.
//!
//! [`SpectrumAnalyzer`] plans once and reuses its buffers (no allocation per call);
//! [`fundamental`] is the one-shot convenience.

use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};

/// The dominant spectral line in a band.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Peak {
    /// Interpolated frequency, Hz.
    pub frequency_hz: f64,
    /// Amplitude (zero-to-peak) of the sine at that frequency, in the signal's unit.
    pub amplitude: f64,
    /// Index of the peak bin.
    pub bin: usize,
    /// Bin spacing, Hz.
    pub resolution_hz: f64,
}

/// Reusable analyzer for signals of a fixed length.
pub struct SpectrumAnalyzer {
    len: usize,
    fft: Arc<dyn RealToComplex<f64>>,
    window: Vec<f64>,
    window_sum: f64,
    input: Vec<f64>,
    output: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
    magnitude: Vec<f64>,
}

impl SpectrumAnalyzer {
    /// Analyzer for signals of `len` samples (`len >= 8`).
    pub fn new(len: usize) -> Self {
        assert!(len >= 8, "spectrum needs at least 8 samples");
        let mut planner = RealFftPlanner::<f64>::new();
        let fft = planner.plan_fft_forward(len);
        let window: Vec<f64> = (0..len)
            .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / len as f64).cos())
            .collect();
        let window_sum = window.iter().sum();
        let input = fft.make_input_vec();
        let output = fft.make_output_vec();
        let scratch = fft.make_scratch_vec();
        let magnitude = vec![0.0; output.len()];
        SpectrumAnalyzer {
            len,
            fft,
            window,
            window_sum,
            input,
            output,
            scratch,
            magnitude,
        }
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Amplitude spectrum (zero-to-peak per bin, window-corrected) of the last analysis.
    pub fn amplitudes(&self) -> &[f64] {
        &self.magnitude
    }

    /// Strongest line of `signal` (exactly `len` samples, rate `sample_rate_hz`) with
    /// frequency within `[band.0, band.1]` Hz. `None` if the band holds no interior bin or the
    /// signal is constant.
    pub fn fundamental(
        &mut self,
        signal: &[f64],
        sample_rate_hz: f64,
        band: (f64, f64),
    ) -> Option<Peak> {
        assert_eq!(
            signal.len(),
            self.len,
            "signal length differs from the plan"
        );
        let n = self.len as f64;
        // Least-squares linear trend.
        let tm = 0.5 * (n - 1.0);
        let mean = signal.iter().sum::<f64>() / n;
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for (i, &y) in signal.iter().enumerate() {
            let dt = i as f64 - tm;
            sxy += dt * (y - mean);
            sxx += dt * dt;
        }
        let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        for (i, x) in self.input.iter_mut().enumerate() {
            *x = (signal[i] - mean - slope * (i as f64 - tm)) * self.window[i];
        }
        self.fft
            .process_with_scratch(&mut self.input, &mut self.output, &mut self.scratch)
            .ok()?;
        let scale = 2.0 / self.window_sum;
        for (m, c) in self.magnitude.iter_mut().zip(self.output.iter()) {
            *m = c.norm() * scale;
        }
        let df = sample_rate_hz / n;
        let lo = ((band.0 / df).ceil() as usize).max(1);
        let hi = ((band.1 / df).floor() as usize).min(self.magnitude.len() - 2);
        if lo > hi {
            return None;
        }
        let mut k = lo;
        for i in lo..=hi {
            if self.magnitude[i] > self.magnitude[k] {
                k = i;
            }
        }
        let b = self.magnitude[k];
        if b <= 0.0 {
            return None;
        }
        let (a, c) = (self.magnitude[k - 1], self.magnitude[k + 1]);
        // Gaussian (log-parabolic) interpolation; fall back to the bin if a side is zero.
        let delta = if a > 0.0 && c > 0.0 {
            let (la, lb, lc) = (a.ln(), b.ln(), c.ln());
            let den = la - 2.0 * lb + lc;
            if den < 0.0 {
                (0.5 * (la - lc) / den).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        } else {
            0.0
        };
        // Scalloping correction: the Hann window's response at `delta` bins off centre,
        // relative to its centre, is sinc(delta) / (1 - delta^2).
        let peak = b / hann_gain(delta);
        Some(Peak {
            frequency_hz: (k as f64 + delta) * df,
            amplitude: peak,
            bin: k,
            resolution_hz: df,
        })
    }
}

/// Hann window amplitude response at `delta` bins from a line, relative to the centre.
fn hann_gain(delta: f64) -> f64 {
    if delta.abs() < 1e-9 {
        return 1.0;
    }
    let x = std::f64::consts::PI * delta;
    (x.sin() / x) / (1.0 - delta * delta)
}

/// One-shot: strongest line of `signal` within `band` Hz (see [`SpectrumAnalyzer`]).
pub fn fundamental(signal: &[f64], sample_rate_hz: f64, band: (f64, f64)) -> Option<Peak> {
    if signal.len() < 8 {
        return None;
    }
    SpectrumAnalyzer::new(signal.len()).fundamental(signal, sample_rate_hz, band)
}

/// Half the peak-to-peak excursion of `signal` after removing its mean: a time-domain
/// amplitude that needs no spectral assumption.
pub fn half_peak_to_peak(signal: &[f64]) -> f64 {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &x in signal {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if signal.is_empty() {
        0.0
    } else {
        0.5 * (hi - lo)
    }
}
