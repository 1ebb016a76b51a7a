//! Offline scenario execution: the reference master and the simulated drive on an in-process
//! bus in lock-step with a virtual clock (the loop of `session::OfflineRun`, with the
//! drive's endpoint wrapped in a [`FaultyBus`] for CAN faults), the timeline applied every
//! tick, the detector run on the master's sample log, expectations checked, report written.
//!
//! Two clocks: *physical* time is what the bus, the protocol and the physics see; *scenario*
//! time is physical time plus the idle time fast-forwarded so far. An `idle` step of the motion
//! program runs as a short dwell (`idle_dwell_s`, default 0.1 s) and advances scenario time by
//! the rest of its duration at once: parameter ramps (wear) follow scenario time, so a
//! one-hour wear ramp needs only its measurement passes simulated. Nothing moves while idle (the
//! axis stands in position control), so skipping it loses nothing the detector looks at; what
//! it does lose is whatever would happen *during* the idle (thermal transients, timeouts):
//! scenarios that need those set `fast_forward_idle = false`.

use super::expect::{check_all, ExpectResult, RunRecord};
use super::file::SensorKind;
use super::timeline::{Action, CanFault, Drivers, Observation, Timeline};
use super::{Scenario, ScenarioError};
use crate::analysis::detector::{analyze, AxisTrace, DetectorConfig, DetectorReport};
use crate::bus::fault::{FaultRule, FaultStats, FaultyBus, RuleId};
use crate::bus::inproc::{InProcBus, InProcEndpoint};
use crate::bus::CanBus;
use crate::drive::axis_drive::{AxisDrive, Encoder};
use crate::master::Master;
use crate::presets::{AxisConfig, AxisKind};
use crate::runtime::{AxisSlot, Runtime};
use crate::samples::Sample;
use drive_protocol::Cia402State;
use drive_protocol::{Drive, Node};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How to run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Physical length of the dwell an idle step becomes when fast-forwarded, s.
    pub idle_dwell_s: f64,
    /// Draw a progress line on stderr (only if stderr is a terminal).
    pub progress: bool,
    /// Apply slow drivers (ramps) every this many ticks; profiles are applied every tick.
    pub ramp_every_ticks: u64,
    /// Memory cap for the master's sample log (and its copies for the report), MB: a
    /// scenario whose physical program would need more is refused before it runs.
    pub max_memory_mb: f64,
}

/// Default of [`RunOptions::max_memory_mb`] (`scenario --max-memory-mb`).
pub const DEFAULT_MAX_MEMORY_MB: f64 = 2048.0;

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            idle_dwell_s: 0.1,
            progress: true,
            ramp_every_ticks: 10,
            max_memory_mb: DEFAULT_MAX_MEMORY_MB,
        }
    }
}

/// One machine's run (one per preset of a sweep).
#[derive(Debug, Clone, serde::Serialize)]
pub struct PresetRun {
    pub preset: String,
    pub rotary: bool,
    pub kv_per_s: f64,
    /// Simulated (physics, bus) time, s.
    pub physical_s: f64,
    /// Scenario time covered, s (physical plus fast-forwarded).
    pub scenario_s: f64,
    pub fast_forwarded_s: f64,
    pub wall_s: f64,
    pub program_finished: bool,
    pub program_error: Option<String>,
    /// Set when the master program failed or did not finish: the run fails.
    pub program_failure: Option<String>,
    pub emcys: Vec<(f64, String)>,
    pub events: Vec<(f64, String)>,
    pub fault_stats: FaultStats,
    pub detector: Option<DetectorReport>,
    pub expectations: Vec<ExpectResult>,
    /// The parameter the first ramp drives, over scenario time: (s, value in file units).
    pub ramp_param: Option<String>,
    #[serde(skip)]
    pub ramp_series: Vec<(f64, f64)>,
    #[serde(skip)]
    pub samples: Vec<Sample>,
    #[serde(skip)]
    pub trace: Option<AxisTrace>,
}

impl PresetRun {
    /// Every expectation met and the master program ran to its end without error.
    pub fn passed(&self) -> bool {
        self.program_failure.is_none() && self.expectations.iter().all(|e| e.passed)
    }
}

