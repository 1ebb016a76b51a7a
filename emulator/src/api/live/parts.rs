//! A live run on CAN: the bus, the observation bus and its readers (trace, detector), the
//! scenario thread, the loop thread with its hook (publish, apply the injections), the summary.

use super::args::{validate_args, RunArgs};
use super::axes::live_axes;
use super::status::{watch, Status};
use super::{inconclusive_text, LiveBus, LiveRun};
use crate::bus::fault::FaultyBus;
use crate::bus::live::LiveTransport;
use crate::bus::socketcand::SocketcandBus;
use crate::drive::axis_drive::AxisDrive;
use crate::drive::machine::{self, MachineFile};
use crate::monitor::{AxisFacts, DetectOptions, DetectResults, Detector};
use crate::observe::trace::Recorder;
use crate::observe::{Observation, Observer};
use crate::presets::AxisConfig;
use crate::runtime::realtime::{self, RealtimeRequest};
use crate::runtime::trace::trace_paths;
use crate::runtime::{Lockstep, Runtime};
use crate::scenario::live::{run_timeline, LiveEnd, LiveLink, LiveOutcome, LoopInjector};
use crate::scenario::Scenario;
use crate::time::MonotonicClock;
use anyhow::{Context, Result};
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The bus the options ask for: the SocketCAN interface, or the socketcand server (said on
/// stderr with the address it got).
fn open_transport(args: &RunArgs) -> Result<LiveTransport> {
    if let Some(addr) = &args.socketcand {
        let bus = SocketcandBus::bind(addr)?;
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
    #[cfg(feature = "socketcan")]
    {
        Ok(LiveTransport::SocketCan(
            crate::bus::socketcan::SocketCanBus::open(&args.iface)?,
        ))
    }
    #[cfg(not(feature = "socketcan"))]
    anyhow::bail!(
        "cannot open CAN interface {}: this drive-emu was built without SocketCAN (cargo \
         feature `socketcan`); serve the bus with --socketcand ADDR:PORT instead \
         (docs/socketcand.md)",
        args.iface
    )
}

/// Run the drive(s) on the bus; with a scenario, inject its timeline into axis 0 and return
/// what it found. The steps: the checks, the machine and its axes, the bus, the stop flag,
/// the observation bus and its readers (trace, detector), the panel, the scenario thread, the
/// loop thread, the status line until the run stops, the readers' end, the summary.
pub fn run_live(args: &RunArgs, scenario: Option<&Scenario>) -> Result<LiveRun> {
    check_live(args, scenario)?;
    let (machine, axes) = live_axes(args, scenario)?;
    let (bus, socketcand, label) = open_bus(args, scenario)?;
    let rt = Runtime::new(bus, axes, 1_000_000 / u64::from(machine.tick_hz));
    let stop = stop_flag(args, scenario)?;
    // The observation bus: the loop publishes every tick into it; the trace recorder, the
    // detector, the scenario thread, the status line and the panel read it.
    let (observer, obs) = crate::observe::channel(
        rt.axes.len(),
        crate::observe::run_ring_capacity(machine.tick_hz),
    );
    let lockstep = lockstep_of(args, scenario);
    let readers = start_readers(
        args,
        &obs,
        rt.axes.iter().map(|a| (a.node.node_id(), &a.drive)),
        gap_models(&machine, scenario),
    )?;
    announce(args, &label, &machine, lockstep.as_ref(), scenario);
    // The scenario thread follows the loop's time and feeds it injections.
    let link = Arc::new(LiveLink::new());
    let mut injector = scenario.map(|s| LoopInjector::new(s.run.master.master_id));
    // The live panel (--panel): bound before the loop starts; it takes the scenario's
    // injections into its own injector.
    let context = crate::panel::RunContext {
        bus: crate::panel::PanelBus::Can,
        iface: socketcand.is_none().then_some(args.iface.as_str()),
        node: args.node,
        lockstep: args.lockstep,
        json: args.json,
        machine: &machine,
        scenario,
    };
    let (panel, panel_loop) =
        crate::panel::start_for_run(&args.panel, context, (&link, &obs), &mut injector)?.unzip();
    let scenario_thread = match scenario {
        Some(s) => Some(spawn_scenario(args, s, (&link, &obs), &stop)?),
        None => None,
    };
    let wear_at_boot = rt.axes.iter().map(|a| {
        use drive_protocol::Drive as _;
        let gap = a.drive.param(crate::drive::objects::AxisParam::Backlash);
        machine::wear_text(gap, a.drive.info().rotary)
    });
    let status = Arc::new(Status::new(Arc::clone(&obs), wear_at_boot.collect()));
    let loop_thread = spawn_loop(LoopParts {
        rt,
        request: realtime_request(args),
        lockstep,
        stop: Arc::clone(&stop),
        observer,
        injections: LoopInjections {
            status: Arc::clone(&status),
            link,
            injector,
            panel: panel_loop,
            detect: readers.detect.clone(),
        },
    })?;
    let bus_of = (label.as_str(), socketcand);
    let shown = (&machine, lockstep.as_ref());
    watch(args, bus_of, shown, &status, &stop, &loop_thread)?;
    stop.store(true, Ordering::Relaxed);
    let joined = loop_thread.join();
    if std::io::stderr().is_terminal() {
        eprintln!();
    }
    // The trace is flushed whatever happened to the loop.
    let detector = readers.finish()?;
    if let Some(p) = panel {
        p.stop();
    }
    let rt = joined.map_err(|_| anyhow::anyhow!("the loop thread panicked"))?;
    let scenario = join_scenario(scenario_thread)?;
    Ok(live_summary(&rt, lockstep.is_some(), detector, scenario))
}

/// A live run's options and scenario, checked before anything opens: its bus faults must be
/// CAN's, the panel's options, and the timeline's values within what axis 0's drive accepts
/// (the live loop would drop a refused one silently).
fn check_live(args: &RunArgs, scenario: Option<&Scenario>) -> Result<()> {
    validate_args(args)?;
    if let Some(s) = scenario {
        crate::scenario::check_bus(s, "can").map_err(crate::cli::exit::usage)?;
    }
    crate::panel::check_args(&args.panel)?;
    if let Some((s, cfg)) = scenario.and_then(|s| Some((s, s.machine.configs.first()?))) {
        crate::scenario::inject::check_ranges(s, cfg).map_err(crate::cli::exit::scenario_file)?;
    }
    Ok(())
}

/// The live bus (the interface or socketcand server behind the scenario's fault injector),
/// the socketcand server's address, and the bus's name for people.
fn open_bus(
    args: &RunArgs,
    scenario: Option<&Scenario>,
) -> Result<(LiveBus, Option<std::net::SocketAddr>, String)> {
    let transport = open_transport(args)?;
    let socketcand = transport.socketcand().map(SocketcandBus::local_addr);
    let label = match socketcand {
        Some(a) => format!("socketcand {a}"),
        None => args.iface.clone(),
    };
    let seed = scenario.map_or(1, |s| s.run.seed);
    Ok((FaultyBus::new(transport, seed), socketcand, label))
}

/// The loop thread's scheduling: SCHED_FIFO priority, CPU, locked memory.
pub(super) fn realtime_request(args: &RunArgs) -> RealtimeRequest {
    RealtimeRequest {
        fifo_priority: (args.rt_priority > 0).then_some(args.rt_priority),
        cpu: args.cpu,
        lock_memory: !args.no_mlock,
    }
}

/// `--lockstep`: simulated time per SYNC; with a scenario, a SYNC missing for a second hands
/// the clock to the wall (a live scenario must end).
fn lockstep_of(args: &RunArgs, scenario: Option<&Scenario>) -> Option<Lockstep> {
    args.lockstep.then_some(Lockstep {
        sync_period_us: args.sync_period_us,
        free_run_after_us: scenario.map(|_| {
            args.sync_period_us
                .map_or(1_000_000, |p| (10 * p).max(1_000_000))
        }),
    })
}

/// The scenario thread's outcome, once it ended.
pub(super) fn join_scenario(
    t: Option<std::thread::JoinHandle<LiveOutcome>>,
) -> Result<Option<LiveOutcome>> {
    t.map(|t| {
        t.join()
            .map_err(|_| anyhow::anyhow!("the scenario thread panicked"))
    })
    .transpose()
}

/// What the loop did, said on stderr, and the run's result.
fn live_summary(
    rt: &Runtime<LiveBus, AxisDrive>,
    lockstep: bool,
    detector: Vec<(u8, Option<crate::analysis::detector::DetectorReport>)>,
    scenario: Option<LiveOutcome>,
) -> LiveRun {
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
    LiveRun {
        stats: summary,
        detector,
        lockstep_period_us,
        free_run_ticks: rt.lockstep_free_ticks,
        scenario,
    }
}

/// The readers of the observation bus a live run starts before its loop (`--trace`,
/// `--detect`), the same on CAN and on EtherCAT, and the detector's way back to the loop.
pub(super) struct Readers {
    recorder: Option<Recorder>,
    pub(super) detect: Option<Arc<DetectResults>>,
    detector: Option<Detector>,
    node_ids: Vec<u8>,
}

/// Start the readers the options ask for, one axis per (node ID, drive) of `axes`: the trace
/// files are created here, before the loop starts (a bad path loses nothing).
pub(super) fn start_readers<'a>(
    args: &RunArgs,
    obs: &Arc<Observation>,
    axes: impl Iterator<Item = (u8, &'a AxisDrive)>,
    gap: Vec<Option<crate::analysis::gap::GapModel>>,
) -> Result<Readers> {
    let (node_ids, drives): (Vec<u8>, Vec<&AxisDrive>) = axes.unzip();
    let recorder = start_trace(args, obs, &node_ids)?;
    let detect = args
        .detect
        .then(|| Arc::new(DetectResults::new(node_ids.len())));
    let detector = match &detect {
        Some(results) => Some(start_detector(
            args,
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

impl Readers {
    /// After the loop has stopped: the trace flushed and closed, the detector's last analysis
    /// (per axis, its node ID and report), each said on stderr.
    pub(super) fn finish(
        self,
    ) -> Result<Vec<(u8, Option<crate::analysis::detector::DetectorReport>)>> {
        if let Some(rec) = self.recorder {
            finish_trace(rec)?;
        }
        match self.detector {
            Some(d) => finish_detector(d, &self.node_ids),
            None => Ok(Vec::new()),
        }
    }
}

/// Set on Ctrl-C / SIGTERM, and (without a scenario) after `--duration` of wall time; with a
/// scenario, `--duration` is the scenario's end and its thread sets the flag.
pub(super) fn stop_flag(args: &RunArgs, scenario: Option<&Scenario>) -> Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = Arc::clone(&stop);
        ctrlc::set_handler(move || stop.store(true, Ordering::Relaxed))
            .context("cannot install the Ctrl-C / SIGTERM handler")?;
    }
    // Without a scenario, --duration is wall time; with one, the scenario's end.
    if let (Some(d), None) = (args.duration, scenario) {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_secs_f64(d));
            stop.store(true, Ordering::Relaxed);
        });
    }
    Ok(stop)
}

/// What runs where, on stderr: axes, interface, rate, lock-step, scenario; the user unit.
fn announce(
    args: &RunArgs,
    label: &str,
    machine: &MachineFile,
    lockstep: Option<&Lockstep>,
    scenario: Option<&Scenario>,
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
        match (lockstep, args.sync_period_us) {
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
        scenario.map_or(String::new(), |s| format!("; scenario {}", s.name)),
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
pub(super) fn spawn_scenario(
    args: &RunArgs,
    s: &Scenario,
    (link, obs): (&Arc<LiveLink>, &Arc<Observation>),
    stop: &Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<LiveOutcome>> {
    let end = LiveEnd::for_scenario(s, args.duration.map(|d| (d * 1e6) as u64));
    eprintln!("drive-emu: scenario {} ends {}", s.name, end.describe(s));
    let (s, snapshot) = (s.clone(), AxisDrive::from_config(&s.machine.configs[0])?);
    let (link, obs, stop) = (Arc::clone(link), Arc::clone(obs), Arc::clone(stop));
    Ok(std::thread::spawn(move || {
        let cfg = s.machine.configs[0].clone();
        let outcome = run_timeline(&s, &cfg, &snapshot, (&link, &obs), &stop, end);
        stop.store(true, Ordering::Relaxed);
        outcome
    }))
}

/// What the loop thread owns.
struct LoopParts {
    rt: Runtime<LiveBus, AxisDrive>,
    request: RealtimeRequest,
    lockstep: Option<Lockstep>,
    stop: Arc<AtomicBool>,
    /// The observation bus's writer: every tick published, the node events drained.
    observer: Observer,
    injections: LoopInjections,
}

/// Everything the loop applies to the drives after a tick: the panel's and a live scenario's
/// injections, the detector's results (`--detect`), the LSS store service.
struct LoopInjections {
    status: Arc<Status>,
    link: Arc<LiveLink>,
    injector: Option<LoopInjector>,
    panel: Option<crate::panel::PanelLoop>,
    detect: Option<Arc<DetectResults>>,
}

impl LoopInjections {
    /// After every tick, once it is published: no allocation, lock or I/O.
    fn apply(&mut self, rt: &mut Runtime<LiveBus, AxisDrive>) {
        if let Some(p) = self.panel.as_mut() {
            p.on_tick(rt);
        } else if let Some(inj) = self.injector.as_mut() {
            inj.on_tick(&self.link, rt);
        }
        if let Some(d) = &self.detect {
            d.apply(rt);
        }
        self.status.lss_exchange(rt);
    }
}

/// Start the loop thread: real-time setup, boot (the delay on the wall clock), then the loop
/// (lock-step or real-time) whose hook, after every tick until `stop`, is publish (the
/// observation bus) plus apply the injections. It hands the runtime back for the summary.
fn spawn_loop(parts: LoopParts) -> Result<std::thread::JoinHandle<Runtime<LiveBus, AxisDrive>>> {
    let LoopParts {
        mut rt,
        request,
        lockstep,
        stop,
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
            injections.status.booted.store(true, Ordering::Release);
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
fn finish_detector(
    d: Detector,
    node_ids: &[u8],
) -> Result<Vec<(u8, Option<crate::analysis::detector::DetectorReport>)>> {
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
    Ok(node_ids.iter().copied().zip(reports).collect())
}

/// Per axis, the mechanics of the gap estimate (`--detect`): the scenario's machine, or each
/// axis's preset with its overrides; the drive's samples carry the current in per mille.
/// The detector thread of `--detect`, a reader of the bus `obs` whose results go to the loop
/// through `results`, with each drive's facts: the same for the drives on CAN and on EtherCAT.
fn start_detector<'a>(
    args: &RunArgs,
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
        history_s: args.detect_history,
        ..DetectOptions::default()
    };
    Ok(Detector::start(
        Arc::clone(obs),
        Arc::clone(results),
        facts,
        opts,
    )?)
}

pub(super) fn gap_models(
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
    args: &RunArgs,
    obs: &Arc<Observation>,
    node_ids: &[u8],
) -> Result<Option<Recorder>> {
    let Some(path) = &args.trace else {
        return Ok(None);
    };
    Ok(Some(Recorder::start(
        Arc::clone(obs),
        trace_paths(path, node_ids),
    )?))
}

/// Read the rest and close the trace files, and say what they hold.
fn finish_trace(rec: Recorder) -> Result<()> {
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
    Ok(())
}
