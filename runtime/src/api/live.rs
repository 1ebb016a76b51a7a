//! [`LiveRequest`]: the drive(s) live on a bus at a fixed rate (`drive-emu run` on CAN), as a
//! typed request; [`LiveRun`] the running run's handle, [`LiveOutcome`] what it found.
//!
//! ```no_run
//! # fn main() -> Result<(), drive_runtime::api::ApiError> {
//! use drive_runtime::api::live::{LiveBusSpec, LiveRequest};
//! let run = LiveRequest {
//!     bus: LiveBusSpec::Socketcand("127.0.0.1:0".into()),
//!     duration_s: Some(2.0),
//!     ..LiveRequest::default()
//! }
//! .start()?;
//! let outcome = run.wait()?;
//! println!("{} ticks", outcome.stats.ticks);
//! # Ok(()) }
//! ```
//!
//! The steps [`LiveRequest::start`] takes: the checks (the command line's, each error naming
//! its flag), the machine and its axes, the bus, the stop flag, the observation bus and its
//! readers (`--trace`, `--detect`), what the caller attaches ([`LiveRequest::start_with`]: the
//! command line's panel and LSS store service), the scenario thread, the loop thread.
//! [`LiveRun::wait`] joins them and sums up. The terminal status line and the ready line are
//! the command line's: it reads them from [`LiveRun::observation`] while the run goes.
//!
//! `run --ethercat` is not a request yet: it stays in `cli::run::ethercat` and shares the
//! pieces in [`parts`] and [`setup`] (readers, stop flag, scenario thread, axis setup).

pub mod parts;
pub mod setup;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use super::ApiError;
use crate::analysis::detector::DetectorReport;
use crate::bus::fault::FaultyBus;
use crate::bus::inproc::InProcEndpoint;
use crate::drive::axis_drive::AxisDrive;
use crate::drive::machine::MachineFile;
use crate::observe::trace::TraceSummary;
use crate::observe::Observation;
use crate::runtime::stats::StatsSummary;
use crate::runtime::{Lockstep, Runtime};
use crate::scenario::live::{LiveLink, LiveOutcome as ScenarioOutcome, LoopInjector};
use crate::scenario::Scenario;

/// Default of [`LiveRequest::node_id`] (`--node`).
pub const DEFAULT_NODE_ID: u8 = 5;
/// Default of [`LiveRequest::tick_hz`] (`--tick-hz`).
pub const DEFAULT_TICK_HZ: u32 = 1000;
/// Default of [`LiveRequest::rt_priority`] (`--rt-priority`).
pub const DEFAULT_RT_PRIORITY: i32 = 80;
/// Default of [`LiveRequest::detect_history_s`] (`--detect-history`).
pub const DEFAULT_DETECT_HISTORY_S: f64 = 60.0;
/// Default of [`LiveRequest::boot_delay_ms`] (`--boot-delay-ms`): within the 100 ms - seconds
/// real drives take, and long enough that a python master's `nmt.state = 'RESET'` followed by
/// `wait_for_bootup()` sees the boot-up even when the master's host stalls for tens of ms
/// (user-mode Linux, a loaded CI machine).
pub const DEFAULT_BOOT_DELAY_MS: u64 = 200;
/// Longest [`LiveRequest::boot_delay_ms`] accepted.
pub const MAX_BOOT_DELAY_MS: u64 = 60_000;
/// Longest [`LiveRequest::duration_s`] accepted, s (about 31 years: beyond it the number is
/// a typo).
pub const MAX_DURATION_S: f64 = 1e9;
/// Shortest [`LiveRequest::sync_period_us`] accepted.
pub const MIN_SYNC_PERIOD_US: u64 = 100;
/// Longest [`LiveRequest::sync_period_us`] accepted: CiA 301 0x1006 is in us; a SYNC slower
/// than 1 s is no longer a control cycle.
pub const MAX_SYNC_PERIOD_US: u64 = 1_000_000;