/// Why the master program failed, if it did: it reported an error, or it had not finished
/// when the run stopped (and the scenario set no `duration` that cuts it short on purpose).
fn program_failure(
    error: Option<&str>,
    finished: bool,
    has_duration: bool,
    physical_s: f64,
) -> Option<String> {
    match error {
        Some(e) => Some(format!("master program failed: {e}")),
        None if !finished && !has_duration => Some(format!(
            "master program did not finish (stopped after {physical_s:.1} s of physical time)"
        )),
        None => None,
    }
}

/// Refuse a scenario whose sample log would not fit the memory cap.
fn check_size(s: &Scenario, opts: &RunOptions) -> anyhow::Result<()> {
    let (_, skip) = s.master_program(opts.idle_dwell_s);
    let skipped: u64 = skip.iter().sum();
    let mut physical_us = s.program_duration_us().saturating_sub(skipped);
    if let Some(d) = s.run.duration_us {
        physical_us = physical_us.min(d);
    }
    let period_us = u64::from(s.run.master.sync_period_us.max(1));
    let samples = physical_us / period_us;
    // The log, the copy in scenario time and the report's copy.
    let mb = samples as f64 * (3 * std::mem::size_of::<Sample>()) as f64 / 1e6;
    if mb > opts.max_memory_mb {
        anyhow::bail!(
            "{}: the motion program runs {:.0} s of physical time ({samples} samples at one per \
             {period_us} us SYNC, about {mb:.0} MB in memory and a {:.0} MB sample CSV): above \
             the cap of {:.0} MB (--max-memory-mb). Check the cruise and dwell durations, or \
             raise --max-memory-mb.",
            s.name,
            physical_us as f64 * 1e-6,
            samples as f64 * 120.0 / 1e6,
            opts.max_memory_mb
        );
    }
    Ok(())
}

/// A whole scenario's outcome.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Outcome {
    pub scenario: String,
    pub description: String,
    pub file: PathBuf,
    pub fast_forward_idle: bool,
    pub idle_dwell_s: f64,
    pub passed: bool,
    pub wall_s: f64,
    pub runs: Vec<PresetRun>,
}

/// Why the drive refused a value, in the file's units (`scale`: file unit -> SI).
fn param_error_text(e: drive_protocol::ParamError, scale: f64) -> String {
    match e {
        drive_protocol::ParamError::OutOfRange { min, max } => format!(
            "outside what the drive accepts ({} .. {})",
            min / scale,
            max / scale
        ),
        drive_protocol::ParamError::Unsupported => "this drive has no such parameter".into(),
    }
}

/// Apply an encoder fault event to a drive.
pub(crate) fn sensor(drive: &mut AxisDrive, kind: SensorKind, counts: i64) {
    match kind {
        SensorKind::MotorEncoderLoss => drive.set_signal_lost(Encoder::Motor, true),
        SensorKind::DirectEncoderLoss => drive.set_signal_lost(Encoder::Direct, true),
        SensorKind::MotorEncoderGlitch => drive.inject_glitch(Encoder::Motor, counts),
        SensorKind::DirectEncoderGlitch => drive.inject_glitch(Encoder::Direct, counts),
        SensorKind::Restore => {
            drive.set_signal_lost(Encoder::Motor, false);
            drive.set_signal_lost(Encoder::Direct, false);
        }
    }
}

/// The bus rule that injects a CAN fault.
pub(crate) fn rule(fault: CanFault, master_id: u8) -> FaultRule {
    match fault {
        CanFault::Drop { share, cob_id } => {
            let r = FaultRule::drop_share(share);
            cob_id.map_or(r, |c| r.only(c))
        }
        CanFault::Delay {
            share,
            ticks,
            cob_id,
        } => {
            let r = FaultRule::delay_share(share, ticks);
            cob_id.map_or(r, |c| r.only(c))
        }
        CanFault::SyncLoss => FaultRule::sync_loss(),
        CanFault::HeartbeatLoss => FaultRule::heartbeat_loss(master_id),
    }
}

/// The detector settings of a scenario for one machine.
pub(crate) fn detector_config(s: &Scenario, cfg: &AxisConfig) -> DetectorConfig {
    let d = &s.detector;
    let mut dc = DetectorConfig::new(d.kv_per_s.unwrap_or(cfg.kv_per_s));
    if let Some(v) = d.suspect_um {
        dc.suspect_um = v;
    }
    if let Some(v) = d.alarm_um {
        dc.alarm_um = v;
    }
    if let Some(v) = d.min_window_s {
        dc.windows.min_len_s = v;
    }
    if let Some(v) = d.settle_s {
        dc.windows.settle_s = v;
    }
    if let Some(v) = d.confirm_windows {
        dc.confirm_windows = v;
    }
    dc
}

