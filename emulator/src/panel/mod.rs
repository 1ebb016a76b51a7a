//! The live panel of `drive-emu run --panel [ADDR]`: a page served by the process itself (its
//! assets inside the binary) that shows every axis live and injects wear and faults into
//! axis 0 through the path live scenarios use. docs/panel.md describes the stream and the API.
//!
//! Threads: the loop publishes into the observation bus ([`crate::observe`], whose reader the
//! panel is) and applies the panel's queued injections ([`PanelLoop::on_tick`]); it never
//! waits for the panel. The
//! panel has two threads of its own: the HTTP server (a single-threaded tokio runtime, axum)
//! and the collector ([`stream`]), which follows the fan-out, builds the stream's messages
//! once for every client, runs the spectrum and the detector, writes recordings and logs the
//! injections the loop applied. A slow client loses messages (it is told how many), never the
//! loop a tick.
//!
//! - [`auth`]: the token and the loopback rule;
//! - [`assets`]: the page, its script and the vendored plotting library;
//! - [`control`]: injections (validated as scenario events) and the session saved as a
//!   scenario file;
//! - [`record`]: recordings (CSV as `run --trace`, candump -L capture for `drive-emu analyze`);
//! - [`server`]: the HTTP routes;
//! - [`stream`]: the collector and the messages.

pub mod assets;
pub mod auth;
pub mod control;
pub mod history;
pub mod rate;
pub mod record;
pub mod server;
pub mod stream;

use crate::bus::fault::FaultyBus;
use crate::bus::CanBus;
use crate::drive::axis_drive::AxisDrive;
use crate::observe::Observation;
use crate::presets::AxisConfig;
use crate::runtime::Runtime;
use crate::scenario::live::{LiveLink, LoopInjector};
use anyhow::{bail, Context, Result};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

/// Where the panel listens when `--panel` is given without an address.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8080";

/// The panel's command-line options (flattened into `run`'s).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct PanelArgs {
    /// Serve the live panel (a page with every axis's state and plots, and injection controls)
    /// on ADDR, default 127.0.0.1:8080; docs/panel.md. An address that is not loopback needs
    /// --panel-token.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_ADDR)]
    pub panel: Option<String>,
    /// The panel's token: required on every write and on the stream (header
    /// `Authorization: Bearer TOKEN` or query `?token=TOKEN`); required with a non-loopback
    /// --panel address.
    /// Prefer the environment variable DRIVE_EMU_PANEL_TOKEN or --panel-token-file: an
    /// argument is visible to every user of the machine (`ps`); given here it is warned about.
    #[arg(long, value_name = "TOKEN", requires = "panel")]
    pub panel_token: Option<String>,
    /// Read the panel's token from the first line of FILE (instead of --panel-token).
    #[arg(long, value_name = "FILE", requires = "panel")]
    pub panel_token_file: Option<PathBuf>,
    /// Directory for the panel's recordings (default: a new private directory with a random
    /// name under the system's temporary directory). Made with mode 0700 if absent; an
    /// existing one must be this user's and writable by no one else.
    #[arg(long, value_name = "DIR", requires = "panel")]
    pub panel_dir: Option<PathBuf>,
}

/// The address to bind: `addr` parsed, and refused when it is not loopback and no token is
/// given (anyone who reaches the port could inject faults into the drive).
pub fn check_bind(addr: &str, token: Option<&str>) -> Result<SocketAddr> {
    let sa: SocketAddr = addr.trim().parse().with_context(|| {
        format!("--panel {addr}: not an address with a port, e.g. 127.0.0.1:8080 or [::1]:8080")
    })?;
    if let Some(t) = token {
        auth::check_token_text(t)?;
    }
    if !sa.ip().is_loopback() && token.is_none() {
        bail!(
            "--panel {addr}: {} is not a loopback address; anyone who reaches it could inject \
             faults into the drive: give --panel-token TOKEN (then every write and the stream \
             need it), or bind 127.0.0.1",
            sa.ip()
        );
    }
    Ok(sa)
}

