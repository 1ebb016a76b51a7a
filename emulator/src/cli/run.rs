//! `drive-emu run`: the drive(s) on a real or virtual CAN bus, at a fixed rate.

use crate::bus::fault::FaultyBus;
use crate::bus::live::LiveTransport;
use crate::bus::socketcand::SocketcandBus;
use crate::drive::axis_drive::AxisDrive;
use crate::drive::machine::{self, AxisEntry, MachineFile};
use crate::drive::vendor::{self, VendorEds};
use crate::drive::{node_setup, NodeOptions};
use crate::monitor::{AxisFacts, DetectOptions, DetectResults, Detector};
use crate::observe::trace::Recorder;
use crate::observe::{AxisSnapshot, Observation, Observer};
use crate::presets::AxisConfig;
use crate::runtime::realtime::{self, RealtimeRequest};
use crate::runtime::trace::trace_paths;
use crate::runtime::{AxisSlot, Lockstep, Runtime};
use crate::scenario::live::{run_timeline, LiveEnd, LiveLink, LiveOutcome, LoopInjector};
use crate::scenario::Scenario;
use crate::time::MonotonicClock;
use anyhow::{bail, Context, Result};
use clap::Args;
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;

#[derive(Args, Debug, Clone)]
pub struct RunArgs {
    /// CAN interface (can0, vcan0, ...).
    #[arg(long, default_value = "vcan0")]
    pub iface: String,
    /// Serve the bus over TCP in the socketcand protocol on ADDR:PORT instead of a CAN
    /// interface (port 0: any free port, printed on stderr and in the ready line), for
    /// python-can's `socketcand` interface (channel can0) and other socketcand clients: no
    /// kernel CAN needed. Several clients share the bus. See docs/socketcand.md.
    #[arg(long, value_name = "ADDR:PORT", conflicts_with = "iface")]
    pub socketcand: Option<String>,
    /// Node ID of the (single) drive, 1..=127; 255: non-configured, as a drive out of the box:
    /// silent but for LSS (CiA 305) until a master gives it a node-ID. Ignored with --config.
    #[arg(long, default_value_t = 5)]
    pub node: u8,
    /// Serve LSS (CiA 305) even where the vendor's EDS says LSS_Supported=0 or omits it (so
    /// that --node 255 starts non-configured with that file).
    #[arg(long)]
    pub force_lss: bool,
    /// Preset of the (single) axis: cnc1 ... cnc5. Ignored with --config.
    #[arg(long, default_value = "cnc1")]
    pub preset: String,
    /// Override a preset key, e.g. --set backlash_mm=0.05 (repeatable). A gap of its own
    /// (backlash_mm / backlash_deg) is wear, as --worn is.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Serve the preset's worn drive train (its backlash, the paper's machine: a limit cycle
    /// at constant speed, moves that end hunting around the target) instead of the healthy
    /// axis `run` serves by default (no gap: every move ends within the position window). With
    /// --config: every axis, as `worn = true` in the file.
    #[arg(long)]
    pub worn: bool,
    /// Machine file with several axes (docs/master.md, "Several axes in one process"); replaces --node/--preset/--set/--eds.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Serve this vendor's EDS or DCF as the drive's own: its identity, device type, PDO
    /// defaults and COB-IDs, every object it has (the CiA 301/402 ones simulated, the rest
    /// stored), the modes of its 0x6502 that the emulator runs; the motor encoder takes its
    /// 0x608F resolution. The axis behind it is still --preset's. What became of each object:
    /// `drive-emu eds --from FILE`.
    #[arg(long, value_name = "FILE")]
    pub eds: Option<PathBuf>,
    /// First index of the emulator's own objects (axis parameters at +0x00..0x0E, loop
    /// statistics at +0x100, fault injection at +0x101), e.g. 0x4000. Default 0x2000, or
    /// with --eds the first free base of 0x2000, 0x3000, 0x4000, 0x5000, ...
    #[arg(long, value_name = "INDEX", value_parser = parse_index)]
    pub objects_base: Option<u16>,
    /// Behave like a vendor's drive (docs/quirks.md): a profile of `drive-emu profiles`
    /// (nanotec-pd4c, maxon-epos4, ..., strict) or a path to a .toml profile. Sets vendor
    /// switches, and its [identity] (boot delays; with --eds the EDS is the identity).
    #[arg(long, value_name = "NAME|PATH")]
    pub profile: Option<String>,
    /// Turn a vendor switch on, with a parameter: --quirk sdo_response_delay.delay_ms=30
    /// (repeatable, applied after --profile; `drive-emu profiles` lists them).
    #[arg(long = "quirk", value_name = "NAME[.PARAM=VALUE]")]
    pub quirk: Vec<String>,
    /// Turn a vendor switch off (repeatable, applied after --profile).
    #[arg(long = "no-quirk", value_name = "NAME")]
    pub no_quirk: Vec<String>,
    /// Loop rate, Hz (250..8000).
    #[arg(long, default_value_t = 1000)]
    pub tick_hz: u32,
    /// Lock-step: simulated time advances by --sync-period-us at each SYNC received, not by
    /// the wall clock.
    #[arg(long)]
    pub lockstep: bool,
    /// Lock-step: simulated time per SYNC, us. Default: the communication cycle period 0x1006
    /// once the master writes it, else the interpolation time period 0x60C2 once written, else
    /// 1000.
    #[arg(long, value_name = "US", value_parser = clap::value_parser!(u64).range(100..=1_000_000))]
    pub sync_period_us: Option<u64>,
    /// SCHED_FIFO priority for the loop thread (needs CAP_SYS_NICE); 0 = normal scheduling.
    #[arg(long, default_value_t = 80)]
    pub rt_priority: i32,
    /// Pin the loop thread to this CPU.
    #[arg(long)]
    pub cpu: Option<usize>,
    /// Do not lock memory (mlockall).
    #[arg(long)]
    pub no_mlock: bool,
    /// Stop after this many seconds (default: until Ctrl-C / SIGTERM). With --scenario: the
    /// scenario's end in the drive's simulated time (in lock-step, SYNC periods).
    #[arg(long, value_name = "S", value_parser = positive_seconds)]
    pub duration: Option<f64>,
    /// Print only JSON on stdout (loop statistics and, with --scenario, events, EMCYs, detector
    /// and expectations); everything else goes to stderr.
    #[arg(long)]
    pub json: bool,
    /// Inject this scenario's timeline (wear, faults) into the running drive; the machine comes
    /// from the scenario file, the motion from your controller. Ends at --duration, else at the
    /// file's `duration`, else once every event has fired and run its course. In lock-step, a
    /// SYNC missing for 1 s of wall time hands the drive's clock to the wall clock (as a real
    /// drive's), so SYNC supervision fires and the run ends.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Record what the drive reports, one row per tick (the sample-log CSV that `drive-emu
    /// analyze` reads), written as the run goes and flushed on exit, Ctrl-C or SIGTERM. With
    /// several axes, one file each: trace.csv -> trace-node5.csv, ...
    #[arg(long, value_name = "FILE")]
    pub trace: Option<PathBuf>,
    /// Time from power-on or an NMT reset (node or communication) to the boot-up message, ms,
    /// as on a real drive; long enough for a master that sends the reset and then starts
    /// waiting for the boot-up (python canopen's `wait_for_bootup`). In lock-step it passes on
    /// the wall clock. 0 = at once.
    #[arg(long, default_value_t = DEFAULT_BOOT_DELAY_MS, value_parser = clap::value_parser!(u64).range(0..=60_000))]
    pub boot_delay_ms: u64,
    /// The drive's non-volatile memory for LSS store configuration (one axis): the node-ID and
    /// bit timing a master stores by LSS are written to FILE, and a run with the same FILE
    /// boots with them instead of --node (FILE is created at the first store). Without it a
    /// store is kept in memory: an NMT reset node loads it, a new run does not.
    #[arg(long, value_name = "FILE")]
    pub lss_store: Option<PathBuf>,
    /// Print one JSON line on stdout once every drive has sent its boot-up:
    /// `{"event":"ready","iface":..,"nodes":[{"node_id":5,"preset":"cnc1"}],"pid":..,...}`
    /// (for scripts and test fixtures; with --json the statistics follow at exit).
    #[arg(long)]
    pub ready: bool,
    /// Serve the run's drives as EtherCAT CoE slaves on this Ethernet interface (AF_PACKET,
    /// EtherType 0x88A4; a veth end, a TAP or a NIC; needs CAP_NET_RAW) instead of CAN: one
    /// slave per axis in machine-file order, as on a line. With --lockstep the drives' time
    /// advances one tick per process-data frame (LRD/LWR/LRW); --trace, --detect,
    /// --scenario and --panel as on CAN (with EtherCAT's faults).
    #[arg(long, value_name = "IFACE")]
    pub ethercat: Option<String>,
    /// With --ethercat: serve this vendor's ESI XML (ETG.2000) as the slave's own, as --eds
    /// serves an EDS on CAN: the identity of its first device in the SII and 0x1018, its
    /// RxPdo / TxPdo as the default mappings 0x1600.. / 0x1A00.. and assignment 0x1C12 /
    /// 0x1C13 (each entry an object of the drive), its names in the SII (docs/ethercat.md).
    #[arg(long, value_name = "FILE")]
    pub esi: Option<PathBuf>,
    #[command(flatten)]
    pub panel: crate::panel::PanelArgs,
    /// Watch the axis: run the backlash detector on the drive's own samples while it runs (a
    /// thread of its own; the loop hands it the samples through a lock-free queue), publish
    /// its verdict, frequency and amplitude in the drive's objects (0x2102: 1 verdict U8 0 none
    /// yet / 1 inconclusive / 2 ok / 3 suspected / 4 backlash, 2 frequency_hz REAL32, 3
    /// amplitude_um REAL32, 4 kv_per_s REAL32, 5 analyses U32; mappable to a TPDO), and send
    /// EMCY 0xFF01 (manufacturer-specific warning: the drive keeps running) when backlash is
    /// confirmed. Each analysis covers the last --detect-history seconds; the last one, over
    /// the whole history, is printed when the run stops.
    #[arg(long)]
    pub detect: bool,
    /// With --detect: seconds of the drive's own samples each analysis covers (the most
    /// recent).
    #[arg(long, value_name = "S", default_value_t = 60.0, value_parser = positive_seconds)]
    pub detect_history: f64,
}

