//! How large the gap is (issue 31, item 4): the detector says whether an axis has backlash;
//! a maintenance planner wants it in mm (deg on a rotary axis). Two ways, the better first:
//!
//! 1. **Two encoders** (the motor encoder 0x6064 and the direct encoder 0x60E4 both in the
//!    trace): over a limit cycle the drive train crosses the gap from flank to flank, so the
//!    motor-side position minus the direct one swings across the gap plus the elastic
//!    deflection of the drive train. The quasi-static deflection is the transmitted force
//!    over the stiffness, the force the motor's torque (the current times the torque
//!    constant) through the kinematic ratio: `d(t) = x_motor - x_direct - C i(t)`, C the
//!    preset's compliance per unit of current ([`GapModel::compliance_per_current`]). The
//!    spread of `d` (its 1st to 99th percentile) is the gap plus what the impacts compress
//!    the contact by beyond that, which grows with the limit cycle's speed, i.e. with its
//!    frequency: spread / gap = `a + c f^2` (f the limit cycle's frequency; the contact's
//!    own frequency sets c), fitted per preset over a sweep of the simulator
//!    ([`CALIBRATION`]).
//! 2. **The limit cycle's amplitude** (one encoder, or copies of one): the amplitude grows in
//!    proportion to the gap while the frequency follows k_v (the paper: 7.7 / 13.8 / 21.2 um
//!    peak-to-peak for 0.025 / 0.045 / 0.07 mm). The detector's displacement-equivalent
//!    amplitude over the gap is again `a + c f^2` per preset ([`CALIBRATION`]).
//!
//! Each flagged window gives `measure / (a + c f^2)`; the estimate is the median over the
//! flagged windows, the range the estimate over the calibration's error band
//! ([`ERROR_BAND`]). Never a number on a healthy axis: only windows flagged
//! `backlash_suspected` or `backlash` are measured, and a report without any has no
//! estimate (`null`); nor where a master closes the position loop itself (its loop's limit
//! cycle, with its own delays, is not the drive's cascade the calibration is of). docs/scenarios.md ("How large is the gap") gives the method and its
//! error over the sweep (`emulator/tests/gap_estimate.rs`).

use crate::axis_trace::AxisTrace;
use crate::verdict::{median, Verdict, WindowResult};

/// A measure over the gap as a function of the limit cycle's frequency f (Hz):
/// `a + c_per_hz2 f^2`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Calibration {
    pub a: f64,
    pub c_per_hz2: f64,
}

impl Calibration {
    /// The measure per unit of gap at frequency `f_hz`.
    pub fn per_gap(&self, f_hz: f64) -> f64 {
        self.a + self.c_per_hz2 * f_hz * f_hz
    }
}

/// Per preset: (the limit cycle's displacement-equivalent amplitude, the two encoders'
/// spread), each over the gap as `a + c f^2`: least squares over the calibration sweep of
/// `emulator/tests/gap_estimate.rs` (k_v 0.5, 1, 2 x the preset's, gaps 0.025 / 0.045 /
/// 0.07 mm or 0.01 / 0.02 / 0.04 deg, 10 mm/s or 10 deg/s, the detector's flagged windows),
/// which checks that this table is that fit. Dimensionless (um per um, mdeg per mdeg).
pub const CALIBRATION: [(&str, Calibration, Calibration); 5] = [
    ("cnc1", cal(0.1110, 9.55e-5), cal(1.0149, 3.76e-4)),
    ("cnc2", cal(0.1107, 9.83e-5), cal(1.0079, 4.01e-4)),
    ("cnc3", cal(0.1097, 1.050e-4), cal(1.0167, 3.52e-4)),
    ("cnc4", cal(0.0978, 1.821e-4), cal(1.0128, 8.83e-4)),
    ("cnc5", cal(0.1109, 9.43e-5), cal(1.0211, 3.45e-4)),
];

const fn cal(a: f64, c_per_hz2: f64) -> Calibration {
    Calibration { a, c_per_hz2 }
}

/// The calibration's error band: the truth lies within estimate / ERROR_BAND.1 ..
/// estimate / ERROR_BAND.0 (the measure over the fit's prediction: within +-4 % over the
/// calibration sweep, within this band over the validation sweep and the capture corpus).
pub const ERROR_BAND: (f64, f64) = (0.85, 1.15);

/// Set-points with noise quench the limit cycle: a window whose set-point moves in the search
/// band by this share of the limit cycle's displacement or more (a master whose set-points
/// jitter; exact set-points, as a PLC's whole-unit steps, show none) has a smaller limit
/// cycle than the gap alone gives, and its amplitude only bounds the gap from below. The
/// drive takes the set-points' slope as its velocity feed-forward (CSP), so a set-point
/// sampled off its time is a velocity step into the speed loop every cycle, a broadband
/// forcing that breaks the limit cycle up.
pub const DITHER_SHARE: f64 = 0.02;
/// How far set-point noise quenches the limit cycle, at most: the range of such an estimate
/// reaches this many times its top. Measured with set-points every 4 ms sampled up to +-5 %
/// of the period off their time (the corpus' python master), 0.05 mm, 10 mm/s: in the
/// simulator (cnc1, cnc2 x k_v 0.7..1.4 x the preset's, `emulator/tests/gap_dither.rs`) the
/// limit cycle falls to 0.42-0.62 of its size with exact set-points; on the bus (cnc1,
/// python canopen over socketcand) to 0.39, in user-mode Linux (corpus
/// `csp-4ms-lock-worn05-trace-v2`) to 0.65.
pub const DITHER_QUENCH: f64 = 3.0;

