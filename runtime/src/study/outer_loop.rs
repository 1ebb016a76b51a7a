//! The paper's set-up on the bus: the CNC closes the position loop itself over the direct
//! encoder (0x60E4) and sends speed set-points to the drive in CSV
//! ([`crate::master::outer_loop`]). One run: the reference master and one drive in
//! lock-step on the in-process bus, enable in CSV, a short ramp (10 ms) to the cruise speed,
//! then the drive's own motor speed (0x606C, every 1 ms tick) at constant speed gives the
//! limit cycle's frequency and amplitude. Offline only.

use crate::analysis::spectrum::fundamental;
use crate::drive::axis_drive::AxisDrive;
use crate::master::outer_loop::{LoopEncoder, PositionLoop};
use crate::master::{Master, MasterConfig, Step, MODE_CSV};
use crate::presets::{AxisConfig, ConfigError};
use crate::runtime::trace::node_sample;
use crate::runtime::AxisSlot;
use crate::session::OfflineRun;

use super::{backlash_key, LIMIT_CYCLE_MIN_RELATIVE_AMPLITUDE};

/// Ramp time to the cruise speed, s: a usual CNC acceleration, and the end of the ramp is the
/// start disturbance the limit cycle needs.
pub const RAMP_S: f64 = 0.01;
/// Time after the ramp before the analysis window, s.
pub const SETTLE_S: f64 = 1.5;
/// The drive's control tick in these runs, us.
pub const TICK_US: u64 = 1000;

/// One run of the master's position loop.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct OuterLoopCase {
    pub preset: String,
    /// The master's position-loop gain, 1/s.
    pub kv_per_s: f64,
    /// Backlash in the axis unit (mm or deg).
    pub backlash: f64,
    /// Cruise speed, axis unit per second.
    pub velocity: f64,
    /// SYNC period, us.
    pub sync_period_us: u32,
    /// Cruise time, s.
    pub duration_s: f64,
}

/// What it measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct OuterLoopRow {
    pub case: OuterLoopCase,
    /// Strongest line of the motor speed 0x606C at constant speed, 1-200 Hz, Hz.
    pub fundamental_hz: Option<f64>,
    pub f_over_kv: Option<f64>,
    /// Its amplitude, uu/s.
    pub speed_amplitude_uu_s: f64,
    /// At least [`LIMIT_CYCLE_MIN_RELATIVE_AMPLITUDE`] x k_v x backlash.
    pub limit_cycle: bool,
    /// SYNC period over the limit cycle's period (T_sync x f).
    pub sync_over_cycle: Option<f64>,
    /// The master's program failed (with why): no measurement.
    pub error: Option<String>,
}

/// Run one case: master closing the loop on the direct encoder at `case.kv_per_s`, the drive
/// in CSV with the preset's speed loop.
pub fn run_outer_loop(
    base: &AxisConfig,
    case: &OuterLoopCase,
) -> Result<OuterLoopRow, ConfigError> {
    let cfg = base.with_override(backlash_key(base), &format!("{}", case.backlash))?;
    let mut drive = AxisDrive::from_config(&cfg)?;
    let node = crate::drive::node::node(&mut drive, 5).map_err(|e| ConfigError {
        key: "node".into(),
        reason: e.to_string(),
    })?;
    // Axis unit -> user unit (1 um, 1 mdeg).
    let uu = 1000.0;
    let v_uu = case.velocity * uu;
    let mcfg = MasterConfig {
        sync_period_us: case.sync_period_us,
        position_loop: Some(PositionLoop {
            kv_per_s: case.kv_per_s,
            encoder: LoopEncoder::Direct,
        }),
        ..MasterConfig::default()
    };
    let program = vec![
        Step::Enable { mode: MODE_CSV },
        Step::Cruise {
            velocity_uu_s: v_uu,
            accel_uu_s2: v_uu.abs() / RAMP_S,
            duration_s: RAMP_S + SETTLE_S + case.duration_s,
        },
    ];
    let mut run = OfflineRun::new(
        vec![AxisSlot { node, drive }],
        TICK_US,
        Master::new(mcfg, program),
    );
    // Until the cruise starts.
    let mut cruise_from = None;
    let mut speed = Vec::new();
    let limit_us = 60_000_000;
    while !run.master.finished() && run.now_us() < limit_us {
        run.step();
        if cruise_from.is_none() && run.master.current_step() == 1 {
            cruise_from = Some(run.now_us());
        }
        if let Some(t0) = cruise_from {
            if run.now_us() >= t0 + ((RAMP_S + SETTLE_S) * 1e6) as u64 {
                speed.push(f64::from(
                    node_sample(&run.runtime.axes[0].node, run.now_us()).velocity_uu_s,
                ));
            }
        }
    }
    let error = run.master.error().map(str::to_string);
    let peak = (speed.len() >= 8)
        .then(|| fundamental(&speed, 1e6 / TICK_US as f64, (1.0, 200.0)))
        .flatten();
    let amplitude = peak.map_or(0.0, |p| p.amplitude);
    let scale = case.kv_per_s * case.backlash * uu;
    let limit_cycle = error.is_none()
        && peak.is_some()
        && scale > 0.0
        && amplitude >= LIMIT_CYCLE_MIN_RELATIVE_AMPLITUDE * scale;
    Ok(OuterLoopRow {
        fundamental_hz: peak.map(|p| p.frequency_hz),
        f_over_kv: peak.map(|p| p.frequency_hz / case.kv_per_s),
        speed_amplitude_uu_s: amplitude,
        limit_cycle,
        sync_over_cycle: peak.map(|p| f64::from(case.sync_period_us) * 1e-6 * p.frequency_hz),
        error,
        case: case.clone(),
    })
}