/// The panel's token from its one source (`--panel-token-file`, `DRIVE_EMU_PANEL_TOKEN`,
/// `--panel-token`), when the panel is asked for.
pub fn token(args: &PanelArgs) -> Result<Option<(String, auth::TokenSource)>> {
    if args.panel.is_none() {
        return Ok(None);
    }
    auth::resolve_token(
        args.panel_token.as_deref(),
        args.panel_token_file.as_deref(),
        std::env::var_os(auth::TOKEN_ENV),
    )
}

/// The panel's options checked before anything opens (the CAN interface, the port): a
/// non-loopback address without a token is refused at start; a token on the command line is
/// warned about.
pub fn check_args(args: &PanelArgs) -> Result<()> {
    if let Some(addr) = &args.panel {
        let t = token(args)?;
        if matches!(t, Some((_, auth::TokenSource::CommandLine))) {
            eprintln!("{}", auth::COMMAND_LINE_WARNING);
        }
        check_bind(addr, t.as_ref().map(|(t, _)| t.as_str()))?;
    }
    Ok(())
}

/// One axis as the panel shows it.
#[derive(Debug, Clone)]
pub struct PanelAxis {
    pub node_id: u8,
    pub preset: String,
    /// The axis's configuration (preset with the overrides applied).
    pub config: AxisConfig,
    /// The overrides as written (`--set`, machine file, scenario `[machine]`): key, TOML value
    /// text. A saved session repeats them in its `[machine]` table.
    pub overrides: Vec<(String, String)>,
}

/// The fieldbus of the run: which bus faults the panel offers (a CAN run's `can`, an
/// EtherCAT run's `ethercat`, as in a scenario file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PanelBus {
    #[default]
    Can,
    Ethercat,
}

impl PanelBus {
    /// The scenario file's key for this bus's faults.
    pub fn key(self) -> &'static str {
        match self {
            PanelBus::Can => "can",
            PanelBus::Ethercat => "ethercat",
        }
    }
}

/// What the panel needs to know of the run.
#[derive(Debug, Clone)]
pub struct PanelSetup {
    pub axes: Vec<PanelAxis>,
    /// The run's fieldbus.
    pub bus: PanelBus,
    /// The CAN interface (the capture of a recording reads it); `None`: no capture (an
    /// in-process bus).
    pub iface: Option<String>,
    pub tick_hz: u32,
    pub lockstep: bool,
    /// The node ID whose heartbeat a heartbeat-loss injection drops, until the drive's
    /// heartbeat consumer (0x1016:1) names another.
    pub master_id: u8,
    /// Injections are logged on stdout as JSON lines (`run --json`), not as text.
    pub json_stdout: bool,
}

/// The panel, running: its threads and what they share.
pub struct Panel {
    shared: Arc<server::Shared>,
    server: Option<JoinHandle<()>>,
    collector: Option<JoinHandle<()>>,
    pub addr: SocketAddr,
}

/// The loop's half of the panel: the injector of the panel's (and a live scenario's)
/// injections. Called once per tick, after the loop published the tick; real-time safe.
pub struct PanelLoop {
    injector: LoopInjector,
    link: Arc<LiveLink>,
    scenario: Option<Arc<LiveLink>>,
    /// The master ID was given by a scenario (its `[master]`): keep it.
    master_fixed: bool,
    ticks: u64,
}

impl PanelLoop {
    /// A live scenario on the same loop: its injections go through this injector (one list of
    /// CAN rules for both).
    pub fn attach_scenario(&mut self, link: Arc<LiveLink>, master_id: u8) {
        self.scenario = Some(link);
        self.injector.set_master_id(master_id);
        self.master_fixed = true;
    }

    /// After every tick (once the observation bus has it): apply the scenario's and the
    /// panel's injections to axis 0.
    pub fn on_tick<B: CanBus>(&mut self, rt: &mut Runtime<FaultyBus<B>, AxisDrive>) {
        if !self.master_fixed && self.ticks.is_multiple_of(256) {
            // The master a heartbeat-loss fault silences: the one the drive consumes.
            let hb = rt.axes[0].node.object_raw(0x1016, 1).unwrap_or(0);
            let id = ((hb >> 16) & 0x7F) as u8;
            if id != 0 {
                self.injector.set_master_id(id);
            }
        }
        self.ticks += 1;
        if let Some(link) = &self.scenario {
            self.injector.on_tick(link, rt);
        }
        self.link.now_us.store(rt.sim_time_us, Ordering::Relaxed);
        self.injector.apply_queued(&self.link, rt);
    }
}