/// Default boot delay, ms: within the 100 ms - seconds real drives take, and long enough that
/// a python master's `nmt.state = 'RESET'` followed by `wait_for_bootup()` sees the boot-up
/// even when the master's host stalls for tens of ms (user-mode Linux, a loaded CI machine).
pub const DEFAULT_BOOT_DELAY_MS: u64 = 200;

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
    if let (true, Some(p)) = (args.lockstep, &args.lss_store) {
        // The store is written between ticks, and lock-step runs no tick without SYNC (a
        // master configuring by LSS sends none): the answer would never come.
        bail!(
            "--lss-store {} and --lockstep: not together (in lock-step the loop stands still \
             without SYNC, and the store is answered from the loop); without --lss-store a \
             store configuration is kept in memory",
            p.display()
        );
    }
    if let (true, Some(p)) = (args.lockstep, args.sync_period_us) {
        let tick_us = 1_000_000 / u64::from(args.tick_hz.max(1));
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

/// On stderr at start: whether the axis is healthy or worn (and how to have the other), and
/// where its position window 0x6067 is tighter than the gap it was asked to have: a move then
/// ends hunting around its target, outside the window, and never sets target reached.
fn say_wear(e: &AxisEntry, ax: &mut AxisSlot<AxisDrive>) {
    use crate::drive::objects::AxisParam;
    use drive_protocol::Drive as _;
    let info = ax.drive.info();
    let gap = ax.drive.param(AxisParam::Backlash);
    let node = e.node_id;
    let Some(wear) = machine::wear_text(gap, info.rotary) else {
        eprintln!(
            "drive-emu: node {node}: a healthy axis (no backlash); the preset's worn drive \
             train, the paper's machine: --worn (or --set backlash_mm=... / backlash_deg=...)"
        );
        return;
    };
    eprintln!(
        "drive-emu: node {node}: WORN: {wear} (a healthy axis: leave out --worn and the gap)"
    );
    let mut read = |index: u16, sub: u8, fallback: u32| {
        let mut b = [0u8; 4];
        match ax.node.read_object(index, sub, &mut b, &mut ax.drive) {
            Ok(n) if n > 0 => u32::from_le_bytes(b),
            _ => fallback,
        }
    };
    let window_uu = read(0x6067, 0, u32::MAX);
    let terms = [
        read(0x608F, 1, info.encoder_increments_per_rev),
        read(0x608F, 2, 1),
        read(0x6091, 1, info.gear_motor_revs),
        read(0x6091, 2, info.gear_shaft_revs),
        read(0x6092, 1, info.feed_user_units),
        read(0x6092, 2, info.feed_shaft_revs),
    ];
    if window_uu == u32::MAX || terms.contains(&0) {
        return; // no window, or off (CiA 402), or no factor to compare with
    }
    let [enc, enc_r, gm, gs, feed, feed_r] = terms.map(f64::from);
    let inc_per_uu = enc / enc_r * (gm / gs) / (feed / feed_r);
    let window_si = f64::from(window_uu) * inc_per_uu / ax.drive.inc_per_load();
    if window_si < gap {
        eprintln!(
            "drive-emu: node {node}: its position window 0x6067 = {window_uu} uu ({}) is \
             tighter than the {wear} asked for: moves end hunting around their target, outside \
             the window, without target reached (statusword bit 10)",
            machine::wear_text(window_si, info.rotary)
                .map_or("0".into(), |t| t.replace("backlash ", ""))
        );
    }
}

/// Build the nodes and drives of a machine.
/// The LSS slave of a live run's axes: what `--lss-store` holds, and the serial number that
/// keeps the LSS address when the node-ID changes.
#[derive(Clone, Copy, Debug, Default)]
pub struct LssOptions {
    /// Power-on bit timing and whether the store goes to the file.
    pub config: drive_protocol::LssConfig,
    /// 0x1018:4 (`None`: the node-ID at power-on).
    pub serial_number: Option<u32>,
    /// `--force-lss`: an LSS slave even where the vendor's EDS has none.
    pub force: bool,
}

/// The axes of a machine, each node with `boot_delay_us` before its boot-up. With a vendor's
/// EDS, what became of its objects is said on stderr, and the entry's `objects_base` is set
/// to where the emulator's own objects went.
pub fn build_axes(
    entries: &mut [AxisEntry],
    boot_delay_us: u64,
    lss: &LssOptions,
) -> Result<Vec<AxisSlot<AxisDrive>>> {
    entries
        .iter_mut()
        .map(|e| {
            // what the user wrote (its message names the axis): exit status 2
            let cfg = e.run_config().map_err(super::exit::usage)?;
            axis_slot(cfg, e, boot_delay_us, lss)
        })
        .collect()
}

/// The node configuration and the simulated drive of one axis (what [`axis_slot`] builds its
/// node from; `run --ethercat` builds an EtherCAT slave from it).
fn axis_setup(
    cfg: AxisConfig,
    e: &mut AxisEntry,
    boot_delay_us: u64,
    lss: &LssOptions,
) -> Result<(drive_protocol::NodeConfig, AxisDrive)> {
    // what the user wrote (preset, overrides, vendor file): exit status 2, or 4 (crate::cli::exit)
    let at = format!("axis node {}", e.node_id);
    let ctx = |err: anyhow::Error| super::exit::config(&at, err);
    let eds = match &e.eds {
        Some(p) => Some(Arc::new(VendorEds::load(p).map_err(ctx)?)),
        None => None,
    };
    let cfg = match &eds {
        Some(v) => v.adapt(cfg).map_err(ctx)?,
        None => cfg,
    };
    let mut drive = AxisDrive::from_config(&cfg).map_err(|err| ctx(err.into()))?;
    let opts = NodeOptions {
        objects_base: e.objects_base,
        eds: eds.clone(),
        lss: lss.config,
        serial_number: lss.serial_number,
        force_lss: lss.force,
        ..NodeOptions::new(e.node_id).with_boot_delay_us(boot_delay_us)
    };
    let opts = NodeOptions {
        quirk_profile: e.quirk_profile.clone(),
        ..opts
    };
    if let Some(b) = &e.quirk_profile {
        eprintln!("{}", b.announce(e.node_id, boot_delay_us / 1000));
    }
    let setup = node_setup(&mut drive, &opts).map_err(ctx)?;
    if let (Some(v), Some(r)) = (&eds, &setup.report) {
        eprint!(
            "drive-emu: node {}: {}",
            e.node_id,
            report_summary(r, setup.objects_base, &v.path)
        );
    }
    e.objects_base = Some(setup.objects_base);
    Ok((setup.config, drive))
}

/// One axis from its configuration and its machine entry (node ID, vendor EDS, objects base),
/// its LSS slave as `lss` says.
fn axis_slot(
    cfg: AxisConfig,
    e: &mut AxisEntry,
    boot_delay_us: u64,
    lss: &LssOptions,
) -> Result<AxisSlot<AxisDrive>> {
    let (config, drive) = axis_setup(cfg, e, boot_delay_us, lss)?;
    let node = drive_protocol::Node::new(config)
        .map_err(|err| anyhow::anyhow!("axis node {}: {err}", e.node_id))?;
    Ok(AxisSlot { node, drive })
}

/// The first line and the notes of a build report (the whole report: `drive-emu eds --from`).
fn report_summary(
    r: &drive_protocol::od::BuildReport,
    base: u16,
    path: &std::path::Path,
) -> String {
    vendor::report_text(r, base, path)
        .lines()
        .filter(|l| !l.starts_with("  0x"))
        .map(|l| format!("{l}\n"))
        .collect()
}

/// An object index as a user writes it: 0x4000, 4000h or 16384.
pub fn parse_index(s: &str) -> Result<u16, String> {
    let t = s.trim();
    let v = if let Some(h) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        u16::from_str_radix(h, 16)
    } else if let Some(h) = t.strip_suffix('h').or_else(|| t.strip_suffix('H')) {
        u16::from_str_radix(h, 16)
    } else {
        t.parse::<u16>()
    };
    let v = v.map_err(|_| format!("`{s}` is not an object index (0x0000..=0xFFFF)"))?;
    if !(0x2000..=0x5F00).contains(&v) {
        return Err(format!(
            "0x{v:04X} is outside the manufacturer area 0x2000..=0x5F00 (CiA 301)"
        ));
    }
    Ok(v)
}

