//! Backlash detection after Moosavian & MohammadiAsl: at constant commanded speed (set
//! acceleration zero) a backlashed axis runs into a limit cycle whose fundamental, visible in
//! the FFT of motor speed and motor current, lies between k_v/4 and k_v (Hz, k_v in 1/s; about
//! 0.6 k_v) and does not depend on the gap, while its amplitude grows with the gap.
//!
//! Method, per constant-velocity window ([`super::windows`]):
//! 1. fundamental of the motor speed and of the motor current in a search band wider than the
//!    paper's (k_v/8 .. 2 k_v, below Nyquist/1.25), so a peak outside the band is seen and
//!    rejected rather than missed; on the samples' own times
//!    ([`crate::spectrum::WindowSpectra`]: the FFT where they are even, a weighted
//!    least-squares sine fit where SYNCs came late or were lost, with its limits there);
//! 2. displacement-equivalent amplitude of the speed fluctuation, `x = A_v / (2 pi f)` (um or
//!    mdeg: the trace's position unit), and the peak's prominence over the band's median;
//! 3. the window is flagged `backlash_suspected` when the peak is inside k_v/4 .. k_v, prominent,
//!    and `x >= suspect_um`; `backlash` when also `x >= alarm_um`;
//! 4. the verdict is the lowest level among the last `confirm_windows` windows, or fewer
//!    that span as long in all (`confirm_windows` x the shortest window) (so one noisy
//!    window neither raises nor clears an alarm); severity = x / alarm_um of those windows.
//!
//! Alongside: the amplitude trend over time (least squares, per hour), the first time each
//! level was confirmed, and the difference between motor and direct encoder (mean per window,
//! fluctuation, and the lost motion between opposite directions when both are present), and
//! how large the gap is where a window is flagged ([`super::gap`]: from the two encoders, or
//! from the amplitude, calibrated per preset).
//!
//! Windows where the set-points come unevenly (`find_windows`): exactly constant, else
//! constant on average, else a line of the set-point against the samples' own time stamps;
//! then the same with stalled SYNCs bridged where the position went on along its line.

use crate::gap::{BacklashEstimate, GapModel};
use crate::spectrum::{uniform_interval, WindowSpectra};
use crate::windows::{Window, WindowOptions};

// The trace the detector reads and what it finds per window are modules of their own below
// the gap estimate (which reads them too): re-exported here under their old paths.
pub use crate::axis_trace::AxisTrace;
pub(crate) use crate::verdict::median;
pub use crate::verdict::{LoopFit, Verdict, WindowResult};

/// Detector settings.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DetectorConfig {
    /// Position-loop gain, 1/s.
    pub kv_per_s: f64,
    /// Displacement-equivalent amplitude (trace position unit) for `backlash_suspected`.
    pub suspect_um: f64,
    /// ... and for `backlash`.
    pub alarm_um: f64,
    /// Peak amplitude over the median of the search band's spectrum, at least.
    pub min_prominence: f64,
    /// Windows in a row at a level before the verdict takes it.
    pub confirm_windows: usize,
    pub windows: WindowOptions,
    /// The machine's mechanics for the gap estimate ([`super::gap`]); None: no estimate.
    pub gap: Option<GapModel>,
}

impl DetectorConfig {
    pub fn new(kv_per_s: f64) -> Self {
        Self {
            kv_per_s,
            suspect_um: 1.0,
            alarm_um: 3.0,
            min_prominence: 8.0,
            confirm_windows: 2,
            windows: WindowOptions::default(),
            gap: None,
        }
    }
    /// The paper's band, Hz: k_v/4 .. k_v (eq. 11, 12).
    pub fn band_hz(&self) -> (f64, f64) {
        (self.kv_per_s / 4.0, self.kv_per_s)
    }
    /// Where peaks are searched, Hz.
    pub fn search_band_hz(&self, sample_rate_hz: f64) -> (f64, f64) {
        (
            (self.kv_per_s / 8.0).max(0.5),
            (2.0 * self.kv_per_s).min(sample_rate_hz / 2.5),
        )
    }
}

/// The master's position loop as the report gives it: the median of the windows' fits.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct MasterLoop {
    pub kv_per_s: f64,
    pub lag_s: f64,
    pub encoder: &'static str,
    pub explained: f64,
    /// Windows whose set-point follows the axis, of all windows.
    pub windows: usize,
    pub of_windows: usize,
}

/// Share of the set velocity's variation a fit must explain to say the set-point follows the
/// axis.
pub const LOOP_MIN_EXPLAINED: f64 = 0.8;
/// The set velocity must vary beyond its trend by at least this (rms, position unit per s):
/// an exactly constant set-point follows nothing.
pub const LOOP_MIN_RMS: f64 = 1.0;
/// Longest lag searched, in set-points.
pub const LOOP_MAX_LAG: usize = 3;

