//! Studies of the paper's law over many runs: the k_v x backlash x preset sweep (every case a
//! constant-velocity run measured from its trace, run on all cores), the closed speed loop's
//! frequency response measured by exciting the simulated drive, and the paper's figures
//! ([`figures`]). Offline only: nothing here runs on the real-time path.

pub mod figures;
pub mod outer_loop;
pub mod response;

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use crate::analysis::{constant_velocity_run_until, RunError, RunOptions};
use crate::presets::{AxisConfig, AxisKind, ConfigError};

/// The paper's rotary set-point: 0.026 r/s at the table, in deg/s.
pub const ROTARY_VELOCITY_DEG_PER_S: f64 = 0.026 * 360.0;
/// Linear cruise velocity of the measurements, mm/s.
pub const LINEAR_VELOCITY_MM_PER_S: f64 = 20.0;
/// Simulated duration of one case, s (window for the FFT: the last 6.4 s).
pub const DEFAULT_DURATION_S: f64 = 8.0;

/// A limit cycle counts as present when the fundamental of the measured motor speed, expressed
/// as load velocity, is at least this fraction of `k_v x backlash` (the velocity scale of the
/// cycle: the load crosses the gap at about k_v times the gap). Runs without a cycle show
/// encoder-quantisation lines of about 2 % of that scale, cycles 30 % and more.
pub const LIMIT_CYCLE_MIN_RELATIVE_AMPLITUDE: f64 = 0.1;

/// Below this drag number ([`drag_number`]) every preset keeps its limit cycle; measured on
/// CNC1 over k_v 10-30 1/s and two gaps, the cycle dies between 1.25 and 2.2 (docs/physics.md).
pub const DRAG_NUMBER_CYCLE_BELOW: f64 = 1.2;
/// Above this drag number the limit cycle dies (docs/physics.md).
pub const DRAG_NUMBER_NO_CYCLE_ABOVE: f64 = 2.5;

/// The drag number `D / (m k_v^2 b)` of a run: the load's drag at the cruise velocity (Coulomb
/// plus viscous friction, N or N m) against the force scale of the limit cycle (the load mass
/// or inertia `m`, accelerated by about `k_v^2 b`, `b` the gap in m or rad). The drag pulls the
/// load back onto the driving flank between impacts; when it decelerates the load by more than
/// the cycle's velocity swing within half a period, the load never crosses the gap and the
/// cycle dies. Independent of the gap only when it is small: the paper's law (f set by k_v, not
/// by the gap) holds below [`DRAG_NUMBER_CYCLE_BELOW`]. Infinite without backlash.
pub fn drag_number(cfg: &AxisConfig, kv_per_s: f64, backlash: f64, velocity: f64) -> f64 {
    let Ok(built) = cfg.build() else {
        return f64::NAN;
    };
    let unit = built.display_unit;
    let mech = &built.axis.mech;
    let v = (velocity * unit).abs();
    let drag = mech.load_friction.coulomb_at(v) + mech.load_friction.viscous * v;
    let b = backlash * unit;
    drag / (mech.load_mass * kv_per_s * kv_per_s * b)
}

/// Default cruise velocity for a preset: 20 mm/s on linear axes, 0.026 r/s on tables.
pub fn default_velocity(cfg: &AxisConfig) -> f64 {
    match cfg.kind {
        AxisKind::Linear => LINEAR_VELOCITY_MM_PER_S,
        AxisKind::Rotary => ROTARY_VELOCITY_DEG_PER_S,
    }
}

/// The preset's own backlash in its axis unit (mm or deg).
pub fn own_backlash(cfg: &AxisConfig) -> f64 {
    cfg.backlash_mm.or(cfg.backlash_deg).unwrap_or(0.0)
}

/// Key of the backlash in the preset's unit.
pub fn backlash_key(cfg: &AxisConfig) -> &'static str {
    match cfg.kind {
        AxisKind::Linear => "backlash_mm",
        AxisKind::Rotary => "backlash_deg",
    }
}

/// One case of a sweep.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Case {
    pub preset: String,
    pub kv_per_s: f64,
    /// Backlash in the axis unit (mm or deg).
    pub backlash: f64,
    /// Cruise velocity, axis unit per second.
    pub velocity: f64,
    pub duration_s: f64,
}

/// What one case measured (one CSV/JSON row).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CaseRow {
    pub preset: String,
    pub unit: String,
    pub kv_per_s: f64,
    pub backlash: f64,
    pub velocity: f64,
    /// Strongest line of the measured motor speed, Hz (1-200 Hz search band).
    pub fundamental_hz: Option<f64>,
    pub f_over_kv: Option<f64>,
    /// True when the line is a limit cycle ([`LIMIT_CYCLE_MIN_RELATIVE_AMPLITUDE`]).
    pub limit_cycle: bool,
    /// k_v/4 < f < k_v (eq. 11-12), with a limit cycle.
    pub in_band: bool,
    /// [`drag_number`] of the case: the cycle lives below about 1.5.
    pub drag_number: f64,
    pub motor_velocity_amplitude_rpm: f64,
    /// Fundamental of the motor speed as load velocity, axis unit per second.
    pub load_velocity_amplitude: f64,
    pub following_error_half_p2p: f64,
    pub current_amplitude_a: f64,
    pub window_start_s: f64,
    pub window_end_s: f64,
}