/// Percentiles of `d` whose distance is the spread (the extremes, without single samples).
pub const SPREAD_PERCENTILES: (f64, f64) = (0.01, 0.99);

/// What the estimate needs of the machine, in the trace's units.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct GapModel {
    /// The limit cycle's amplitude and the two encoders' spread per unit of gap
    /// ([`CALIBRATION`]); None: no calibration for this machine (no estimate).
    pub amplitude_per_gap: Option<Calibration>,
    pub spread_per_gap: Option<Calibration>,
    /// Elastic deflection of the drive train per unit of the trace's current (trace position
    /// unit per current unit); None: the current's scale is unknown (no correction).
    pub compliance_per_current: Option<f64>,
}

/// The current's unit in a trace: ampere (the simulator's trace), or per mille of the rated
/// current (the drive's 0x6078, a capture).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CurrentUnit {
    Ampere,
    Permille,
}

impl GapModel {
    /// The model of a configured axis (a preset with its overrides), for a trace whose current
    /// is in `current`.
    pub fn for_axis(
        cfg: &drive_physics::presets::AxisConfig,
        current: CurrentUnit,
    ) -> Option<Self> {
        let built = cfg.build().ok()?;
        let mech = &built.axis.mech;
        let motor = &built.axis.motor;
        // Force (or load torque) per motor torque: the kinematic ratio; deflection per force:
        // 1 / stiffness; SI to the trace's unit (um or mdeg): 1e6 per m, 1e3 x 180/pi per rad.
        let si_to_trace = if built.axis.rotary {
            1e3 * 180.0 / std::f64::consts::PI
        } else {
            1e6
        };
        let per_ampere = motor.torque_constant * mech.ratio / mech.contact.stiffness * si_to_trace;
        let per_unit = match current {
            CurrentUnit::Ampere => per_ampere,
            CurrentUnit::Permille => per_ampere * motor.rated_current / 1000.0,
        };
        let cal = CALIBRATION.iter().find(|(n, _, _)| *n == cfg.name);
        Some(GapModel {
            amplitude_per_gap: cal.map(|c| c.1),
            spread_per_gap: cal.map(|c| c.2),
            compliance_per_current: per_unit.is_finite().then_some(per_unit),
        })
    }

    /// A trace's current unit from its name ("A": ampere, "permille").
    pub fn current_unit(name: &str) -> Option<CurrentUnit> {
        match name {
            "A" => Some(CurrentUnit::Ampere),
            "permille" => Some(CurrentUnit::Permille),
            _ => None,
        }
    }
}

/// The estimate, in the trace's position unit (um or mdeg).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GapEstimate {
    pub value: f64,
    pub lo: f64,
    pub hi: f64,
    pub method: GapMethod,
}

/// Which way the estimate was had.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GapMethod {
    /// Motor minus direct encoder over the limit cycle, the elastic part subtracted.
    Encoders,
    /// The limit cycle's amplitude over the preset's amplitude per gap.
    Amplitude,
    /// The same where the set-points carry noise ([`DITHER_SHARE`]), which quenches the
    /// limit cycle: the estimate is a lower bound, its range reaches [`DITHER_QUENCH`] times
    /// higher.
    AmplitudeLowerBound,
}

impl GapMethod {
    pub fn as_str(self) -> &'static str {
        match self {
            GapMethod::Encoders => "encoders",
            GapMethod::Amplitude => "amplitude",
            GapMethod::AmplitudeLowerBound => "amplitude_lower_bound",
        }
    }
}

