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

// ------------------------------------------------------------------------------------------
// Windows on their own time stamps

/// Relative spread of the sample intervals (max |dt - median| / median) up to which a window is
/// taken as uniformly sampled (FFT); beyond it the least-squares fit on the samples' own times
/// ([`uneven_band_spectrum`]) is used.
pub const UNIFORM_SPREAD: f64 = 0.01;

/// The spectrum of one window in a band: its strongest line and the amplitudes of the grid
/// frequencies inside the band (k / T, T the window's length: the FFT's bins), zero-to-peak.
#[derive(Debug, Clone, PartialEq)]
pub struct BandSpectrum {
    pub peak: Option<Peak>,
    /// Amplitudes at the grid frequencies in the band, DC excluded: `band[i]` is at
    /// `first_hz + i * resolution_hz`.
    pub band: Vec<f64>,
    pub first_hz: f64,
    pub resolution_hz: f64,
    /// Computed on the samples' own (uneven) times, not by the FFT.
    pub uneven: bool,
}

/// Whether samples at times `t` are uniformly spaced within [`UNIFORM_SPREAD`], and their
/// median interval (s).
pub fn uniform_interval(t: &[f64]) -> (bool, f64) {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return (true, 0.0);
    }
    let mid = d.len() / 2;
    let med = *d.select_nth_unstable_by(mid, f64::total_cmp).1;
    let uniform = med > 0.0 && d.iter().all(|x| (x - med).abs() <= UNIFORM_SPREAD * med);
    (uniform, med)
}

/// Spectra of windows, FFT plans kept per length: a uniformly sampled window goes through the
/// FFT ([`SpectrumAnalyzer`]), any other through [`uneven_band_spectrum`].
#[derive(Default)]
pub struct WindowSpectra {
    analyzers: std::collections::HashMap<usize, SpectrumAnalyzer>,
}

impl WindowSpectra {
    pub fn new() -> Self {
        Self::default()
    }

    /// The spectrum of `y` sampled at times `t` (s) in `band` (Hz). The band's top is cut at
    /// the mean sampling rate over 2.5.
    pub fn band(&mut self, t: &[f64], y: &[f64], band: (f64, f64)) -> BandSpectrum {
        assert_eq!(t.len(), y.len());
        let n = t.len();
        let empty = BandSpectrum {
            peak: None,
            band: Vec::new(),
            first_hz: 0.0,
            resolution_hz: 0.0,
            uneven: false,
        };
        if n < 8 {
            return empty;
        }
        let (uniform, dt) = uniform_interval(t);
        if uniform {
            let fs = 1.0 / dt;
            let band = (band.0, band.1.min(fs / 2.5));
            let an = self
                .analyzers
                .entry(n)
                .or_insert_with(|| SpectrumAnalyzer::new(n));
            let peak = an.fundamental(y, fs, band);
            let m = an.amplitudes();
            let df = fs / n as f64;
            let lo = ((band.0 / df).ceil() as usize).max(1);
            let hi = ((band.1 / df).floor() as usize).min(m.len() - 1);
            BandSpectrum {
                peak,
                band: if lo <= hi {
                    m[lo..=hi].to_vec()
                } else {
                    Vec::new()
                },
                first_hz: lo as f64 * df,
                resolution_hz: df,
                uneven: false,
            }
        } else {
            uneven_band_spectrum(t, y, band)
        }
    }
}

