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
use super::inject::{Injection, Injector};
use super::timeline::{Action, Drivers, Observation, Timeline};
use super::units::ParamKey;
use super::{Scenario, ScenarioError};
use crate::analysis::detector::{analyze, AxisTrace, DetectorConfig, DetectorReport};
use crate::bus::fault::{FaultStats, FaultyBus};
use crate::bus::inproc::InProcEndpoint;
use crate::drive::axis_drive::AxisDrive;
use crate::master::Master;
use crate::presets::{AxisConfig, AxisKind};
use crate::runtime::AxisSlot;
use crate::samples::{Sample, SampleSource};
use crate::session::OfflineRun;
use drive_protocol::Cia402State;
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
    /// Events that had not fired when the run ended (file line, description): the run fails
    /// (an event after the program's end, a condition never met).
    pub not_fired: Vec<(usize, String)>,
    /// Why the scenario did not finish (`not_fired`), for people.
    pub unfinished: Option<String>,
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
        self.program_failure.is_none()
            && self.unfinished.is_none()
            && self.expectations.iter().all(|e| e.passed)
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
fn param_error_text(e: crate::drive::ParamError, scale: f64) -> String {
    match e {
        crate::drive::ParamError::OutOfRange { min, max } => format!(
            "outside what the drive accepts ({} .. {})",
            min / scale,
            max / scale
        ),
    }
}

