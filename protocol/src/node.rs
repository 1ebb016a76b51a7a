//! The node: glues the CiA 301 services and the CiA 402 layer to the object dictionary.
//! Sans-IO: `handle` takes a received frame, `poll` runs timers and one CiA 402 tick,
//! `pop_tx` hands out frames to send. Built once from a [`NodeConfig`]; nothing here
//! allocates after `Node::new`.
//!
//! By what it holds (docs/decisions/0018): this file the types, the node's state and
//! `Node::new`; `frames` the CAN front end (a received frame dispatched to its service, NMT);
//! `drive_core` the drive core (object access, the write path, EMCY bookkeeping, boot);
//! `writes` the services' write hooks; `cycle` the timers and the CiA 402 tick; `deadlines`
//! the next deadline; `access` the core as a front end other than CAN (EtherCAT) calls it.

pub(crate) mod access;
mod cycle;
pub(crate) mod deadlines;
mod drive_core;
mod frames;
pub(crate) mod writes;

use heapless::Deque;

use crate::cia301::emcy::{Cause, Emcy};
use crate::cia301::heartbeat::{Consumer, Producer};
use crate::cia301::nmt::{self, NmtCommand, NmtState};
use crate::cia301::pdo::mapping;
use crate::cia301::pdo::rpdo::RxOutcome;
use crate::cia301::pdo::PdoEngine;
use crate::cia301::sdo::{abort, ObjectAccess, SdoServer};
use crate::cia301::sync::{SyncConsumer, SyncProducer, EMCY_SYNC_LENGTH, EMCY_SYNC_LOSS};
use crate::cia305::{LssEvent, LssIdentity, LssSlave, LssState};
use crate::cia402::factor::Factor;
use crate::cia402::{objects as o402, Cia402, State};
use crate::drive::{Drive, DriveInfo};
use crate::event::{NodeEvent, EVENT_QUEUE};
use crate::frame::CanFrame;
use crate::od::{idx, Backing, DefaultValue, Entry, Lookup, ObjectDictionary, Slot, Store};
use crate::quirks::{ControlwordLatch, QuirkState, Quirks, SdoAnswer, SdoGate, WatchdogPeriod};
use crate::wire::cob::{Rx, RxTable};
use crate::wire::lss::UNCONFIGURED_NODE_ID;
use crate::wire::{cob, Heartbeat};
use drive_core::{csp_period_us, interpolation_period_us, si_unit_rows};
use writes::{ObjectWrite, Origin, Verdict, WriteHooks};

/// Capacity of the transmit queue; frames beyond it are counted in
/// [`Node::tx_overflows`] and dropped.
pub const TX_QUEUE: usize = 64;

/// EMCY code for a lost heartbeat producer (the master).
pub const EMCY_HEARTBEAT: u16 = 0x8130;
/// EMCY code for an RPDO value the drive refuses (the rules of an SDO write: range, then the
/// write hook of the object's service: a supported mode, min <= max, ...): CiA 402 "parameter error" (0x6320). The object keeps its
/// value, as with the refused SDO write; CiA 301 has no code for it and CANopenNode drops
/// such a value silently, but a master is better served by knowing why 0x6061 did not
/// follow its RPDO.
pub const EMCY_RPDO_VALUE: u16 = 0x6320;

const R_1005: usize = idx(0x1005, 0);
const R_1006: usize = idx(0x1006, 0);
const R_1007: usize = idx(0x1007, 0);
const R_1014: usize = idx(0x1014, 0);
const R_1015: usize = idx(0x1015, 0);
const R_1016: usize = idx(0x1016, 1);
const R_1017: usize = idx(0x1017, 0);
const R_1019: usize = idx(0x1019, 0);
const R_SERIAL: usize = idx(0x1018, 4);

/// The bit timing an LSS slave reports at power-on unless told otherwise: CiA 301 table
/// index 0, 1 Mbit/s.
pub const DEFAULT_LSS_BIT_TIMING: u8 = 0;

/// The node's LSS slave (CiA 305): what its non-volatile memory holds at power-on and who
/// writes a store configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LssConfig {
    /// Bit timing (CiA 301 table index) at power-on.
    pub bit_timing_index: u8,
    /// A store configuration goes to the application ([`Node::take_lss_store`], answered by
    /// [`Node::lss_store_done`]); else the node keeps the stored values in memory (an NMT
    /// reset node loads them, a new node does not) and answers at once.
    pub store_external: bool,
}

impl Default for LssConfig {
    fn default() -> Self {
        LssConfig {
            bit_timing_index: DEFAULT_LSS_BIT_TIMING,
            store_external: false,
        }
    }
}

