//! `drive-emu run`: the drive(s) on a real or virtual CAN bus, at a fixed rate.

use crate::bus::fault::FaultyBus;
use crate::bus::socketcan::SocketCanBus;
use crate::presets::AxisConfig;
use crate::runtime::axis_drive::AxisDrive;
use crate::runtime::clock::MonotonicClock;
use crate::runtime::machine::{self, AxisEntry, MachineFile};
use crate::runtime::realtime::{self, RealtimeRequest};
use crate::runtime::trace::{trace_paths, Recorder, TraceTap};
use crate::runtime::{AxisSlot, Runtime};
use crate::scenario::live::{run_timeline, LiveLink, LiveOutcome, LoopInjector};
use crate::scenario::Scenario;
use anyhow::{bail, Context, Result};
use clap::Args;
use drive_protocol::{Drive, Node};
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use std::sync::Arc;

#[derive(Args, Debug, Clone)]
pub struct RunArgs {
    /// CAN interface (can0, vcan0, ...).
    #[arg(long, default_value = "vcan0")]
    pub iface: String,
    /// Node ID of the (single) drive, 1..=127. Ignored with --config.
    #[arg(long, default_value_t = 5)]
    pub node: u8,
    /// Preset of the (single) axis: cnc1 ... cnc5. Ignored with --config.
    #[arg(long, default_value = "cnc1")]
    pub preset: String,
    /// Override a preset key, e.g. --set backlash_mm=0.05 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Machine file with several axes (see README); replaces --node/--preset/--set.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Loop rate, Hz (250..8000).
    #[arg(long, default_value_t = 1000)]
    pub tick_hz: u32,
    /// Lock-step: simulated time advances by --sync-period-us at each SYNC received, not by
    /// the wall clock.
    #[arg(long)]
    pub lockstep: bool,
    /// SYNC period for lock-step, us.
    #[arg(long, default_value_t = 1000)]
    pub sync_period_us: u64,
    /// SCHED_FIFO priority for the loop thread (needs CAP_SYS_NICE); 0 = normal scheduling.
    #[arg(long, default_value_t = 80)]
    pub rt_priority: i32,
    /// Pin the loop thread to this CPU.
    #[arg(long)]
    pub cpu: Option<usize>,
    /// Do not lock memory (mlockall).
    #[arg(long)]
    pub no_mlock: bool,
    /// Stop after this many seconds (default: until Ctrl-C / SIGTERM).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Print the final statistics as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Inject this scenario's timeline (wear, faults) into the running drive; the machine comes
    /// from the scenario file, the motion from your controller. Stops at the scenario's end.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Record what the drive reports, one row per tick (the sample-log CSV that `drive-emu
    /// analyze` reads), written as the run goes and flushed on exit, Ctrl-C or SIGTERM. With
    /// several axes, one file each: trace.csv -> trace-node5.csv, ...
    #[arg(long, value_name = "FILE")]
    pub trace: Option<PathBuf>,
}

/// Longest `--duration` accepted, s (about 31 years: beyond it the number is a typo).
pub const MAX_DURATION_S: f64 = 1e9;
/// Longest `--sync-period-us` accepted: CiA 301 0x1006 is in us; a SYNC slower than 1 s is
/// no longer a control cycle.
pub const MAX_SYNC_PERIOD_US: u64 = 1_000_000;