/// Does the set-point follow the axis in window `w`? A master closing the position loop
/// sends `v_set = v_ref + k (x_ref - x)`: at constant speed its set velocity (the derivative
/// of the set position it sent: CSV/PV targets, or CSP targets) is a line in time plus `-k`
/// times the position it last had from the drive. Fitted over the set-points (the samples
/// where the set velocity changes: every row of a capture, every SYNC in a drive's own
/// trace, where a set-point holds from one SYNC to the next) by least squares on `[1, t, x]`,
/// x the direct or the motor position at the set-point `lag` set-points before (0 to
/// [`LOOP_MAX_LAG`]); the best fit says so when it explains [`LOOP_MIN_EXPLAINED`] or more of
/// the set velocity's variation beyond its trend, with `0 < k <= 1000 1/s`. A set-point that
/// jitters by itself (its own timing) or beats with SYNC moves independently of the axis and
/// explains nothing; an axis that follows a set-point (integrates it) lags it by a quarter
/// period, orthogonal to a P loop's half period. None when the set-point does not follow the
/// axis.
pub fn fit_master_loop(trace: &AxisTrace, w: &Window) -> Option<LoopFit> {
    let sp = trace.set_position.get(w.start..w.end)?;
    let t = &trace.t_s[w.start..w.end];
    let n = sp.len();
    if n < 16 || sp.iter().any(|x| !x.is_finite()) {
        return None;
    }
    // The set velocity per sample (sample j >= 1), and the samples where a set-point came.
    let v: Vec<f64> = (1..n)
        .map(|j| {
            let dt = t[j] - t[j - 1];
            if dt > 0.0 {
                (sp[j] - sp[j - 1]) / dt
            } else {
                f64::NAN
            }
        })
        .collect();
    if v.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let changes: Vec<usize> = (1..n)
        .filter(|&j| j == 1 || (v[j - 1] - v[j - 2]).abs() > 1e-9 * v[j - 1].abs().max(1.0))
        .collect();
    // A set-point held over several samples (a drive's trace every tick, a new set-point
    // every SYNC): its changes; else every sample is one (a capture, one row per SYNC, where
    // a set-point that happens to repeat is still a set-point).
    let events: Vec<usize> = if 2 * changes.len() < n - 1 {
        changes
    } else {
        (1..n).collect()
    };
    if events.len() < 16 {
        return None;
    }
    let columns: [(&'static str, &[f64]); 2] = [
        ("direct", &trace.direct_position[w.start..w.end]),
        ("motor", &trace.motor_position[w.start..w.end]),
    ];
    // The time between set-points, s (their median).
    let period = {
        let mut d: Vec<f64> = events.windows(2).map(|e| t[e[1]] - t[e[0]]).collect();
        median(&mut d).unwrap_or(0.0)
    };
    let mut best: Option<LoopFit> = None;
    for (c, (name, x)) in columns.iter().enumerate() {
        if c == 1 && columns[0].1 == *x {
            continue;
        }
        for lag in 0..=LOOP_MAX_LAG {
            // Set-point i (at sample events[i]) against x where set-point i - lag came.
            let rows = lag..events.len();
            let m = rows.len() as f64;
            let at = |i: usize| (t[events[i]], x[events[i - lag]], v[events[i] - 1]);
            let (mut st, mut sx, mut sy) = (0.0, 0.0, 0.0);
            for i in rows.clone() {
                let (a, b, c) = at(i);
                st += a;
                sx += b;
                sy += c;
            }
            let (mt, mx, my) = (st / m, sx / m, sy / m);
            let (mut tt, mut xx, mut tx, mut ty, mut xy, mut yy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
            for i in rows {
                let (a, b, c) = at(i);
                let (a, b, c) = (a - mt, b - mx, c - my);
                tt += a * a;
                xx += b * b;
                tx += a * b;
                ty += a * c;
                xy += b * c;
                yy += c * c;
            }
            if tt <= 0.0 {
                continue;
            }
            // Beyond the trend: residuals of v and x on [1, t].
            let yy_t = yy - ty * ty / tt;
            let xx_t = xx - tx * tx / tt;
            let xy_t = xy - tx * ty / tt;
            if yy_t / m < LOOP_MIN_RMS * LOOP_MIN_RMS || xx_t <= 0.0 {
                continue;
            }
            let coef = xy_t / xx_t;
            let explained = (xy_t * xy_t / (xx_t * yy_t)).clamp(0.0, 1.0);
            if best.is_none_or(|b| explained > b.explained) {
                best = Some(LoopFit {
                    kv_per_s: -coef,
                    lag_s: lag as f64 * period,
                    encoder: name,
                    explained,
                });
            }
        }
    }
    best.filter(|b| b.explained >= LOOP_MIN_EXPLAINED && b.kv_per_s > 0.0 && b.kv_per_s <= 1000.0)
}

/// Why a trace gave no usable window.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Inconclusive {
    /// No stretch of constant, non-zero set speed.
    NoConstantSpeed,
    /// Constant-speed stretches, all too short for a window.
    TooShort,
    /// The capture lacks an object the detector needs (motor speed, any set-point source).
    MissingObjects,
    /// The motor speed has no finite sample in any window (NaN, infinite).
    NoFiniteSamples,
    /// Every window's line is the set-point's own motion (the master's set-point timing
    /// beats with its SYNC): the axis was forced, its own vibration not measurable.
    SetPointNotConstant,
    /// In every window the axis did not follow the set speed.
    AxisNotFollowing,
}

impl Inconclusive {
    pub fn as_str(self) -> &'static str {
        match self {
            Inconclusive::NoConstantSpeed => "no_constant_speed",
            Inconclusive::TooShort => "too_short",
            Inconclusive::MissingObjects => "missing_objects",
            Inconclusive::NoFiniteSamples => "no_finite_samples",
            Inconclusive::SetPointNotConstant => "set_point_not_constant",
            Inconclusive::AxisNotFollowing => "axis_not_following",
        }
    }
}

/// The detector's result for a trace.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DetectorReport {
    pub kv_per_s: f64,
    pub band_hz: (f64, f64),
    pub config: DetectorConfig,
    pub verdict: Verdict,
    /// Set when the verdict is inconclusive.
    pub inconclusive: Option<Inconclusive>,
    /// Why: which windows decided, frequency, amplitude against which threshold, band check;
    /// or why nothing could be measured. One sentence each, in the order to print them.
    pub reasons: Vec<String>,
    /// Where the constant speed came from (set-point object, or the actual values).
    pub window_source: String,
    /// How the samples' times were had (a capture: its SYNC time stamps or the SYNC count).
    pub time_base: String,
    /// Displacement amplitude of the deciding windows over `alarm_um` (1.0 = at the alarm).
    pub severity: f64,
    /// Median displacement amplitude of the deciding windows, position unit.
    pub amplitude: f64,
    /// Median fundamental of the flagged windows (None if none flagged), Hz.
    pub frequency_hz: Option<f64>,
    pub frequency_over_kv: Option<f64>,
    /// Median fundamental of all windows, flagged or not, Hz.
    pub dominant_hz: Option<f64>,
    /// When each level was first confirmed (end of the confirming window), s.
    pub first_suspected_s: Option<f64>,
    pub first_backlash_s: Option<f64>,
    /// Least-squares slope of the displacement amplitude over time, position unit per hour.
    pub amplitude_trend_per_h: Option<f64>,
    /// Mean(motor - direct) at positive minus at negative speed: the lost motion at reversal
    /// (backlash plus elastic wind-up), position unit; None without both directions or when the
    /// trace has no independent motor position.
    pub lost_motion: Option<f64>,
    /// How large the gap is ([`super::gap`]): `backlash_estimate_mm` and
    /// `backlash_estimate_range_mm` [lo, hi] (`_deg` on a rotary axis), null on a healthy
    /// axis or where it cannot be said, and `backlash_estimate_method`.
    #[serde(flatten)]
    pub backlash_estimate: BacklashEstimate,
    pub position_unit: String,
    pub windows: Vec<WindowResult>,
    /// Windows not measured: their line is the set-point's own motion
    /// ([`WindowResult::forced`]), or the axis did not follow ([`WindowResult::not_following`]).
    pub forced_windows: Vec<WindowResult>,
    /// The master closes the position loop itself (the set-point follows the axis): its gain,
    /// which `kv_per_s` and the band then are.
    pub master_loop: Option<MasterLoop>,
}