/// A store configuration (LSS) the application is to write to non-volatile memory: the
/// pending node-ID (`None`: non-configured) and bit timing. See [`Node::take_lss_store`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LssStore {
    /// Node-ID to store (`None`: non-configured).
    pub node_id: Option<u8>,
    /// CiA 301 bit timing table index to store.
    pub bit_timing_index: u8,
}

/// Everything a node is built from, once ([`Node::new`]).
#[derive(Clone, Debug)]
pub struct NodeConfig {
    /// Node ID 1..=127; 255 (with LSS): non-configured, silent but for LSS until a master
    /// gives it one.
    pub node_id: u8,
    /// Static facts of the drive (factor-group defaults).
    pub info: DriveInfo,
    /// The object dictionary: [`ObjectDictionary::standard`] plus the application's objects,
    /// or one built from a vendor's EDS.
    pub od: ObjectDictionary,
    /// Time from power-on (and, unless said below, an NMT reset) to the boot-up message, us
    /// (0: at once). Real drives take 100 ms to seconds; a master that sends the reset and
    /// then starts waiting for the boot-up (python canopen's `wait_for_bootup`) needs some.
    pub boot_delay_us: u64,
    /// Time from an NMT reset node to the boot-up, us (`None`: `boot_delay_us`).
    pub reset_node_boot_delay_us: Option<u64>,
    /// Time from an NMT reset communication to the boot-up, us (`None`: `boot_delay_us`).
    /// A real drive restarts its communication in milliseconds (docs/quirks.md 3.5).
    pub reset_communication_boot_delay_us: Option<u64>,
    /// Timeout of a stalled SDO transfer, us (default 1 s).
    pub sdo_timeout_us: u64,
    /// The LSS slave (CiA 305); `None`: the node answers no LSS (and cannot be
    /// non-configured). Its identity is the dictionary's 0x1018:1-4.
    pub lss: Option<LssConfig>,
    /// The vendor behaviour switches (docs/quirks.md); all off: the strict drive.
    pub quirks: Quirks,
}

impl NodeConfig {
    /// A node with the standard objects only, no boot delay, the default SDO timeout.
    pub fn new(node_id: u8, info: DriveInfo) -> NodeConfig {
        NodeConfig {
            node_id,
            info,
            od: ObjectDictionary::standard(&info),
            boot_delay_us: 0,
            reset_node_boot_delay_us: None,
            reset_communication_boot_delay_us: None,
            sdo_timeout_us: crate::cia301::sdo::DEFAULT_TIMEOUT_US,
            lss: Some(LssConfig::default()),
            quirks: Quirks::default(),
        }
    }

    /// The same configuration with these vendor switches.
    pub fn with_quirks(mut self, quirks: Quirks) -> NodeConfig {
        self.quirks = quirks;
        self
    }

    /// The same configuration with a boot delay.
    pub fn with_boot_delay_us(mut self, delay_us: u64) -> NodeConfig {
        self.boot_delay_us = delay_us;
        self
    }

    /// The same configuration with another object dictionary.
    pub fn with_od(mut self, od: ObjectDictionary) -> NodeConfig {
        self.od = od;
        self
    }
}

/// What a received frame was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameEvent {
    /// Not for this node (or not in a state to take it).
    Ignored,
    /// Consumed.
    Handled,
    /// A SYNC (counter byte if the SYNC carries one). Reported in every booted NMT state so
    /// a lock-step runtime can advance; PDOs are only processed in Operational.
    Sync {
        /// The SYNC counter (1..=0x1019), when the producer sends one.
        counter: Option<u8>,
    },
}

/// The two clocks a node runs on, us. The application clock times the drive: the CiA 402
/// cycle, window times, following-error time-outs, the CSP interpolation, SYNC supervision.
/// The communication clock times what a master measures on its own clock: the heartbeat
/// producer and consumer, TPDO event timers and inhibit times, the EMCY inhibit time, the SDO
/// time-out and the boot delay. A runtime in real time gives the same clock twice
/// ([`Clocks::same`]); a lock-step runtime, whose simulated time advances only with SYNC,
/// gives the wall clock as the communication clock, so a master's heartbeat supervision
/// agrees with the drive whatever its SYNC period. The two are never compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Clocks {
    /// Application (simulated) time.
    pub app_us: u64,
    /// Communication time.
    pub comm_us: u64,
}

impl Clocks {
    /// One clock for both.
    pub const fn same(now_us: u64) -> Clocks {
        Clocks {
            app_us: now_us,
            comm_us: now_us,
        }
    }
}