/// Simulated seconds a sweep case may run: the FFT window is the cruise after the start-up
/// transient (shorter leaves too little of it), and a case longer than ten minutes belongs in
/// `sim`.
pub const CASE_DURATION_S: std::ops::RangeInclusive<f64> = 2.0..=600.0;

/// Run one case.
pub fn run_case(base: &AxisConfig, case: &Case) -> Result<CaseRow, ConfigError> {
    run_case_until(base, case, &AtomicBool::new(false)).map_err(|e| match e {
        RunError::Config(e) => e,
        RunError::Stopped { .. } => ConfigError::new("stop", "stopped"),
    })
}

/// [`run_case`], ended early once `stop` is set.
pub fn run_case_until(
    base: &AxisConfig,
    case: &Case,
    stop: &AtomicBool,
) -> Result<CaseRow, RunError> {
    let cfg = base
        .with_override("kv_per_s", &format!("{}", case.kv_per_s))?
        .with_override(backlash_key(base), &format!("{}", case.backlash))?;
    measure_until(&cfg, case.velocity, case.duration_s, stop)
}

/// Measure one configured axis as a sweep case does (a constant-velocity run at `velocity`
/// for `duration_s`, its k_v and backlash those of `cfg`), ended early once `stop` is set.
/// The Python module's sweep runs each case of its grid (any preset keys) through this.
pub fn measure_until(
    cfg: &AxisConfig,
    velocity: f64,
    duration_s: f64,
    stop: &AtomicBool,
) -> Result<CaseRow, RunError> {
    let built = cfg.build()?;
    let kv_per_s = cfg.kv_per_s;
    let backlash = own_backlash(cfg);
    let res = constant_velocity_run_until(cfg, &RunOptions::new(velocity, duration_s), stop)?;
    let s = res.summary;
    // motor rpm -> load velocity in axis units/s
    let rpm_to_load = std::f64::consts::PI / 30.0 / built.axis.mech.ratio / built.display_unit;
    let load_amp = s.motor_velocity_amplitude_rpm * rpm_to_load;
    let scale = kv_per_s * backlash;
    let limit_cycle = s.fundamental_hz.is_some()
        && scale > 0.0
        && load_amp >= LIMIT_CYCLE_MIN_RELATIVE_AMPLITUDE * scale;
    let in_band = limit_cycle
        && s.fundamental_hz
            .is_some_and(|f| f > kv_per_s / 4.0 && f < kv_per_s);
    Ok(CaseRow {
        preset: cfg.name.clone(),
        unit: s.unit.clone(),
        kv_per_s,
        backlash,
        velocity,
        fundamental_hz: s.fundamental_hz,
        f_over_kv: s.f_over_kv,
        limit_cycle,
        in_band,
        drag_number: drag_number(cfg, kv_per_s, backlash, velocity),
        motor_velocity_amplitude_rpm: s.motor_velocity_amplitude_rpm,
        load_velocity_amplitude: load_amp,
        following_error_half_p2p: s.following_error_half_p2p,
        current_amplitude_a: s.current_amplitude_a,
        window_start_s: s.window_start_s,
        window_end_s: s.window_end_s,
    })
}

/// Run cases on `threads` worker threads (0 = all cores); results in the order of `cases`.
pub fn run_cases(
    cases: &[(AxisConfig, Case)],
    threads: usize,
) -> Vec<Result<CaseRow, ConfigError>> {
    let stop = AtomicBool::new(false);
    run_parallel(
        cases,
        threads,
        &stop,
        &AtomicUsize::new(0),
        |(cfg, case)| run_case(cfg, case),
    )
    .into_iter()
    .map(|r| r.expect("nothing sets the stop flag: every case ran"))
    .collect()
}

/// Run `work` on every item on `threads` worker threads (0 = all cores), each thread taking
/// the next item not yet taken; results in the order of `items`. `done` counts the items
/// finished (for a progress display). Once `stop` is set no further item starts: those are
/// `None`. A panic in `work` is resumed on the calling thread once every worker has ended.
pub fn run_parallel<T: Sync, R: Send>(
    items: &[T],
    threads: usize,
    stop: &AtomicBool,
    done: &AtomicUsize,
    work: impl Fn(&T) -> R + Sync,
) -> Vec<Option<R>> {
    let threads = if threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        threads
    }
    .clamp(1, items.len().max(1));
    let next = AtomicUsize::new(0);
    let parts = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let mut finished = Vec::new();
                    while !stop.load(Ordering::Relaxed) {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(item) = items.get(i) else {
                            break;
                        };
                        finished.push((i, work(item)));
                        done.fetch_add(1, Ordering::Relaxed);
                    }
                    finished
                })
            })
            .collect();
        let joined: Vec<_> = handles.into_iter().map(|h| h.join()).collect();
        joined
            .into_iter()
            .map(|r| r.unwrap_or_else(|panic| std::panic::resume_unwind(panic)))
            .collect::<Vec<_>>()
    });
    let mut out: Vec<Option<R>> = std::iter::repeat_with(|| None).take(items.len()).collect();
    for (i, r) in parts.into_iter().flatten() {
        out[i] = Some(r);
    }
    out
}