/// Check the numeric flags that the machine file does not cover.
pub fn validate_args(args: &RunArgs) -> Result<()> {
    if let Some(d) = args.duration {
        if !(d.is_finite() && d > 0.0 && d <= MAX_DURATION_S) {
            bail!(
                "--duration {d}: must be a number of seconds > 0 and <= {MAX_DURATION_S:e} (omit \
                 it to run until Ctrl-C / SIGTERM)"
            );
        }
    }
    if !(0..=99).contains(&args.rt_priority) {
        bail!(
            "--rt-priority {}: must be 0..=99 (SCHED_FIFO priorities; 0 = normal scheduling)",
            args.rt_priority
        );
    }
    if let Some(cpu) = args.cpu {
        let n = std::thread::available_parallelism().map_or(1, |n| n.get());
        if cpu >= n {
            bail!("--cpu {cpu}: this machine has CPUs 0..={}", n - 1);
        }
    }
    if args.lockstep {
        let tick_us = 1_000_000 / u64::from(args.tick_hz.max(1));
        let p = args.sync_period_us;
        if p == 0 || p > MAX_SYNC_PERIOD_US || !p.is_multiple_of(tick_us) {
            bail!(
                "--sync-period-us {p}: must be a whole multiple of the tick period ({tick_us} us \
                 at --tick-hz {}) between {tick_us} and {MAX_SYNC_PERIOD_US} us: each SYNC \
                 advances simulated time by whole ticks",
                args.tick_hz
            );
        }
    }
    Ok(())
}

/// Build the nodes and drives of a machine.
pub fn build_axes(entries: &[AxisEntry]) -> Result<Vec<AxisSlot<AxisDrive>>> {
    entries
        .iter()
        .map(|e| {
            let mut cfg = AxisConfig::from_preset(&e.preset)
                .map_err(|err| anyhow::anyhow!("axis node {}: {err}", e.node_id))?;
            for (k, v) in &e.set {
                cfg = cfg
                    .with_override(k, &machine::value_text(v))
                    .map_err(|err| anyhow::anyhow!("axis node {}: {err}", e.node_id))?;
            }
            let drive = AxisDrive::from_config(&cfg)
                .map_err(|err| anyhow::anyhow!("axis node {}: {err}", e.node_id))?;
            let node = Node::new(e.node_id, drive.info())
                .map_err(|err| anyhow::anyhow!("axis node {}: {err}", e.node_id))?;
            Ok(AxisSlot { node, drive })
        })
        .collect()
}

/// The machine described by the command line (one axis) or by --config.
pub fn machine_from_args(args: &RunArgs) -> Result<MachineFile> {
    if let Some(path) = &args.config {
        return machine::load(path);
    }
    let mut set = std::collections::BTreeMap::new();
    for s in &args.set {
        let Some((k, v)) = s.split_once('=') else {
            bail!("--set {s}: an override must be written key=value");
        };
        let value = toml::from_str::<toml::Table>(&format!("v = {v}"))
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(v.to_string()));
        set.insert(k.trim().to_string(), value);
    }
    let m = MachineFile {
        tick_hz: args.tick_hz,
        axes: vec![AxisEntry {
            node_id: args.node,
            preset: args.preset.clone(),
            set,
        }],
    };
    machine::validate(&m)?;
    Ok(m)
}

/// What the loop thread publishes for the status line: plain atomics, no locks.
#[derive(Default)]
struct Status {
    statusword: AtomicU64,
    mode: AtomicI64,
    position_uu: AtomicI64,
    following_error_uu: AtomicI64,
    overruns: AtomicU64,
    ticks: AtomicU64,
    link_up: AtomicBool,
}

pub fn run(args: &RunArgs) -> Result<()> {
    let scenario = match &args.scenario {
        Some(path) => Some(crate::scenario::load(path).map_err(|e| anyhow::anyhow!("{e}"))?),
        None => None,
    };
    let outcome = run_live(args, scenario.as_ref())?;
    if let Some(o) = outcome {
        print_outcome(&o);
        if !o.passed() {
            bail!("scenario expectations failed");
        }
    }
    Ok(())
}

/// Print what a live scenario run found.
pub fn print_outcome(o: &LiveOutcome) {
    for (t, what) in &o.fired {
        println!("  t={:>9.3} s  event: {what}", *t as f64 * 1e-6);
    }
    for (t, code) in &o.record.emcys {
        println!("  t={:>9.3} s  EMCY {code:#06X}", *t as f64 * 1e-6);
    }
    if let Some(d) = &o.detector {
        println!(
            "  detector: {} | amplitude {:.2} {} | frequency {}",
            d.verdict.as_str(),
            d.amplitude,
            d.position_unit,
            d.frequency_hz.map_or("-".into(), |f| format!("{f:.2} Hz"))
        );
    }
    for e in &o.expectations {
        println!("  {e}");
    }
    if o.samples_lost > 0 {
        println!(
            "  ({} samples lost: the scenario thread fell behind)",
            o.samples_lost
        );
    }
}