/// Why a node could not be built.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ConfigError {
    /// Node IDs are 1..=127, or 255 (non-configured) with LSS.
    InvalidNodeId(u8),
    /// A zero in the encoder resolution, gear ratio or feed constant.
    InvalidDriveInfo,
    /// The LSS bit timing is not a CiA 301 table index the slave supports.
    InvalidBitTiming(u8),
    /// The dictionary lacks an object every CiA 301 node has (0x1000, 0x1001, 0x1018:1-4).
    MissingObject {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// A vendor switch needs an object the dictionary lacks (e.g. `sync_watchdog` with its
    /// period from 0x60C2 on a dictionary without 0x60C2).
    QuirkNeedsObject {
        /// The switch.
        switch: &'static str,
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// A vendor switch cannot change a default of the dictionary (its limits refuse it).
    QuirkDefault {
        /// The switch.
        switch: &'static str,
        /// Why.
        reason: String,
    },
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ConfigError::InvalidNodeId(n) => {
                write!(
                    f,
                    "node id {n} outside 1..=127 (255: non-configured, with LSS)"
                )
            }
            ConfigError::InvalidDriveInfo => write!(f, "drive info has a zero in the factor group"),
            ConfigError::InvalidBitTiming(i) => write!(
                f,
                "LSS bit timing index {i} is not a CiA 301 bit rate (0..=4, 6..=8)"
            ),
            ConfigError::MissingObject { index, sub } => write!(
                f,
                "the object dictionary has no 0x{index:04X} sub {sub}, which every CiA 301 node has"
            ),
            ConfigError::QuirkNeedsObject { switch, index, sub } => write!(
                f,
                "switch {switch} needs object 0x{index:04X} sub {sub}, which the object \
                 dictionary (the EDS) does not have"
            ),
            ConfigError::QuirkDefault { switch, reason } => {
                write!(f, "switch {switch}: {reason}")
            }
        }
    }
}

impl std::error::Error for ConfigError {}

/// A core output as its CAN frame, on the node-ID and EMCY CAN-ID (of 0x1014) given. Out of
/// line: a TPDO's frame (the hot path) leaves [`Node::pop_tx`] as one copy.
#[cold]
#[inline(never)]
fn frame(o: CoreOutput, node_id: u8, emcy_cob: u32) -> CanFrame {
    match o {
        CoreOutput::Bootup => {
            CanFrame::new(cob::HEARTBEAT + node_id as u32, &Heartbeat::BOOTUP.emit())
        }
        CoreOutput::Heartbeat { state } => {
            CanFrame::new(cob::HEARTBEAT + node_id as u32, &Heartbeat { state }.emit())
        }
        CoreOutput::Emcy(d) => CanFrame::new(emcy_cob, &d),
        CoreOutput::CanOnly(f) => f,
    }
}

/// Queue an output of the drive core; a full queue drops it and counts.
fn emit(out: &mut Deque<CoreOutput, TX_QUEUE>, dropped: &mut u32, o: CoreOutput) {
    if out.push_back(o).is_err() {
        *dropped = dropped.wrapping_add(1);
    }
}

/// What the drive core has to send, in order, for its front end to put on its bus
/// ([`DriveCore::take_output`]; the CAN front end's transmit queue is this queue: it frames
/// each output when [`Node::pop_tx`] takes it). Nothing here knows a COB-ID but
/// [`CoreOutput::CanOnly`].
///
/// `repr(C)`: a tag beside the payload (not in a niche of the frame's flags), so a
/// [`CoreOutput::CanOnly`] frame leaves [`Node::pop_tx`] as one 16-byte copy; built from
/// its pieces it was stored piecewise and read back whole, a stalled store-to-load forward
/// that cost a SYNC with 4 TPDOs about 18 % (docs/decisions/0018, "Cost").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub enum CoreOutput {
    /// The boot-up message is due (the core entered pre-operational after a reset).
    Bootup,
    /// The heartbeat producer (0x1017) is due; `state` is the NMT state it reports.
    Heartbeat {
        /// NMT state byte (0x04 stopped, 0x05 operational, 0x7F pre-operational).
        state: u8,
    },
    /// An emergency the EMCY bookkeeping (0x1001, 0x1003, the inhibit time 0x1015) lets go:
    /// error code (LE), error register, five manufacturer bytes. CAN sends it on 0x1014's
    /// COB-ID, EtherCAT as a CoE emergency.
    Emcy([u8; 8]),
    /// A frame only a CAN front end sends, built by the PDO engine (a TPDO, on its 0x18xx
    /// COB-ID) or a vendor switch (a delayed SDO answer, an extra heartbeat); another front
    /// end drops it.
    CanOnly(CanFrame),
}