/// Run one preset of a scenario.
pub fn run_preset(s: &Scenario, cfg: &AxisConfig, opts: &RunOptions) -> anyhow::Result<PresetRun> {
    let wall = Instant::now();
    let rotary = cfg.kind == AxisKind::Rotary;
    let mcfg = s.run.master.clone();
    let tick = s.run.tick_us;
    let drive = AxisDrive::from_config(cfg).map_err(|e| anyhow::anyhow!("{}: {e}", cfg.name))?;
    let node = Node::new(mcfg.node_id, drive.info()).map_err(|e| anyhow::anyhow!("node: {e}"))?;
    let mut eps = InProcBus::endpoints(2, 4096);
    let mut master_ep: InProcEndpoint = eps.pop().expect("two endpoints");
    let bus = FaultyBus::new(eps.pop().expect("two endpoints"), s.run.seed);
    let mut rt = Runtime::new(bus, vec![AxisSlot { node, drive }], tick);
    rt.boot();
    let (steps, skip) = s.master_program(opts.idle_dwell_s);
    let mut master = Master::new(mcfg.clone(), steps);
    let mut timeline = Timeline::new(s.events.clone());
    let mut drivers = Drivers::default();
    let mut values = Vec::new();
    let mut can_rules: Vec<(RuleId, Option<u64>)> = Vec::new();
    let mut offset_us = 0u64;
    // (physical us, offset us) from which an offset applies: maps sample times.
    let mut breaks: Vec<(u64, u64)> = vec![(0, 0)];
    let mut last_step = usize::MAX;
    let mut seen_emcy = 0usize;
    let mut emcys: Vec<(u64, u16)> = Vec::new();
    let mut fired: Vec<(u64, String)> = Vec::new();
    let mut new_codes: Vec<u16> = Vec::new();
    let ramp_key = s.events.iter().find_map(|e| match &e.action {
        Action::Ramp { key, .. } => Some(*key),
        _ => None,
    });
    let mut ramp_series = Vec::new();
    let limit_scenario_us = s.run.duration_us;
    let physical_limit_us = s.program_duration_us().min(24 * 3600 * 1_000_000) + 120_000_000;
    check_size(s, opts)?;
    let progress = opts.progress && std::io::stderr().is_terminal();
    let total_us = limit_scenario_us
        .unwrap_or_else(|| s.program_duration_us())
        .max(1);
    let mut last_draw = Instant::now();
    let mut finished_at: Option<u64> = None;
    let mut ticks = 0u64;
    loop {
        let phys = rt.sim_time_us;
        // Fast-forward: entering an idle dwell adds the rest of the idle to scenario time.
        let cur = master.current_step();
        if cur != last_step {
            if !master.finished() && cur < skip.len() && skip[cur] > 0 {
                offset_us += skip[cur];
                breaks.push((phys, offset_us));
            }
            last_step = cur;
        }
        let now = phys + offset_us;
        // Timeline.
        let state = Cia402State::from_statusword(master.latest().statusword);
        let obs = Observation {
            state,
            new_emcy: &new_codes,
        };
        let due: Vec<_> = timeline.due(now, &obs).cloned().collect();
        for ev in due {
            fired.push((now, ev.describe()));
            let drive = &mut rt.axes[0].drive;
            match &ev.action {
                Action::Set { key, value } => {
                    drivers.stop(key);
                    drive.set_param(key.param, value * key.scale).map_err(|e| {
                        anyhow::anyhow!(
                            "line {}: {} = {value}: {}",
                            ev.line,
                            key.key,
                            param_error_text(e, key.scale)
                        )
                    })?;
                }
                Action::Ramp { key, .. } | Action::Profile { key, .. } => {
                    let cur = drive.param(key.param).map_err(|e| {
                        anyhow::anyhow!(
                            "line {}: {}: {}",
                            ev.line,
                            key.key,
                            param_error_text(e, key.scale)
                        )
                    })? / key.scale;
                    drivers.start(&ev.action, now, cur);
                }
                Action::Sensor { kind, counts } => sensor(drive, *kind, *counts),
                Action::Can { fault, over_us } => {
                    let id = rt.bus.add_rule(rule(*fault, mcfg.master_id));
                    can_rules.push((id, over_us.map(|o| now + o)));
                }
                Action::CanRestore => {
                    rt.bus.clear_rules();
                    can_rules.clear();
                }
            }
        }
        can_rules.retain(|(id, end)| {
            if end.is_some_and(|e| now >= e) {
                rt.bus.remove_rule(*id);
                false
            } else {
                true
            }
        });
        if !drivers.is_empty()
            && (drivers.has_profile() || ticks.is_multiple_of(opts.ramp_every_ticks.max(1)))
        {
            drivers.values(now, &mut values);
            for (key, v) in &values {
                rt.axes[0]
                    .drive
                    .set_param(key.param, v * key.scale)
                    .map_err(|e| {
                        anyhow::anyhow!("{} = {v}: {}", key.key, param_error_text(e, key.scale))
                    })?;
                if Some(*key) == ramp_key && ticks.is_multiple_of(100) {
                    ramp_series.push((now as f64 * 1e-6, *v));
                }
            }
        }
        // One lock-step tick (as OfflineRun::step); the runtime advances the fault injector's clock.
        master.poll(phys);
        while let Some(f) = master.pop_tx() {
            let _ = master_ep.send(&f);
        }
        rt.tick();
        while let Ok(Some(f)) = master_ep.recv() {
            master.handle(&f, rt.sim_time_us);
        }
        ticks += 1;
        new_codes.clear();
        for e in &master.emcys()[seen_emcy..] {
            emcys.push((e.t_us + offset_us, e.code));
            new_codes.push(e.code);
        }
        seen_emcy = master.emcys().len();
        // Stop?
        let now = rt.sim_time_us + offset_us;
        if master.finished() && finished_at.is_none() {
            finished_at = Some(now);
        }
        let done = match limit_scenario_us {
            Some(l) => now >= l,
            // A short tail after the program for late EMCYs and state changes.
            None => finished_at.is_some_and(|f| now >= f + 200_000),
        };
        if done || rt.sim_time_us >= physical_limit_us {
            break;
        }
        if progress && last_draw.elapsed().as_millis() >= 200 {
            last_draw = Instant::now();
            eprint!(
                "\r{} [{}] scenario {:>8.1} s / {:.1} s ({:>3.0} %), physical {:.1} s   ",
                s.name,
                cfg.name,
                now as f64 * 1e-6,
                total_us as f64 * 1e-6,
                100.0 * (now as f64 / total_us as f64).min(1.0),
                rt.sim_time_us as f64 * 1e-6
            );
        }
    }
    if progress {
        eprintln!();
    }
    // Samples in scenario time.
    let mut samples: Vec<Sample> = master.samples().to_vec();
    let mut b = 0;
    for smp in &mut samples {
        let t_us = (smp.t_s * 1e6).round() as u64;
        while b + 1 < breaks.len() && breaks[b + 1].0 <= t_us {
            b += 1;
        }
        smp.t_s = (t_us + breaks[b].1) as f64 * 1e-6;
    }
    let end_us = rt.sim_time_us + offset_us;
    let (detector, trace) = if s.detector.enabled {
        let tr = AxisTrace::from_samples(&samples, rotary);
        (Some(analyze(&tr, &detector_config(s, cfg))), Some(tr))
    } else {
        (None, None)
    };
    let mut events = std::collections::HashMap::new();
    for (i, e) in timeline.events().iter().enumerate() {
        if let (Some(id), Some(t)) = (&e.id, timeline.fired_at(i)) {
            events.insert(id.clone(), t);
        }
    }
    let rec = RunRecord {
        samples: samples.clone(),
        emcys: emcys.clone(),
        events,
        detector: detector.clone(),
        program_finished: master.finished(),
        program_error: master.error().map(str::to_string),
        end_us,
    };
    let expectations = check_all(&s.expectations, &rec);
    let physical_s = rt.sim_time_us as f64 * 1e-6;
    let program_failure = program_failure(
        rec.program_error.as_deref(),
        rec.program_finished,
        limit_scenario_us.is_some(),
        physical_s,
    );
    Ok(PresetRun {
        program_failure,
        preset: cfg.name.clone(),
        rotary,
        kv_per_s: cfg.kv_per_s,
        physical_s: rt.sim_time_us as f64 * 1e-6,
        scenario_s: end_us as f64 * 1e-6,
        fast_forwarded_s: offset_us as f64 * 1e-6,
        wall_s: wall.elapsed().as_secs_f64(),
        program_finished: rec.program_finished,
        program_error: rec.program_error,
        emcys: emcys
            .iter()
            .map(|(t, c)| (*t as f64 * 1e-6, format!("{c:#06X}")))
            .collect(),
        events: fired
            .into_iter()
            .map(|(t, d)| (t as f64 * 1e-6, d))
            .collect(),
        fault_stats: rt.bus.stats(),
        detector,
        expectations,
        ramp_param: ramp_key.map(|k| k.key.to_string()),
        ramp_series,
        samples,
        trace,
    })
}