impl PanelLoop {
    /// After every drive cycle of `run --ethercat` at simulated time `now_us` (once the
    /// observation bus has it): apply the scenario's and the panel's injections to the first
    /// slave, its drive and the port's faults. Real-time safe, as [`PanelLoop::on_tick`].
    pub fn on_ethercat_cycle(
        &mut self,
        seg: &mut drive_ethercat::Segment,
        drives: &mut [AxisDrive],
        faults: &mut crate::bus::ethercat::EcatFaults,
        now_us: u64,
    ) {
        self.ticks += 1;
        let (Some(slave), Some(drive)) = (seg.slaves.first_mut(), drives.first_mut()) else {
            return;
        };
        if let Some(link) = &self.scenario {
            self.injector
                .on_ethercat_cycle(link, now_us, slave, drive, faults);
        }
        self.link.now_us.store(now_us, Ordering::Relaxed);
        self.injector
            .apply_queued_ethercat(&self.link, now_us, slave, drive, faults);
    }
}

/// What the panel needs of a live run's options.
pub struct RunContext<'a> {
    pub bus: PanelBus,
    /// The CAN interface; `None`: the bus is not one (socketcand).
    pub iface: Option<&'a str>,
    /// The node ID a scenario's axis gets (`--node`).
    pub node: u8,
    pub lockstep: bool,
    /// `--json`: injections logged as JSON lines.
    pub json: bool,
    pub machine: &'a crate::drive::machine::MachineFile,
    pub scenario: Option<&'a crate::scenario::Scenario>,
}

/// `run --panel`: the panel of a live run (`drive-emu run`, `scenario --iface`), started when
/// the options ask for it, with the machine's axes; a live scenario's injections (`link`,
/// `injector`) move into the panel's loop half; it reads the run's observation bus `obs`.
/// Says where it listens on stderr.
pub fn start_for_run(
    args: &PanelArgs,
    run: RunContext<'_>,
    (link, obs): (&Arc<LiveLink>, &Arc<Observation>),
    injector: &mut Option<LoopInjector>,
) -> Result<Option<(Panel, PanelLoop)>> {
    if args.panel.is_none() {
        return Ok(None);
    }
    let RunContext {
        bus,
        iface,
        node,
        lockstep,
        json,
        machine,
        scenario,
    } = run;
    let axes = match scenario {
        Some(s) => vec![PanelAxis {
            node_id: node,
            preset: s.machine.presets[0].clone(),
            config: s.machine.configs[0].clone(),
            overrides: s.machine.overrides.clone(),
        }],
        None => machine
            .axes
            .iter()
            .map(|e| {
                let mut cfg = AxisConfig::from_preset(&e.preset)
                    .map_err(|err| anyhow::anyhow!("axis node {}: {err}", e.node_id))?;
                let mut overrides = Vec::new();
                for (k, v) in &e.set {
                    let text = crate::drive::machine::value_text(v);
                    cfg = cfg
                        .with_override(k, &text)
                        .map_err(|err| anyhow::anyhow!("axis node {}: {err}", e.node_id))?;
                    overrides.push((k.clone(), v.to_string()));
                }
                Ok(PanelAxis {
                    node_id: e.node_id,
                    preset: e.preset.clone(),
                    config: cfg,
                    overrides,
                })
            })
            .collect::<Result<Vec<_>>>()?,
    };
    let setup = PanelSetup {
        axes,
        bus,
        iface: iface.map(str::to_string),
        tick_hz: machine.tick_hz,
        lockstep,
        master_id: scenario.map_or(crate::master::MasterConfig::default().master_id, |s| {
            s.run.master.master_id
        }),
        json_stdout: json,
    };
    let started = start(args, setup, Arc::clone(obs))?;
    if let Some((panel, mut panel_loop)) = started {
        if let (Some(s), Some(_)) = (scenario, injector.take()) {
            panel_loop.attach_scenario(Arc::clone(link), s.run.master.master_id);
        }
        eprintln!(
            "drive-emu: panel on {}{}",
            panel.url(),
            if panel.shared.auth.required() {
                " (token required: ?token=TOKEN)"
            } else {
                ""
            }
        );
        return Ok(Some((panel, panel_loop)));
    }
    Ok(None)
}

