//! `drive-emu run`'s arguments: the options, their checks, and the machine they describe.

use crate::api::live::{LiveBusSpec, LiveRequest, LssMemory};
use crate::drive::machine::MachineFile;
use crate::scenario::Scenario;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

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
    #[arg(long, default_value_t = crate::api::live::DEFAULT_NODE_ID)]
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
    #[arg(long, default_value_t = crate::api::live::DEFAULT_TICK_HZ)]
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
    #[arg(long, default_value_t = crate::api::live::DEFAULT_RT_PRIORITY)]
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
    #[arg(long, value_name = "S", default_value_t = crate::api::live::DEFAULT_DETECT_HISTORY_S, value_parser = positive_seconds)]
    pub detect_history: f64,
}

pub use crate::api::live::{DEFAULT_BOOT_DELAY_MS, MAX_DURATION_S, MAX_SYNC_PERIOD_US};

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
    crate::api::live::setup::machine_of(&args.request_base()).map_err(crate::cli::api_error)
}

/// `--duration`: a positive number of seconds.
pub fn positive_seconds(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v < 1e9 => Ok(v),
        Ok(_) => Err(format!("{s}: a duration in seconds, more than 0")),
        Err(_) => Err(format!("{s}: not a number of seconds")),
    }
}

impl RunArgs {
    /// The typed request these options describe (the scenario read by the caller), with the
    /// LSS store file read (`--lss-store`). The checks are the request's
    /// ([`LiveRequest::check`]), at its start.
    pub fn request(&self, scenario: Option<Scenario>) -> Result<LiveRequest> {
        let lss_memory = match &self.lss_store {
            Some(path) => Some(LssMemory {
                path: path.clone(),
                stored: crate::cli::lss_store::load(path)?.map(|s| drive_protocol::LssStore {
                    node_id: s.node_id,
                    bit_timing_index: s.bit_timing_index,
                }),
                bit_timing_text: crate::cli::lss_store::bit_timing_text,
            }),
            None => None,
        };
        Ok(LiveRequest {
            scenario,
            lss_memory,
            ..self.request_base()
        })
    }

    /// The request of these options without a scenario or an LSS store (what `run
    /// --ethercat` and `drive-emu esi` share).
    pub fn request_base(&self) -> LiveRequest {
        LiveRequest {
            bus: match &self.socketcand {
                Some(addr) => LiveBusSpec::Socketcand(addr.clone()),
                None => LiveBusSpec::SocketCan(self.iface.clone()),
            },
            node_id: self.node,
            force_lss: self.force_lss,
            preset: self.preset.clone(),
            sets: self.set.clone(),
            worn: self.worn,
            machine_file: self.config.clone(),
            eds: self.eds.clone(),
            objects_base: self.objects_base,
            profile: self.profile.clone(),
            quirks: self.quirk.clone(),
            no_quirks: self.no_quirk.clone(),
            tick_hz: self.tick_hz,
            lockstep: self.lockstep,
            sync_period_us: self.sync_period_us,
            rt_priority: self.rt_priority,
            cpu: self.cpu,
            lock_memory: !self.no_mlock,
            duration_s: self.duration,
            scenario: None,
            trace: self.trace.clone(),
            boot_delay_ms: self.boot_delay_ms,
            lss_memory: None,
            detect: self.detect,
            detect_history_s: self.detect_history,
            stop_on_signal: true,
        }
    }

    /// What the bus is, for people: the interface, or `socketcand ADDR:PORT`.
    pub fn bus_label(&self) -> String {
        match &self.socketcand {
            Some(addr) => format!("socketcand {addr}"),
            None => self.iface.clone(),
        }
    }
}