/// Spectrum of samples at uneven times (lost, late and early samples: a capture's own time
/// stamps): at each frequency f of the grid k / T (T = n times the mean interval, the FFT's
/// bins) the least-squares fit of `a cos(2 pi f t) + b sin(2 pi f t) + c` to the signal, its
/// linear trend removed, weighted by a Hann window over time; the amplitude is
/// `sqrt(a^2 + b^2)` (a generalised, weighted Lomb-Scargle periodogram, Zechmeister & Kürster
/// 2009). With uniform samples it gives the Hann-windowed FFT's amplitudes; the strongest line
/// is refined by fits on a grid of 1/16 bin around it and a parabola through the best three.
///
/// Limits: a line is resolved to about 1/T as with the FFT; samples must come often enough
/// for the band (a mean rate of at least 2.5 times its top frequency, which is cut there), and
/// a gap longer than half the period of a frequency leaves that frequency badly constrained
/// (the windows are cut at such gaps, `WindowOptions::max_gap_s` of the windows module); a sample
/// placed at a wrong time (a value answered late and stamped at the next SYNC) is taken as
/// measured when stamped.
pub fn uneven_band_spectrum(t: &[f64], y: &[f64], band: (f64, f64)) -> BandSpectrum {
    let n = t.len();
    let none = BandSpectrum {
        peak: None,
        band: Vec::new(),
        first_hz: 0.0,
        resolution_hz: 0.0,
        uneven: true,
    };
    if n < 8 || y.iter().any(|v| !v.is_finite()) {
        return none;
    }
    let t0 = t[0];
    let span = t[n - 1] - t0;
    if span <= 0.0 {
        return none;
    }
    let t_len = span * n as f64 / (n - 1) as f64;
    let df = 1.0 / t_len;
    let mean_rate = (n - 1) as f64 / span;
    let top = band.1.min(mean_rate / 2.5);
    let lo = ((band.0 / df).ceil() as usize).max(1);
    let hi = (top / df).floor() as usize;
    if lo > hi {
        return none;
    }
    // Linear trend (least squares over time) removed, Hann weights over time.
    let tm = t.iter().map(|x| x - t0).sum::<f64>() / n as f64;
    let ym = y.iter().sum::<f64>() / n as f64;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (ti, yi) in t.iter().zip(y) {
        let dt = ti - t0 - tm;
        sxy += dt * (yi - ym);
        sxx += dt * dt;
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let x: Vec<f64> = t
        .iter()
        .zip(y)
        .map(|(ti, yi)| yi - ym - slope * (ti - t0 - tm))
        .collect();
    if x.iter().all(|v| *v == 0.0) {
        return none;
    }
    let w: Vec<f64> = t
        .iter()
        .map(|ti| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * (ti - t0) / t_len).cos())
        .collect();
    let fit = WeightedFit::new(t, &x, &w, t0);
    let amps = grid_amplitudes(t, &x, &w, t0, lo, hi, df);
    let (k_best, &a_best) = amps
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .expect("a band of at least one bin");
    if a_best <= 0.0 || !a_best.is_finite() {
        return BandSpectrum {
            peak: None,
            band: amps,
            first_hz: lo as f64 * df,
            resolution_hz: df,
            uneven: true,
        };
    }
    // Refine: 1/16 bin steps over +-1 bin (kept inside the band), a parabola through the best.
    let f_bin = (lo + k_best) as f64 * df;
    let steps: Vec<(f64, f64)> = (-16..=16)
        .map(|j| f_bin + j as f64 * df / 16.0)
        .filter(|f| *f >= lo as f64 * df && *f <= hi as f64 * df)
        .map(|f| (f, fit.amplitude_at(f)))
        .collect();
    let j = steps
        .iter()
        .enumerate()
        .max_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
        .map_or(0, |(j, _)| j);
    let mut f_peak = steps[j].0;
    if j > 0 && j + 1 < steps.len() {
        let (a, b, c) = (steps[j - 1].1, steps[j].1, steps[j + 1].1);
        let den = a - 2.0 * b + c;
        if den < 0.0 {
            f_peak += (0.5 * (a - c) / den).clamp(-0.5, 0.5) * df / 16.0;
        }
    }
    let amplitude = fit.amplitude_at(f_peak).max(steps[j].1);
    // Uneven samples spread a line's energy over the whole band (their spectral window has no
    // deep sidelobes), which would raise the band's median with the line itself: the band is
    // given as the spectrum of what is left once the line is taken out (one step of CLEAN),
    // the line at its bin.
    let (a, b, c) = fit.coefficients_at(f_peak);
    let residual: Vec<f64> = t
        .iter()
        .zip(&x)
        .map(|(ti, xi)| {
            let (sn, cs) = (2.0 * std::f64::consts::PI * f_peak * (ti - t0)).sin_cos();
            xi - a * cs - b * sn - c
        })
        .collect();
    let mut band = grid_amplitudes(t, &residual, &w, t0, lo, hi, df);
    band[k_best] = band[k_best].max(amplitude);
    BandSpectrum {
        peak: Some(Peak {
            frequency_hz: f_peak,
            amplitude,
            bin: lo + k_best,
            resolution_hz: df,
        }),
        band,
        first_hz: lo as f64 * df,
        resolution_hz: df,
        uneven: true,
    }
}