/// Run every preset of a scenario.
pub fn run(s: &Scenario, opts: &RunOptions) -> anyhow::Result<Outcome> {
    let wall = Instant::now();
    let mut runs = Vec::new();
    for cfg in &s.machine.configs {
        runs.push(run_preset(s, cfg, opts)?);
    }
    Ok(Outcome {
        scenario: s.name.clone(),
        description: s.description.clone(),
        file: s.path.clone(),
        fast_forward_idle: s.run.fast_forward_idle,
        idle_dwell_s: opts.idle_dwell_s,
        passed: runs.iter().all(PresetRun::passed),
        wall_s: wall.elapsed().as_secs_f64(),
        runs,
    })
}

/// Write the report: `summary.json`, per preset `<preset>-samples.csv` and the detector plots,
/// and for sweeps `frequency_vs_kv.png`. Returns the files written.
pub fn write_report(out: &Outcome, dir: &Path, plots: bool) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    let mut files = Vec::new();
    let p = dir.join("summary.json");
    crate::report::write_json(&p, out)?;
    files.push(p);
    let mut points = Vec::new();
    for r in &out.runs {
        let p = dir.join(format!("{}-samples.csv", r.preset));
        write_samples(&p, &r.samples)?;
        files.push(p);
        if let (Some(d), Some(tr), true) = (&r.detector, &r.trace, plots) {
            let series = r
                .ramp_param
                .as_deref()
                .map(|n| (n, r.ramp_series.as_slice()));
            files.extend(crate::report::detector_plots(
                dir,
                &format!("{}-", r.preset),
                tr,
                d,
                series,
            )?);
            if let Some(f) = d.frequency_hz.or(d.dominant_hz) {
                points.push(crate::report::KvPoint {
                    name: r.preset.clone(),
                    kv_per_s: d.kv_per_s,
                    frequency_hz: f,
                });
            }
        }
    }
    // Frequency against k_v says something only across several gains (a sweep).
    let mut gains: Vec<f64> = points.iter().map(|p| p.kv_per_s).collect();
    gains.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    if plots && gains.len() >= 2 {
        let p = dir.join("frequency_vs_kv.png");
        crate::report::plot_frequency_vs_kv(&p, &points)?;
        files.push(p);
    }
    Ok(files)
}