/// A list of values written as `A..B:N` (N points, linear), `A,B,C` or `A`; each value may end
/// in `x` to mean a multiple of the preset's own value (`0.5x..2x:7`).
#[derive(Clone, Debug, PartialEq)]
pub struct ValueSpec {
    values: Vec<(f64, bool)>,
}

/// Most cases one sweep takes (`drive-emu sweep` and the Python module's `sweep`, which
/// reads it from here): its table is held in memory, so a grid beyond this is refused,
/// counted before any case is built.
pub const MAX_SWEEP_CASES: usize = 1_000_000;

impl ValueSpec {
    /// How many values it gives (what [`ValueSpec::resolve`] returns, without building it).
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether it gives no value (never, once parsed).
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    pub fn parse(text: &str) -> Result<Self, String> {
        let num = |s: &str| -> Result<(f64, bool), String> {
            let s = s.trim();
            let (s, rel) = match s.strip_suffix('x') {
                Some(r) => (r, true),
                None => (s, false),
            };
            let v: f64 = s
                .parse()
                .map_err(|_| format!("`{s}` is not a number (in `{text}`)"))?;
            if !v.is_finite() || v < 0.0 {
                return Err(format!("`{s}` must be a finite number >= 0 (in `{text}`)"));
            }
            Ok((v, rel))
        };
        let values = if let Some((range, n)) = text.split_once(':') {
            let (a, b) = range
                .split_once("..")
                .ok_or_else(|| format!("`{text}`: a range is written A..B:N"))?;
            let (a, b) = (num(a)?, num(b)?);
            if a.1 != b.1 {
                return Err(format!("`{text}`: both ends relative (x) or both absolute"));
            }
            let n: usize = n
                .trim()
                .parse()
                .map_err(|_| format!("`{text}`: N must be a whole number"))?;
            if !(1..=1000).contains(&n) {
                return Err(format!("`{text}`: N must be 1..1000"));
            }
            (0..n)
                .map(|i| {
                    let t = if n == 1 {
                        0.0
                    } else {
                        i as f64 / (n - 1) as f64
                    };
                    (a.0 + t * (b.0 - a.0), a.1)
                })
                .collect()
        } else if text.contains("..") {
            return Err(format!("`{text}`: a range is written A..B:N (N points)"));
        } else {
            text.split(',').map(num).collect::<Result<Vec<_>, _>>()?
        };
        if values.is_empty() {
            return Err(format!("`{text}`: no values"));
        }
        Ok(ValueSpec { values })
    }

    /// The values for a preset whose own value is `own`.
    pub fn resolve(&self, own: f64) -> Vec<f64> {
        self.values
            .iter()
            .map(|&(v, rel)| if rel { v * own } else { v })
            .collect()
    }
}

/// Rows as CSV (header with units).
pub fn rows_csv(rows: &[CaseRow]) -> String {
    let mut s = String::from(
        "preset,unit,kv_per_s,backlash,velocity_per_s,fundamental_hz,f_over_kv,limit_cycle,\
         in_band,drag_number,motor_velocity_amplitude_rpm,load_velocity_amplitude_per_s,\
         following_error_half_p2p,current_amplitude_a,window_start_s,window_end_s\n",
    );
    let o = |x: Option<f64>| x.map(|v| format!("{v:.4}")).unwrap_or_default();
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{:.4},{:.5},{:.6},{:.6},{:.5},{:.3},{:.3}\n",
            r.preset,
            r.unit,
            r.kv_per_s,
            r.backlash,
            r.velocity,
            o(r.fundamental_hz),
            o(r.f_over_kv),
            r.limit_cycle,
            r.in_band,
            r.drag_number,
            r.motor_velocity_amplitude_rpm,
            r.load_velocity_amplitude,
            r.following_error_half_p2p,
            r.current_amplitude_a,
            r.window_start_s,
            r.window_end_s
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_specs() {
        assert_eq!(
            ValueSpec::parse("0.5x..2x:4").unwrap().resolve(30.0),
            vec![15.0, 30.0, 45.0, 60.0]
        );
        assert_eq!(
            ValueSpec::parse("10,20").unwrap().resolve(30.0),
            vec![10.0, 20.0]
        );
        assert_eq!(ValueSpec::parse("1x").unwrap().resolve(0.03), vec![0.03]);
        assert!(ValueSpec::parse("1..2").is_err());
        assert!(ValueSpec::parse("1x..2:3").is_err());
        assert!(ValueSpec::parse("a").is_err());
        assert!(ValueSpec::parse("-1").is_err());
    }
}