/// Run the drive(s) on the bus; with a scenario, inject its timeline into axis 0 and return
/// what it found.
pub fn run_live(args: &RunArgs, scenario: Option<&Scenario>) -> Result<Option<LiveOutcome>> {
    validate_args(args)?;
    let machine = match scenario {
        // The scenario's machine: its first preset with the file's overrides applied.
        Some(s) => {
            let cfg = s
                .machine
                .configs
                .first()
                .context("the scenario has no machine")?;
            MachineFile {
                tick_hz: args.tick_hz,
                axes: vec![AxisEntry {
                    node_id: args.node,
                    preset: cfg.name.clone(),
                    set: Default::default(),
                }],
            }
        }
        None => machine_from_args(args)?,
    };
    machine::validate(&machine)?;
    let axes = match scenario {
        Some(s) => {
            let drive = AxisDrive::from_config(&s.machine.configs[0])?;
            let node = Node::new(args.node, drive.info()).map_err(|e| anyhow::anyhow!("{e}"))?;
            vec![AxisSlot { node, drive }]
        }
        None => build_axes(&machine.axes)?,
    };
    let seed = scenario.map_or(1, |s| s.run.seed);
    let bus = FaultyBus::new(SocketCanBus::open(&args.iface)?, seed);
    let period_us = 1_000_000 / u64::from(machine.tick_hz);
    let n_axes = axes.len();
    let mut rt = Runtime::new(bus, axes, period_us);

    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = Arc::clone(&stop);
        ctrlc::set_handler(move || stop.store(true, Ordering::Relaxed))
            .context("cannot install the Ctrl-C / SIGTERM handler")?;
    }
    if let Some(d) = args.duration {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_secs_f64(d));
            stop.store(true, Ordering::Relaxed);
        });
    }
    let status = Arc::new(Status::default());
    let request = RealtimeRequest {
        fifo_priority: (args.rt_priority > 0).then_some(args.rt_priority),
        cpu: args.cpu,
        lock_memory: !args.no_mlock,
    };
    let lockstep = args.lockstep.then_some(args.sync_period_us);
    // The trace files are created before the loop starts: a bad path loses nothing.
    let node_ids: Vec<u8> = rt.axes.iter().map(|a| a.node.node_id()).collect();
    let tap = args.trace.as_ref().map(|_| Arc::new(TraceTap::new(n_axes)));
    let recorder = match (&args.trace, &tap) {
        (Some(path), Some(tap)) => Some(Recorder::start(
            Arc::clone(tap),
            trace_paths(path, &node_ids),
        )?),
        _ => None,
    };
    eprintln!(
        "drive-emu: {} axis(es) on {} at {} Hz{}: {}{}",
        n_axes,
        args.iface,
        machine.tick_hz,
        if lockstep.is_some() {
            " (lock-step on SYNC)"
        } else {
            ""
        },
        machine
            .axes
            .iter()
            .map(|a| format!("node {} = {}", a.node_id, a.preset))
            .collect::<Vec<_>>()
            .join(", "),
        scenario.map_or(String::new(), |s| format!("; scenario {}", s.name)),
    );

    // The scenario thread follows the loop's time and feeds it injections.
    let link = Arc::new(LiveLink::new());
    let mut injector = scenario.map(|s| LoopInjector::new(s.run.master.master_id));
    let scenario_thread = match scenario {
        Some(s) => {
            let (s, snapshot) = (s.clone(), AxisDrive::from_config(&s.machine.configs[0])?);
            let (link, stop) = (Arc::clone(&link), Arc::clone(&stop));
            Some(std::thread::spawn(move || {
                let cfg = s.machine.configs[0].clone();
                let outcome = run_timeline(&s, &cfg, &snapshot, &link, &stop);
                stop.store(true, Ordering::Relaxed);
                outcome
            }))
        }
        None => None,
    };

    let loop_thread = {
        let (stop, status, link) = (Arc::clone(&stop), Arc::clone(&status), Arc::clone(&link));
        let tap = tap.clone();
        std::thread::Builder::new()
            .name("drive-emu-loop".into())
            .spawn(move || {
                let report = realtime::apply(&request);
                for w in &report.warnings {
                    eprintln!("drive-emu: warning: {w}");
                }
                eprintln!("drive-emu: loop thread: {report}");
                rt.boot();
                let hook = |rt: &mut Runtime<FaultyBus<SocketCanBus>, AxisDrive>| {
                    if let Some(inj) = injector.as_mut() {
                        inj.on_tick(&link, rt);
                    }
                    if let Some(tap) = &tap {
                        tap.on_tick(rt);
                    }
                    let n = &rt.axes[0].node;
                    status
                        .statusword
                        .store(u64::from(n.statusword()), Ordering::Relaxed);
                    status.mode.store(i64::from(n.mode()), Ordering::Relaxed);
                    status
                        .position_uu
                        .store(i64::from(n.position_actual()), Ordering::Relaxed);
                    status
                        .following_error_uu
                        .store(n.following_error().round() as i64, Ordering::Relaxed);
                    status.overruns.store(rt.stats.overruns, Ordering::Relaxed);
                    status.ticks.store(rt.stats.ticks, Ordering::Relaxed);
                    status
                        .link_up
                        .store(rt.bus.inner().link_up(), Ordering::Relaxed);
                };
                match lockstep {
                    Some(sync_us) => rt.run_lockstep(sync_us, &stop, hook),
                    None => rt.run_realtime(&mut MonotonicClock::new(), &stop, hook),
                }
                rt
            })?
    };

    let tty = std::io::stdout().is_terminal();
    while !stop.load(Ordering::Relaxed) && !loop_thread.is_finished() {
        std::thread::sleep(std::time::Duration::from_millis(200));
        if tty {
            let sw = status.statusword.load(Ordering::Relaxed) as u16;
            print!(
                "\r{} | {} mode {} | pos {} uu | ferr {} uu | ticks {} overruns {}{}   ",
                args.iface,
                crate::master::state_name(sw),
                status.mode.load(Ordering::Relaxed),
                status.position_uu.load(Ordering::Relaxed),
                status.following_error_uu.load(Ordering::Relaxed),
                status.ticks.load(Ordering::Relaxed),
                status.overruns.load(Ordering::Relaxed),
                if status.link_up.load(Ordering::Relaxed) {
                    ""
                } else {
                    " | LINK DOWN"
                },
            );
            let _ = std::io::stdout().flush();
        }
    }
    stop.store(true, Ordering::Relaxed);
    let joined = loop_thread.join();
    // The trace is flushed whatever happened to the loop.
    if let (Some(rec), Some(tap)) = (recorder, &tap) {
        let t = rec.finish(tap).context("writing the trace")?;
        eprintln!(
            "drive-emu: trace: {} samples in {}{}",
            t.samples,
            t.paths
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
            if t.lost > 0 {
                format!(" ({} lost: the disk was too slow)", t.lost)
            } else {
                String::new()
            }
        );
    }
    let rt = joined.map_err(|_| anyhow::anyhow!("the loop thread panicked"))?;
    if tty {
        println!();
    }
    let summary = rt.stats.summary();
    eprintln!("drive-emu: stopped. {summary}");
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    }
    match scenario_thread {
        Some(t) => {
            Ok(Some(t.join().map_err(|_| {
                anyhow::anyhow!("the scenario thread panicked")
            })?))
        }
        None => Ok(None),
    }
}