/// The detector settings of a scenario for one machine.
pub(crate) fn detector_config(s: &Scenario, cfg: &AxisConfig) -> DetectorConfig {
    let d = &s.detector;
    // The loop's gain: the master's own position loop where it closes one, else the drive's.
    let kv = s
        .run
        .master
        .position_loop
        .map_or(cfg.kv_per_s, |p| p.kv_per_s);
    let mut dc = DetectorConfig::new(d.kv_per_s.unwrap_or(kv));
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

/// CAN fault rules an offline run keeps in force at once (the live loop keeps 16).
const OFFLINE_MAX_CAN_RULES: usize = 64;

/// The drive-side bus of an offline scenario run: the in-process endpoint behind a fault
/// injector.
type ScenarioBus = FaultyBus<InProcEndpoint>;

/// Scenario time over physical time: an idle step entered adds the rest of its duration to the
/// offset at once (see the module doc).
struct FastForward {
    skip_us: Vec<u64>,
    offset_us: u64,
    /// (physical us, offset us) from which an offset applies: maps sample times.
    breaks: Vec<(u64, u64)>,
    last_step: usize,
}

impl FastForward {
    fn new(skip_us: Vec<u64>) -> Self {
        Self {
            skip_us,
            offset_us: 0,
            breaks: vec![(0, 0)],
            last_step: usize::MAX,
        }
    }

    /// Before a tick at physical time `phys_us`: entering an idle dwell adds the rest of the
    /// idle to scenario time.
    fn on_step(&mut self, master: &Master, phys_us: u64) {
        let cur = master.current_step();
        if cur != self.last_step {
            if !master.finished() && cur < self.skip_us.len() && self.skip_us[cur] > 0 {
                self.offset_us += self.skip_us[cur];
                self.breaks.push((phys_us, self.offset_us));
            }
            self.last_step = cur;
        }
    }

    /// The master's samples with their times moved from physical to scenario time.
    fn to_scenario_time(&self, physical: &[Sample]) -> Vec<Sample> {
        let mut samples = physical.to_vec();
        let mut b = 0;
        for smp in &mut samples {
            let t_us = (smp.t_s * 1e6).round() as u64;
            while b + 1 < self.breaks.len() && self.breaks[b + 1].0 <= t_us {
                b += 1;
            }
            smp.t_s = Sample::t_s_of_us(t_us + self.breaks[b].1);
        }
        samples
    }
}

/// The timeline side of an offline run: events, their drivers (ramps, profiles), the CAN rules
/// in force, and what fired.
struct TimelineState {
    timeline: Timeline,
    drivers: Drivers,
    values: Vec<(&'static ParamKey, f64)>,
    injector: Injector<OFFLINE_MAX_CAN_RULES>,
    fired: Vec<(u64, String)>,
    /// The parameter the first ramp drives, and its value over scenario time.
    ramp_key: Option<&'static ParamKey>,
    ramp_series: Vec<(f64, f64)>,
}

impl TimelineState {
    fn new(s: &Scenario) -> Self {
        Self {
            timeline: Timeline::new(s.events.clone()),
            drivers: Drivers::default(),
            values: Vec::new(),
            injector: Injector::new(s.run.master.master_id),
            fired: Vec::new(),
            ramp_key: s.events.iter().find_map(|e| match &e.action {
                Action::Ramp { key, .. } => Some(*key),
                _ => None,
            }),
            ramp_series: Vec::new(),
        }
    }

    /// Fire the events due at scenario time `now` (the drive's state and the EMCYs new since
    /// the last tick decide the triggered ones), then end the CAN rules whose time is over.
    fn fire_due(
        &mut self,
        now: u64,
        obs: &Observation,
        drive: &mut AxisDrive,
        bus: &mut ScenarioBus,
    ) -> anyhow::Result<()> {
        let due: Vec<_> = self.timeline.due(now, obs).cloned().collect();
        for ev in due {
            self.fired.push((now, ev.describe()));
            match &ev.action {
                Action::Set { key, value } => {
                    self.drivers.stop(key);
                    let inj = Injection::of_action(&ev.action, now).expect("a set injects");
                    self.injector.apply(inj, drive, bus).map_err(|e| {
                        anyhow::anyhow!(
                            "line {}: {} = {value}: {}",
                            ev.line,
                            key.key,
                            param_error_text(e, key.scale)
                        )
                    })?;
                }
                Action::Ramp { key, .. } | Action::Profile { key, .. } => {
                    let cur = drive.param(key.param) / key.scale;
                    self.drivers.start(&ev.action, now, cur);
                }
                Action::Sensor { .. }
                | Action::Can { .. }
                | Action::CanRestore
                | Action::Ethercat { .. }
                | Action::EthercatRestore => {
                    let inj = Injection::of_action(&ev.action, now).expect("injects");
                    // Only a `Param` injection can be refused.
                    let _ = self.injector.apply(inj, drive, bus);
                }
            }
        }
        self.injector.expire(now, bus);
        Ok(())
    }

    /// Apply the ramps and profiles running at `now` (profiles every tick, ramps every
    /// `ramp_every_ticks`), sampling the first ramp's value every 100 ticks.
    fn drive_params(
        &mut self,
        now: u64,
        ticks: u64,
        ramp_every_ticks: u64,
        drive: &mut AxisDrive,
        bus: &mut ScenarioBus,
    ) -> anyhow::Result<()> {
        if self.drivers.is_empty()
            || !(self.drivers.has_profile() || ticks.is_multiple_of(ramp_every_ticks.max(1)))
        {
            return Ok(());
        }
        self.drivers.values(now, &mut self.values);
        for &(key, v) in &self.values {
            let inj = Injection::Param {
                param: key.param,
                value_si: v * key.scale,
            };
            self.injector.apply(inj, drive, bus).map_err(|e| {
                anyhow::anyhow!("{} = {v}: {}", key.key, param_error_text(e, key.scale))
            })?;
            if Some(key) == self.ramp_key && ticks.is_multiple_of(100) {
                self.ramp_series.push((now as f64 * 1e-6, v));
            }
        }
        Ok(())
    }

    /// (event id, scenario time us it fired) of every event with an id that fired.
    fn fired_ids(&self) -> std::collections::HashMap<String, u64> {
        let mut events = std::collections::HashMap::new();
        for (i, e) in self.timeline.events().iter().enumerate() {
            if let (Some(id), Some(t)) = (&e.id, self.timeline.fired_at(i)) {
                events.insert(id.clone(), t);
            }
        }
        events
    }
}

/// The progress line on stderr, at most every 200 ms of wall time.
struct Progress {
    on: bool,
    last_draw: Instant,
    total_us: u64,
}

impl Progress {
    fn draw(&mut self, s: &Scenario, cfg: &AxisConfig, now: u64, physical_us: u64) {
        if !self.on || self.last_draw.elapsed().as_millis() < 200 {
            return;
        }
        self.last_draw = Instant::now();
        eprint!(
            "\r{} [{}] scenario {:>8.1} s / {:.1} s ({:>3.0} %), physical {:.1} s   ",
            s.name,
            cfg.name,
            now as f64 * 1e-6,
            self.total_us as f64 * 1e-6,
            100.0 * (now as f64 / self.total_us as f64).min(1.0),
            physical_us as f64 * 1e-6
        );
    }
}

/// The reference master and the preset's drive on a fault-injecting in-process bus, booted;
/// and the idle time each program step fast-forwards.
fn start_run(
    s: &Scenario,
    cfg: &AxisConfig,
    opts: &RunOptions,
) -> anyhow::Result<(OfflineRun<AxisDrive, ScenarioBus>, Vec<u64>)> {
    let mcfg = s.run.master.clone();
    // A value the drive would refuse when its event fires is refused before the first tick.
    super::inject::check_ranges(s, cfg)?;
    let mut drive =
        AxisDrive::from_config(cfg).map_err(|e| anyhow::anyhow!("{}: {e}", cfg.name))?;
    let node = crate::drive::node(&mut drive, mcfg.node_id)?;
    let (steps, skip) = s.master_program(opts.idle_dwell_s);
    let master = Master::new(mcfg, steps);
    let seed = s.run.seed;
    let run = OfflineRun::with_drive_bus(
        vec![AxisSlot { node, drive }],
        s.run.tick_us,
        master,
        |ep| FaultyBus::new(ep, seed),
    );
    Ok((run, skip))
}

/// Run one preset of a scenario: lock-step ticks with the timeline applied before each, until
/// the scenario's duration (or the program's end and a short tail) or the physical limit.
pub fn run_preset(s: &Scenario, cfg: &AxisConfig, opts: &RunOptions) -> anyhow::Result<PresetRun> {
    let wall = Instant::now();
    let (mut run, skip) = start_run(s, cfg, opts)?;
    let mut ff = FastForward::new(skip);
    let mut tl = TimelineState::new(s);
    let mut seen_emcy = 0usize;
    let mut emcys: Vec<(u64, u16)> = Vec::new();
    let mut new_codes: Vec<u16> = Vec::new();
    let limit_scenario_us = s.run.duration_us;
    let physical_limit_us = s.program_duration_us().min(24 * 3600 * 1_000_000) + 120_000_000;
    check_size(s, opts)?;
    let mut progress = Progress {
        on: opts.progress && std::io::stderr().is_terminal(),
        last_draw: Instant::now(),
        total_us: limit_scenario_us
            .unwrap_or_else(|| s.program_duration_us())
            .max(1),
    };
    let mut finished_at: Option<u64> = None;
    let mut ticks = 0u64;
    loop {
        let phys = run.now_us();
        ff.on_step(&run.master, phys);
        let now = phys + ff.offset_us;
        let obs = Observation {
            state: Cia402State::from_statusword(run.master.latest().statusword),
            new_emcy: &new_codes,
        };
        let rt = &mut run.runtime;
        tl.fire_due(now, &obs, &mut rt.axes[0].drive, &mut rt.bus)?;
        tl.drive_params(
            now,
            ticks,
            opts.ramp_every_ticks,
            &mut rt.axes[0].drive,
            &mut rt.bus,
        )?;
        // One lock-step tick; the runtime advances the fault injector's clock.
        run.step();
        ticks += 1;
        new_codes.clear();
        for e in &run.master.emcys()[seen_emcy..] {
            emcys.push((e.t_us + ff.offset_us, e.code));
            new_codes.push(e.code);
        }
        seen_emcy = run.master.emcys().len();
        // Stop?
        let now = run.now_us() + ff.offset_us;
        if run.master.finished() && finished_at.is_none() {
            finished_at = Some(now);
        }
        let done = match limit_scenario_us {
            Some(l) => now >= l,
            // A short tail after the program for late EMCYs and state changes.
            None => finished_at.is_some_and(|f| now >= f + 200_000),
        };
        if done || run.now_us() >= physical_limit_us {
            break;
        }
        progress.draw(s, cfg, now, run.now_us());
    }
    if progress.on {
        eprintln!();
    }
    Ok(conclude(s, cfg, &run, &ff, tl, emcys, wall))
}

/// After the run: the samples in scenario time, the detector, the expectations, the record.
fn conclude(
    s: &Scenario,
    cfg: &AxisConfig,
    run: &OfflineRun<AxisDrive, ScenarioBus>,
    ff: &FastForward,
    tl: TimelineState,
    emcys: Vec<(u64, u16)>,
    wall: Instant,
) -> PresetRun {
    let rotary = cfg.kind == AxisKind::Rotary;
    let master = &run.master;
    let samples = ff.to_scenario_time(master.samples());
    let end_us = run.now_us() + ff.offset_us;
    let (detector, trace) = if s.detector.enabled {
        let tr = AxisTrace::from_sample_log(&samples, SampleSource::Master, rotary);
        (Some(analyze(&tr, &detector_config(s, cfg))), Some(tr))
    } else {
        (None, None)
    };
    let rec = RunRecord {
        samples: samples.clone(),
        emcys: emcys.clone(),
        events: tl.fired_ids(),
        detector: detector.clone(),
        program_finished: master.finished(),
        program_error: master.error().map(str::to_string),
        end_us,
    };
    let expectations = check_all(&s.expectations, &rec);
    let not_fired: Vec<(usize, String)> = tl
        .timeline
        .not_fired()
        .map(|i| {
            let e = &tl.timeline.events()[i];
            (e.line, e.describe())
        })
        .collect();
    let unfinished = super::timeline::not_fired_text(&not_fired, end_us);
    let physical_s = run.now_us() as f64 * 1e-6;
    let program_failure = program_failure(
        rec.program_error.as_deref(),
        rec.program_finished,
        s.run.duration_us.is_some(),
        physical_s,
    );
    PresetRun {
        program_failure,
        not_fired,
        unfinished,
        preset: cfg.name.clone(),
        rotary,
        kv_per_s: cfg.kv_per_s,
        physical_s,
        scenario_s: end_us as f64 * 1e-6,
        fast_forwarded_s: ff.offset_us as f64 * 1e-6,
        wall_s: wall.elapsed().as_secs_f64(),
        program_finished: rec.program_finished,
        program_error: rec.program_error,
        emcys: emcys
            .iter()
            .map(|(t, c)| (*t as f64 * 1e-6, format!("{c:#06X}")))
            .collect(),
        events: tl
            .fired
            .into_iter()
            .map(|(t, d)| (t as f64 * 1e-6, d))
            .collect(),
        fault_stats: run.runtime.bus.stats(),
        detector,
        expectations,
        ramp_param: tl.ramp_key.map(|k| k.key.to_string()),
        ramp_series: tl.ramp_series,
        samples,
        trace,
    }
}

/// Run every preset of a scenario.
pub fn run(s: &Scenario, opts: &RunOptions) -> anyhow::Result<Outcome> {
    // the simulated bus here is CAN
    super::check_bus(s, "can")?;
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
    // Every event's value within what each machine's drive accepts, before any run.
    for cfg in &s.machine.configs {
        super::inject::check_ranges(&s, cfg).map_err(RunError::File)?;
    }
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
