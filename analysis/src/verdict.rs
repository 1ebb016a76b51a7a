//! What the backlash detector finds per window ([`WindowResult`], its level a [`Verdict`],
//! the master's loop fitted in it, [`LoopFit`]): below the detector and the gap estimate,
//! which both read it.

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
    /// The set-point's own strongest line in the search band, as a displacement (NaN: the
    /// trace has no set position), position unit.
    pub set_point_amplitude: f64,
    /// The speed's line reaches the suspect level, and the set-point itself moves in the
    /// search band by the suspect level and by half that line or more (set-points that jitter
    /// by a good part of a period, or a set-point task that beats with SYNC): the axis is
    /// forced, its own line cannot be told apart. Such a window measures nothing.
    pub forced: bool,
    /// The axis did not follow the set speed: the mean motor speed in the window is off the
    /// set speed by more than half (a drive in fault, disabled, or in another mode). Such a
    /// window measures nothing either.
    pub not_following: bool,
    /// The set-point follows the axis: the master closes the position loop itself
    /// (the detector's `fit_master_loop`). Its motion is then the loop's answer to the axis,
    /// not a force from outside: the window is measured, against the master's k_v.
    pub master_loop: Option<LoopFit>,
}

/// The master's own position loop, fitted from one window: the set velocity (the derivative
/// of the set position the master sent) against the position it had from the drive,
/// `v_set(t) = v0 + a t - k x(t - lag)` (`v0 + a t` stands for its reference `k x_ref(t)`
/// and feed-forward at constant speed).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LoopFit {
    /// The master's gain k, 1/s.
    pub kv_per_s: f64,
    /// How long before the set-point the position it answers was sampled, s (whole
    /// set-point periods).
    pub lag_s: f64,
    /// "direct" (the direct-encoder column, 0x60E4) or "motor" (0x6064).
    pub encoder: &'static str,
    /// Share of the set velocity's variation (beyond its trend) the position explains.
    pub explained: f64,
}

/// The median of `v` (sorted in place); `None` when empty.
pub fn median(v: &mut [f64]) -> Option<f64> {
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