/// The machine described by the command line (one axis) or by --config.
/// Its errors are usage errors (exit status 2: docs/getting-started.md), or 4 where a file
/// cannot be read.
pub fn machine_from_args(args: &RunArgs) -> Result<MachineFile> {
    machine_from_args_inner(args).map_err(super::exit::usage)
}

fn machine_from_args_inner(args: &RunArgs) -> Result<MachineFile> {
    let quirk_profile = crate::drive::quirk_profile::QuirkProfile::from_args(
        args.profile.as_deref(),
        &args.quirk,
        &args.no_quirk,
    )?;
    if let Some(path) = &args.config {
        if quirk_profile.is_some() {
            bail!(
                "--profile / --quirk / --no-quirk with --config {}: set `profile =` and `quirks \
                 = {{...}}` per [[axis]] in the machine file",
                path.display()
            );
        }
        let mut m = machine::load(path)?;
        for a in &mut m.axes {
            a.worn |= args.worn;
        }
        return Ok(m);
    }
    // Said as the user wrote it (machine::validate would name the machine file's key).
    if !(1..=127).contains(&args.node) && args.node != 255 {
        bail!(
            "--node {}: outside 1..=127 (255: non-configured, a drive out of the box that \
             answers LSS only)",
            args.node
        );
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
            name: None,
            preset: args.preset.clone(),
            set,
            worn: args.worn,
            eds: args.eds.clone(),
            objects_base: args.objects_base,
            profile: args.profile.clone(),
            quirks: None,
            quirk_profile: quirk_profile.map(Arc::new),
        }],
        ballbar: None,
        contour: None,
    };
    machine::validate(&m)?;
    Ok(m)
}

/// The LSS store service of one axis between the loop and the watch thread: plain atomics,
/// no locks.
#[derive(Default)]
struct LssSlot {
    /// LSS store configuration to write: 0 none, else `1 << 32 | node_id << 8 | bit timing`.
    lss_store_request: AtomicU64,
    /// Its outcome for the loop: 0 none, 1 written, 2 failed.
    lss_store_result: AtomicU8,
    /// LSS activate bit timing to report: 0 none, else `1 << 32 | index << 16 | delay_ms`.
    lss_activation: AtomicU64,
}

/// The wear an axis runs with now (`backlash 0.03 mm`), `None` on a healthy axis.
fn wear(a: &AxisSnapshot) -> Option<String> {
    machine::wear_text(a.gap_si, a.rotary)
}

/// The watch thread's side of the run: the LSS store service and whether every node booted;
/// what it shows (status line, ready line) it reads from the observation bus.
struct Status {
    axes: Vec<LssSlot>,
    obs: Arc<Observation>,
    /// Each axis's wear at power-on, for the ready line (in lock-step no tick has run then).
    wear_at_boot: Vec<Option<String>>,
    /// Every node has sent its boot-up (power-on boot delay over).
    booted: AtomicBool,
}

/// The loop line of the status block, as the observation bus's board has it.
#[derive(Debug, Default, Clone, Copy)]
struct LoopLine {
    sim_time_us: u64,
    ticks: u64,
    overruns: u64,
    sync_lock: u64,
    sync_phase_error_us: u64,
    rx_overflows: u64,
    link_up: bool,
}

impl LoopLine {
    fn of(obs: &Observation) -> Self {
        let b = &obs.board;
        let ld = |a: &AtomicU64| a.load(Ordering::Relaxed);
        LoopLine {
            sim_time_us: ld(&b.sim_time_us),
            ticks: ld(&b.loop_ticks),
            overruns: ld(&b.overruns),
            sync_lock: ld(&b.sync_lock),
            sync_phase_error_us: ld(&b.sync_phase_error_us),
            rx_overflows: ld(&b.rx_overflows),
            link_up: b.link_up.load(Ordering::Relaxed),
        }
    }
}

impl Status {
    /// After every tick (loop thread): hand LSS store requests and bit timing activations
    /// out to the watch thread, and its store outcomes back to the nodes. Atomics only.
    fn lss_exchange<B: crate::bus::CanBus>(&self, rt: &mut Runtime<B, AxisDrive>) {
        for (a, st) in rt.axes.iter_mut().zip(&self.axes) {
            let n = &mut a.node;
            if let Some(s) = n.take_lss_store() {
                let id = u64::from(s.node_id.unwrap_or(255));
                st.lss_store_request.store(
                    1 << 32 | id << 8 | u64::from(s.bit_timing_index),
                    Ordering::Release,
                );
            }
            match st.lss_store_result.swap(0, Ordering::Acquire) {
                1 => n.lss_store_done(true),
                2 => n.lss_store_done(false),
                _ => {}
            }
            if let Some((index, delay_ms)) = n.take_lss_bit_timing_activation() {
                st.lss_activation.store(
                    1 << 32 | u64::from(index) << 16 | u64::from(delay_ms),
                    Ordering::Release,
                );
            }
        }
    }

    /// Watch thread: write the LSS stores the loop handed out (to `path`; a node asks only
    /// when it has one) and say what the masters did.
    fn lss_service(&self, path: Option<&std::path::Path>) {
        for (k, st) in self.axes.iter().enumerate() {
            let node = self.obs.latest(k).map_or(0, |a| a.node_id);
            let req = st.lss_store_request.swap(0, Ordering::Acquire);
            if req != 0 {
                let s = drive_protocol::LssStore {
                    node_id: Some((req >> 8) as u8).filter(|&n| n != 255),
                    bit_timing_index: req as u8,
                };
                let ok = match path.map(|p| (p, super::lss_store::save(p, &s))) {
                    Some((p, Ok(()))) => {
                        eprintln!(
                            "drive-emu: node {node}: LSS store configuration: node-ID {}, bit \
                             timing {} written to {}",
                            (req >> 8) as u8,
                            super::lss_store::bit_timing_text(s.bit_timing_index),
                            p.display()
                        );
                        true
                    }
                    Some((_, Err(e))) => {
                        eprintln!("drive-emu: node {node}: LSS store configuration failed: {e:#}");
                        false
                    }
                    None => false,
                };
                st.lss_store_result
                    .store(if ok { 1 } else { 2 }, Ordering::Release);
            }
            let act = st.lss_activation.swap(0, Ordering::Acquire);
            if act != 0 {
                eprintln!(
                    "drive-emu: node {node}: LSS activate bit timing {} after {} ms: a real \
                     drive switches its CAN controller then; drive-emu cannot change the \
                     interface's bit rate (set it with `ip link`), it keeps running as before",
                    super::lss_store::bit_timing_text((act >> 16) as u8),
                    act as u16
                );
            }
        }
    }