/// Least-squares slope of y over x.
fn slope(x: &[f64], y: &[f64]) -> Option<f64> {
    if x.len() < 2 {
        return None;
    }
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Analyze one window (exposed for tests and plots). Its spectra are taken on the samples'
/// own times ([`WindowSpectra`]: the FFT where they are even, a least-squares fit where not).
pub fn analyze_window(
    trace: &AxisTrace,
    w: &Window,
    cfg: &DetectorConfig,
    spectra: &mut WindowSpectra,
) -> WindowResult {
    let t = &trace.t_s[w.start..w.end];
    let n = w.len();
    let (uniform, dt) = uniform_interval(t);
    let span = t[n - 1] - t[0];
    let fs = if uniform && dt > 0.0 {
        1.0 / dt
    } else if span > 0.0 {
        (n - 1) as f64 / span
    } else {
        1.0
    };
    let band = cfg.search_band_hz(fs);
    let speed_spectrum = spectra.band(t, &trace.motor_velocity[w.start..w.end], band);
    let speed = speed_spectrum.peak;
    let prominence = speed.map_or(0.0, |p| line_prominence(p.amplitude, &speed_spectrum.band));
    let current = spectra.band(t, &trace.current[w.start..w.end], band).peak;
    let (speed_hz, speed_amplitude) =
        speed.map_or((None, 0.0), |p| (Some(p.frequency_hz), p.amplitude));
    let set_point_amplitude = set_point_line(trace, w, spectra, band);
    let (current_hz, current_amplitude) =
        current.map_or((None, 0.0), |p| (Some(p.frequency_hz), p.amplitude));
    let displacement_amplitude = match speed_hz {
        Some(f) if f > 0.0 => speed_amplitude / (2.0 * std::f64::consts::PI * f),
        _ => 0.0,
    };
    let (lo, hi) = cfg.band_hz();
    let in_band = speed_hz.is_some_and(|f| f >= lo && f <= hi);
    let current_agrees = match (speed_hz, current_hz) {
        (Some(a), Some(b)) => (a - b).abs() <= 0.1 * a,
        _ => false,
    };
    let (mean, half_pp) = encoder_difference(trace, w);
    let unit = unit_text(&trace.position_unit);
    // The speed shows a line of the size we look for, and the set-point shakes the axis in the
    // band by the suspect level and half that line or more: the line is not the axis's own.
    // (A quiet speed under a moving set-point is no vibration of the axis: ok stays ok.)
    // Unless the set-point follows the axis (the master's own position loop): then its motion
    // is the loop's answer, and the limit cycle the loop's.
    let master_loop = fit_master_loop(trace, w);
    let forced = master_loop.is_none()
        && displacement_amplitude >= cfg.suspect_um
        && set_point_amplitude >= cfg.suspect_um.max(0.5 * displacement_amplitude);
    let mean_speed = trace.motor_velocity[w.start..w.end].iter().sum::<f64>() / n.max(1) as f64;
    let not_following = (mean_speed - w.velocity).abs() > 0.5 * w.velocity.abs();
    let (level, reason) = if not_following {
        (
            Verdict::Ok,
            format!(
                "not measured: the axis did not follow the set speed (mean motor speed \
                 {mean_speed:.1} {unit}/s against {:.1} {unit}/s set)",
                w.velocity
            ),
        )
    } else if forced {
        (
            Verdict::Ok,
            format!(
                "not measured: the set-point itself moves by {set_point_amplitude:.2} {unit} in \
                 the search band {:.2}..{:.2} Hz (the master's set-point timing; the speed's \
                 line, {displacement_amplitude:.2} {unit}, is not the axis's own)",
                band.0, band.1
            ),
        )
    } else {
        judge_line(cfg, speed_hz, prominence, displacement_amplitude, unit)
    };
    WindowResult {
        t_start_s: trace.t_s[w.start],
        t_end_s: trace.t_s[w.end - 1],
        start: w.start,
        end: w.end,
        set_velocity: w.velocity,
        speed_hz,
        speed_amplitude,
        current_hz,
        current_amplitude,
        displacement_amplitude,
        prominence,
        in_band,
        current_agrees,
        encoder_difference_mean: mean,
        encoder_difference_half_pp: half_pp,
        level,
        reason,
        set_point_amplitude,
        forced,
        not_following,
        master_loop,
    }
}

/// The line's amplitude over the median amplitude of the search band's grid (`band`, the
/// amplitudes of a [`BandSpectrum`](crate::spectrum::BandSpectrum)): how far the line stands
/// out of the noise.
fn line_prominence(amplitude: f64, band: &[f64]) -> f64 {
    let mut m: Vec<f64> = band.to_vec();
    let med = median(&mut m).unwrap_or(0.0);
    if med > 0.0 {
        amplitude / med
    } else {
        f64::INFINITY
    }
}

/// Motor minus direct encoder over window `w`: its mean and half peak-to-peak.
fn encoder_difference(trace: &AxisTrace, w: &Window) -> (f64, f64) {
    let diff: Vec<f64> = (w.start..w.end)
        .map(|i| trace.motor_position[i] - trace.direct_position[i])
        .collect();
    let mean = diff.iter().sum::<f64>() / w.len().max(1) as f64;
    (mean, crate::spectrum::half_peak_to_peak(&diff))
}

/// The level a measured window's speed line earns, and why: none, outside k_v/4..k_v, not
/// prominent enough, or its displacement amplitude against the suspect and alarm levels.
fn judge_line(
    cfg: &DetectorConfig,
    speed_hz: Option<f64>,
    prominence: f64,
    displacement_amplitude: f64,
    unit: &str,
) -> (Verdict, String) {
    let (lo, hi) = cfg.band_hz();
    let in_band = speed_hz.is_some_and(|f| f >= lo && f <= hi);
    // A line, not noise: prominent over the band's median. A clear limit cycle (at or above
    // the alarm amplitude) needs half the prominence, so that a small change of the capture
    // (a few samples more, a little more noise) cannot flip a clear case to ok.
    let needed = if displacement_amplitude >= cfg.alarm_um {
        0.5 * cfg.min_prominence
    } else {
        cfg.min_prominence
    };
    match speed_hz {
        None => (
            Verdict::Ok,
            "no spectral line in the search band".to_string(),
        ),
        Some(f) if !in_band => (
            Verdict::Ok,
            format!(
                "strongest line {f:.2} Hz is outside the band {lo:.2}..{hi:.2} Hz (k_v/4..k_v)"
            ),
        ),
        Some(f) if prominence < needed => (
            Verdict::Ok,
            format!(
                "{f:.2} Hz in band but no clear line: prominence {prominence:.1}x the band's \
                 median < {needed:.1}x ({displacement_amplitude:.2} {unit})"
            ),
        ),
        Some(f) => {
            let lvl = if displacement_amplitude >= cfg.alarm_um {
                Verdict::Backlash
            } else if displacement_amplitude >= cfg.suspect_um {
                Verdict::BacklashSuspected
            } else {
                Verdict::Ok
            };
            let cmp = match lvl {
                Verdict::Backlash => format!(">= alarm {:.2} {unit}", cfg.alarm_um),
                Verdict::BacklashSuspected => format!(
                    ">= suspect {:.2} {unit}, < alarm {:.2} {unit}",
                    cfg.suspect_um, cfg.alarm_um
                ),
                _ => format!("< suspect {:.2} {unit}", cfg.suspect_um),
            };
            (
                lvl,
                format!(
                    "{f:.2} Hz = {:.2} k_v in band {lo:.2}..{hi:.2} Hz, prominence \
                     {prominence:.1}x, amplitude {displacement_amplitude:.2} {unit} {cmp}",
                    f / cfg.kv_per_s
                ),
            )
        }
    }
}

/// The set-point's own motion in window `w`: the strongest line of the set position (its
/// cruise, the linear trend, removed) in `band` (Hz), position unit; NaN without a set
/// position.
fn set_point_line(
    trace: &AxisTrace,
    w: &Window,
    spectra: &mut WindowSpectra,
    band: (f64, f64),
) -> f64 {
    let Some(sp) = trace.set_position.get(w.start..w.end) else {
        return f64::NAN;
    };
    if sp.len() < 2 || sp.iter().any(|x| !x.is_finite()) {
        return f64::NAN;
    }
    let t = &trace.t_s[w.start..w.end];
    // On an even time base (k x the SYNC period), the set position again from its
    // increments. An increment well above the median (by half of it, or 2 units) is a
    // catch-up: where such are rare (a fifth of the increments or fewer), they are SYNCs the
    // capture lost (its time base counts SYNCs; the drive saw them), not a motion of the
    // set-point, and take the median. Holds (increments below it: the master sent nothing
    // new) are what the drive saw and stay, as does a pattern of holds and double steps that
    // beats with SYNC (not rare). On the samples' own times a lost SYNC is a longer interval
    // already: the set position is taken as it is.
    let pos: Vec<f64> = if uniform_interval(t).0 {
        let mut d: Vec<f64> = sp.windows(2).map(|p| p[1] - p[0]).collect();
        let mut sorted = d.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        let far = (0.5 * median.abs()).max(2.0);
        let catch_up = |x: f64| (x - median) * median.signum() > far;
        let catch_ups = d.iter().filter(|x| catch_up(**x)).count();
        if catch_ups * 5 <= d.len() {
            for x in d.iter_mut() {
                if catch_up(*x) {
                    *x = median;
                }
            }
        }
        let mut x = 0.0;
        std::iter::once(0.0)
            .chain(d.iter().map(|s| {
                x += s;
                x
            }))
            .collect()
    } else {
        sp.to_vec()
    };
    // Its spectrum (trend removed: the cruise itself) is a displacement already.
    let s = spectra.band(t, &pos, band);
    if s.peak.is_none() {
        return 0.0;
    }
    s.band.iter().copied().fold(0.0, f64::max)
}

/// Longest gap between two samples bridged inside a window, in periods of the lowest
/// frequency of the paper's band (k_v/4).
pub const MAX_GAP_LOW_PERIODS: f64 = 0.5;

/// The window options in force: `cfg.windows`, where no gap limit is set with gaps up to half
/// the longest period of the paper's band (`0.5 / (k_v/4)` = 2 / k_v, 67 ms at 30 1/s) bridged:
/// the spectra are fitted on the samples' own times, where a late SYNC or a few lost ones only
/// cost the samples that are missing; a longer silence (a drive or a capture that stalled)
/// may hide a change of speed and ends the window.
pub fn window_options(cfg: &DetectorConfig) -> WindowOptions {
    let mut wo = cfg.windows;
    if wo.max_gap_s.is_none() && cfg.kv_per_s > 0.0 {
        wo.max_gap_s = Some(MAX_GAP_LOW_PERIODS / (cfg.kv_per_s / 4.0));
    }
    wo
}

/// The master's position loop, if the set-point follows the axis in more than half of the
/// `windows` ([`fit_master_loop`]): the median gain, lag and share explained of those that do.
fn master_loop(trace: &AxisTrace, windows: &[&Window]) -> Option<MasterLoop> {
    let fits: Vec<LoopFit> = windows
        .iter()
        .filter_map(|w| fit_master_loop(trace, w))
        .collect();
    if fits.is_empty() || 2 * fits.len() <= windows.len() {
        return None;
    }
    let med = |f: fn(&LoopFit) -> f64| median(&mut fits.iter().map(f).collect::<Vec<_>>());
    let direct = fits.iter().filter(|f| f.encoder == "direct").count();
    Some(MasterLoop {
        kv_per_s: med(|f| f.kv_per_s)?,
        lag_s: med(|f| f.lag_s)?,
        encoder: if 2 * direct >= fits.len() {
            "direct"
        } else {
            "motor"
        },
        explained: med(|f| f.explained)?,
        windows: fits.len(),
        of_windows: windows.len(),
    })
}

/// How the constant-speed windows were found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FoundBy {
    /// Stretches of exactly constant set speed.
    Exact,
    /// The set position's speed constant on average over a span.
    Average,
    /// The set position against the time stamps a line.
    Line,
}