/// Whether window `w` of the trace has two independent encoders: the motor and the direct
/// position differ in most of its samples. One encoder copied into both columns, or a drive
/// whose 0x6064 follows the direct encoder (the position loop closed on it), differs at
/// most where one of two PDOs came late.
pub fn two_encoders(trace: &AxisTrace, w: &WindowResult) -> bool {
    let differ = (w.start..w.end)
        .filter(|&i| trace.motor_position[i] != trace.direct_position[i])
        .count();
    2 * differ > w.end - w.start
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// The gap one window shows between the two encoders: the spread of motor minus direct
/// position minus the elastic deflection (`compliance` x current), trace position unit.
pub fn encoder_spread(trace: &AxisTrace, w: &WindowResult, compliance: Option<f64>) -> Option<f64> {
    let c = compliance.unwrap_or(0.0);
    let mut d: Vec<f64> = (w.start..w.end)
        .map(|i| trace.motor_position[i] - trace.direct_position[i] - c * trace.current[i])
        .filter(|x| x.is_finite())
        .collect();
    if d.len() < 16 {
        return None;
    }
    d.sort_by(f64::total_cmp);
    Some(percentile(&d, SPREAD_PERCENTILES.1) - percentile(&d, SPREAD_PERCENTILES.0))
}

/// The gap from the windows a report measured (`results`, its verdict `verdict`): None on a
/// healthy axis (no window flagged), or where neither way applies.
pub fn estimate(
    trace: &AxisTrace,
    results: &[WindowResult],
    verdict: Verdict,
    model: Option<&GapModel>,
) -> Option<GapEstimate> {
    if verdict < Verdict::BacklashSuspected {
        return None;
    }
    let flagged: Vec<&WindowResult> = results
        .iter()
        .filter(|r| r.level >= Verdict::BacklashSuspected)
        .collect();
    if flagged.is_empty() {
        return None;
    }
    let model = model?;
    // Per flagged window: its measure over the measure per unit of gap at its frequency.
    let per_window = |measure: &dyn Fn(&WindowResult) -> Option<f64>, cal: Calibration| {
        median(
            &mut flagged
                .iter()
                .filter_map(|w| {
                    let f = w.speed_hz?;
                    let m = measure(w)?;
                    let per_gap = cal.per_gap(f);
                    (per_gap > 0.0 && m > 0.0).then(|| m / per_gap)
                })
                .collect::<Vec<f64>>(),
        )
    };
    // A master that closes the position loop itself: the limit cycle is its loop's, with
    // its own delays; the calibration is the drive's cascade.
    if flagged.iter().any(|w| w.master_loop.is_some()) {
        return None;
    }
    let (value, method) = if flagged.iter().all(|w| two_encoders(trace, w)) {
        let c = model.compliance_per_current;
        let v = per_window(&|w| encoder_spread(trace, w, c), model.spread_per_gap?)?;
        (v, GapMethod::Encoders)
    } else {
        let v = per_window(
            &|w| Some(w.displacement_amplitude),
            model.amplitude_per_gap?,
        )?;
        let dithered = flagged.iter().any(|w| {
            w.set_point_amplitude.is_finite()
                && w.set_point_amplitude >= DITHER_SHARE * w.displacement_amplitude
        });
        if dithered {
            (v, GapMethod::AmplitudeLowerBound)
        } else {
            (v, GapMethod::Amplitude)
        }
    };
    let quench = match method {
        GapMethod::AmplitudeLowerBound => DITHER_QUENCH,
        GapMethod::Encoders | GapMethod::Amplitude => 1.0,
    };
    Some(GapEstimate {
        value,
        lo: value / ERROR_BAND.1,
        hi: value / ERROR_BAND.0 * quench,
        method,
    })
}

/// The estimate as the report serializes it: `backlash_estimate_mm` and
/// `backlash_estimate_range_mm` [lo, hi] on a linear axis (um in the trace), `_deg` on a
/// rotary one (mdeg), `null` without an estimate, and `backlash_estimate_method`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BacklashEstimate {
    /// The trace's position unit is mdeg (a rotary axis).
    pub rotary: bool,
    /// In the trace's position unit.
    pub estimate: Option<GapEstimate>,
}

impl BacklashEstimate {
    /// The axis unit's name: "mm" or "deg".
    pub fn unit(&self) -> &'static str {
        if self.rotary {
            "deg"
        } else {
            "mm"
        }
    }
    /// The estimate in mm (deg): the trace's um (mdeg) / 1000.
    pub fn value(&self) -> Option<f64> {
        self.estimate.map(|e| e.value / 1000.0)
    }
    /// The range [lo, hi] in mm (deg).
    pub fn range(&self) -> Option<[f64; 2]> {
        self.estimate.map(|e| [e.lo / 1000.0, e.hi / 1000.0])
    }
    pub fn method(&self) -> Option<GapMethod> {
        self.estimate.map(|e| e.method)
    }
    /// For people: "0.048 mm (0.044..0.053, encoders)" or "none".
    pub fn text(&self) -> String {
        match (self.value(), self.range(), self.method()) {
            (Some(v), Some([lo, hi]), Some(m)) => format!(
                "{v:.4} {u} ({lo:.4}..{hi:.4} {u}, from the {})",
                match m {
                    GapMethod::Encoders => "two encoders",
                    GapMethod::Amplitude => "limit cycle's amplitude",
                    GapMethod::AmplitudeLowerBound =>
                        "limit cycle's amplitude; a lower bound: the set-points carry noise, \
                         which quenches the limit cycle",
                },
                u = self.unit()
            ),
            _ => "none".into(),
        }
    }
}

impl serde::Serialize for BacklashEstimate {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(Some(3))?;
        let u = self.unit();
        m.serialize_entry(&format!("backlash_estimate_{u}"), &self.value())?;
        m.serialize_entry(&format!("backlash_estimate_range_{u}"), &self.range())?;
        m.serialize_entry("backlash_estimate_method", &self.method())?;
        m.end()
    }
}