/// The weighted least-squares amplitudes of `x` (at times `t`, weights `w`) at the grid
/// frequencies `k df`, k in `lo..=hi`, by a rotation per sample (one sin/cos per sample, not
/// per frequency).
fn grid_amplitudes(
    t: &[f64],
    x: &[f64],
    w: &[f64],
    t0: f64,
    lo: usize,
    hi: usize,
    df: f64,
) -> Vec<f64> {
    let fit = WeightedFit::new(t, x, w, t0);
    let mut sums = vec![[0.0f64; 7]; hi + 1 - lo];
    for i in 0..t.len() {
        let ph = 2.0 * std::f64::consts::PI * (t[i] - t0);
        let (s0, c0) = (ph * lo as f64 * df).sin_cos();
        let (sd, cd) = (ph * df).sin_cos();
        let (mut c, mut s) = (c0, s0);
        let (wi, wx) = (w[i], w[i] * x[i]);
        for acc in sums.iter_mut() {
            let wc = wi * c;
            let ws = wi * s;
            acc[0] += wc * c;
            acc[1] += ws * s;
            acc[2] += wc * s;
            acc[3] += wc;
            acc[4] += ws;
            acc[5] += wx * c;
            acc[6] += wx * s;
            (c, s) = (c * cd - s * sd, s * cd + c * sd);
        }
    }
    sums.iter().map(|acc| fit.amplitude_of(acc)).collect()
}

/// The weighted least-squares sine fit of [`uneven_band_spectrum`] at one frequency.
struct WeightedFit<'a> {
    t: &'a [f64],
    x: &'a [f64],
    w: &'a [f64],
    t0: f64,
    sw: f64,
    swx: f64,
}

impl<'a> WeightedFit<'a> {
    fn new(t: &'a [f64], x: &'a [f64], w: &'a [f64], t0: f64) -> Self {
        let sw = w.iter().sum();
        let swx = w.iter().zip(x).map(|(a, b)| a * b).sum();
        Self {
            t,
            x,
            w,
            t0,
            sw,
            swx,
        }
    }

    /// The amplitude from the weighted sums [cc, ss, cs, c, s, xc, xs] at one frequency.
    fn amplitude_of(&self, acc: &[f64; 7]) -> f64 {
        let (a, b, _) = self.solve(acc);
        a.hypot(b)
    }

    /// The fit (a, b, c) from the weighted sums: the constant eliminated, then the 2 x 2
    /// normal equations of (a, b).
    fn solve(&self, acc: &[f64; 7]) -> (f64, f64, f64) {
        let [cc, ss, cs, c, s, xc, xs] = *acc;
        if self.sw <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let (mc, ms, mx) = (c / self.sw, s / self.sw, self.swx / self.sw);
        let a11 = cc - c * mc;
        let a22 = ss - s * ms;
        let a12 = cs - c * ms;
        let b1 = xc - c * mx;
        let b2 = xs - s * mx;
        let det = a11 * a22 - a12 * a12;
        if det.abs() <= 1e-12 * (a11 * a22).abs().max(f64::MIN_POSITIVE) {
            return (0.0, 0.0, mx);
        }
        let a = (b1 * a22 - b2 * a12) / det;
        let b = (a11 * b2 - a12 * b1) / det;
        (a, b, mx - a * mc - b * ms)
    }

    /// The amplitude at frequency `f` (Hz), summed directly.
    fn amplitude_at(&self, f: f64) -> f64 {
        self.amplitude_of(&self.sums_at(f))
    }

    /// The fit (a, b, c) at frequency `f` (Hz).
    fn coefficients_at(&self, f: f64) -> (f64, f64, f64) {
        self.solve(&self.sums_at(f))
    }