#[derive(Debug, Clone, Copy)]
struct Found {
    how: FoundBy,
    bridged: bool,
}

/// The windows of a trace: stretches of exactly constant set speed; else, where the
/// set-points jitter, constant on average ([`crate::windows::set_velocity_on_average`]);
/// else a line of the set position against the samples' times
/// ([`crate::windows::set_velocity_by_line`]). Where none of these gives a window, the same
/// again with silences bridged where the position advanced as the speed says
/// ([`crate::windows::scan_windows_bridging`]: the set position, or where there is none the
/// direct encoder's).
fn find_windows(trace: &AxisTrace, wo: &WindowOptions) -> (crate::windows::WindowScan, Found) {
    use crate::windows::{scan_windows_bridging, set_velocity_by_line, set_velocity_on_average};
    let has_set_position = trace.set_position.iter().any(|x| x.is_finite());
    let mut first = None;
    for bridged in [false, true] {
        let position: Option<&[f64]> = if !bridged {
            None
        } else if has_set_position {
            Some(trace.set_position.as_slice())
        } else {
            Some(trace.direct_position.as_slice())
        };
        let scan = scan_windows_bridging(&trace.t_s, &trace.set_velocity, wo, position);
        if !scan.windows.is_empty() {
            return (
                scan,
                Found {
                    how: FoundBy::Exact,
                    bridged,
                },
            );
        }
        if has_set_position {
            for how in [FoundBy::Average, FoundBy::Line] {
                let v = match how {
                    FoundBy::Average => set_velocity_on_average(&trace.t_s, &trace.set_position),
                    _ => set_velocity_by_line(&trace.t_s, &trace.set_position),
                };
                let s = scan_windows_bridging(&trace.t_s, &v, wo, position);
                if !s.windows.is_empty() {
                    return (s, Found { how, bridged });
                }
            }
        }
        // The reason without windows is the exact scan's, unbridged.
        first.get_or_insert(scan);
    }
    (
        first.unwrap_or_default(),
        Found {
            how: FoundBy::Exact,
            bridged: false,
        },
    )
}