    fn new(obs: Arc<Observation>, wear_at_boot: Vec<Option<String>>) -> Self {
        Self {
            axes: (0..obs.rings.len()).map(|_| LssSlot::default()).collect(),
            obs,
            wear_at_boot,
            booted: AtomicBool::new(false),
        }
    }

    /// Every axis's newest snapshot (an axis not published yet: a default one).
    fn snapshots(&self) -> Vec<AxisSnapshot> {
        (0..self.axes.len())
            .map(|k| self.obs.latest(k).unwrap_or_default())
            .collect()
    }
}

/// The status block: the loop (time, ticks, overruns, SYNC lock, drops, link), then one line
/// per axis with its node ID, NMT state, CiA 402 state, mode name, position and following
/// error (in user units, uu), and under a worn axis the wear it runs with.
fn status_lines(lp: &LoopLine, axes: &[AxisSnapshot], iface: &str, lockstep: bool) -> Vec<String> {
    let mut head = format!(
        "{iface} t={:.1} s | ticks {} overruns {}",
        lp.sim_time_us as f64 * 1e-6,
        lp.ticks,
        lp.overruns
    );
    if lockstep {
        head += " | lock-step";
    } else {
        head += " | ";
        head += crate::runtime::stats::lock_name(lp.sync_lock as u32);
        if lp.sync_lock == 2 {
            head += &format!(" (phase error {} us)", lp.sync_phase_error_us);
        }
    }
    if lp.rx_overflows > 0 {
        head += &format!(" | rx overflow {}", lp.rx_overflows);
    }
    if !lp.link_up {
        head += " | LINK DOWN";
    }
    let axes = axes.iter().flat_map(|a| {
        let line = format!(
            "node {:<3} {:<15} {:<21} {:<7} pos {} ferr {} uu",
            a.node_id,
            // The heartbeat's 0x00 is the boot-up; the state before it is initialising,
            // or, without a node-ID, waiting for one by LSS.
            if a.nmt == 0 && a.node_id == 255 {
                "UNCONFIGURED"
            } else if a.nmt == 0 {
                "INITIALISING"
            } else {
                crate::master::nmt_name(a.nmt)
            },
            crate::master::state_name(a.sample.statusword),
            crate::master::mode_short(a.sample.mode_display),
            a.sample.position_uu,
            a.sample.following_error_uu,
        );
        // a worn axis: a line of its own under it (the axis line fills 80 columns)
        let wear = wear(a).map(|w| format!("         WORN: {w} (healthy: without --worn)"));
        std::iter::once(line).chain(wear)
    });
    std::iter::once(head).chain(axes).collect()
}

/// Draw the status block on a terminal over the one drawn before (`drawn` lines): up to its
/// first line, then each line cleared and rewritten, cut to `width` characters (a wrapped
/// line would break the redraw). Returns the lines now drawn.
fn redraw(
    out: &mut impl Write,
    drawn: usize,
    lines: &[String],
    width: usize,
) -> std::io::Result<usize> {
    if drawn > 1 {
        write!(out, "\x1b[{}A", drawn - 1)?;
    }
    for (i, l) in lines.iter().enumerate() {
        let cut: String = l.chars().take(width.saturating_sub(1)).collect();
        write!(out, "{}\r\x1b[2K{cut}", if i > 0 { "\n" } else { "" })?;
    }
    out.flush()?;
    Ok(lines.len())
}

/// `--duration`: a positive number of seconds.
pub fn positive_seconds(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v < 1e9 => Ok(v),
        Ok(_) => Err(format!("{s}: a duration in seconds, more than 0")),
        Err(_) => Err(format!("{s}: not a number of seconds")),
    }
}

pub fn run(args: &RunArgs) -> Result<()> {
    if let (Some(p), None) = (&args.esi, &args.ethercat) {
        return Err(super::exit::usage_msg(format!(
            "--esi {}: an ESI describes an EtherCAT slave; it needs --ethercat IFACE (on CAN, \
             serve a vendor's EDS with --eds FILE)",
            crate::quote::text(&p.display().to_string())
        )));
    }
    if let Some(iface) = &args.ethercat {
        return run_ethercat(args, iface);
    }
    let scenario = match &args.scenario {
        Some(path) => Some(crate::scenario::load(path).map_err(super::exit::scenario_file)?),
        None => None,
    };
    let outcome = run_live(args, scenario.as_ref())?;
    if let (Some(o), Some(s)) = (&outcome.scenario, &scenario) {
        if args.json {
            println!(
                "{}",
                serde_json::to_string_pretty(&outcome_json(&outcome, s))?
            );
        } else {
            print_outcome(o);
            println!(
                "{} (live on {}): {}",
                s.name,
                args.bus_label(),
                if o.passed() { "passed" } else { "FAILED" }
            );
        }
        if let Some(why) = o.unfinished() {
            bail!("{why}");
        }
        if !o.passed() {
            bail!("scenario expectations failed");
        }
    } else if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&outcome_json_stats(&outcome))?
        );
    }
    Ok(())
}

/// What `run_live` found: the loop's statistics and, with a scenario, its outcome.
pub struct LiveRun {
    pub stats: crate::runtime::stats::StatsSummary,
    /// With --detect: per axis, its node ID and the detector's last analysis.
    pub detector: Vec<(u8, Option<crate::analysis::detector::DetectorReport>)>,
    /// Lock-step: simulated time per SYNC in force at the end, us.
    pub lockstep_period_us: Option<u64>,
    /// Lock-step: ticks run on the drive's own clock while SYNC was missing.
    pub free_run_ticks: u64,
    pub scenario: Option<LiveOutcome>,
}

fn outcome_json_stats(run: &LiveRun) -> serde_json::Value {
    let mut v = serde_json::json!({
        "stats": run.stats,
        "lockstep_sync_period_us": run.lockstep_period_us,
        "free_run_ticks_without_sync": run.free_run_ticks,
    });
    if !run.detector.is_empty() {
        v["detect"] = serde_json::json!(run
            .detector
            .iter()
            .map(|(node_id, rep)| serde_json::json!({ "node_id": node_id, "report": rep }))
            .collect::<Vec<_>>());
    }
    v
}

/// The JSON document of `run --scenario --json` and `scenario --iface --json`.
pub fn outcome_json(run: &LiveRun, s: &Scenario) -> serde_json::Value {
    let mut v = outcome_json_stats(run);
    if let Some(o) = &run.scenario {
        v["scenario"] = serde_json::json!({
            "name": s.name,
            "passed": o.passed(),
            "finished": o.unfinished().is_none(),
            "failure": o.unfinished(),
            "end_s": o.record.end_us as f64 * 1e-6,
            "end_reason": o.end_reason,
            "events": o.fired.iter().map(|(t, what)| serde_json::json!({
                "t_s": *t as f64 * 1e-6, "event": what })).collect::<Vec<_>>(),
            "events_not_fired": o.not_fired.iter().map(|(line, what)| serde_json::json!({
                "line": line, "event": what })).collect::<Vec<_>>(),
            "emcys": o.record.emcys.iter().map(|(t, c)| serde_json::json!({
                "t_s": *t as f64 * 1e-6, "code": format!("{c:#06X}"),
                "meaning": crate::master::emcy_name(*c) })).collect::<Vec<_>>(),
            "detector": o.detector,
            "expectations": o.expectations,
            "samples": o.record.samples.len(),
            "samples_lost": o.samples_lost,
            "emcys_lost": o.emcys_lost,
        });
    }
    v
}

