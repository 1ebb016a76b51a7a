//! Backlash detection after Moosavian & MohammadiAsl: at constant commanded speed (set
//! acceleration zero) a backlashed axis runs into a limit cycle whose fundamental, visible in
//! the FFT of motor speed and motor current, lies between k_v/4 and k_v (Hz, k_v in 1/s; about
//! 0.6 k_v) and does not depend on the gap, while its amplitude grows with the gap.
//!
//! Method, per constant-velocity window ([`super::windows`]):
//! 1. fundamental of the motor speed and of the motor current in a search band wider than the
//!    paper's (k_v/8 .. 2 k_v, below Nyquist/1.25), so a peak outside the band is seen and
//!    rejected rather than missed;
//! 2. displacement-equivalent amplitude of the speed fluctuation, `x = A_v / (2 pi f)` (um or
//!    mdeg: the trace's position unit), and the peak's prominence over the band's median;
//! 3. the window is flagged `backlash_suspected` when the peak is inside k_v/4 .. k_v, prominent,
//!    and `x >= suspect_um`; `backlash` when also `x >= alarm_um`;
//! 4. the verdict is the lowest level among the last `confirm_windows` windows (so one noisy
//!    window neither raises nor clears an alarm); severity = x / alarm_um of those windows.
//!
//! Alongside: the amplitude trend over time (least squares, per hour), the first time each
//! level was confirmed, and the difference between motor and direct encoder (mean per window,
//! fluctuation, and the lost motion between opposite directions when both are present).

use super::spectrum::SpectrumAnalyzer;
use super::windows::{median_dt, scan_windows, Window, WindowOptions};
use std::collections::HashMap;

/// A trace as the detector needs it. Positions in one unit `u` (um for a linear axis, mdeg for a
/// rotary one: the master's user units), velocities in u/s, current in any unit (per mille of
/// rated current for the master's log, A for the simulator's trace).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AxisTrace {
    pub t_s: Vec<f64>,
    pub set_velocity: Vec<f64>,
    pub motor_velocity: Vec<f64>,
    pub current: Vec<f64>,
    pub motor_position: Vec<f64>,
    pub direct_position: Vec<f64>,
    /// Unit names for reports, e.g. ("um", "permille").
    pub position_unit: String,
    pub current_unit: String,
    /// Where `set_velocity` came from, for the report (e.g. "0x607A target position (CSP,
    /// RPDO)"); empty: "set velocity column".
    pub set_velocity_source: String,
}

impl AxisTrace {
    pub fn len(&self) -> usize {
        self.t_s.len()
    }
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }
    /// Check that every column has the same length.
    pub fn check(&self) -> Result<(), String> {
        let n = self.t_s.len();
        for (name, c) in [
            ("set_velocity", &self.set_velocity),
            ("motor_velocity", &self.motor_velocity),
            ("current", &self.current),
            ("motor_position", &self.motor_position),
            ("direct_position", &self.direct_position),
        ] {
            if c.len() != n {
                return Err(format!(
                    "column {name} has {} samples, time has {n}",
                    c.len()
                ));
            }
        }
        Ok(())
    }
}