    /// The weighted sums at frequency `f` (Hz), summed directly.
    fn sums_at(&self, f: f64) -> [f64; 7] {
        let mut acc = [0.0f64; 7];
        for ((ti, xi), wi) in self.t.iter().zip(self.x).zip(self.w) {
            let (s, c) = (2.0 * std::f64::consts::PI * f * (ti - self.t0)).sin_cos();
            let (wc, ws) = (wi * c, wi * s);
            acc[0] += wc * c;
            acc[1] += ws * s;
            acc[2] += wc * s;
            acc[3] += wc;
            acc[4] += ws;
            acc[5] += wi * xi * c;
            acc[6] += wi * xi * s;
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic uniform numbers in 0..1 (splitmix64).
    fn uniform01(k: u64) -> f64 {
        let mut z = k.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    #[test]
    fn uneven_samples_give_the_line_the_fft_gives_on_even_ones() {
        // 4 s at a 4 ms SYNC: a 17.9 Hz line of 500 units/s on a ramp, plus a weaker 41 Hz line
        // and +-100 units/s of noise.
        let line = |t: f64| {
            100.0 * t
                + 500.0 * (2.0 * std::f64::consts::PI * 17.9 * t + 0.3).sin()
                + 40.0 * (2.0 * std::f64::consts::PI * 41.0 * t).cos()
                + 200.0 * (uniform01((t * 1e6) as u64) - 0.5)
        };
        let even: Vec<f64> = (0..1000).map(|k| k as f64 * 4e-3).collect();
        let y: Vec<f64> = even.iter().map(|t| line(*t)).collect();
        let mut ws = WindowSpectra::new();
        let fft = ws.band(&even, &y, (3.75, 60.0));
        assert!(!fft.uneven);
        let p = fft.peak.unwrap();
        assert!((p.frequency_hz - 17.9).abs() < 0.05, "{p:?}");
        assert!((p.amplitude - 500.0).abs() < 10.0, "{p:?}");
        // The same signal where SYNCs came late (a fifth of them by 1-2 periods) or were lost
        // (one in 20): every sample at its own time.
        let mut t = Vec::new();
        let mut now = 0.0;
        for k in 0..1000u64 {
            now += 4e-3;
            if uniform01(k) < 0.2 {
                now += 4e-3 * (1.0 + uniform01(k + 7777));
            }
            if uniform01(k + 99_999) < 0.05 {
                continue;
            }
            t.push(now);
        }
        let late = t.windows(2).filter(|w| w[1] - w[0] > 6e-3).count();
        assert!(late > 150, "{late} late intervals");
        let y: Vec<f64> = t.iter().map(|t| line(*t)).collect();
        let s = ws.band(&t, &y, (3.75, 60.0));
        assert!(s.uneven);
        let q = s.peak.unwrap();
        assert!((q.frequency_hz - 17.9).abs() < 0.05, "{q:?}");
        assert!((q.amplitude - 500.0).abs() < 10.0, "{q:?}");
        // The line stands out of the noise as far as on the FFT (prominence within a factor 2).
        let med = |v: &[f64]| {
            let mut v = v.to_vec();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (pf, pu) = (p.amplitude / med(&fft.band), q.amplitude / med(&s.band));
        assert!(
            pu > 0.5 * pf && pu > 20.0,
            "prominence fft {pf:.1} uneven {pu:.1}"
        );
        // Placed at k x the median interval instead (what the capture reader did), the same
        // samples smear the line.
        let dt = uniform_interval(&t).1;
        let kdt: Vec<f64> = (0..t.len()).map(|k| k as f64 * dt).collect();
        let smeared = ws.band(&kdt, &y, (3.75, 60.0)).peak.unwrap();
        assert!(
            smeared.amplitude < 0.7 * q.amplitude || (smeared.frequency_hz - 17.9).abs() > 0.5,
            "{smeared:?}"
        );
    }

    #[test]
    fn a_constant_signal_has_no_line() {
        let t: Vec<f64> = (0..200)
            .map(|k| k as f64 * 4e-3 + (k % 3) as f64 * 1e-3)
            .collect();
        let y = vec![5.0; t.len()];
        assert!(uneven_band_spectrum(&t, &y, (3.0, 60.0)).peak.is_none());
    }
}
