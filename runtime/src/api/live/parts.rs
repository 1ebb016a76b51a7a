//! The pieces of a live run: the bus, the stop flag, the observation bus's readers (trace,
//! detector), the scenario thread, the loop thread with its hook (publish, apply the
//! injections), the summary. [`super::LiveRequest::start_with`] puts them together on CAN;
//! `run --ethercat` (the command line) uses the same readers, stop flag and scenario thread.

use super::{LiveBus, LiveBusSpec, LiveCan, LiveOutcome, LiveRequest, TickHook};
use crate::api::ApiError;
use crate::bus::fault::FaultyBus;
use crate::bus::live::LiveTransport;
use crate::bus::socketcand::SocketcandBus;
use crate::drive::axis_drive::AxisDrive;
use crate::drive::machine::MachineFile;
use crate::monitor::{AxisFacts, DetectOptions, DetectResults, Detector};
use crate::observe::trace::{Recorder, TraceSummary};
use crate::observe::{Observation, Observer};
use crate::presets::AxisConfig;
use crate::runtime::realtime::{self, RealtimeRequest};
use crate::runtime::trace::trace_paths;
use crate::runtime::{Lockstep, Runtime};
use crate::scenario::live::{
    run_timeline, LiveEnd, LiveLink, LiveOutcome as ScenarioOutcome, LoopInjector,
};
use crate::scenario::Scenario;
use crate::time::MonotonicClock;
use anyhow::{Context, Result};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The bus the request asks for: the SocketCAN interface, the socketcand server (said on
/// stderr with the address it got), or the in-process endpoint.
fn open_transport(bus: LiveBusSpec) -> Result<LiveCan> {
    let iface = match bus {
        LiveBusSpec::InProcess(end) => return Ok(LiveCan::InProcess(end)),
        LiveBusSpec::Socketcand(addr) => {
            let bus = SocketcandBus::bind(&addr)?;
            let a = bus.local_addr();
            eprintln!(
                "drive-emu: socketcand on {a}, bus {}: python-can Bus(interface=\"socketcand\", \
                 host=\"{}\", port={}, channel=\"{}\")",
                crate::bus::socketcand::CHANNEL,
                a.ip(),
                a.port(),
                crate::bus::socketcand::CHANNEL
            );
            return Ok(LiveTransport::Socketcand(bus));
        }
        LiveBusSpec::SocketCan(iface) => iface,
    };
    #[cfg(feature = "socketcan")]
    {
        Ok(LiveTransport::SocketCan(
            crate::bus::socketcan::SocketCanBus::open(&iface)?,
        ))
    }
    #[cfg(not(feature = "socketcan"))]
    anyhow::bail!(
        "cannot open CAN interface {iface}: this drive-emu was built without SocketCAN (cargo \
         feature `socketcan`); serve the bus with --socketcand ADDR:PORT instead \
         (docs/socketcand.md)"
    )
}

/// The live bus (the interface or socketcand server behind the scenario's fault injector),
/// the socketcand server's address, and the bus's name for people.
pub(super) fn open_bus(
    bus: LiveBusSpec,
    scenario: Option<&Scenario>,
) -> Result<(LiveBus, Option<std::net::SocketAddr>, String), ApiError> {
    let name = bus.label();
    let transport = open_transport(bus).map_err(ApiError::Failed)?;
    let socketcand = transport.socketcand().map(SocketcandBus::local_addr);
    let label = match socketcand {
        Some(a) => format!("socketcand {a}"),
        None => name,
    };
    let seed = scenario.map_or(1, |s| s.run.seed);
    Ok((FaultyBus::new(transport, seed), socketcand, label))
}

/// The loop thread's scheduling: SCHED_FIFO priority, CPU, locked memory.
pub fn realtime_request(req: &LiveRequest) -> RealtimeRequest {
    RealtimeRequest {
        fifo_priority: (req.rt_priority > 0).then_some(req.rt_priority),
        cpu: req.cpu,
        lock_memory: req.lock_memory,
    }
}

/// `--lockstep`: simulated time per SYNC; with a scenario, a SYNC missing for a second hands
/// the clock to the wall (a live scenario must end).
pub(super) fn lockstep_of(req: &LiveRequest) -> Option<Lockstep> {
    req.lockstep.then_some(Lockstep {
        sync_period_us: req.sync_period_us,
        free_run_after_us: req.scenario.as_ref().map(|_| {
            req.sync_period_us
                .map_or(1_000_000, |p| (10 * p).max(1_000_000))
        }),
    })
}

/// The scenario thread's outcome, once it ended.
pub fn join_scenario(
    t: Option<std::thread::JoinHandle<ScenarioOutcome>>,
) -> Result<Option<ScenarioOutcome>> {
    t.map(|t| {
        t.join()
            .map_err(|_| anyhow::anyhow!("the scenario thread panicked"))
    })
    .transpose()
}

/// What the loop did, said on stderr, and the run's result.
pub(super) fn live_summary(
    rt: &Runtime<LiveBus, AxisDrive>,
    lockstep: bool,
    readers: ReadersEnd,
    scenario: Option<ScenarioOutcome>,
) -> LiveOutcome {
    let summary = rt.stats.summary();
    eprintln!("drive-emu: stopped. {}", summary.text(lockstep));
    if let Some(server) = rt.bus.inner().socketcand() {
        eprintln!("drive-emu: socketcand: {}", server.stats().summary());
    }
    let lockstep_period_us =
        (lockstep && rt.lockstep_period_us > 0).then_some(rt.lockstep_period_us);
    if let Some(p) = lockstep_period_us {
        eprintln!("drive-emu: lock-step: {p} us of simulated time per SYNC");
    }
    if rt.lockstep_free_ticks > 0 {
        eprintln!(
            "drive-emu: SYNC stopped: the drive's own clock ran {} ticks without it",
            rt.lockstep_free_ticks
        );
    }
    LiveOutcome {
        stats: summary,
        trace: readers.trace,
        detector: readers.detector,
        detector_lost: readers.detector_lost,
        lockstep_period_us,
        free_run_ticks: rt.lockstep_free_ticks,
        scenario,
    }
}

/// The readers of the observation bus a live run starts before its loop (`--trace`,
/// `--detect`), the same on CAN and on EtherCAT, and the detector's way back to the loop.
pub struct Readers {
    recorder: Option<Recorder>,
    pub detect: Option<Arc<DetectResults>>,
    detector: Option<Detector>,
    node_ids: Vec<u8>,
}

/// Start the readers the options ask for, one axis per (node ID, drive) of `axes`: the trace
/// files are created here, before the loop starts (a bad path loses nothing).
pub fn start_readers<'a>(
    req: &LiveRequest,
    obs: &Arc<Observation>,
    axes: impl Iterator<Item = (u8, &'a AxisDrive)>,
    gap: Vec<Option<crate::analysis::gap::GapModel>>,
) -> Result<Readers> {
    let (node_ids, drives): (Vec<u8>, Vec<&AxisDrive>) = axes.unzip();
    let recorder = start_trace(req, obs, &node_ids)?;
    let detect = req
        .detect
        .then(|| Arc::new(DetectResults::new(node_ids.len())));
    let detector = match &detect {
        Some(results) => Some(start_detector(
            req,
            (obs, results),
            drives.into_iter(),
            gap,
        )?),
        None => None,
    };
    Ok(Readers {
        recorder,
        detect,
        detector,
        node_ids,
    })
}

/// What the readers found once they ended.
pub struct ReadersEnd {
    /// `--trace`: the files, samples written, ticks lost.
    pub trace: Option<TraceSummary>,
    /// `--detect`: per axis, its node ID and the last analysis.
    pub detector: Vec<(u8, Option<crate::analysis::detector::DetectorReport>)>,
    /// `--detect`: ticks the detector lost.
    pub detector_lost: u64,
}

impl Readers {
    /// After the loop has stopped: the trace flushed and closed, the detector's last analysis
    /// (per axis, its node ID and report), each said on stderr.
    pub fn finish(self) -> Result<ReadersEnd> {
        let trace = match self.recorder {
            Some(rec) => Some(finish_trace(rec)?),
            None => None,
        };
        let (detector, detector_lost) = match self.detector {
            Some(d) => finish_detector(d, &self.node_ids)?,
            None => (Vec::new(), 0),
        };
        Ok(ReadersEnd {
            trace,
            detector,
            detector_lost,
        })
    }
}

/// Set on Ctrl-C / SIGTERM (with `stop_on_signal`), and (without a scenario) after
/// `--duration` of wall time; with a scenario, `--duration` is the scenario's end and its
/// thread sets the flag.
pub fn stop_flag(req: &LiveRequest) -> Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    if req.stop_on_signal {
        let stop = Arc::clone(&stop);
        ctrlc::set_handler(move || stop.store(true, Ordering::Relaxed))
            .context("cannot install the Ctrl-C / SIGTERM handler")?;
    }
    // Without a scenario, --duration is wall time; with one, the scenario's end.
    if let (Some(d), None) = (req.duration_s, &req.scenario) {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_secs_f64(d));
            stop.store(true, Ordering::Relaxed);
        });
    }
    Ok(stop)
}