/// The bus a live run serves its drives on.
pub enum LiveBusSpec {
    /// A SocketCAN interface (`--iface`, default vcan0; needs the cargo feature `socketcan`).
    SocketCan(String),
    /// A socketcand server on ADDR:PORT (`--socketcand`; port 0: any free port, said on
    /// stderr and by [`LiveRun::socketcand_addr`]).
    Socketcand(String),
    /// One endpoint of an in-process bus ([`crate::bus::inproc::InProcBus::endpoints`]): the
    /// caller keeps the others and attaches a master to them (tests, embedding).
    InProcess(InProcEndpoint),
}

impl std::fmt::Debug for LiveBusSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.label())
    }
}

impl LiveBusSpec {
    /// What the bus is, for people: the interface, `socketcand ADDR:PORT`, or `in-process`.
    pub fn label(&self) -> String {
        match self {
            LiveBusSpec::SocketCan(iface) => iface.clone(),
            LiveBusSpec::Socketcand(addr) => format!("socketcand {addr}"),
            LiveBusSpec::InProcess(_) => "in-process".into(),
        }
    }

    /// The SocketCAN interface's name, if the bus is one.
    pub fn iface(&self) -> Option<&str> {
        match self {
            LiveBusSpec::SocketCan(iface) => Some(iface),
            _ => None,
        }
    }
}

/// The drive's non-volatile memory for LSS store configuration (`--lss-store FILE`, one
/// axis): what FILE held at start (the command line reads it), and where a store goes. The
/// store itself is written by the caller's [`TickHook`] (the command line's LSS store
/// service); without one, a node's store request gets no answer.
#[derive(Debug, Clone)]
pub struct LssMemory {
    /// The file, as the user wrote it (said in messages).
    pub path: PathBuf,
    /// What it holds; `None`: nothing stored yet.
    pub stored: Option<drive_protocol::LssStore>,
    /// How a bit timing index is said (`index 2 (500 kbit/s)`).
    pub bit_timing_text: fn(u8) -> String,
}

/// `drive-emu run` on CAN as a typed request: the axes, the bus, how long, a scenario, the
/// readers. Every field has the command line's default ([`Default`]); messages name the
/// fields as the command line's flags (`--node 0: outside 1..=127 ...`).
#[derive(Debug)]
pub struct LiveRequest {
    /// The bus (`--iface`, default `vcan0`, or `--socketcand`).
    pub bus: LiveBusSpec,
    /// Node ID of the single axis, 1..=127, or 255: non-configured (`--node`, default 5).
    pub node_id: u8,
    /// Serve LSS even where the vendor's EDS says it has none (`--force-lss`).
    pub force_lss: bool,
    /// Preset of the single axis (`--preset`, default cnc1).
    pub preset: String,
    /// Preset overrides, `key=value` (`--set`).
    pub sets: Vec<String>,
    /// Serve the preset's worn drive train (`--worn`).
    pub worn: bool,
    /// Machine file with several axes (`--config`): replaces node, preset, sets and eds.
    pub machine_file: Option<PathBuf>,
    /// Vendor EDS or DCF served as the drive's own (`--eds`).
    pub eds: Option<PathBuf>,
    /// First index of the emulator's own objects, 0x2000..=0x5F00 (`--objects-base`).
    pub objects_base: Option<u16>,
    /// Vendor profile, a name or a .toml path (`--profile`).
    pub profile: Option<String>,
    /// Vendor switches on, `NAME[.PARAM=VALUE]` (`--quirk`).
    pub quirks: Vec<String>,
    /// Vendor switches off (`--no-quirk`).
    pub no_quirks: Vec<String>,
    /// Loop rate, Hz (`--tick-hz`, default 1000).
    pub tick_hz: u32,
    /// Simulated time advances per SYNC received (`--lockstep`).
    pub lockstep: bool,
    /// Lock-step: simulated time per SYNC, us (`--sync-period-us`).
    pub sync_period_us: Option<u64>,
    /// SCHED_FIFO priority of the loop thread, 0 = normal (`--rt-priority`, default 80).
    pub rt_priority: i32,
    /// Pin the loop thread to this CPU (`--cpu`).
    pub cpu: Option<usize>,
    /// Lock memory, mlockall (default true; `--no-mlock` turns it off).
    pub lock_memory: bool,
    /// Stop after this many seconds of wall time; with a scenario, the scenario's end in
    /// simulated time (`--duration`; `None`: until [`LiveRun::stop`] or the scenario ends).
    pub duration_s: Option<f64>,
    /// Inject this scenario's timeline into axis 0; its machine replaces preset and sets
    /// (`--scenario FILE`, read by the caller: `crate::scenario::load`).
    pub scenario: Option<Scenario>,
    /// Record the drives' samples as CSV (`--trace FILE`; several axes: one file each).
    pub trace: Option<PathBuf>,
    /// Power-on / reset to boot-up, ms, 0..=60000 (`--boot-delay-ms`, default 200).
    pub boot_delay_ms: u64,
    /// The LSS store memory (`--lss-store FILE`); `None`: a store is kept in memory.
    pub lss_memory: Option<LssMemory>,
    /// Run the backlash detector on the drives' own samples (`--detect`).
    pub detect: bool,
    /// With `detect`: seconds of samples each analysis covers (`--detect-history`, default
    /// 60).
    pub detect_history_s: f64,
    /// Set the stop flag on Ctrl-C / SIGTERM (the command line: true). A process-wide
    /// handler, installed once: default false.
    pub stop_on_signal: bool,
}