/// The fieldbus-independent drive core: the object dictionary and its values, the SDO
/// server's semantics by index ([`DriveCore::read_object`] / [`DriveCore::write_object`]: the
/// rules, not the frames), the PDO mapping engine, the CiA 402 state machine and modes, the
/// vendor switches, the supervisions (heartbeat consumer, SYNC, the vendor's watchdog), the
/// EMCY bookkeeping and the services' write hooks (docs/decisions/0018). What it has to send
/// it queues as [`CoreOutput`]s. The CAN front end ([`Node`]) and the EtherCAT slave
/// (`drive-ethercat`) are built around one. The fields the services' write hooks
/// ([`writes`]) work on are visible to the crate.
#[derive(Clone, Debug)]
pub struct DriveCore {
    /// The node-ID the dictionary's `$NODEID` values resolve with (255: none yet, LSS);
    /// the CAN front end's LSS slave sets it at an NMT reset.
    node_id: u8,
    info: DriveInfo,
    pub(crate) od: ObjectDictionary,
    pub(crate) store: Store,
    /// Parameters saved by 0x1010 (`has_saved`), allocated with the node.
    pub(crate) saved: Store,
    pub(crate) has_saved: bool,
    nmt: NmtState,
    pub(crate) pdo: PdoEngine,
    sync: SyncConsumer,
    /// The SYNC producer (0x1005 bit 30, 0x1006, 0x1019).
    pub(crate) sync_producer: SyncProducer,
    pub(crate) hb: Producer,
    pub(crate) hbc: Consumer,
    pub(crate) hb_lost: bool,
    emcy: Emcy,
    cia: Cia402,
    /// What the core has to send, for the front end ([`DriveCore::take_output`]).
    out: Deque<CoreOutput, TX_QUEUE>,
    /// Outputs dropped because `out` was full (or a vendor-delayed SDO answer dropped).
    out_dropped: u32,
    /// Synchronous TPDOs not sent because the 0x1007 window had closed.
    sync_window_missed: u32,
    pending_sync: Option<u64>,
    /// Application clock, as last given.
    now_us: u64,
    /// Communication clock, as last given.
    pub(crate) comm_us: u64,
    /// Time from power-on to the boot-up message, us (0: at once).
    boot_delay_us: u64,
    /// From an NMT reset node / reset communication to the boot-up, us.
    reset_node_delay_us: u64,
    reset_comm_delay_us: u64,
    /// The vendor switches and what they keep while the node runs.
    pub(crate) quirks: Quirks,
    qs: QuirkState,
    /// Controlword edges written between ticks (and the hold time's view of it).
    pub(crate) cw_latch: ControlwordLatch,
    /// The services' write rules, by object index (filled in [`DriveCore::new`]).
    hooks: WriteHooks,
    /// While initialising after a reset: when the boot-up is due.
    boot_due_us: Option<u64>,
    /// The pending boot follows a communication reset: the application (CiA 402) keeps
    /// running meanwhile, only the communication is silent.
    boot_keeps_app: bool,
    events: Deque<NodeEvent, EVENT_QUEUE>,
    events_dropped: u32,
    /// CiA 402 and NMT state as last reported in an event.
    seen_cia: State,
    seen_nmt: NmtState,
}

/// The CANopen-over-CAN front end around a [`DriveCore`]: the SDO server's frame state and
/// the LSS slave. Its transmit queue is the core's output queue, framed when taken.
#[derive(Clone, Debug)]
struct CanFrontEnd {
    sdo: SdoServer,
    /// LSS slave (CiA 305); the core's node-ID is its active node-ID (0xFF: non-configured).
    lss: Option<LssSlave>,
    /// Store configuration is written by the application ([`LssConfig::store_external`]).
    lss_store_external: bool,
    /// A store the application has not taken yet.
    lss_store: Option<LssStore>,
    /// The last activate bit timing (table index, switch delay ms), not yet taken.
    lss_bit_timing_activated: Option<(u8, u16)>,
}

/// A CiA 301 + CiA 402 servo-drive node on CAN: a [`DriveCore`] and the CAN front end
/// around it (COB-IDs and the Rx table, NMT / SYNC / EMCY / heartbeat frames, the SDO
/// server's frames, LSS, the transmit queue). The core's methods are the node's too
/// (`Deref`); the node's own (`handle`, `poll`, `pop_tx`, `poll_at`, ...) add the CAN side.
#[derive(Clone, Debug)]
pub struct Node {
    core: DriveCore,
    can: CanFrontEnd,
}

impl core::ops::Deref for Node {
    type Target = DriveCore;
    fn deref(&self) -> &DriveCore {
        &self.core
    }
}

impl core::ops::DerefMut for Node {
    fn deref_mut(&mut self) -> &mut DriveCore {
        &mut self.core
    }
}

struct Access<'a, D: Drive> {
    core: &'a mut DriveCore,
    drive: &'a mut D,
}