/// Run the detector on a trace.
pub fn analyze(trace: &AxisTrace, cfg: &DetectorConfig) -> DetectorReport {
    let wo = window_options(cfg);
    let (scan, found) = find_windows(trace, &wo);
    let finite = |w: &Window| {
        trace.motor_velocity[w.start..w.end]
            .iter()
            .all(|v| v.is_finite())
    };
    let usable: Vec<&Window> = scan.windows.iter().filter(|w| w.len() >= 16).collect();
    let non_finite = usable.iter().filter(|w| !finite(w)).count();
    // A master that closes the position loop itself: the limit cycle is its loop's, judged
    // against its gain (fitted from the capture) instead of the drive's.
    let master_loop = master_loop(trace, &usable);
    let cfg_in_force = match &master_loop {
        Some(m) => DetectorConfig {
            kv_per_s: m.kv_per_s,
            ..*cfg
        },
        None => *cfg,
    };
    let cfg = &cfg_in_force;
    let mut spectra = WindowSpectra::new();
    let (forced, results): (Vec<WindowResult>, Vec<WindowResult>) = usable
        .iter()
        .filter(|w| finite(w))
        .map(|w| analyze_window(trace, w, cfg, &mut spectra))
        .partition(|r| r.forced || r.not_following);
    let mut rep = summarize(results, trace, cfg);
    if let Some(m) = master_loop {
        note_master_loop(&mut rep, m);
    }
    note_window_source(&mut rep, found, &wo);
    note_forced(&mut rep, &forced, trace);
    if rep.windows.is_empty() {
        let (why, text) = why_inconclusive(trace, cfg, &forced, non_finite, &scan, &rep);
        rep.mark_inconclusive(why, text);
    } else if non_finite > 0 {
        rep.reasons.push(format!(
            "{non_finite} windows skipped: non-finite motor-speed samples (NaN or infinite)"
        ));
    }
    rep
}

/// The master closes the position loop itself: the report says so (its second reason, after
/// the verdict's own) and gives its loop.
fn note_master_loop(rep: &mut DetectorReport, m: MasterLoop) {
    rep.master_loop = Some(m);
    let at = usize::from(!rep.reasons.is_empty());
    rep.reasons.insert(
        at,
        format!(
            "the set-point follows the axis: the master closes the position loop itself \
             (v_set = v0 + k (x_cmd - x) fits with k = {:.2} 1/s on the {} position, {:.1} \
             ms late, explaining {:.0} % of the set velocity's variation, in {} of {} \
             windows): the limit cycle is its loop's, judged against its k (band \
             {:.2}..{:.2} Hz)",
            m.kv_per_s,
            m.encoder,
            m.lag_s * 1e3,
            m.explained * 100.0,
            m.windows,
            m.of_windows,
            m.kv_per_s / 4.0,
            m.kv_per_s
        ),
    );
}

/// How the windows were found, beyond exactly constant set-points: bridged silences, constant
/// on average, a line against the time stamps.
fn note_window_source(rep: &mut DetectorReport, found: Found, wo: &WindowOptions) {
    if found.bridged {
        rep.window_source.push_str(&format!(
            "; silences longer than {:.3} s bridged (up to {} s) where the position advanced \
             as the set speed says (SYNCs that stalled)",
            wo.max_gap_s.unwrap_or(0.0),
            crate::windows::MAX_BRIDGE_S
        ));
    }
    if found.how == FoundBy::Average {
        rep.window_source.push_str(&format!(
            "; constant on average over {} s (the set-points jitter: no stretch of exactly \
             constant set speed)",
            crate::windows::AVERAGE_SPAN_S
        ));
    }
    if found.how == FoundBy::Line {
        rep.window_source.push_str(&format!(
            "; constant where the set-point against the samples' time stamps is a line (blocks \
             of {} s, rms residual <= {} s of travel or {} units; the increments per SYNC are \
             uneven)",
            crate::windows::LINE_BLOCK_S,
            crate::windows::LINE_RESIDUAL_S,
            crate::windows::LINE_RESIDUAL_UNITS
        ));
    }
}

/// The windows that measure nothing (forced by the set-point, or the axis not following),
/// each with its reason.
fn note_forced(rep: &mut DetectorReport, forced: &[WindowResult], trace: &AxisTrace) {
    rep.forced_windows = forced.to_vec();
    for r in forced {
        rep.reasons.push(format!(
            "window {:.2}..{:.2} s at {:.1} {}/s: {}",
            r.t_start_s,
            r.t_end_s,
            r.set_velocity,
            unit_text(&trace.position_unit),
            r.reason
        ));
    }
}