impl Default for LiveRequest {
    /// The command line's defaults (`drive-emu run` with no flags), without a signal handler.
    fn default() -> Self {
        Self {
            bus: LiveBusSpec::SocketCan("vcan0".into()),
            node_id: DEFAULT_NODE_ID,
            force_lss: false,
            preset: "cnc1".into(),
            sets: Vec::new(),
            worn: false,
            machine_file: None,
            eds: None,
            objects_base: None,
            profile: None,
            quirks: Vec::new(),
            no_quirks: Vec::new(),
            tick_hz: DEFAULT_TICK_HZ,
            lockstep: false,
            sync_period_us: None,
            rt_priority: DEFAULT_RT_PRIORITY,
            cpu: None,
            lock_memory: true,
            duration_s: None,
            scenario: None,
            trace: None,
            boot_delay_ms: DEFAULT_BOOT_DELAY_MS,
            lss_memory: None,
            detect: false,
            detect_history_s: DEFAULT_DETECT_HISTORY_S,
            stop_on_signal: false,
        }
    }
}

/// What runs in the loop thread after every tick, once it is published and a scenario's
/// injections are applied: no allocation, lock or I/O (the real-time path).
pub trait TickHook: Send {
    fn on_tick(&mut self, rt: &mut Runtime<LiveBus, AxisDrive>);
}

/// What a caller of [`LiveRequest::start_with`] gets to attach its own readers and loop hook
/// (the command line's panel and LSS store service): the run's observation bus, the scenario's
/// link and injector (a panel takes the injector into its own), the machine.
pub struct Attach<'a> {
    pub obs: &'a Arc<Observation>,
    pub link: &'a Arc<LiveLink>,
    pub injector: &'a mut Option<LoopInjector>,
    pub machine: &'a MachineFile,
    pub scenario: Option<&'a Scenario>,
    /// The socketcand server's address, if that is the bus.
    pub socketcand: Option<SocketAddr>,
}

/// A running live run: stop it, watch it (its observation bus), wait for its outcome.
pub struct LiveRun {
    stop: Arc<AtomicBool>,
    booted: Arc<AtomicBool>,
    obs: Arc<Observation>,
    machine: MachineFile,
    label: String,
    socketcand: Option<SocketAddr>,
    lockstep: Option<Lockstep>,
    wear_at_boot: Vec<Option<String>>,
    loop_thread: JoinHandle<Runtime<LiveBus, AxisDrive>>,
    readers: parts::Readers,
    scenario_thread: Option<JoinHandle<ScenarioOutcome>>,
}