/// Print what a live scenario run found.
pub fn print_outcome(o: &LiveOutcome) {
    println!("  run {}", o.end_reason);
    for (t, what) in &o.fired {
        println!("  t={:>9.3} s  event: {what}", *t as f64 * 1e-6);
    }
    for (line, what) in &o.not_fired {
        println!("  not fired: line {line}: {what}");
    }
    for (t, code) in &o.record.emcys {
        println!(
            "  t={:>9.3} s  EMCY {code:#06X} ({})",
            *t as f64 * 1e-6,
            crate::master::emcy_name(*code)
        );
    }
    if let Some(d) = o.detector.as_ref().filter(|d| d.inconclusive.is_some()) {
        println!("  detector: {}", inconclusive_text(d));
    } else if let Some(d) = &o.detector {
        println!(
            "  detector: {} | amplitude {:.2} {} | frequency {}",
            d.verdict.as_str(),
            d.amplitude,
            crate::report::unit_text(&d.position_unit),
            d.frequency_hz.map_or("-".into(), |f| format!("{f:.2} Hz"))
        );
    }
    for e in &o.expectations {
        println!("  {e}");
    }
    if let Some(why) = o.unfinished() {
        println!("  FAIL {why}");
    }
    if o.samples_lost > 0 {
        println!(
            "  ({} samples lost: the scenario thread fell more than the observation ring behind)",
            o.samples_lost
        );
    }
    if o.emcys_lost > 0 {
        println!(
            "  ({} EMCYs not recorded: more in one tick than a snapshot carries)",
            o.emcys_lost
        );
    }
}

/// The live bus: the interface or socketcand server behind the scenario's fault injector.
type LiveBus = FaultyBus<LiveTransport>;