/// Why no window measured anything, and the sentence that says it.
fn why_inconclusive(
    trace: &AxisTrace,
    cfg: &DetectorConfig,
    forced: &[WindowResult],
    non_finite: usize,
    scan: &crate::windows::WindowScan,
    rep: &DetectorReport,
) -> (Inconclusive, String) {
    let any_finite = trace.motor_velocity.iter().any(|v| v.is_finite());
    if !forced.is_empty() && forced.iter().all(|r| !r.forced) {
        (
            Inconclusive::AxisNotFollowing,
            format!(
                "in all {} constant-speed windows the axis did not follow the set speed \
                 (a drive in fault, disabled or in another mode)",
                forced.len()
            ),
        )
    } else if !forced.is_empty() {
        (
            Inconclusive::SetPointNotConstant,
            format!(
                "in all {} constant-speed windows the set-point itself moves in the search \
                 band by the suspect level or more: the axis was forced by the master's \
                 set-point timing, its own vibration cannot be told apart",
                forced.len()
            ),
        )
    } else if !any_finite || non_finite > 0 {
        (
            Inconclusive::NoFiniteSamples,
            if any_finite {
                format!("all {non_finite} constant-speed windows hold non-finite motor-speed samples (NaN or infinite)")
            } else {
                format!(
                    "no finite motor-speed sample in the trace ({} samples, all NaN or infinite)",
                    trace.len()
                )
            },
        )
    } else if scan.runs == 0 {
        (
            Inconclusive::NoConstantSpeed,
            format!(
                "no constant set speed anywhere in the trace ({} samples, {:.2} s; set speed from {})",
                trace.len(),
                trace.t_s.last().copied().unwrap_or(0.0) - trace.t_s.first().copied().unwrap_or(0.0),
                rep.window_source
            ),
        )
    } else {
        let o = &cfg.windows;
        let need = format!(
            "a window needs {:.1} s of settling plus {:.1} s at constant set speed (|v| >= {} {}/s)",
            o.settle_s,
            o.min_len_s,
            o.min_speed,
            unit_text(&trace.position_unit)
        );
        (
            Inconclusive::TooShort,
            format!(
                "{} constant-speed stretches, the longest {:.2} s: too short ({need})",
                scan.runs, scan.longest_run_s
            ),
        )
    }
}

impl DetectorReport {
    /// Nothing was measured: the verdict is inconclusive, for `why`, explained by `text`.
    pub fn mark_inconclusive(&mut self, why: Inconclusive, text: String) {
        self.verdict = Verdict::Inconclusive;
        self.inconclusive = Some(why);
        self.severity = 0.0;
        self.amplitude = 0.0;
        self.backlash_estimate.estimate = None;
        self.reasons
            .insert(0, format!("inconclusive ({}): {text}", why.as_str()));
    }

    /// The report of a trace that could not be built (missing objects): inconclusive.
    pub fn inconclusive(
        cfg: &DetectorConfig,
        why: Inconclusive,
        text: String,
        position_unit: &str,
    ) -> Self {
        let tr = AxisTrace {
            position_unit: position_unit.into(),
            ..AxisTrace::default()
        };
        let mut rep = summarize(Vec::new(), &tr, cfg);
        rep.window_source = "-".into();
        rep.mark_inconclusive(why, text);
        rep
    }
}

/// Measuring time that confirms a level by itself, s: `confirm_windows` windows of the
/// shortest length. A limit cycle lasts as long as the constant speed; what confirms it is
/// time spent measuring it, so one long window counts as much as two short ones.
fn confirm_s(cfg: &DetectorConfig) -> f64 {
    cfg.confirm_windows as f64 * cfg.windows.min_len_s
}

/// The first of the windows in a row ending at `end` that confirm a level: the last
/// `confirm_windows` windows, or fewer that together span [`confirm_s`]. None: too few yet.
fn confirming(results: &[WindowResult], end: usize, cfg: &DetectorConfig) -> Option<usize> {
    let need = cfg.confirm_windows.max(1);
    let mut spanned = 0.0;
    for from in (0..=end).rev() {
        let r = &results[from];
        spanned += r.t_end_s - r.t_start_s;
        if end + 1 - from >= need || spanned >= 0.99 * confirm_s(cfg) {
            return Some(from);
        }
    }
    None
}

fn summarize(
    results: Vec<WindowResult>,
    trace: &AxisTrace,
    cfg: &DetectorConfig,
) -> DetectorReport {
    let (first_suspected_s, first_backlash_s) = first_confirmed(&results, cfg);
    // The verdict: the last windows that confirm a level; a trace with fewer is judged on
    // all it has.
    let from = match results.len() {
        0 => 0,
        n => confirming(&results, n - 1, cfg).unwrap_or(0),
    };
    let last = &results[from..];
    let verdict = if !results.is_empty() {
        last.iter().map(|r| r.level).min().unwrap_or(Verdict::Ok)
    } else {
        Verdict::Inconclusive
    };
    let reasons = verdict_reasons(&results, last, verdict, trace, cfg);
    let amplitude = median(
        &mut last
            .iter()
            .map(|r| r.displacement_amplitude)
            .collect::<Vec<_>>(),
    )
    .unwrap_or(0.0);
    let severity = amplitude / cfg.alarm_um;
    let frequency_hz = median(
        &mut results
            .iter()
            .filter(|r| r.level > Verdict::Ok)
            .filter_map(|r| r.speed_hz)
            .collect::<Vec<_>>(),
    );
    let dominant_hz = median(
        &mut results
            .iter()
            .filter_map(|r| r.speed_hz)
            .collect::<Vec<_>>(),
    );
    let amplitude_trend_per_h = amplitude_trend_per_h(&results);
    let lost_motion = lost_motion(trace, &results);
    let backlash_estimate = BacklashEstimate {
        rotary: trace.position_unit == "mdeg",
        estimate: crate::gap::estimate(trace, &results, verdict, cfg.gap.as_ref()),
    };
    let mut reasons = reasons;
    if backlash_estimate.estimate.is_some() {
        let at = usize::from(!reasons.is_empty());
        reasons.insert(at, format!("the gap: {}", backlash_estimate.text()));
    }
    DetectorReport {
        kv_per_s: cfg.kv_per_s,
        band_hz: cfg.band_hz(),
        config: *cfg,
        verdict,
        inconclusive: None,
        reasons,
        window_source: if trace.set_velocity_source.is_empty() {
            "the trace's set-point column".into()
        } else {
            trace.set_velocity_source.clone()
        },
        time_base: if trace.time_base.is_empty() {
            "the trace's time column".into()
        } else {
            trace.time_base.clone()
        },
        severity,
        amplitude,
        frequency_hz,
        frequency_over_kv: frequency_hz.map(|f| f / cfg.kv_per_s),
        dominant_hz,
        first_suspected_s,
        first_backlash_s,
        amplitude_trend_per_h,
        lost_motion,
        backlash_estimate,
        position_unit: trace.position_unit.clone(),
        windows: results,
        forced_windows: Vec::new(),
        master_loop: None,
    }
}

/// When a level was first confirmed (end of the window, s): backlash suspected, backlash.
/// After each window the confirmed level is the lowest of the windows that confirm it.
fn first_confirmed(results: &[WindowResult], cfg: &DetectorConfig) -> (Option<f64>, Option<f64>) {
    let mut first_suspected_s = None;
    let mut first_backlash_s = None;
    for i in 0..results.len() {
        // (A trace with fewer windows than `confirm_windows` is judged on all it has.)
        let short = results.len() < cfg.confirm_windows;
        let Some(from) = confirming(results, i, cfg).or(short.then_some(0)) else {
            continue;
        };
        let lvl = results[from..=i]
            .iter()
            .map(|r| r.level)
            .min()
            .unwrap_or(Verdict::Ok);
        if lvl >= Verdict::BacklashSuspected && first_suspected_s.is_none() {
            first_suspected_s = Some(results[i].t_end_s);
        }
        if lvl >= Verdict::Backlash && first_backlash_s.is_none() {
            first_backlash_s = Some(results[i].t_end_s);
        }
    }
    (first_suspected_s, first_backlash_s)
}