/// What a live run found: what the command line prints at its end.
#[derive(Debug)]
pub struct LiveOutcome {
    /// The loop's statistics (ticks, overruns, SYNC, frames).
    pub stats: StatsSummary,
    /// `--trace`: the files, samples written and ticks lost.
    pub trace: Option<TraceSummary>,
    /// `--detect`: per axis, its node ID and the detector's last analysis.
    pub detector: Vec<(u8, Option<DetectorReport>)>,
    /// `--detect`: ticks the detector lost (it fell more than the observation ring behind).
    pub detector_lost: u64,
    /// Lock-step: simulated time per SYNC in force at the end, us.
    pub lockstep_period_us: Option<u64>,
    /// Lock-step: ticks run on the drive's own clock while SYNC was missing.
    pub free_run_ticks: u64,
    /// With a scenario: its outcome (events, EMCYs, expectations, samples and samples lost).
    pub scenario: Option<ScenarioOutcome>,
}

impl LiveRequest {
    /// Start the run with nothing attached: [`start_with`](Self::start_with).
    pub fn start(self) -> Result<LiveRun, ApiError> {
        self.start_with(|_| Ok(None))
    }

    /// Start the run: the request checked (an error names the flag: [`ApiError::Invalid`],
    /// or [`ApiError::Unreadable`] for an input file that cannot be read), the machine built,
    /// the bus opened, the readers started (a bad `--trace` path loses nothing), then `attach`
    /// called (its error, e.g. a panel that cannot bind, is [`ApiError::Failed`] with its
    /// chain kept), then the scenario thread and the loop thread. The loop runs after every
    /// tick: publish, the scenario's injections, `attach`'s hook, the detector's results.
    pub fn start_with(
        self,
        attach: impl FnOnce(Attach<'_>) -> anyhow::Result<Option<Box<dyn TickHook>>>,
    ) -> Result<LiveRun, ApiError> {
        self.check()?;
        let (machine, axes) = setup::live_axes(&self)?;
        let req = self;
        let (bus, socketcand, label) = parts::open_bus(req.bus, req.scenario.as_ref())?;
        // The bus is the runtime's now (an in-process endpoint moved into it); the request
        // keeps only its name, which nothing after this point reads.
        let req = LiveRequest {
            bus: LiveBusSpec::SocketCan(label.clone()),
            ..req
        };
        let scenario = req.scenario.as_ref();
        let rt = Runtime::new(bus, axes, 1_000_000 / u64::from(machine.tick_hz));
        let stop = parts::stop_flag(&req).map_err(ApiError::Failed)?;
        // The observation bus: the loop publishes every tick into it; the trace recorder, the
        // detector, the scenario thread, the status line and the panel read it.
        let (observer, obs) = crate::observe::channel(
            rt.axes.len(),
            crate::observe::run_ring_capacity(machine.tick_hz),
        );
        let lockstep = parts::lockstep_of(&req);
        let readers = parts::start_readers(
            &req,
            &obs,
            rt.axes.iter().map(|a| (a.node.node_id(), &a.drive)),
            parts::gap_models(&machine, scenario),
        )
        .map_err(ApiError::Failed)?;
        parts::announce(&req, &label, &machine, lockstep.as_ref());
        // The scenario thread follows the loop's time and feeds it injections.
        let link = Arc::new(LiveLink::new());
        let mut injector = scenario.map(|s| LoopInjector::new(s.run.master.master_id));
        let hook = attach(Attach {
            obs: &obs,
            link: &link,
            injector: &mut injector,
            machine: &machine,
            scenario,
            socketcand,
        })
        .map_err(ApiError::Failed)?;
        let scenario_thread = match scenario {
            Some(s) => Some(parts::spawn_scenario(&req, s, (&link, &obs), &stop)?),
            None => None,
        };
        let wear_at_boot = rt
            .axes
            .iter()
            .map(|a| {
                use drive_protocol::Drive as _;
                let gap = a.drive.param(crate::drive::objects::AxisParam::Backlash);
                crate::drive::machine::wear_text(gap, a.drive.info().rotary)
            })
            .collect();
        let booted = Arc::new(AtomicBool::new(false));
        let loop_thread = parts::spawn_loop(parts::LoopParts {
            rt,
            request: parts::realtime_request(&req),
            lockstep,
            stop: Arc::clone(&stop),
            booted: Arc::clone(&booted),
            observer,
            injections: parts::LoopInjections {
                link,
                injector,
                hook,
                detect: readers.detect.clone(),
            },
        })
        .map_err(ApiError::Failed)?;
        Ok(LiveRun {
            stop,
            booted,
            obs,
            machine,
            label,
            socketcand,
            lockstep,
            wear_at_boot,
            loop_thread,
            readers,
            scenario_thread,
        })
    }
}

impl LiveRun {
    /// Ask the run to stop (the loop ends at its next tick; a scenario still running ends).
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    /// The stop flag: set by [`stop`](Self::stop), `duration_s`, a scenario's end, a signal.
    pub fn stop_flag(&self) -> &Arc<AtomicBool> {
        &self.stop
    }