impl AxisTrace {
    /// From the simulator's trace (`analysis::Trace`, axis units mm or deg): positions to user
    /// units (um / mdeg), set velocity from the set-point, motor velocity from the motor
    /// speed (rpm) scaled by the kinematic ratio estimated from the motor-encoder position.
    pub fn from_sim(
        t_s: &[f64],
        setpoint: &[f64],
        motor_position: &[f64],
        direct_position: &[f64],
        motor_rpm: &[f64],
        current_a: &[f64],
        rotary: bool,
    ) -> Self {
        let n = t_s.len();
        let uu = |v: &[f64]| v.iter().map(|x| x * 1000.0).collect::<Vec<_>>();
        let deriv = |x: &[f64]| {
            let mut d = vec![0.0; n];
            for i in 1..n {
                let dt = t_s[i] - t_s[i - 1];
                d[i] = if dt > 0.0 {
                    (x[i] - x[i - 1]) / dt
                } else {
                    d[i - 1]
                };
            }
            if n > 1 {
                d[0] = d[1];
            }
            d
        };
        let motor_position = uu(motor_position);
        let set_velocity: Vec<f64> = deriv(&uu(setpoint))
            .into_iter()
            // The set-point is stored with finite precision: round the noise away so constant
            // segments are exactly constant.
            .map(|v| (v * 1e3).round() / 1e3)
            .collect();
        let mv = deriv(&motor_position);
        let (sa, sb): (f64, f64) = mv
            .iter()
            .zip(motor_rpm)
            .filter(|(_, r)| r.abs() > 1e-9)
            .fold((0.0, 0.0), |(a, b), (v, r)| (a + v * r, b + r * r));
        let k = if sb > 0.0 { sa / sb } else { 0.0 };
        Self {
            t_s: t_s.to_vec(),
            set_velocity,
            motor_velocity: motor_rpm.iter().map(|r| r * k).collect(),
            current: current_a.to_vec(),
            motor_position,
            direct_position: uu(direct_position),
            position_unit: if rotary { "mdeg" } else { "um" }.into(),
            current_unit: "A".into(),
            set_velocity_source: "derivative of the position set-point".into(),
        }
    }

    /// From the reference master's sample log (user units, per mille current).
    pub fn from_samples(samples: &[crate::samples::Sample], rotary: bool) -> Self {
        Self {
            t_s: samples.iter().map(|s| s.t_s).collect(),
            set_velocity: samples.iter().map(|s| s.setpoint_velocity_uu_s).collect(),
            motor_velocity: samples.iter().map(|s| f64::from(s.velocity_uu_s)).collect(),
            current: samples
                .iter()
                .map(|s| f64::from(s.current_permille))
                .collect(),
            motor_position: samples.iter().map(|s| f64::from(s.position_uu)).collect(),
            direct_position: samples
                .iter()
                .map(|s| f64::from(s.direct_position_uu))
                .collect(),
            position_unit: if rotary { "mdeg" } else { "um" }.into(),
            current_unit: "permille".into(),
            set_velocity_source: "the master's interpolator velocity".into(),
        }
    }
}

impl AxisTrace {
    /// From samples of what the drive itself reports (`run --trace`, live scenarios:
    /// [`crate::runtime::trace::node_sample`]). A drive has no interpolator velocity to report
    /// (its 0x606B is the position controller's output, which carries the limit cycle), so the
    /// set velocity is derived from the position demand `target_uu` (0x6062).
    pub fn from_drive_samples(samples: &[crate::samples::Sample], rotary: bool) -> Self {
        let mut tr = Self::from_samples(samples, rotary);
        let demand: Vec<f64> = samples.iter().map(|s| s.target_uu).collect();
        tr.set_velocity = super::windows::set_velocity_from_demand(
            &tr.t_s,
            &demand,
            super::windows::DEMAND_SPAN_S,
        );
        tr.set_velocity_source = "position demand 0x6062".into();
        tr
    }
}

/// Detector verdict.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Nothing could be measured (no usable constant-speed window): never "ok". Only a
    /// report's verdict, never a window's level.
    Inconclusive,
    Ok,
    BacklashSuspected,
    Backlash,
}

impl Verdict {
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Inconclusive => "inconclusive",
            Verdict::Ok => "ok",
            Verdict::BacklashSuspected => "backlash_suspected",
            Verdict::Backlash => "backlash",
        }
    }
}

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

/// The analysis of one window.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct WindowResult {
    pub t_start_s: f64,
    pub t_end_s: f64,
    pub start: usize,
    pub end: usize,
    pub set_velocity: f64,
    /// Fundamental of the motor speed, Hz, and its amplitude (zero-to-peak, u/s).
    pub speed_hz: Option<f64>,
    pub speed_amplitude: f64,
    /// Fundamental of the motor current, Hz, and its amplitude (current unit).
    pub current_hz: Option<f64>,
    pub current_amplitude: f64,
    /// Displacement-equivalent amplitude of the speed fluctuation, position unit.
    pub displacement_amplitude: f64,
    pub prominence: f64,
    pub in_band: bool,
    /// Speed and current peaks agree within 10 %.
    pub current_agrees: bool,
    /// Mean and half peak-to-peak of motor minus direct position.
    pub encoder_difference_mean: f64,
    pub encoder_difference_half_pp: f64,
    pub level: Verdict,
    /// Why the window got its level: frequency against the band, prominence, amplitude
    /// against the thresholds.
    pub reason: String,
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
}