/// The report's reasons: how the verdict follows from the `last` (confirming) windows, then
/// one line per window.
fn verdict_reasons(
    results: &[WindowResult],
    last: &[WindowResult],
    verdict: Verdict,
    trace: &AxisTrace,
    cfg: &DetectorConfig,
) -> Vec<String> {
    let mut reasons = Vec::new();
    if let (Some(first), Some(end)) = (last.first(), last.last()) {
        let lowest = last.iter().map(|r| r.level).min().unwrap_or(Verdict::Ok);
        reasons.push(format!(
            "verdict {}: the lowest level of the last {} of {} windows ({:.2}..{:.2} s); a level \
             needs {} windows in a row, or windows in a row of {:.1} s in all",
            verdict.as_str(),
            last.len(),
            results.len(),
            first.t_start_s,
            end.t_end_s,
            cfg.confirm_windows,
            confirm_s(cfg),
        ));
        debug_assert_eq!(lowest, verdict);
    }
    for r in results {
        reasons.push(format!(
            "window {:.2}..{:.2} s at {:.1} {}/s: {}: {}",
            r.t_start_s,
            r.t_end_s,
            r.set_velocity,
            unit_text(&trace.position_unit),
            r.level.as_str(),
            r.reason
        ));
    }
    reasons
}

/// Least-squares slope of the windows' displacement amplitude over time, per hour.
fn amplitude_trend_per_h(results: &[WindowResult]) -> Option<f64> {
    let ts: Vec<f64> = results
        .iter()
        .map(|r| 0.5 * (r.t_start_s + r.t_end_s) / 3600.0)
        .collect();
    let amps: Vec<f64> = results.iter().map(|r| r.displacement_amplitude).collect();
    slope(&ts, &amps)
}

/// Lost motion: the mean encoder difference moving forward minus moving backward; needs an
/// independent motor position (not a copy of the direct one).
fn lost_motion(trace: &AxisTrace, results: &[WindowResult]) -> Option<f64> {
    let independent = trace
        .motor_position
        .iter()
        .zip(&trace.direct_position)
        .any(|(a, b)| a != b);
    let mean_dir = |pos: bool| {
        let v: Vec<f64> = results
            .iter()
            .filter(|r| (r.set_velocity > 0.0) == pos)
            .map(|r| r.encoder_difference_mean)
            .collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    };
    match (independent, mean_dir(true), mean_dir(false)) {
        (true, Some(p), Some(n)) => Some(p - n),
        _ => None,
    }
}