fn lookup(od: &ObjectDictionary, index: u16, sub: u8) -> Result<(usize, &Entry), u32> {
    match od.find(index, sub) {
        Lookup::Found(slot) => Ok((slot.get(), od.entry(slot))),
        Lookup::NoObject => Err(abort::NO_OBJECT),
        Lookup::NoSub => Err(abort::NO_SUB),
    }
}

impl DriveCore {
    /// Build a drive core for a front end other than CAN (state: initialising; call
    /// [`DriveCore::boot`]): `cfg`'s node ID must be 1..=127 (it resolves the dictionary's
    /// `$NODEID` values); its LSS and SDO time-out are the CAN front end's and not used.
    /// Every allocation the core will ever make happens here.
    pub fn new(cfg: NodeConfig) -> Result<DriveCore, ConfigError> {
        DriveCore::build(cfg, false)
    }

    fn build(cfg: NodeConfig, may_be_unconfigured: bool) -> Result<DriveCore, ConfigError> {
        let NodeConfig {
            node_id,
            info,
            od,
            boot_delay_us,
            reset_node_boot_delay_us,
            reset_communication_boot_delay_us,
            sdo_timeout_us: _,
            lss: _,
            quirks,
        } = cfg;
        let unconfigured = node_id == UNCONFIGURED_NODE_ID && may_be_unconfigured;
        if !(1..=127).contains(&node_id) && !unconfigured {
            return Err(ConfigError::InvalidNodeId(node_id));
        }
        for (index, sub) in [
            (0x1000, 0),
            (0x1001, 0),
            (0x1018, 1),
            (0x1018, 2),
            (0x1018, 3),
            (0x1018, 4),
        ] {
            if od.get(index, sub).is_none() {
                return Err(ConfigError::MissingObject { index, sub });
            }
        }
        let factor = Factor::from_info(&info).ok_or(ConfigError::InvalidDriveInfo)?;
        if let Some((switch, index, sub)) = quirks.missing_object(&od) {
            return Err(ConfigError::QuirkNeedsObject { switch, index, sub });
        }
        let od = quirk_defaults(od, &quirks)?;
        // the 0x1003 history has the sub-indices the dictionary shows (a vendor's may have 2)
        let history_len = (1..=8u8)
            .take_while(|&s| od.get(0x1003, s).is_some())
            .count();
        let store = Store::new(&od, node_id);
        let saved = store.clone();
        let mut pdo = PdoEngine::new(&od);
        pdo.rules = quirks.pdo_rules();
        let qs = QuirkState::new(&quirks, &od);
        let fe_window_zero_off = od.device.following_error_window_zero_off;
        let si_rows = si_unit_rows(&od);
        let mut hooks = WriteHooks::standard();
        hooks.index_rows(&od);
        let mut core = DriveCore {
            node_id,
            info,
            od,
            store,
            saved,
            has_saved: false,
            nmt: NmtState::Initialising,
            pdo,
            sync: SyncConsumer::default(),
            sync_producer: SyncProducer::default(),
            hb: Producer::default(),
            hbc: Consumer::default(),
            hb_lost: false,
            emcy: Emcy::with_history(history_len),
            cia: Cia402::new(factor, quirks.cia402()).with_device(fe_window_zero_off, si_rows),
            out: Deque::new(),
            out_dropped: 0,
            sync_window_missed: 0,
            pending_sync: None,
            now_us: 0,
            comm_us: 0,
            boot_delay_us,
            reset_node_delay_us: reset_node_boot_delay_us.unwrap_or(boot_delay_us),
            reset_comm_delay_us: reset_communication_boot_delay_us.unwrap_or(boot_delay_us),
            quirks,
            qs,
            cw_latch: ControlwordLatch::default(),
            hooks,
            boot_due_us: None,
            boot_keeps_app: false,
            events: Deque::new(),
            events_dropped: 0,
            seen_cia: State::NotReadyToSwitchOn,
            seen_nmt: NmtState::Initialising,
        };
        core.seen_cia = core.cia.state;
        core.refresh_all();
        Ok(core)
    }

    /// Power-on: the boot-up ([`CoreOutput::Bootup`]) and pre-operational, after the boot
    /// delay ([`NodeConfig::boot_delay_us`]) if there is one.
    pub fn boot(&mut self, now_us: u64) {
        self.boot_with(Clocks::same(now_us));
    }

    /// [`DriveCore::boot`] with two clocks (the boot delay runs on the communication clock).
    pub fn boot_with(&mut self, clocks: Clocks) {
        self.now_us = clocks.app_us;
        self.comm_us = clocks.comm_us;
        self.start_boot(clocks.comm_us, false, self.boot_delay_us);
        self.observe();
    }

    /// Delay between power-on and the boot-up message, microseconds.
    pub fn boot_delay_us(&self) -> u64 {
        self.boot_delay_us
    }