/// What runs where, on stderr: axes, interface, rate, lock-step, scenario; the user unit.
pub(super) fn announce(
    req: &LiveRequest,
    label: &str,
    machine: &MachineFile,
    lockstep: Option<&Lockstep>,
) {
    eprintln!(
        "drive-emu: {} {} on {} at {} Hz{}: {}{}",
        machine.axes.len(),
        if machine.axes.len() == 1 {
            "axis"
        } else {
            "axes"
        },
        label,
        machine.tick_hz,
        match (lockstep, req.sync_period_us) {
            (None, _) => String::new(),
            (Some(_), Some(p)) => format!(" (lock-step: {p} us per SYNC)"),
            (Some(_), None) => {
                " (lock-step: per SYNC the period in 0x1006, else in 0x60C2, else 1000 us)".into()
            }
        },
        machine
            .axes
            .iter()
            .map(|a| format!("node {} = {}", a.node_id, a.preset))
            .collect::<Vec<_>>()
            .join(", "),
        req.scenario
            .as_ref()
            .map_or(String::new(), |s| format!("; scenario {}", s.name)),
    );
    eprintln!(
        "drive-emu: positions in user units (uu): {}",
        machine
            .axes
            .iter()
            .map(|a| {
                let rotary = AxisConfig::from_preset(&a.preset)
                    .map(|c| c.kind == crate::presets::AxisKind::Rotary)
                    .unwrap_or(false);
                format!(
                    "node {}: 1 uu = {}",
                    a.node_id,
                    crate::report::user_unit(rotary)
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    );
}

/// Start the scenario thread: it follows the loop's time through `link`, and sets `stop` when
/// the scenario ends.
pub fn spawn_scenario(
    req: &LiveRequest,
    s: &Scenario,
    (link, obs): (&Arc<LiveLink>, &Arc<Observation>),
    stop: &Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<ScenarioOutcome>, ApiError> {
    let end = LiveEnd::for_scenario(s, req.duration_s.map(|d| (d * 1e6) as u64));
    eprintln!("drive-emu: scenario {} ends {}", s.name, end.describe(s));
    let snapshot = AxisDrive::from_config(&s.machine.configs[0])
        .map_err(|e| ApiError::Invalid(anyhow::anyhow!("{e}")))?;
    let s = s.clone();
    let (link, obs, stop) = (Arc::clone(link), Arc::clone(obs), Arc::clone(stop));
    Ok(std::thread::spawn(move || {
        let cfg = s.machine.configs[0].clone();
        let outcome = run_timeline(&s, &cfg, &snapshot, (&link, &obs), &stop, end);
        stop.store(true, Ordering::Relaxed);
        outcome
    }))
}

/// What the loop thread owns.
pub(super) struct LoopParts {
    pub(super) rt: Runtime<LiveBus, AxisDrive>,
    pub(super) request: RealtimeRequest,
    pub(super) lockstep: Option<Lockstep>,
    pub(super) stop: Arc<AtomicBool>,
    /// Set once every node has sent its boot-up.
    pub(super) booted: Arc<AtomicBool>,
    /// The observation bus's writer: every tick published, the node events drained.
    pub(super) observer: Observer,
    pub(super) injections: LoopInjections,
}

/// Everything the loop applies to the drives after a tick: a live scenario's injections
/// (unless the caller's hook took them: the panel), the caller's hook (the panel, the LSS
/// store service), the detector's results (`--detect`).
pub(super) struct LoopInjections {
    pub(super) link: Arc<LiveLink>,
    pub(super) injector: Option<LoopInjector>,
    pub(super) hook: Option<Box<dyn TickHook>>,
    pub(super) detect: Option<Arc<DetectResults>>,
}

impl LoopInjections {
    /// After every tick, once it is published: no allocation, lock or I/O.
    fn apply(&mut self, rt: &mut Runtime<LiveBus, AxisDrive>) {
        if let Some(inj) = self.injector.as_mut() {
            inj.on_tick(&self.link, rt);
        }
        if let Some(h) = self.hook.as_mut() {
            h.on_tick(rt);
        }
        if let Some(d) = &self.detect {
            d.apply(rt);
        }
    }
}

/// Start the loop thread: real-time setup, boot (the delay on the wall clock), then the loop
/// (lock-step or real-time) whose hook, after every tick until `stop`, is publish (the
/// observation bus) plus apply the injections. It hands the runtime back for the summary.
pub(super) fn spawn_loop(
    parts: LoopParts,
) -> Result<std::thread::JoinHandle<Runtime<LiveBus, AxisDrive>>> {
    let LoopParts {
        mut rt,
        request,
        lockstep,
        stop,
        booted,
        mut observer,
        mut injections,
    } = parts;
    Ok(std::thread::Builder::new()
        .name("drive-emu-loop".into())
        .spawn(move || {
            let report = realtime::apply(&request);
            for w in &report.warnings {
                eprintln!("drive-emu: warning: {w}");
            }
            eprintln!("drive-emu: loop thread: {report}");
            // Power-on: the boot delay passes on the wall clock before the loop starts
            // (frames meanwhile wait in the socket; a booting node ignores them anyway).
            rt.boot();
            let delay_us = rt.axes.iter().map(|a| a.node.boot_delay_us()).max();
            if let Some(d) = delay_us.filter(|d| *d > 0) {
                std::thread::sleep(std::time::Duration::from_micros(d));
                rt.finish_boots();
            }
            booted.store(true, Ordering::Release);
            let hook = |rt: &mut Runtime<LiveBus, AxisDrive>| {
                observer.publish(rt);
                observer.set_link_up(rt.bus.inner().link_up());
                injections.apply(rt);
            };
            match lockstep {
                Some(cfg) => rt.run_lockstep_with(cfg, &stop, hook),
                None => rt.run_realtime(&mut MonotonicClock::new(), &stop, hook),
            }
            rt
        })?)
}

/// The detector's last analysis per axis (`--detect`), said on stderr: verdict, frequency,
/// amplitude, the k_v judged against.
#[allow(clippy::type_complexity)]
fn finish_detector(
    d: Detector,
    node_ids: &[u8],
) -> Result<(
    Vec<(u8, Option<crate::analysis::detector::DetectorReport>)>,
    u64,
)> {
    let (reports, lost) = d.finish().context("the detector")?;
    for (n, rep) in node_ids.iter().zip(&reports) {
        match rep {
            Some(r) if r.inconclusive.is_some() => {
                eprintln!("drive-emu: detector: node {n}: {}", inconclusive_text(r))
            }
            Some(r) => eprintln!(
                "drive-emu: detector: node {n}: {} | frequency {} | amplitude {:.2} {} | gap {} | k_v {:.2} 1/s{}",
                r.verdict.as_str(),
                r.frequency_hz.map_or("-".into(), |f| format!("{f:.2} Hz")),
                r.amplitude,
                crate::report::unit_text(&r.position_unit),
                r.backlash_estimate.text(),
                r.kv_per_s,
                if r.master_loop.is_some() {
                    " (the master's own position loop)"
                } else {
                    ""
                }
            ),
            None => eprintln!("drive-emu: detector: node {n}: no samples"),
        }
    }
    if lost > 0 {
        eprintln!(
            "drive-emu: detector: {lost} ticks lost (the detector thread fell more than the \
             observation ring behind)"
        );
    }
    Ok((node_ids.iter().copied().zip(reports).collect(), lost))
}

/// Per axis, the mechanics of the gap estimate (`--detect`): the scenario's machine, or each
/// axis's preset with its overrides; the drive's samples carry the current in per mille.
/// The detector thread of `--detect`, a reader of the bus `obs` whose results go to the loop
/// through `results`, with each drive's facts: the same for the drives on CAN and on EtherCAT.
fn start_detector<'a>(
    req: &LiveRequest,
    (obs, results): (&Arc<Observation>, &Arc<DetectResults>),
    drives: impl Iterator<Item = &'a AxisDrive>,
    gap: Vec<Option<crate::analysis::gap::GapModel>>,
) -> Result<Detector> {
    let facts = drives
        .zip(gap)
        .map(|(d, gap)| AxisFacts {
            rotary: drive_protocol::Drive::info(d).rotary,
            kv_per_s: d.param(crate::drive::objects::AxisParam::Kv),
            gap,
        })
        .collect();
    let opts = DetectOptions {
        history_s: req.detect_history_s,
        ..DetectOptions::default()
    };
    Ok(Detector::start(
        Arc::clone(obs),
        Arc::clone(results),
        facts,
        opts,
    )?)
}

pub fn gap_models(
    machine: &MachineFile,
    scenario: Option<&Scenario>,
) -> Vec<Option<crate::analysis::gap::GapModel>> {
    use crate::analysis::gap::{CurrentUnit, GapModel};
    let configs: Vec<Option<AxisConfig>> = match scenario {
        Some(s) => vec![s.machine.configs.first().cloned()],
        None => machine.axes.iter().map(|e| e.run_config().ok()).collect(),
    };
    configs
        .iter()
        .map(|c| {
            c.as_ref()
                .and_then(|c| GapModel::for_axis(c, CurrentUnit::Permille))
        })
        .collect()
}

/// `--trace`: the recorder, a reader of the bus `obs` (one file per node of `node_ids`), the
/// same for the drives on CAN and on EtherCAT. The files are created here, before the loop
/// starts: a bad path loses nothing.
fn start_trace(
    req: &LiveRequest,
    obs: &Arc<Observation>,
    node_ids: &[u8],
) -> Result<Option<Recorder>> {
    let Some(path) = &req.trace else {
        return Ok(None);
    };
    Ok(Some(Recorder::start(
        Arc::clone(obs),
        trace_paths(path, node_ids),
    )?))
}

/// Read the rest and close the trace files, and say what they hold.
fn finish_trace(rec: Recorder) -> Result<TraceSummary> {
    let t = rec.finish().context("writing the trace")?;
    eprintln!(
        "drive-emu: trace: {} samples in {}{}",
        t.samples,
        t.paths
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        if t.lost > 0 {
            format!(
                " ({} ticks lost: the recorder fell more than the observation ring behind, a \
                 slow disk)",
                t.lost
            )
        } else {
            String::new()
        }
    );
    Ok(t)
}

/// An inconclusive detector result for people: its first reason, which
/// [`DetectorReport::mark_inconclusive`](crate::analysis::detector::DetectorReport::mark_inconclusive)
/// words as the verdict, its kind and why (no amplitude or frequency: nothing was measured).
pub fn inconclusive_text(d: &crate::analysis::detector::DetectorReport) -> String {
    d.reasons.first().cloned().unwrap_or_else(|| {
        format!(
            "inconclusive ({})",
            d.inconclusive.map_or("", |i| i.as_str())
        )
    })
}