impl RunArgs {
    /// What the bus is, for people: the interface, or `socketcand ADDR:PORT`.
    pub fn bus_label(&self) -> String {
        match &self.socketcand {
            Some(addr) => format!("socketcand {addr}"),
            None => self.iface.clone(),
        }
    }
}

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
    bail!(
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
        crate::scenario::check_bus(s, "can").map_err(super::exit::usage)?;
    }
    crate::panel::check_args(&args.panel)?;
    if let Some((s, cfg)) = scenario.and_then(|s| Some((s, s.machine.configs.first()?))) {
        crate::scenario::inject::check_ranges(s, cfg).map_err(super::exit::scenario_file)?;
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
fn realtime_request(args: &RunArgs) -> RealtimeRequest {
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
fn join_scenario(t: Option<std::thread::JoinHandle<LiveOutcome>>) -> Result<Option<LiveOutcome>> {
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
struct Readers {
    recorder: Option<Recorder>,
    detect: Option<Arc<DetectResults>>,
    detector: Option<Detector>,
    node_ids: Vec<u8>,
}

/// Start the readers the options ask for, one axis per (node ID, drive) of `axes`: the trace
/// files are created here, before the loop starts (a bad path loses nothing).
fn start_readers<'a>(
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
    fn finish(self) -> Result<Vec<(u8, Option<crate::analysis::detector::DetectorReport>)>> {
        if let Some(rec) = self.recorder {
            finish_trace(rec)?;
        }
        match self.detector {
            Some(d) => finish_detector(d, &self.node_ids),
            None => Ok(Vec::new()),
        }
    }
}

/// The machine a live run serves and its axes, validated, with the boot delay set: the
/// scenario's machine (its first preset, the file's overrides applied) on `--node`, or the
/// machine file / flags.
fn live_axes(
    args: &RunArgs,
    scenario: Option<&Scenario>,
) -> Result<(MachineFile, Vec<AxisSlot<AxisDrive>>)> {
    let machine = match scenario {
        Some(s) => scenario_machine(args, s)?,
        None => machine_from_args(args)?,
    };
    machine::validate(&machine)?;
    let mut machine = machine;
    let lss = lss_options(args, &mut machine)?;
    let boot_delay_us = args.boot_delay_ms * 1000;
    let axes = match scenario {
        Some(s) => vec![axis_slot(
            s.machine.configs[0].clone(),
            &mut machine.axes[0],
            boot_delay_us,
            &lss,
        )?],
        None => build_axes(&mut machine.axes, boot_delay_us, &lss)?,
    };
    let mut axes = axes;
    for (e, ax) in machine.axes.iter().zip(&mut axes) {
        say_wear(e, ax);
    }
    for ax in &axes {
        if ax.node.node_id() == 255 {
            eprintln!(
                "drive-emu: node-ID 255: non-configured, silent but for LSS (CiA 305, COB-ID \
                 0x7E5) until a master gives it a node-ID"
            );
        }
    }
    Ok((machine, axes))
}

/// The scenario's machine: its first preset with the file's overrides applied, one axis on
/// `--node` (the same on CAN and on EtherCAT).
fn scenario_machine(args: &RunArgs, s: &Scenario) -> Result<MachineFile> {
    let cfg = s
        .machine
        .configs
        .first()
        .context("the scenario has no machine")?;
    Ok(MachineFile {
        tick_hz: args.tick_hz,
        axes: vec![AxisEntry {
            node_id: args.node,
            name: None,
            preset: cfg.name.clone(),
            set: Default::default(),
            // the scenario's machine is as its file says (the preset's wear, its
            // overrides): scenarios are where wear is studied
            worn: true,
            eds: args.eds.clone(),
            objects_base: args.objects_base,
            profile: args.profile.clone(),
            quirks: None,
            quirk_profile: crate::drive::quirk_profile::QuirkProfile::from_args(
                args.profile.as_deref(),
                &args.quirk,
                &args.no_quirk,
            )?
            .map(Arc::new),
        }],
        ballbar: None,
        contour: None,
    })
}

/// `--lss-store FILE`: the drive's non-volatile memory (one axis). What it holds replaces the
/// node-ID (the serial number stays `--node`'s, so the LSS address does not move), and a
/// store configuration is written to it.
fn lss_options(args: &RunArgs, machine: &mut MachineFile) -> Result<LssOptions> {
    let Some(path) = &args.lss_store else {
        return Ok(LssOptions {
            force: args.force_lss,
            ..LssOptions::default()
        });
    };
    if machine.axes.len() != 1 {
        bail!(
            "--lss-store {}: one axis only (the machine has {}): it is one drive's memory",
            path.display(),
            machine.axes.len()
        );
    }
    let configured = machine.axes[0].node_id;
    let mut opts = LssOptions {
        config: drive_protocol::LssConfig {
            store_external: true,
            ..Default::default()
        },
        serial_number: Some(u32::from(configured)),
        force: args.force_lss,
    };
    match super::lss_store::load(path)? {
        Some(s) => {
            let id = s.node_id.unwrap_or(255);
            machine.axes[0].node_id = id;
            opts.config.bit_timing_index = s.bit_timing_index;
            eprintln!(
                "drive-emu: LSS store {}: node-ID {id}, bit timing {} (instead of --node {configured})",
                path.display(),
                super::lss_store::bit_timing_text(s.bit_timing_index),
            );
        }
        None => eprintln!(
            "drive-emu: LSS store {}: nothing stored yet (written at the first LSS store \
             configuration)",
            path.display()
        ),
    }
    Ok(opts)
}

/// Set on Ctrl-C / SIGTERM, and (without a scenario) after `--duration` of wall time; with a
/// scenario, `--duration` is the scenario's end and its thread sets the flag.
fn stop_flag(args: &RunArgs, scenario: Option<&Scenario>) -> Result<Arc<AtomicBool>> {
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
fn spawn_scenario(
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

/// Until the run stops: the ready line on stdout once booted (`--ready`), the status line on
/// stderr (a terminal only, so stdout stays clean for --json and pipes).
fn watch(
    args: &RunArgs,
    (label, socketcand): (&str, Option<std::net::SocketAddr>),
    (machine, lockstep): (&MachineFile, Option<&Lockstep>),
    status: &Status,
    stop: &AtomicBool,
    loop_thread: &std::thread::JoinHandle<Runtime<LiveBus, AxisDrive>>,
) -> Result<()> {
    let tty = std::io::stderr().is_terminal();
    let mut ready_sent = !args.ready;
    let mut drawn = 0;
    let mut drawn_at = std::time::Instant::now();
    while !stop.load(Ordering::Relaxed) && !loop_thread.is_finished() {
        // LSS store configuration: the master waits for the answer (python canopen 0.5 s).
        status.lss_service(args.lss_store.as_deref());
        let published = status.obs.board.ticks.load(Ordering::Acquire) > 0;
        if !ready_sent && status.booted.load(Ordering::Acquire) {
            ready_sent = true;
            let line = serde_json::json!({
                "event": "ready",
                "iface": socketcand.is_none().then_some(&args.iface),
                "socketcand": socketcand.map(|a| serde_json::json!({
                    "host": a.ip().to_string(), "port": a.port(),
                    "channel": crate::bus::socketcand::CHANNEL,
                })),
                "nodes": machine.axes.iter().zip(&status.wear_at_boot).map(|(a, w)| serde_json::json!({
                    "node_id": a.node_id, "preset": a.preset,
                    // the wear the axis runs with (null: healthy, no gap)
                    "worn": w,
                    "eds": a.eds.as_ref().map(|p| p.display().to_string()),
                    "objects_base": a.objects_base.map(|b| format!("0x{b:04X}")),
                    "profile": a.quirk_profile.as_ref().and_then(|b| b.profile.clone()),
                    "quirks": a.quirk_profile.as_ref().map_or(vec![], |b| b.quirks.on().collect()),
                })).collect::<Vec<_>>(),
                "tick_hz": machine.tick_hz,
                "lockstep": args.lockstep,
                "sync_period_us": lockstep.and_then(|l| l.sync_period_us),
                "boot_delay_ms": args.boot_delay_ms,
                "pid": std::process::id(),
            });
            let mut out = std::io::stdout().lock();
            writeln!(out, "{line}")?;
            out.flush()?;
        }
        // 5 ms until the ready line is out, then 50 ms: an LSS store configuration is still
        // answered well within a master's wait (python canopen: 0.5 s), and this thread wakes
        // 20 times a second beside the loop, not 200 (one CPU under user-mode Linux).
        std::thread::sleep(std::time::Duration::from_millis(
            if ready_sent && status.booted.load(Ordering::Acquire) {
                50
            } else {
                5
            },
        ));
        // Nothing to show before the loop's first tick has published the axes; redrawn every
        // 200 ms.
        if tty && published && drawn_at.elapsed() >= std::time::Duration::from_millis(200) {
            drawn_at = std::time::Instant::now();
            let lines = status_lines(
                &LoopLine::of(&status.obs),
                &status.snapshots(),
                label,
                lockstep.is_some(),
            );
            drawn = redraw(
                &mut std::io::stderr().lock(),
                drawn,
                &lines,
                terminal_width(),
            )
            .unwrap_or(drawn);
        }
    }
    Ok(())
}

/// An inconclusive detector result for people: its first reason, which
/// [`DetectorReport::mark_inconclusive`](crate::analysis::detector::DetectorReport::mark_inconclusive)
/// words as the verdict, its kind and why (no amplitude or frequency: nothing was measured).
pub(crate) fn inconclusive_text(d: &crate::analysis::detector::DetectorReport) -> String {
    d.reasons.first().cloned().unwrap_or_else(|| {
        format!(
            "inconclusive ({})",
            d.inconclusive.map_or("", |i| i.as_str())
        )
    })
}

/// Columns of the terminal on stderr (TIOCGWINSZ), 80 when it does not say.
fn terminal_width() -> usize {
    let mut ws = libc::winsize {
        ws_row: 0,
        ws_col: 0,
        ws_xpixel: 0,
        ws_ypixel: 0,
    };
    // SAFETY: TIOCGWINSZ writes a winsize into the struct we pass; fd 2 is ours.
    let ok = unsafe { libc::ioctl(libc::STDERR_FILENO, libc::TIOCGWINSZ, &mut ws) } == 0;
    if ok && ws.ws_col > 0 {
        usize::from(ws.ws_col)
    } else {
        80
    }
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

fn gap_models(
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

/// The run's axes as EtherCAT slaves (in machine-file order) and their drives, as
/// `run --ethercat` serves them and `drive-emu esi` describes them.
pub fn ethercat_slaves(
    args: &RunArgs,
) -> Result<(MachineFile, Vec<drive_ethercat::Slave>, Vec<AxisDrive>)> {
    ethercat_slaves_for(args, None)
}

/// [`ethercat_slaves`], or with a scenario its machine (one axis, as on CAN).
fn ethercat_slaves_for(
    args: &RunArgs,
    scenario: Option<&Scenario>,
) -> Result<(MachineFile, Vec<drive_ethercat::Slave>, Vec<AxisDrive>)> {
    let mut machine = match scenario {
        Some(s) => scenario_machine(args, s)?,
        None => machine_from_args(args)?,
    };
    machine::validate(&machine)?;
    let lss = LssOptions::default();
    let esi = match &args.esi {
        Some(path) => Some(load_esi(path)?),
        None => None,
    };
    let mut slaves = Vec::new();
    let mut drives = Vec::new();
    for e in machine.axes.iter_mut() {
        let cfg = match scenario {
            Some(s) => s.machine.configs[0].clone(),
            None => e.run_config()?,
        };
        // no boot delay: an EtherCAT slave's mailbox is there from PRE-OP on
        let (config, mut drive) = axis_setup(cfg, e, 0, &lss)?;
        let slave = match &esi {
            Some((path, dev)) => {
                drive_ethercat::Slave::with_esi(config, &mut drive, dev).map_err(|err| {
                    super::exit::usage_msg(format!(
                        "--esi {}: axis node {}: {err}",
                        crate::quote::text(&path.display().to_string()),
                        e.node_id
                    ))
                })?
            }
            None => drive_ethercat::Slave::new(config, &mut drive)
                .map_err(|err| anyhow::anyhow!("axis node {}: {err}", e.node_id))?,
        };
        slaves.push(slave);
        drives.push(drive);
    }
    Ok((machine, slaves, drives))
}

/// Read a vendor's ESI (`--esi FILE`): bounded, UTF-8, its first device; an error says the
/// file, the line and why (exit 2; 4 when the file cannot be read).
fn load_esi(path: &std::path::Path) -> Result<(PathBuf, drive_ethercat::esi::EsiDevice)> {
    let text = crate::infile::read_text(path, "ESI file", crate::infile::MAX_CONFIG_BYTES)
        .map_err(super::exit::unreadable)?;
    let dev = drive_ethercat::esi::parse(&text).map_err(|e| {
        super::exit::usage_msg(format!(
            "--esi {}: {e}",
            crate::quote::text(&path.display().to_string())
        ))
    })?;
    Ok((path.to_path_buf(), dev))
}

/// `run --ethercat IFACE`: the machine's axes as EtherCAT slaves on a raw Ethernet port; with
/// `--scenario`, its machine on one slave and its timeline (parameters, sensor and EtherCAT
/// faults) injected as on CAN.
fn run_ethercat(args: &RunArgs, iface: &str) -> Result<()> {
    let scenario = ethercat_scenario(args)?;
    let (machine, slaves, mut drives) = ethercat_slaves_for(args, scenario.as_ref())?;
    let mut sock = crate::bus::ethercat::PacketSocket::open(iface)?;
    let stop = stop_flag(args, scenario.as_ref())?;
    let period_us = 1_000_000 / u64::from(machine.tick_hz);
    announce_ethercat(args, iface, &machine, scenario.as_ref());
    // The observation bus, as on CAN: published after each drive cycle
    let (mut observer, obs) = crate::observe::channel(
        slaves.len(),
        crate::observe::run_ring_capacity(machine.tick_hz),
    );
    // --trace, --detect: the same readers as on CAN
    let readers = start_readers(
        args,
        &obs,
        slaves.iter().map(|s| s.node().node_id()).zip(drives.iter()),
        gap_models(&machine, scenario.as_ref()),
    )?;
    let detect = readers.detect.clone();
    // --scenario: its thread follows the drives' time and feeds the first slave injections
    let link = Arc::new(LiveLink::new());
    let mut injector = scenario
        .as_ref()
        .map(|s| LoopInjector::new(s.run.master.master_id));
    // --panel: the same panel as on CAN, its bus faults EtherCAT's; it takes the scenario's
    // injections into its own injector
    let context = crate::panel::RunContext {
        bus: crate::panel::PanelBus::Ethercat,
        iface: None,
        node: args.node,
        lockstep: args.lockstep,
        json: args.json,
        machine: &machine,
        scenario: scenario.as_ref(),
    };
    let (panel, mut panel_loop) =
        crate::panel::start_for_run(&args.panel, context, (&link, &obs), &mut injector)?.unzip();
    let scenario_thread = match &scenario {
        Some(s) => Some(spawn_scenario(args, s, (&link, &obs), &stop)?),
        None => None,
    };
    let mut faults =
        crate::bus::ethercat::EcatFaults::new(scenario.as_ref().map_or(1, |s| s.run.seed));
    let mut seg = drive_ethercat::Segment::new(slaves);
    // The loop runs on this thread: real-time scheduling, CPU and locked memory as on CAN.
    let report = realtime::apply(&realtime_request(args));
    for w in &report.warnings {
        eprintln!("drive-emu: warning: {w}");
    }
    eprintln!("drive-emu: loop thread: {report}");
    let stats = crate::runtime::ethercat::serve(
        &mut sock,
        &mut seg,
        &mut drives,
        (period_us, args.lockstep),
        &stop,
        &mut faults,
        |seg, drives, faults, t_us| {
            // publish: every slave's node beside its drive, its events drained
            observer.publish_axes(
                t_us,
                seg.slaves
                    .iter_mut()
                    .map(|s| s.node_mut())
                    .zip(drives.iter()),
            );
            // apply the injections: the panel's and the scenario's, the detector's results
            if let Some(p) = panel_loop.as_mut() {
                p.on_ethercat_cycle(seg, drives, faults, t_us);
            } else if let (Some(inj), Some(slave), Some(drive)) = (
                injector.as_mut(),
                seg.slaves.first_mut(),
                drives.first_mut(),
            ) {
                inj.on_ethercat_cycle(&link, t_us, slave, drive, faults);
            }
            if let Some(d) = &detect {
                for (k, (s, drive)) in seg.slaves.iter_mut().zip(drives.iter()).enumerate() {
                    d.apply_axis(k, s.node_mut(), drive);
                }
            }
        },
    );
    // the loop has stopped: a scenario still running ends now
    stop.store(true, Ordering::Relaxed);
    if let Some(p) = panel {
        p.stop();
    }
    let detector = readers.finish()?;
    let outcome = join_scenario(scenario_thread)?;
    ethercat_summary(
        &stats,
        &faults,
        (detector, outcome),
        (iface, scenario.as_ref()),
        args,
    )
}

/// `run --ethercat`'s options and scenario, checked before anything opens: the scenario read
/// and its bus faults EtherCAT's.
fn ethercat_scenario(args: &RunArgs) -> Result<Option<Scenario>> {
    validate_args(args)?;
    crate::panel::check_args(&args.panel)?;
    let scenario = match &args.scenario {
        Some(path) => Some(crate::scenario::load(path).map_err(super::exit::scenario_file)?),
        None => None,
    };
    if let Some(s) = &scenario {
        crate::scenario::check_bus(s, "ethercat").map_err(super::exit::usage)?;
    }
    Ok(scenario)
}

/// What runs where, on stderr, and with `--ready` the ready line on stdout.
fn announce_ethercat(
    args: &RunArgs,
    iface: &str,
    machine: &MachineFile,
    scenario: Option<&Scenario>,
) {
    eprintln!(
        "drive-emu: {} EtherCAT slave(s) on {iface}, {} Hz{}{}",
        machine.axes.len(),
        machine.tick_hz,
        if args.lockstep {
            " per process-data cycle (lock-step)"
        } else {
            ""
        },
        scenario.map_or(String::new(), |s| format!("; scenario {}", s.name)),
    );
    if args.ready {
        let nodes: Vec<serde_json::Value> = machine
            .axes
            .iter()
            .map(|e| serde_json::json!({"node_id": e.node_id, "preset": e.preset}))
            .collect();
        println!(
            "{}",
            serde_json::json!({"event": "ready", "ethercat": iface, "nodes": nodes,
                "scenario": scenario.map(|s| s.name.clone()),
                "pid": std::process::id()})
        );
        use std::io::Write;
        std::io::stdout().flush().ok();
    }
}

/// What the EtherCAT loop did and, with a scenario, what it found: on stderr, on stdout
/// (text, or `--json`), and the run's exit status.
fn ethercat_summary(
    stats: &crate::runtime::ethercat::EthercatStats,
    faults: &crate::bus::ethercat::EcatFaults,
    (detector, outcome): (
        Vec<(u8, Option<crate::analysis::detector::DetectorReport>)>,
        Option<LiveOutcome>,
    ),
    (iface, scenario): (&str, Option<&Scenario>),
    args: &RunArgs,
) -> Result<()> {
    let fs = faults.stats();
    eprintln!(
        "drive-emu: stopped. {} frames answered, {} refused, {} socket errors, {} cycles ({} late); \
         faults: {} frames lost, {} held, {} with bad working counters",
        stats.frames,
        stats.refused,
        stats.socket_errors,
        stats.cycles,
        stats.late_cycles,
        fs.lost + fs.hold_full,
        fs.held,
        fs.bad_wkc
    );
    if let (Some(o), Some(s)) = (&outcome, &scenario) {
        if !args.json {
            print_outcome(o);
            println!(
                "{} (live on EtherCAT {iface}): {}",
                s.name,
                if o.passed() { "passed" } else { "FAILED" }
            );
        }
    }
    if args.json {
        let mut v = serde_json::json!({"frames": stats.frames, "refused": stats.refused,
            "socket_errors": stats.socket_errors, "cycles": stats.cycles,
            "late_cycles": stats.late_cycles, "faults": fs,
            "sync0_locked_cycles": stats.sync0_locked_cycles,
            "sync0_phase_p50_us": stats.sync0_phase_p50_us,
            "sync0_phase_p99_us": stats.sync0_phase_p99_us,
            "sync0_phase_max_us": stats.sync0_phase_max_us,
            "detect": detector.iter().map(|(node_id, rep)|
                serde_json::json!({ "node_id": node_id, "report": rep }))
                .collect::<Vec<_>>()});
        if let (Some(o), Some(s)) = (outcome, &scenario) {
            let run = LiveRun {
                stats: Default::default(),
                detector: Vec::new(),
                lockstep_period_us: None,
                free_run_ticks: 0,
                scenario: Some(o),
            };
            v["scenario"] = outcome_json(&run, s)["scenario"].take();
            println!("{v}");
            let o = run.scenario.as_ref().expect("just set");
            return scenario_status(o);
        }
        println!("{v}");
    } else if let Some(o) = &outcome {
        return scenario_status(o);
    }
    Ok(())
}

/// The exit status of a live scenario: it did not finish, or an expectation failed.
fn scenario_status(o: &LiveOutcome) -> Result<()> {
    if let Some(why) = o.unfinished() {
        bail!("{why}");
    }
    if !o.passed() {
        bail!("scenario expectations failed");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axis(node: u8, nmt: u8, statusword: u16, mode: i8) -> AxisSnapshot {
        let mut a = AxisSnapshot {
            node_id: node,
            nmt,
            ..AxisSnapshot::default()
        };
        a.sample.statusword = statusword;
        a.sample.mode_display = mode;
        a.sample.position_uu = -1234;
        a
    }

    fn up() -> LoopLine {
        LoopLine {
            link_up: true,
            ..LoopLine::default()
        }
    }

    #[test]
    fn status_block_has_one_named_line_per_axis() {
        let axes = [axis(20, 0x05, 0x0637, 8), axis(21, 0x7F, 0x0250, 0)];
        let lines = status_lines(&up(), &axes, "vcan0", true);
        assert_eq!(lines.len(), 3, "{lines:#?}");
        assert!(lines[0].starts_with("vcan0 t=") && lines[0].contains("lock-step"));
        for (l, want) in lines[1..].iter().zip([
            ["node 20 ", "OPERATIONAL", "OPERATION ENABLED", "CSP"],
            [
                "node 21 ",
                "PRE-OPERATIONAL",
                "SWITCH ON DISABLED",
                "no mode",
            ],
        ]) {
            for w in want {
                assert!(l.contains(w), "{w:?} missing in {l:?}");
            }
            assert!(l.contains("pos -1234 ferr 0 uu"), "{l:?}");
        }
        // Mode names, not numbers; no Debug text.
        for l in &lines {
            assert!(!l.contains("mode 8") && !l.contains("mode 0"), "{l:?}");
            assert!(!l.contains('{') && !l.contains("::"), "{l:?}");
        }
        // The columns line up: the NMT, CiA 402 state and mode columns start at the same
        // place on every axis line.
        let col = |l: &str, w: &str| l.find(w).unwrap();
        assert_eq!(
            col(&lines[1], "OPERATIONAL"),
            col(&lines[2], "PRE-OPERATIONAL")
        );
        assert_eq!(
            col(&lines[1], "OPERATION ENABLED"),
            col(&lines[2], "SWITCH ON DISABLED")
        );
        assert_eq!(col(&lines[1], "CSP"), col(&lines[2], "no mode"));
    }

    #[test]
    fn status_of_one_axis_is_the_loop_line_and_the_axis_line() {
        let mut a = axis(5, 0x00, 0x0000, 3);
        a.sample.position_uu = -123_456;
        a.sample.following_error_uu = -789;
        let lines = status_lines(&LoopLine::default(), &[a], "can0", false);
        assert_eq!(lines.len(), 2, "{lines:#?}");
        assert!(lines[0].starts_with("can0 t=") && lines[0].contains("LINK DOWN"));
        for w in ["node 5 ", "INITIALISING", "NOT READY TO SWITCH ON", "PV"] {
            assert!(lines[1].contains(w), "{w:?} missing in {:?}", lines[1]);
        }
        // Each line fits an 80-column terminal with a six-digit position.
        assert!(lines.iter().all(|l| l.chars().count() <= 80), "{lines:#?}");
        let mut a = axis(5, 0x05, 0x0637, -2);
        assert!(
            status_lines(&up(), &[a], "can0", true)[1].contains("manufacturer-specific mode -2")
        );
        // a worn axis (issue 33, item 4): a line under it says so, and fits the terminal
        a.gap_si = 3e-5;
        let lines = status_lines(&up(), &[a], "can0", false);
        assert_eq!(lines.len(), 3, "{lines:#?}");
        assert!(lines[2].contains("WORN: backlash 0.03 mm"), "{lines:#?}");
        assert!(lines[2].chars().count() <= 80, "{lines:#?}");
        a.rotary = true;
        a.gap_si = 0.02f64.to_radians();
        assert!(status_lines(&up(), &[a], "can0", false)[2].contains("WORN: backlash 0.02 deg"));
        a.gap_si = 0.0;
        assert_eq!(
            status_lines(&up(), &[a], "can0", false).len(),
            2,
            "healthy: no wear line"
        );
    }

    #[test]
    fn a_non_configured_axis_is_shown_as_such() {
        let line = &status_lines(&up(), &[axis(255, 0x00, 0x0000, 0)], "can0", false)[1];
        assert!(line.contains("node 255 UNCONFIGURED"), "{line}");
        let line = &status_lines(&up(), &[axis(12, 0x00, 0x0000, 0)], "can0", false)[1];
        assert!(line.contains("INITIALISING"));
    }

    /// The status line reads the observation bus: what the loop published (board and
    /// snapshot) is what it shows, and nothing before the first tick.
    #[test]
    fn the_status_line_shows_what_the_loop_published() {
        use crate::bus::inproc::InProcBus;
        let mut drive = AxisDrive::from_config(&AxisConfig::from_preset("cnc1").unwrap()).unwrap();
        let node = crate::drive::node(&mut drive, 9).unwrap();
        let bus = InProcBus::endpoints(1, 16).remove(0);
        let mut rt = Runtime::new(bus, vec![AxisSlot { node, drive }], 1000);
        rt.boot();
        let (mut observer, obs) = crate::observe::channel(1, 1024);
        let status = Status::new(Arc::clone(&obs), vec![None]);
        assert_eq!(status.obs.latest(0), None, "nothing published yet");
        for _ in 0..3 {
            rt.tick();
            rt.stats.record_tick(5, 20);
            observer.publish(&mut rt);
        }
        observer.set_link_up(false);
        let lines = status_lines(&LoopLine::of(&obs), &status.snapshots(), "can0", false);
        assert!(
            lines[0].contains("ticks 3 ") && lines[0].contains("LINK DOWN"),
            "{lines:?}"
        );
        assert!(lines[1].starts_with("node 9 "), "{lines:?}");
        assert_eq!(status.snapshots()[0].t_us, rt.sim_time_us);
    }

    /// LSS store configuration from a node on the loop to the file and the answer back:
    /// the loop hands the request out, the watch thread writes FILE, the loop queues the
    /// answer (error 0); an unwritable FILE gives error 2.
    #[test]
    fn an_lss_store_goes_from_the_loop_to_the_file_and_back() {
        use crate::bus::inproc::{InProcBus, InProcEndpoint};
        use drive_protocol::CanFrame;
        let dir = std::env::temp_dir().join(format!("run-lss-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("drive.lss");
        let mut drive = AxisDrive::from_config(&AxisConfig::from_preset("cnc1").unwrap()).unwrap();
        let opts = NodeOptions {
            lss: drive_protocol::LssConfig {
                store_external: true,
                ..Default::default()
            },
            ..NodeOptions::new(255)
        };
        let mut node = crate::drive::build_node(&mut drive, &opts).unwrap();
        node.boot(0);
        let bus = InProcBus::endpoints(1, 16).remove(0);
        let mut rt = Runtime::new(bus, vec![AxisSlot { node, drive }], 1000);
        let status = Status::new(crate::observe::channel(1, 1024).1, vec![None]);
        let lss = |rt: &mut Runtime<InProcEndpoint, AxisDrive>, d: [u8; 8]| {
            let ax = &mut rt.axes[0];
            ax.node.handle(&CanFrame::new(0x7E5, &d), 0, &mut ax.drive);
        };
        let answers = |rt: &mut Runtime<InProcEndpoint, AxisDrive>| {
            let mut v = Vec::new();
            while let Some(f) = rt.axes[0].node.pop_tx() {
                v.push(f.data);
            }
            v
        };
        lss(&mut rt, [0x04, 1, 0, 0, 0, 0, 0, 0]);
        lss(&mut rt, [0x11, 12, 0, 0, 0, 0, 0, 0]);
        lss(&mut rt, [0x13, 0, 3, 0, 0, 0, 0, 0]);
        answers(&mut rt);
        for (file, answer) in [(path.clone(), 0u8), (dir.join("no/such/dir/x"), 2)] {
            lss(&mut rt, [0x17, 0, 0, 0, 0, 0, 0, 0]);
            assert!(answers(&mut rt).is_empty(), "answered after the write");
            status.lss_exchange(&mut rt); // loop: hands the request out
            status.lss_service(Some(&file)); // watch thread: writes
            assert!(answers(&mut rt).is_empty());
            status.lss_exchange(&mut rt); // loop: the answer
            assert_eq!(answers(&mut rt), [[0x17, answer, 0, 0, 0, 0, 0, 0]]);
        }
        assert_eq!(
            crate::cli::lss_store::load(&path).unwrap(),
            Some(crate::cli::lss_store::Stored {
                node_id: Some(12),
                bit_timing_index: 3
            })
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn an_inconclusive_detector_is_said_without_an_amplitude() {
        use crate::analysis::detector::{DetectorConfig, DetectorReport, Inconclusive};
        let d = DetectorReport::inconclusive(
            &DetectorConfig::new(30.0),
            Inconclusive::NoConstantSpeed,
            "no window of constant set speed".into(),
            "um",
        );
        let t = inconclusive_text(&d);
        assert!(
            t.starts_with("inconclusive (no_constant_speed): ") && t.contains("constant"),
            "{t}"
        );
        assert!(!t.contains("amplitude") && !t.contains("0.00"), "{t}");
        // Said once, not "inconclusive (x): inconclusive (x): ...".
        assert_eq!(t.matches("inconclusive (").count(), 1, "{t}");
    }

    #[test]
    fn redraw_goes_back_over_the_block_it_drew() {
        let lines: Vec<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
        let mut out = Vec::new();
        let drawn = redraw(&mut out, 0, &lines, 80).unwrap();
        assert_eq!(drawn, 3);
        assert_eq!(out, b"\r\x1b[2Ka\n\r\x1b[2Kb\n\r\x1b[2Kc");
        out.clear();
        redraw(&mut out, drawn, &lines, 80).unwrap();
        assert!(out.starts_with(b"\x1b[2A\r\x1b[2Ka"), "{out:?}");
        // A line wider than the terminal is cut, so it cannot wrap.
        out.clear();
        redraw(&mut out, 0, &["µ".repeat(100)], 40).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            format!("\r\x1b[2K{}", "µ".repeat(39))
        );
    }
}