    /// Whether a boot is pending (initialising, the boot delay not over).
    pub fn boot_pending(&self) -> bool {
        self.nmt == NmtState::Initialising && self.boot_due_us.is_some()
    }

    /// Complete a pending boot now (a lock-step runtime whose simulated time stands still
    /// while the master waits for the boot-up lets the delay pass on the wall clock).
    pub fn finish_boot(&mut self, now_us: u64) {
        if self.boot_pending() {
            self.now_us = now_us;
            self.comm_us = now_us;
            self.boot_now(now_us);
            self.observe();
        }
    }

    /// The next event (state change, EMCY raised or cleared, SYNC, finished SDO transfer),
    /// oldest first. Events beyond [`EVENT_QUEUE`] unread are dropped and counted in
    /// [`DriveCore::events_dropped`].
    pub fn poll_event(&mut self) -> Option<NodeEvent> {
        self.events.pop_front()
    }

    /// Events dropped because the event queue was full.
    pub fn events_dropped(&self) -> u32 {
        self.events_dropped
    }

    /// The next thing the core has to send, oldest first (a [`Node`] takes them itself).
    pub fn take_output(&mut self) -> Option<CoreOutput> {
        self.out.pop_front()
    }

    /// The application reports a condition of its own that is not a fault (a warning: a
    /// condition monitor's finding, e.g. backlash confirmed): EMCY `code` (manufacturer-specific
    /// 0xFF00..=0xFFFF, say) with `info` in its five manufacturer bytes, sent once, held in
    /// 0x1001 and 0x1003 until [`DriveCore::clear_condition`]; the CiA 402 state does not
    /// change. No allocation (real-time safe).
    pub fn raise_condition(&mut self, code: u16, info: [u8; 5]) {
        self.raise_emcy(code, info, Cause::Condition);
    }

    /// The condition of [`DriveCore::raise_condition`] is gone: its error clears (EMCY 0x0000
    /// when it was the last one).
    pub fn clear_condition(&mut self, code: u16) {
        self.clear_emcy(code, Cause::Condition);
    }

    /// Whether error `code` is active (EMCY sent, in 0x1001 / 0x1003).
    pub fn error_active(&self, code: u16) -> bool {
        self.emcy.is_active(code)
    }

    /// Set a stored object's value (raw form: signed sign-extended, REAL as bits) from the
    /// application, e.g. the runtime's statistics or the detector's verdict, for SDO reads
    /// and TPDOs. No allocation: fit for the real-time path. A `slot` of another dictionary
    /// is the caller's bug (it panics on an out-of-range slot).
    pub fn set_value(&mut self, slot: Slot, raw: u64) {
        self.store.set(slot.get(), raw);
    }

    /// A stored object's value (raw form), `None` for a slot a handler keeps.
    pub fn value(&self, slot: Slot) -> Option<u64> {
        match self.od.entry(slot).backing {
            Backing::Stored => Some(self.store.raw(slot.get())),
            Backing::Handler(_) => None,
        }
    }

    /// The object dictionary.
    pub fn od(&self) -> &ObjectDictionary {
        &self.od
    }

    /// The EDS (CiA 306) of this drive: every visible object; the objects a handler keeps
    /// have the value the drive answers to an SDO read as their DefaultValue.
    pub fn export_eds(&self, drive: &mut impl Drive, meta: &crate::od::eds::EdsMeta) -> String {
        let mut buf = [0u8; 8];
        let mut value_of = |e: &Entry| match e.backing {
            Backing::Handler(tag) if !e.dtype.variable() && e.access.readable() => drive
                .read_object(tag, e.index, e.sub, &mut buf)
                .ok()
                .map(|n| e.decode(&buf[..n])),
            _ => None,
        };
        crate::od::eds::export(&self.od, meta, &mut value_of)
    }