/// The master's sample log as CSV (the layout `drive-emu analyze` reads).
pub fn write_samples(path: &Path, samples: &[Sample]) -> anyhow::Result<()> {
    use std::io::Write;
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(w, "{}", Sample::CSV_HEADER)?;
    for s in samples {
        s.write_csv_row(&mut w)?;
    }
    w.flush()?;
    Ok(())
}

/// Load, run and report: what `drive-emu scenario FILE` does. Returns the outcome; the
/// caller decides the exit status from `Outcome::passed`.
pub fn run_file(
    file: &Path,
    out_dir: Option<&Path>,
    opts: &RunOptions,
    plots: bool,
) -> Result<(Outcome, PathBuf), RunError> {
    let s = super::load(file).map_err(RunError::File)?;
    let out = run(&s, opts).map_err(RunError::Run)?;
    let dir = out_dir
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("out").join(&s.name));
    write_report(&out, &dir, plots).map_err(RunError::Run)?;
    Ok((out, dir))
}

/// Why a scenario could not be run.
#[derive(Debug)]
pub enum RunError {
    File(ScenarioError),
    Run(anyhow::Error),
}

impl std::fmt::Display for RunError {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            RunError::File(e) => write!(f, "{e}"),
            RunError::Run(e) => write!(f, "{e:#}"),
        }
    }
}

impl std::error::Error for RunError {}