/// Run cases on all cores; results in order.
pub fn run_outer_loops(
    cases: &[(AxisConfig, OuterLoopCase)],
) -> Vec<Result<OuterLoopRow, ConfigError>> {
    use std::sync::atomic::{AtomicBool, AtomicUsize};
    super::run_parallel(
        cases,
        0,
        &AtomicBool::new(false),
        &AtomicUsize::new(0),
        |(cfg, case)| run_outer_loop(cfg, case),
    )
    .into_iter()
    .map(|r| r.expect("nothing sets the stop flag: every case ran"))
    .collect()
}

/// The master's gains of the law's sweep, multiples of each preset's own k_v.
pub const LAW_MULTIPLES: [f64; 7] = [0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0];
/// The SYNC periods of the bus sweep, us (whole ticks).
pub const SYNC_PERIODS_US: [u32; 8] = [1000, 2000, 3000, 4000, 6000, 8000, 12000, 16000];
/// Cruise time of each run, s.
pub const CRUISE_S: f64 = 4.0;
/// The paper's law as the tests hold it: f / k_v within this of 0.6.
pub const LAW_TOLERANCE: f64 = 0.1;

fn case(cfg: &AxisConfig, kv_per_s: f64, sync_period_us: u32) -> OuterLoopCase {
    OuterLoopCase {
        preset: cfg.name.clone(),
        kv_per_s,
        backlash: super::own_backlash(cfg),
        velocity: super::default_velocity(cfg),
        sync_period_us,
        duration_s: CRUISE_S,
    }
}

/// Every preset at its own backlash, the master's k_v from half to twice the preset's, SYNC
/// 1 ms.
pub fn law_cases() -> Result<Vec<(AxisConfig, OuterLoopCase)>, ConfigError> {
    let mut out = Vec::new();
    for name in crate::presets::preset_names() {
        let cfg = AxisConfig::from_preset(name)?;
        for m in LAW_MULTIPLES {
            out.push((cfg.clone(), case(&cfg, m * cfg.kv_per_s, 1000)));
        }
    }
    Ok(out)
}

/// Every preset at its own k_v and backlash over the SYNC periods of [`SYNC_PERIODS_US`].
pub fn sync_cases() -> Result<Vec<(AxisConfig, OuterLoopCase)>, ConfigError> {
    let mut out = Vec::new();
    for name in crate::presets::preset_names() {
        let cfg = AxisConfig::from_preset(name)?;
        for t in SYNC_PERIODS_US {
            out.push((cfg.clone(), case(&cfg, cfg.kv_per_s, t)));
        }
    }
    Ok(out)
}

/// Where the bus cycle breaks the law on one preset.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SyncBreak {
    pub preset: String,
    pub kv_per_s: f64,
    /// The limit cycle at the shortest SYNC period, Hz.
    pub f0_hz: f64,
    /// The longest SYNC period at which f / k_v is still within 0.6 +- [`LAW_TOLERANCE`], us.
    pub holds_up_to_us: Option<u32>,
    /// The first SYNC period at which it is not, us, and that period over the limit cycle's
    /// period at the shortest SYNC (T_sync x f0).
    pub breaks_at_us: Option<u32>,
    pub breaks_at_ratio: Option<f64>,
    /// The drop of f per unit of T_sync x f0, fitted over the periods where the law holds
    /// (f(T) / f0 = 1 - slope x (T - T0) f0).
    pub drop_per_ratio: Option<f64>,
}

/// Per preset, from the rows of [`sync_cases`] (in that order).
pub fn sync_breaks(rows: &[OuterLoopRow]) -> Vec<SyncBreak> {
    let mut out: Vec<SyncBreak> = Vec::new();
    for group in rows.chunk_by(|a, b| a.case.preset == b.case.preset) {
        let Some(first) = group.first() else { continue };
        let f0 = first.fundamental_hz.unwrap_or(f64::NAN);
        let holds = |r: &OuterLoopRow| {
            r.limit_cycle
                && r.f_over_kv
                    .is_some_and(|x| (x - 0.6).abs() <= LAW_TOLERANCE)
        };
        let k = group.iter().position(|r| !holds(r));
        let holds_up_to_us = match k {
            Some(0) => None,
            Some(k) => Some(group[k - 1].case.sync_period_us),
            None => group.last().map(|r| r.case.sync_period_us),
        };
        let breaks_at_us = k.map(|k| group[k].case.sync_period_us);
        // f / f0 against (T - T0) f0 over the holding runs: least squares through (0, 1).
        let t0 = f64::from(first.case.sync_period_us) * 1e-6;
        let (mut sxx, mut sxy) = (0.0, 0.0);
        for r in group.iter().take(k.unwrap_or(group.len())) {
            if let Some(f) = r.fundamental_hz {
                let x = (f64::from(r.case.sync_period_us) * 1e-6 - t0) * f0;
                sxx += x * x;
                sxy += x * (1.0 - f / f0);
            }
        }
        out.push(SyncBreak {
            preset: first.case.preset.clone(),
            kv_per_s: first.case.kv_per_s,
            f0_hz: f0,
            holds_up_to_us,
            breaks_at_us,
            breaks_at_ratio: breaks_at_us.map(|t| f64::from(t) * 1e-6 * f0),
            drop_per_ratio: (sxx > 0.0).then(|| sxy / sxx),
        });
    }
    out
}