    // ----- read-only accessors -----
    /// Node ID, 1..=127, or 255 while non-configured (LSS).
    pub fn node_id(&self) -> u8 {
        self.node_id
    }
    /// NMT state (what the heartbeat reports).
    pub fn nmt_state(&self) -> NmtState {
        self.nmt
    }
    /// CiA 402 device state (decoded from statusword 0x6041).
    pub fn cia402_state(&self) -> State {
        self.cia.state
    }
    /// Mode of operation display (0x6061).
    pub fn mode(&self) -> i8 {
        self.cia.mode_display
    }
    /// Statusword 0x6041 as of the last tick.
    pub fn statusword(&self) -> u16 {
        self.cia.statusword
    }
    /// Position actual value 0x6064, user units.
    pub fn position_actual(&self) -> i32 {
        self.cia.position_actual_uu
    }
    /// Following error, user units.
    pub fn following_error(&self) -> f64 {
        self.cia.following_error_uu
    }
    /// Outputs dropped because the output queue was full (a [`Node`] adds its transmit
    /// queue's).
    pub fn tx_overflows(&self) -> u32 {
        self.out_dropped
    }
    /// Synchronous TPDOs not sent because the synchronous window (0x1007) had closed.
    pub fn sync_window_missed(&self) -> u32 {
        self.sync_window_missed
    }
    /// The synchronous window length 0x1007, us (0: none). A runtime that hands frames over
    /// late needs to tell [`Node::handle_late`] how late only when it is non-zero.
    #[inline]
    pub fn sync_window_us(&self) -> u32 {
        self.store.u32(R_1007)
    }
    /// Raw value of a stored object (diagnostics and tests), if it exists; truncated to 32
    /// bits (see [`DriveCore::value`] for 64-bit objects).
    pub fn object_raw(&self, index: u16, sub: u8) -> Option<u32> {
        match self.od.find(index, sub) {
            Lookup::Found(slot) => self.value(slot).map(|v| v as u32),
            _ => None,
        }
    }
    /// The interpolation time period 0x60C2 written by the master (value x 10^index s), us;
    /// `None` while it is 0 (the default: not set) or the dictionary has no 0x60C2.
    pub fn interpolation_period_us(&self) -> Option<u64> {
        if !matches!(self.od.find(0x60C2, 1), Lookup::Found(_)) {
            return None;
        }
        Some(interpolation_period_us(&self.store)).filter(|&p| p > 0)
    }
    /// Whether a CiA 402 state has the drive's power stage on.
    pub fn is_enabled(&self) -> bool {
        self.cia.state.enabled()
    }
}

impl Node {
    /// Build a node (state: initialising; call [`Node::boot`]). Every allocation the node
    /// will ever make happens here.
    pub fn new(cfg: NodeConfig) -> Result<Node, ConfigError> {
        let (lss, sdo_timeout_us) = (cfg.lss, cfg.sdo_timeout_us);
        let core = DriveCore::build(cfg, lss.is_some())?;
        let lss_slave = match lss {
            Some(l) => {
                let store = &core.store;
                let identity = LssIdentity {
                    vendor_id: store.u32(idx(0x1018, 1)),
                    product_code: store.u32(idx(0x1018, 2)),
                    revision_number: store.u32(idx(0x1018, 3)),
                    serial_number: store.u32(R_SERIAL),
                };
                let id = (core.node_id != UNCONFIGURED_NODE_ID).then_some(core.node_id);
                Some(
                    LssSlave::new(identity, id, l.bit_timing_index).map_err(|e| match e {
                        crate::cia305::LssConfigError::UnsupportedBitTiming(i) => {
                            ConfigError::InvalidBitTiming(i)
                        }
                        crate::cia305::LssConfigError::InvalidNodeId(n) => {
                            ConfigError::InvalidNodeId(n)
                        }
                    })?,
                )
            }
            None => None,
        };
        let mut sdo = SdoServer::with_capacity(core.store.max_capacity());
        sdo.timeout_us = sdo_timeout_us;
        let can = CanFrontEnd {
            sdo,
            lss: lss_slave,
            lss_store_external: lss.is_some_and(|l| l.store_external),
            lss_store: None,
            lss_bit_timing_activated: None,
        };
        Ok(Node { core, can })
    }

    /// The drive core inside the node.
    pub fn core(&self) -> &DriveCore {
        &self.core
    }

    /// The drive core inside the node, to change (what it sends goes out with the node's
    /// next call).
    pub fn core_mut(&mut self) -> &mut DriveCore {
        &mut self.core
    }

    /// Power-on: queue the boot-up message and enter pre-operational, after the boot delay
    /// ([`NodeConfig::boot_delay_us`]) if there is one.
    pub fn boot(&mut self, now_us: u64) {
        self.boot_with(Clocks::same(now_us));
    }

    /// [`Node::boot`] with two clocks (the boot delay runs on the communication clock).
    pub fn boot_with(&mut self, clocks: Clocks) {
        self.core.boot_with(clocks);
    }

    /// Complete a pending boot now (a lock-step runtime whose simulated time stands still
    /// while the master waits for the boot-up lets the delay pass on the wall clock).
    pub fn finish_boot(&mut self, now_us: u64) {
        self.core.finish_boot(now_us);
    }

    /// The core's output queue is the transmit queue: an output is framed on its COB-ID
    /// when taken ([`Node::pop_tx`]), and a frame of the front end's own (an LSS answer, an
    /// RTR's TPDO) is queued behind it as a [`CoreOutput::CanOnly`]. Before a frame that
    /// may change the node-ID or the EMCY COB-ID (an SDO, NMT or LSS frame: everything but
    /// SYNC and RPDO, the hot path) what is queued is framed in place, on the COB-IDs it
    /// was queued under.
    #[inline]
    fn frame_queued(&mut self) {
        if !self.core.out.is_empty() {
            self.frame_queued_now();
        }
    }