/// A position unit for people: "µm" for the machine-readable "um" (the JSON keeps "um").
fn unit_text(unit: &str) -> &str {
    if unit == "um" {
        "µm"
    } else {
        unit
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::windows::scan_windows;

    /// A synthetic cruise with a limit cycle of displacement amplitude `x` at `f` Hz.
    fn synth(x: f64, f: f64, secs: f64) -> AxisTrace {
        let mut tr = AxisTrace::default();
        let n = (secs * 1000.0) as usize;
        let w = 2.0 * std::f64::consts::PI * f;
        for i in 0..n {
            let t = i as f64 * 1e-3;
            let v = if t < 0.2 { 5000.0 * t } else { 1000.0 };
            let osc = x * w * (w * t).cos();
            let noise = ((i * 7919) % 13) as f64 * 0.01;
            tr.t_s.push(t);
            tr.set_velocity.push(v);
            tr.motor_velocity.push(v + osc + noise);
            tr.current.push(100.0 + 20.0 * (w * t).sin() + noise);
            tr.motor_position.push(1000.0 * t + x * (w * t).sin());
            tr.direct_position.push(1000.0 * t);
        }
        tr
    }

    #[test]
    fn flags_a_limit_cycle_in_band_and_ignores_a_clean_cruise() {
        let cfg = DetectorConfig::new(30.0);
        let r = analyze(&synth(10.0, 18.0, 10.0), &cfg);
        assert_eq!(r.verdict, Verdict::Backlash, "{r:#?}");
        let f = r.frequency_hz.unwrap();
        assert!((f - 18.0).abs() < 0.3, "{f}");
        assert!((r.amplitude - 10.0).abs() < 1.0, "{}", r.amplitude);
        let clean = analyze(&synth(0.0, 18.0, 10.0), &cfg);
        assert_eq!(clean.verdict, Verdict::Ok);
        assert_eq!(clean.frequency_hz, None);
    }

    #[test]
    fn a_peak_outside_the_band_is_not_backlash() {
        let cfg = DetectorConfig::new(30.0);
        let r = analyze(&synth(10.0, 45.0, 10.0), &cfg);
        assert!(r.windows.iter().all(|w| !w.in_band));
        assert_eq!(r.verdict, Verdict::Ok);
    }

    /// A 4 ms capture at 10 mm/s after a 0.2 s ramp: the set position per SYNC from
    /// `set_position(k)`, the motor speed from `motor(k, raw set velocity)`.
    fn captured(
        secs: f64,
        set_position: impl Fn(usize) -> f64,
        motor: impl Fn(usize, f64) -> f64,
    ) -> AxisTrace {
        let dt = 4e-3;
        let n = (secs / dt) as usize;
        let mut tr = AxisTrace::default();
        for k in 0..n {
            let t = k as f64 * dt;
            let p = set_position(k);
            let v_raw = if k > 0 {
                (p - set_position(k - 1)) / dt
            } else {
                0.0
            };
            tr.t_s.push(t);
            tr.set_position.push(p);
            tr.motor_velocity.push(motor(k, v_raw));
            tr.current.push(0.0);
            tr.motor_position.push(p);
            tr.direct_position.push(p);
        }
        tr.position_unit = "um".into();
        tr.set_velocity = crate::windows::set_velocity_from_demand(
            &tr.t_s,
            &tr.set_position,
            crate::windows::DEMAND_SPAN_S,
        );
        tr
    }

    /// Deterministic uniform numbers in -1..1 (splitmix64 of k: no pattern over k).
    fn uniform(k: usize) -> f64 {
        let mut z = (k as u64)
            .wrapping_add(1)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    /// The position of a 10 mm/s cruise after a 0.2 s ramp at master time `t`, um.
    fn cruise_um(t: f64) -> f64 {
        let (v, t_ramp) = (10_000.0, 0.2);
        if t < t_ramp {
            0.5 * v / t_ramp * t * t
        } else {
            0.5 * v * t_ramp + v * (t - t_ramp)
        }
    }

    /// Half the spread of the master's clock sampling, in periods.
    const JITTER: f64 = 0.3;

    #[test]
    fn set_points_that_jitter_give_windows_constant_on_average_and_the_limit_cycle() {
        // A master that samples its own clock up to 0.3 periods late or early: no stretch of
        // exactly constant set speed, and the set-point moves in the band by less than the
        // limit cycle.
        let dt = 4e-3;
        let sp = |k: usize| cruise_um((k as f64 + JITTER * uniform(k)) * dt).round();
        let w = 2.0 * std::f64::consts::PI * 18.0;
        let tr = captured(8.0, sp, |k, _| {
            let t = k as f64 * dt;
            if t < 0.2 {
                50_000.0 * t
            } else {
                10_000.0 + 8.0 * w * (w * t).cos()
            }
        });
        let cfg = DetectorConfig::new(30.0);
        assert!(
            scan_windows(&tr.t_s, &tr.set_velocity, &cfg.windows)
                .windows
                .is_empty(),
            "the exact scan must find nothing here, or the test tests nothing"
        );
        let r = analyze(&tr, &cfg);
        assert_eq!(r.verdict, Verdict::Backlash, "{:#?}", r.reasons);
        assert!(
            r.window_source.contains("constant on average"),
            "{}",
            r.window_source
        );
        let f = r.frequency_hz.unwrap();
        assert!((f - 18.0).abs() < 0.5, "{f}");
        assert!(r.forced_windows.is_empty(), "{:#?}", r.forced_windows);
        assert_eq!(r.master_loop, None, "jitter of its own is no loop");
    }

    #[test]
    fn a_set_point_task_beating_with_sync_forces_the_axis_and_is_inconclusive() {
        // 8 set-points per 15 SYNCs (a 7.5 ms task against a 4 ms SYNC): holds and double
        // steps that repeat every 60 ms, a 16.7 Hz line in the band; the axis follows them
        // (feed-forward), it has no limit cycle of its own.
        let dt = 4e-3;
        let sp = |k: usize| {
            let sent = ((k * 8) / 15) as f64 * 15.0 / 8.0;
            cruise_um(sent * dt).round()
        };
        let tr = captured(8.0, sp, |_, v_raw| v_raw);
        let r = analyze(&tr, &DetectorConfig::new(30.0));
        assert_eq!(r.verdict, Verdict::Inconclusive, "{:#?}", r.reasons);
        assert_eq!(r.inconclusive, Some(Inconclusive::SetPointNotConstant));
        assert!(!r.forced_windows.is_empty());
        // Its set-point does not follow the axis: no master's loop.
        assert_eq!(r.master_loop, None);
        assert!(r
            .forced_windows
            .iter()
            .all(|w| w.set_point_amplitude >= 1.0));
        // The same axis with set-points on time: ok, nothing forced.
        let on_time = captured(8.0, |k| cruise_um(k as f64 * dt).round(), |_, v| v);
        let r = analyze(&on_time, &DetectorConfig::new(30.0));
        assert_eq!(r.verdict, Verdict::Ok, "{:#?}", r.reasons);
        assert!(r.forced_windows.is_empty());
    }

    /// A capture of a drive in real time whose master's SYNCs jitter (intervals 1..7 ms, one
    /// in five 20 ms) and stall for 150 ms every second, each set-point taken from the
    /// master's clock up to 3 ms before its SYNC's time stamp; the motor speed with a limit
    /// cycle of `x` um at 18 Hz, on the stamps.
    fn stalled(x: f64) -> AxisTrace {
        let w = 2.0 * std::f64::consts::PI * 18.0;
        let mut tr = AxisTrace::default();
        let (mut now, mut next_stall, mut k) = (0.0, 1.0, 0usize);
        while now < 6.0 {
            let u = 0.5 * (uniform(k) + 1.0);
            now += if u < 0.8 {
                0.001 + 0.006 * 0.5 * (uniform(k + 7_000_000) + 1.0)
            } else {
                0.02
            };
            if now >= next_stall {
                now += 0.15;
                next_stall += 1.0;
            }
            let sent = now - 0.003 * 0.5 * (uniform(k + 1_000_000) + 1.0);
            let p = cruise_um(sent).round();
            let v = if now < 0.2 {
                50_000.0 * now
            } else {
                10_000.0 + x * w * (w * now).cos()
            };
            tr.t_s.push(now);
            tr.set_position.push(p);
            tr.motor_velocity.push(v);
            tr.current.push(0.0);
            tr.motor_position.push(p);
            tr.direct_position.push(p);
            k += 1;
        }
        tr.position_unit = "um".into();
        tr.set_velocity = crate::windows::set_velocity_from_demand(
            &tr.t_s,
            &tr.set_position,
            crate::windows::DEMAND_SPAN_S,
        );
        tr
    }

    #[test]
    fn stalled_jittery_syncs_get_a_verdict_on_the_capture_s_own_time_stamps() {
        let cfg = DetectorConfig::new(30.0);
        let r = analyze(&stalled(8.0), &cfg);
        assert_eq!(r.verdict, Verdict::Backlash, "{:#?}", r.reasons);
        assert!(
            (r.frequency_hz.unwrap() - 18.0).abs() < 0.5,
            "{:?}",
            r.frequency_hz
        );
        assert!(r.window_source.contains("bridged"), "{}", r.window_source);
        let r = analyze(&stalled(0.0), &cfg);
        assert_eq!(r.verdict, Verdict::Ok, "{:#?}", r.reasons);
        // Without the bridges (stalls end windows) nothing would be measured.
        let tr = stalled(8.0);
        let wo = window_options(&cfg);
        assert!(scan_windows(&tr.t_s, &tr.set_velocity, &wo)
            .windows
            .is_empty());
    }

    #[test]
    fn an_axis_that_does_not_follow_its_set_speed_is_inconclusive_not_ok() {
        // A drive in fault while the master keeps streaming: the motor stands still.
        let dt = 4e-3;
        let tr = captured(8.0, |k| cruise_um(k as f64 * dt).round(), |_, _| 0.0);
        let r = analyze(&tr, &DetectorConfig::new(30.0));
        assert_eq!(r.verdict, Verdict::Inconclusive, "{:#?}", r.reasons);
        assert_eq!(r.inconclusive, Some(Inconclusive::AxisNotFollowing));
    }
}