    /// The loop thread has ended (stopped, or panicked).
    pub fn is_finished(&self) -> bool {
        self.loop_thread.is_finished()
    }

    /// Every node has sent its boot-up (the power-on boot delay is over).
    pub fn booted(&self) -> bool {
        self.booted.load(Ordering::Acquire)
    }

    /// The run's observation bus: a reader of its own follows every tick (status line, tests).
    pub fn observation(&self) -> &Arc<Observation> {
        &self.obs
    }

    /// The machine served (its axes' node IDs, presets, vendor files, objects bases).
    pub fn machine(&self) -> &MachineFile {
        &self.machine
    }

    /// The bus, for people: the interface, `socketcand ADDR:PORT` with the port it got, or
    /// `in-process`.
    pub fn bus_label(&self) -> &str {
        &self.label
    }

    /// The socketcand server's address, if that is the bus.
    pub fn socketcand_addr(&self) -> Option<SocketAddr> {
        self.socketcand
    }

    /// Lock-step: its configuration.
    pub fn lockstep(&self) -> Option<&Lockstep> {
        self.lockstep.as_ref()
    }

    /// Each axis's wear at power-on (`backlash 0.03 mm`; `None`: healthy).
    pub fn wear_at_boot(&self) -> &[Option<String>] {
        &self.wear_at_boot
    }

    /// Wait for the run to end (its stop flag: [`stop`](Self::stop), `duration_s`, the
    /// scenario's end, a signal), then end the readers (the trace flushed whatever happened
    /// to the loop) and the scenario thread, and sum up (said on stderr, as the command line
    /// does). A thread that panicked is [`ApiError::Failed`].
    pub fn wait(self) -> Result<LiveOutcome, ApiError> {
        let joined = self.loop_thread.join();
        // a loop that ended on its own (it panicked) still ends the scenario
        self.stop.store(true, Ordering::Relaxed);
        let readers = self.readers.finish().map_err(ApiError::Failed)?;
        let rt =
            joined.map_err(|_| ApiError::Failed(anyhow::anyhow!("the loop thread panicked")))?;
        let scenario = parts::join_scenario(self.scenario_thread).map_err(ApiError::Failed)?;
        Ok(parts::live_summary(
            &rt,
            self.lockstep.is_some(),
            readers,
            scenario,
        ))
    }
}

/// The transport under a live run's fault injector: the command line's (SocketCAN,
/// socketcand), or an in-process endpoint.
pub use crate::bus::live::LiveTransport as LiveCan;

/// The live bus: the transport behind the scenario's fault injector.
pub type LiveBus = FaultyBus<LiveCan>;