    /// [`Node::frame_queued`] when something is queued.
    fn frame_queued_now(&mut self) {
        let (node_id, emcy_cob) = (self.core.node_id, self.core.emcy_can_id());
        for o in self.core.out.iter_mut() {
            if !matches!(o, CoreOutput::CanOnly(_)) {
                *o = CoreOutput::CanOnly(frame(*o, node_id, emcy_cob));
            }
        }
    }

    /// Queue a frame of the front end's own (after the core's outputs so far).
    fn send(&mut self, f: CanFrame) {
        self.core.emit(CoreOutput::CanOnly(f));
    }

    /// A store configuration to write (once per request, with [`LssConfig::store_external`]);
    /// then call [`Node::lss_store_done`].
    pub fn take_lss_store(&mut self) -> Option<LssStore> {
        self.can.lss_store.take()
    }

    /// The outcome of the store handed out by [`Node::take_lss_store`]: the LSS answer is
    /// queued (error 0, or 2 when `stored` is false).
    pub fn lss_store_done(&mut self, stored: bool) {
        if let Some(f) = self.can.lss.as_mut().and_then(|l| l.store_done(stored)) {
            self.send(f);
        }
    }

    /// The last LSS activate bit timing not yet taken: (CiA 301 table index, switch delay
    /// ms). A real drive switches its CAN controller; the emulator can only report it.
    pub fn take_lss_bit_timing_activation(&mut self) -> Option<(u8, u16)> {
        self.can.lss_bit_timing_activated.take()
    }

    /// LSS state (waiting or configuration); `None` without LSS.
    pub fn lss_state(&self) -> Option<LssState> {
        self.can.lss.as_ref().map(|l| l.state())
    }

    /// The LSS slave's pending node-ID (active after the next NMT reset communication).
    pub fn lss_pending_node_id(&self) -> Option<u8> {
        self.can.lss.as_ref().and_then(|l| l.pending_node_id())
    }

    /// The next frame to send.
    pub fn pop_tx(&mut self) -> Option<CanFrame> {
        match self.core.out.pop_front()? {
            CoreOutput::CanOnly(f) => Some(f),
            o => Some(frame(o, self.core.node_id, self.core.emcy_can_id())),
        }
    }

    /// Frames dropped because the TX queue was full.
    pub fn tx_overflows(&self) -> u32 {
        self.core.out_dropped
    }

    /// Frames waiting in the TX queue.
    pub fn tx_pending(&self) -> usize {
        self.core.out.len()
    }

    /// An NMT reset: the LSS slave's node-ID for the reset (pending at reset communication,
    /// stored at reset node) becomes the core's.
    fn take_lss_node_id(&mut self, reset_node: bool) {
        let Some(lss) = self.can.lss.as_mut() else {
            return;
        };
        if reset_node {
            lss.reset_node();
            self.can.lss_store = None;
        } else {
            lss.reset_communication();
        }
        self.core.node_id = lss.active_node_id().unwrap_or(UNCONFIGURED_NODE_ID);
    }
}

/// The dictionary with the defaults a vendor switch changes: TPDO COB-IDs with bit 30 (no
/// RTR, 3.10), the heartbeat producer's period (3.5).
fn quirk_defaults(
    mut od: ObjectDictionary,
    quirks: &Quirks,
) -> Result<ObjectDictionary, ConfigError> {
    let fail = |switch: &'static str| {
        move |e: crate::od::OdError| ConfigError::QuirkDefault {
            switch,
            reason: e.to_string(),
        }
    };
    if quirks.tpdo_rtr_unsupported.is_some() {
        let cob_ids: Vec<(u16, DefaultValue)> = od
            .iter()
            .filter(|(_, e)| (0x1800..=0x19FF).contains(&e.index) && e.sub == 1)
            .map(|(_, e)| (e.index, e.default.clone()))
            .collect();
        for (index, d) in cob_ids {
            let with_bit = match d {
                DefaultValue::Value(v) => DefaultValue::Value(v | 0x4000_0000),
                DefaultValue::NodeId(b) => DefaultValue::NodeId(b | 0x4000_0000),
                other => other,
            };
            od.set_default(index, 1, with_bit)
                .map_err(fail("tpdo_rtr_unsupported"))?;
        }
    }
    if let Some(b) = quirks.bootup_then_heartbeat {
        if od.get(0x1017, 0).is_some() {
            od.set_default(
                0x1017,
                0,
                DefaultValue::Value(u64::from(b.heartbeat_ms_default)),
            )
            .map_err(fail("bootup_then_heartbeat"))?;
        }
    }
    Ok(od)
}