impl Inconclusive {
    pub fn as_str(self) -> &'static str {
        match self {
            Inconclusive::NoConstantSpeed => "no_constant_speed",
            Inconclusive::TooShort => "too_short",
            Inconclusive::MissingObjects => "missing_objects",
            Inconclusive::NoFiniteSamples => "no_finite_samples",
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
    pub position_unit: String,
    pub windows: Vec<WindowResult>,
}

fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
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

/// Analyze one window (exposed for tests and plots).
pub fn analyze_window(
    trace: &AxisTrace,
    w: &Window,
    cfg: &DetectorConfig,
    analyzers: &mut HashMap<usize, SpectrumAnalyzer>,
) -> WindowResult {
    let dt = median_dt(&trace.t_s[w.start..w.end]);
    let fs = if dt > 0.0 { 1.0 / dt } else { 1.0 };
    let band = cfg.search_band_hz(fs);
    let n = w.len();
    let an = analyzers
        .entry(n)
        .or_insert_with(|| SpectrumAnalyzer::new(n));
    let speed = an.fundamental(&trace.motor_velocity[w.start..w.end], fs, band);
    let prominence = match speed {
        Some(p) => {
            let df = fs / n as f64;
            let lo = ((band.0 / df).ceil() as usize).max(1);
            let hi = ((band.1 / df).floor() as usize).min(an.amplitudes().len() - 1);
            let mut m: Vec<f64> = an.amplitudes()[lo..=hi.max(lo)].to_vec();
            let med = median(&mut m).unwrap_or(0.0);
            if med > 0.0 {
                p.amplitude / med
            } else {
                f64::INFINITY
            }
        }
        None => 0.0,
    };
    let current = an.fundamental(&trace.current[w.start..w.end], fs, band);
    let (speed_hz, speed_amplitude) =
        speed.map_or((None, 0.0), |p| (Some(p.frequency_hz), p.amplitude));
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
    // Motor minus direct encoder.
    let diff: Vec<f64> = (w.start..w.end)
        .map(|i| trace.motor_position[i] - trace.direct_position[i])
        .collect();
    let mean = diff.iter().sum::<f64>() / n.max(1) as f64;
    let half_pp = super::spectrum::half_peak_to_peak(&diff);
    let unit = unit_text(&trace.position_unit);
    // A line, not noise: prominent over the band's median. A clear limit cycle (at or above
    // the alarm amplitude) needs half the prominence, so that a small change of the capture
    // (a few samples more, a little more noise) cannot flip a clear case to ok.
    let needed = if displacement_amplitude >= cfg.alarm_um {
        0.5 * cfg.min_prominence
    } else {
        cfg.min_prominence
    };
    let (level, reason) = match speed_hz {
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
    }
}

/// Run the detector on a trace.
pub fn analyze(trace: &AxisTrace, cfg: &DetectorConfig) -> DetectorReport {
    let scan = scan_windows(&trace.t_s, &trace.set_velocity, &cfg.windows);
    let finite = |w: &Window| {
        trace.motor_velocity[w.start..w.end]
            .iter()
            .all(|v| v.is_finite())
    };
    let usable: Vec<&Window> = scan.windows.iter().filter(|w| w.len() >= 16).collect();
    let non_finite = usable.iter().filter(|w| !finite(w)).count();
    let mut analyzers = HashMap::new();
    let results: Vec<WindowResult> = usable
        .iter()
        .filter(|w| finite(w))
        .map(|w| analyze_window(trace, w, cfg, &mut analyzers))
        .collect();
    let mut rep = summarize(results, trace, cfg);
    let o = &cfg.windows;
    let need = format!(
        "a window needs {:.1} s of settling plus {:.1} s at constant set speed (|v| >= {} {}/s)",
        o.settle_s,
        o.min_len_s,
        o.min_speed,
        unit_text(&trace.position_unit)
    );
    if rep.windows.is_empty() {
        let any_finite = trace.motor_velocity.iter().any(|v| v.is_finite());
        let (why, text) = if !any_finite || non_finite > 0 {
            (
                Inconclusive::NoFiniteSamples,
                if any_finite {
                    format!("all {non_finite} constant-speed windows hold non-finite motor-speed samples (NaN or infinite)")
                } else {
                    format!("no finite motor-speed sample in the trace ({} samples, all NaN or infinite)", trace.len())
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
            (
                Inconclusive::TooShort,
                format!(
                    "{} constant-speed stretches, the longest {:.2} s: too short ({need})",
                    scan.runs, scan.longest_run_s
                ),
            )
        };
        rep.mark_inconclusive(why, text);
    } else if non_finite > 0 {
        rep.reasons.push(format!(
            "{non_finite} windows skipped: non-finite motor-speed samples (NaN or infinite)"
        ));
    }
    rep
}

impl DetectorReport {
    /// Nothing was measured: the verdict is inconclusive, for `why`, explained by `text`.
    pub fn mark_inconclusive(&mut self, why: Inconclusive, text: String) {
        self.verdict = Verdict::Inconclusive;
        self.inconclusive = Some(why);
        self.severity = 0.0;
        self.amplitude = 0.0;
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

fn summarize(
    results: Vec<WindowResult>,
    trace: &AxisTrace,
    cfg: &DetectorConfig,
) -> DetectorReport {
    // A trace with fewer windows than `confirm_windows` is judged on all it has.
    let k = cfg.confirm_windows.min(results.len()).max(1);
    // Confirmed level after each window: the lowest of the last k levels.
    let mut first_suspected_s = None;
    let mut first_backlash_s = None;
    for i in 0..results.len() {
        if i + 1 < k {
            continue;
        }
        let lvl = results[i + 1 - k..=i]
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
    let last = &results[results.len().saturating_sub(k)..];
    let verdict = if !results.is_empty() {
        last.iter().map(|r| r.level).min().unwrap_or(Verdict::Ok)
    } else {
        Verdict::Inconclusive
    };
    let mut reasons = Vec::new();
    if let (Some(first), Some(end)) = (last.first(), last.last()) {
        let lowest = last.iter().map(|r| r.level).min().unwrap_or(Verdict::Ok);
        reasons.push(format!(
            "verdict {}: the lowest level of the last {} of {} windows ({:.2}..{:.2} s); a level \
             needs {} windows in a row",
            verdict.as_str(),
            last.len(),
            results.len(),
            first.t_start_s,
            end.t_end_s,
            cfg.confirm_windows.min(results.len()).max(1),
        ));
        debug_assert_eq!(lowest, verdict);
    }
    for r in &results {
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
    let ts: Vec<f64> = results
        .iter()
        .map(|r| 0.5 * (r.t_start_s + r.t_end_s) / 3600.0)
        .collect();
    let amps: Vec<f64> = results.iter().map(|r| r.displacement_amplitude).collect();
    let amplitude_trend_per_h = slope(&ts, &amps);
    // Lost motion: needs an independent motor position (not a copy of the direct one).
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
    let lost_motion = match (independent, mean_dir(true), mean_dir(false)) {
        (true, Some(p), Some(n)) => Some(p - n),
        _ => None,
    };
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
        severity,
        amplitude,
        frequency_hz,
        frequency_over_kv: frequency_hz.map(|f| f / cfg.kv_per_s),
        dominant_hz,
        first_suspected_s,
        first_backlash_s,
        amplitude_trend_per_h,
        lost_motion,
        position_unit: trace.position_unit.clone(),
        windows: results,
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
}