/// Start the panel when `args.panel` asks for it: the address checked and bound (an error here
/// comes before the loop starts), the server and the collector (a reader of `obs`, one ring
/// per axis of `setup`) started. Returns the panel and the loop's half.
pub fn start(
    args: &PanelArgs,
    setup: PanelSetup,
    obs: Arc<Observation>,
) -> Result<Option<(Panel, PanelLoop)>> {
    let Some(addr) = &args.panel else {
        return Ok(None);
    };
    let tok = token(args)?.map(|(t, _)| t);
    let sa = check_bind(addr, tok.as_deref())?;
    let listener = std::net::TcpListener::bind(sa)
        .with_context(|| format!("--panel {addr}: cannot listen there"))?;
    let dir = match &args.panel_dir {
        Some(d) => record::RecordDir::named(d)?,
        None => record::RecordDir::private_in(&std::env::temp_dir())?,
    };
    start_with(listener, tok, dir, setup, obs).map(Some)
}

/// Start the panel on a bound listener (tests bind port 0), recordings in `record_dir` (as
/// `--panel-dir`: made 0700 when absent, else it must be private to this user).
pub fn start_on(
    listener: std::net::TcpListener,
    token: Option<String>,
    record_dir: PathBuf,
    setup: PanelSetup,
    obs: Arc<Observation>,
) -> Result<(Panel, PanelLoop)> {
    start_with(
        listener,
        token,
        record::RecordDir::named(&record_dir)?,
        setup,
        obs,
    )
}

fn start_with(
    listener: std::net::TcpListener,
    token: Option<String>,
    record_dir: record::RecordDir,
    setup: PanelSetup,
    observation: Arc<Observation>,
) -> Result<(Panel, PanelLoop)> {
    if setup.axes.is_empty() {
        bail!("the panel needs at least one axis");
    }
    if observation.rings.len() != setup.axes.len() {
        bail!(
            "the panel has {} axes, the observation bus {}",
            setup.axes.len(),
            observation.rings.len()
        );
    }
    let addr = listener.local_addr()?;
    let link = Arc::new(LiveLink::new());
    let controls = control::Controls::new(&setup)?;
    let shared = Arc::new(server::Shared::new(
        auth::Auth::new(token),
        setup.clone(),
        controls,
        observation,
        Arc::clone(&link),
        record_dir,
    ));
    let server = server::spawn(listener, Arc::clone(&shared))?;
    let collector = stream::spawn(Arc::clone(&shared))?;
    let injector = LoopInjector::new(setup.master_id);
    Ok((
        Panel {
            shared,
            server: Some(server),
            collector: Some(collector),
            addr,
        },
        PanelLoop {
            injector,
            link,
            scenario: None,
            master_fixed: false,
            ticks: 0,
        },
    ))
}

impl Panel {
    /// Stream clients connected now.
    pub fn clients(&self) -> usize {
        self.shared.client_count()
    }

    /// The URL of the page (with the token, if any, for people to open).
    pub fn url(&self) -> String {
        let host = match self.addr {
            SocketAddr::V6(a) => format!("[{}]:{}", a.ip(), a.port()),
            SocketAddr::V4(a) => a.to_string(),
        };
        format!("http://{host}/")
    }

    /// Stop: close every stream, finish a recording in progress, end both threads.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        let _ = self.shared.shutdown_tx.send(true);
        if let Some(t) = self.collector.take() {
            let _ = t.join();
        }
        if let Some(t) = self.server.take() {
            let _ = t.join();
        }
        self.shared.finish_recording();
        self.shared.record_dir.remove_if_empty();
    }

    /// The recording directory.
    pub fn record_dir(&self) -> &std::path::Path {
        &self.shared.record_dir.path
    }

    /// Change the recording caps (tests make them small).
    pub fn set_record_limits(&self, limits: record::RecordLimits) {
        if let Ok(mut l) = self.shared.record_limits.lock() {
            *l = limits;
        }
    }
}

impl Drop for Panel {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Whether the panel was asked to stop.
pub(crate) fn stopping(stop: &AtomicBool) -> bool {
    stop.load(Ordering::Acquire)
}
