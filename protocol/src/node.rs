//! The node: glues the CiA 301 services and the CiA 402 layer to the object dictionary.
//! Sans-IO: `handle` takes a received frame, `poll` runs timers and one CiA 402 tick,
//! `pop_tx` hands out frames to send. Built once from a [`NodeConfig`]; nothing here
//! allocates after `Node::new`.

pub(crate) mod access;
pub(crate) mod writes;

use heapless::Deque;

use crate::cia301::emcy::{Cause, Emcy};
use crate::cia301::heartbeat::{Consumer, Producer};
use crate::cia301::nmt::{self, NmtCommand, NmtState};
use crate::cia301::pdo::mapping;
use crate::cia301::pdo::rpdo::RxOutcome;
use crate::cia301::pdo::PdoEngine;
use crate::cia301::sdo::{abort, ObjectAccess, SdoServer};
use crate::cia301::sync::{SyncConsumer, EMCY_SYNC_LENGTH, EMCY_SYNC_LOSS};
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
use writes::{ObjectWrite, Origin, Verdict, WriteHooks};

/// Capacity of the transmit queue; frames beyond it are counted in
/// [`Node::tx_overflows`] and dropped.
pub const TX_QUEUE: usize = 64;

/// EMCY code for a lost heartbeat producer (the master).
pub const EMCY_HEARTBEAT: u16 = 0x8130;
/// EMCY code for an RPDO value the drive refuses (the checks of an SDO write: range, a
/// supported mode, min <= max): CiA 402 "parameter error" (0x6320). The object keeps its
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

/// Queue a frame to send; a full queue drops it and counts.
fn push(tx: &mut Deque<CanFrame, TX_QUEUE>, overflows: &mut u32, f: CanFrame) {
    if tx.push_back(f).is_err() {
        *overflows = overflows.wrapping_add(1);
    }
}

/// Everything but the SDO server (so the server can borrow it as its object access). The
/// fields the services' write hooks ([`writes`]) work on are visible to the crate.
#[derive(Clone, Debug)]
pub(crate) struct Core {
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
    pub(crate) hb: Producer,
    pub(crate) hbc: Consumer,
    pub(crate) hb_lost: bool,
    emcy: Emcy,
    cia: Cia402,
    tx: Deque<CanFrame, TX_QUEUE>,
    tx_overflows: u32,
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
    /// The services' write rules, by object index (filled in [`Node::new`]).
    hooks: WriteHooks,
    /// While initialising after a reset: when the boot-up is due.
    boot_due_us: Option<u64>,
    /// The pending boot follows a communication reset: the application (CiA 402) keeps
    /// running meanwhile, only the communication is silent.
    boot_keeps_app: bool,
    events: Deque<NodeEvent, EVENT_QUEUE>,
    events_dropped: u32,
    /// LSS slave (CiA 305); `node_id` is its active node-ID (0xFF: non-configured).
    lss: Option<LssSlave>,
    /// Store configuration is written by the application ([`LssConfig::store_external`]).
    lss_store_external: bool,
    /// A store the application has not taken yet.
    lss_store: Option<LssStore>,
    /// The last activate bit timing (table index, switch delay ms), not yet taken.
    lss_bit_timing_activated: Option<(u8, u16)>,
    /// CiA 402 and NMT state as last reported in an event.
    seen_cia: State,
    seen_nmt: NmtState,
}

/// A CiA 301 + CiA 402 servo-drive node.
#[derive(Clone, Debug)]
pub struct Node {
    sdo: SdoServer,
    core: Core,
}

struct Access<'a, D: Drive> {
    core: &'a mut Core,
    drive: &'a mut D,
}

fn lookup(od: &ObjectDictionary, index: u16, sub: u8) -> Result<(usize, &Entry), u32> {
    match od.find(index, sub) {
        Lookup::Found(slot) => Ok((slot.get(), od.entry(slot))),
        Lookup::NoObject => Err(abort::NO_OBJECT),
        Lookup::NoSub => Err(abort::NO_SUB),
    }
}

impl<D: Drive> ObjectAccess for Access<'_, D> {
    fn read(&mut self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, u32> {
        let (slot, e) = lookup(&self.core.od, index, sub)?;
        if !e.access.readable() {
            return Err(abort::WRITE_ONLY);
        }
        match e.backing {
            Backing::Handler(tag) => self.drive.read_object(tag, index, sub, buf),
            Backing::Stored => Ok(self.core.store.read_bytes(slot, e.dtype.size(), buf)),
        }
    }

    fn check_write(&mut self, index: u16, sub: u8, size: Option<usize>) -> Result<(), u32> {
        let (_, e) = lookup(&self.core.od, index, sub)?;
        if !e.access.writable() {
            return Err(abort::READ_ONLY);
        }
        let n = e.dtype.size();
        match size {
            Some(s) if n > 0 && s > n => Err(abort::TOO_LONG),
            Some(s) if n > 0 && s < n => Err(abort::TOO_SHORT),
            Some(s) if n == 0 && s > e.capacity => Err(abort::TOO_LONG),
            _ => Ok(()),
        }
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), u32> {
        self.check_write(index, sub, Some(data.len()))?;
        let (slot, e) = lookup(&self.core.od, index, sub)?;
        if e.dtype.variable() {
            if let Backing::Handler(tag) = e.backing {
                return self.drive.write_object(tag, index, sub, data);
            }
            return if self.core.store.write_bytes(slot, data) {
                Ok(())
            } else {
                Err(abort::TOO_LONG)
            };
        }
        let raw = e.decode(data);
        if let Err(high) = e.check_limits(raw) {
            return Err(if high {
                abort::VALUE_HIGH
            } else {
                abort::VALUE_LOW
            });
        }
        if let Backing::Handler(tag) = e.backing {
            return self.drive.write_object(tag, index, sub, data);
        }
        self.core.write_stored(&ObjectWrite {
            row: slot,
            index,
            sub,
            raw,
            origin: Origin::Sdo,
        })
    }
}

impl Core {
    fn event(&mut self, e: NodeEvent) {
        if self.events.push_back(e).is_err() {
            self.events_dropped = self.events_dropped.wrapping_add(1);
        }
    }

    /// Report state changes since the last call as events.
    fn observe(&mut self) {
        if self.cia.state != self.seen_cia {
            let from = self.seen_cia;
            self.seen_cia = self.cia.state;
            self.event(NodeEvent::Cia402State {
                from,
                to: self.cia.state,
            });
        }
        if self.nmt != self.seen_nmt {
            let from = self.seen_nmt;
            self.seen_nmt = self.nmt;
            self.event(NodeEvent::NmtState { from, to: self.nmt });
        }
    }

    fn raise_emcy(&mut self, code: u16, info: [u8; 5], cause: Cause) {
        if self.emcy.raise(&mut self.store, code, info, cause) {
            self.event(NodeEvent::EmcyRaised { code });
        }
    }

    pub(crate) fn clear_emcy(&mut self, code: u16, cause: Cause) {
        if self.emcy.clear(&mut self.store, code, cause) {
            self.event(NodeEvent::EmcyCleared { code });
        }
    }

    /// `cause` holds no error any more: the errors only it held clear.
    fn clear_cause(&mut self, cause: Cause) {
        for code in self.emcy.clear_cause(&mut self.store, cause) {
            self.event(NodeEvent::EmcyCleared { code });
        }
    }

    /// Every error goes (reset node).
    fn clear_all_emcy(&mut self) {
        for code in self.emcy.active_codes() {
            self.event(NodeEvent::EmcyCleared { code });
        }
        self.emcy.reset(&mut self.store);
    }

    /// RPDO `k` arrived with a length error `code` (0 = right length): raise it once, and
    /// clear it when no RPDO holds it any more.
    fn rpdo_length_condition(&mut self, k: usize, code: u16, len: u8) {
        let old = self.pdo.rpdo[k].len_error;
        if old == code {
            return;
        }
        self.pdo.rpdo[k].len_error = code;
        if old != 0 && !self.pdo.rpdo.iter().any(|p| p.len_error == old) {
            self.clear_emcy(old, Cause::Condition);
        }
        if code != 0 {
            let info = [k as u8 + 1, len, self.pdo.rpdo[k].len, 0, 0];
            self.raise_emcy(code, info, Cause::Condition);
        }
    }

    /// RPDO `k` carried only acceptable values (`ok`) or not: EMCY 0x6320 held meanwhile.
    fn rpdo_value_condition(&mut self, k: usize, ok: bool) {
        if self.pdo.rpdo[k].value_error != ok {
            return;
        }
        self.pdo.rpdo[k].value_error = !ok;
        if ok {
            if !self.pdo.rpdo.iter().any(|p| p.value_error) {
                self.clear_emcy(EMCY_RPDO_VALUE, Cause::Condition);
            }
        } else {
            self.raise_emcy(EMCY_RPDO_VALUE, [k as u8 + 1, 0, 0, 0, 0], Cause::Condition);
        }
    }

    /// A reconfigured (or reset) RPDO starts without errors: they are reported again.
    pub(crate) fn rpdo_conditions_reset(&mut self, k: usize) {
        self.rpdo_length_condition(k, 0, 0);
        self.rpdo_value_condition(k, true);
    }

    fn push(&mut self, f: CanFrame) {
        push(&mut self.tx, &mut self.tx_overflows, f);
    }

    /// A write to a stored object whose type and dictionary limits were checked, from an SDO
    /// download or an RPDO: the hook of the service that owns the object ([`WriteHooks`])
    /// checks it and applies its side effects; the value is stored unless the hook applied
    /// it itself. A refused write changes nothing.
    pub(crate) fn write_stored(&mut self, w: &ObjectWrite) -> Result<(), u32> {
        if let Some(hook) = self.hooks.find(w.index) {
            if hook(self, w)? == Verdict::Applied {
                return Ok(());
            }
        }
        self.store.set(w.row, w.raw);
        Ok(())
    }

    /// One value of a received RPDO for the store row `row`: the dictionary's limits, then
    /// [`Core::write_stored`] as for an SDO write. Whether it was taken.
    fn rpdo_value(&mut self, row: usize, raw: u64) -> bool {
        let e = self.od.entry(Slot::at(row));
        if e.check_limits(raw).is_err() {
            return false;
        }
        let w = ObjectWrite {
            row,
            index: e.index,
            sub: e.sub,
            raw,
            origin: Origin::Rpdo,
        };
        self.write_stored(&w).is_ok()
    }

    /// Apply received data to RPDO `k`'s mapped objects, each value through
    /// [`Core::rpdo_value`]. Whether every value was taken (for
    /// [`Core::rpdo_value_condition`]).
    fn apply_rpdo(&mut self, k: usize, data: &[u8]) -> bool {
        let (map, n, len) = self.pdo.rpdo[k].rx_map();
        let Some(data) = data.get(..len) else {
            return false;
        };
        mapping::unpack(&map[..n], data, |row, raw| self.rpdo_value(row, raw))
    }

    /// An SDO answer to a request at `now_us`: sent now or after the vendor's delay.
    fn sdo_answer(&mut self, f: CanFrame, now_us: u64) {
        match self.qs.sdo_answer(&self.quirks, f, now_us) {
            SdoAnswer::Now(f) => self.push(f),
            SdoAnswer::Queued => {}
            SdoAnswer::Dropped => self.tx_overflows = self.tx_overflows.wrapping_add(1),
        }
    }

    /// The period `sync_watchdog` watches, us (0: none), and whether the drive is in a
    /// watched state (OPERATION ENABLED in one of its modes).
    fn watchdog_period(&self) -> (u64, bool) {
        let Some(w) = &self.quirks.sync_watchdog else {
            return (0, false);
        };
        let watched =
            self.cia.state == State::OperationEnabled && w.modes.contains(&self.cia.mode_display);
        let cycle = u64::from(self.store.u32(R_1006));
        let period = match w.period_from {
            WatchdogPeriod::Interpolation => match interpolation_period_us(&self.store) {
                0 => cycle,
                p => p,
            },
            WatchdogPeriod::CommunicationCycle => cycle,
        };
        (period, watched)
    }

    fn refresh_all(&mut self) {
        for k in 0..self.pdo.rpdo.len() {
            self.rpdo_conditions_reset(k);
        }
        self.pdo.refresh_all(&self.od, &self.store);
        for i in 0..4 {
            let e = self.store.u32(R_1016 + i);
            self.hbc.configure(i, e);
        }
    }

    /// Event-driven TPDOs (with the values of the last CiA 402 cycle) and EMCYs held by their
    /// inhibit time, on the communication clock.
    fn comm_timers_after(&mut self, comm_us: u64) {
        if self.nmt == NmtState::Operational {
            let (tx, overflows) = (&mut self.tx, &mut self.tx_overflows);
            self.pdo
                .poll_events(&self.store, comm_us, &mut |f| push(tx, overflows, f));
        }
        if self.emcy_allowed() {
            let inhibit = self.store.u32(R_1015) as u16;
            while let Some(d) = self.emcy.next(comm_us, inhibit) {
                let f = CanFrame::new(self.store.u32(R_1014) & 0x7FF, &d);
                self.push(f);
            }
        }
    }

    fn emcy_allowed(&self) -> bool {
        matches!(self.nmt, NmtState::PreOperational | NmtState::Operational)
            && self.store.u32(R_1014) & 0x8000_0000 == 0
            && !self.qs.not_ready()
    }

    /// Report a communication event without keeping it active (history + EMCY frame).
    fn report(&mut self, code: u16, info: [u8; 5]) {
        if self.emcy.report(&mut self.store, code, info) {
            self.event(NodeEvent::EmcyRaised { code });
            self.event(NodeEvent::EmcyCleared { code });
        }
    }

    /// Begin a boot: at once without a boot delay (`delay_us`), else initialising (silent,
    /// deaf) until the delay has passed ([`Node::poll`] or [`Node::finish_boot`] completes
    /// it).
    fn start_boot(&mut self, now_us: u64, keeps_app: bool, delay_us: u64) {
        self.qs.on_reset();
        if delay_us == 0 {
            self.boot(now_us);
        } else {
            self.nmt = NmtState::Initialising;
            self.boot_due_us = Some(now_us.saturating_add(delay_us));
            self.boot_keeps_app = keeps_app;
        }
    }

    fn boot(&mut self, now_us: u64) {
        self.boot_due_us = None;
        self.boot_keeps_app = false;
        if self.node_id == UNCONFIGURED_NODE_ID {
            // CiA 305: no node-ID, no boot-up; the node stays initialising and answers LSS
            // only (as Lely's NMT does; CANopenNode skips the other services).
            return;
        }
        self.nmt = NmtState::PreOperational;
        self.refresh_all();
        self.sync = SyncConsumer::default();
        self.pending_sync = None;
        self.hb_lost = false;
        self.hb.restart(now_us, self.store.u32(R_1017) as u16);
        self.push(CanFrame::new(
            cob::HEARTBEAT + self.node_id as u32,
            &Heartbeat::BOOTUP.emit(),
        ));
        self.qs.on_bootup(&self.quirks, now_us);
    }

    fn restore_range(&mut self, lo: u16, hi: u16) {
        let serial = self.store.raw(R_SERIAL);
        if self.has_saved {
            self.store.copy_range(&self.saved, &self.od, lo, hi);
        } else {
            self.store.reset_range(&self.od, lo, hi, self.node_id);
        }
        // The serial number (0x1018:4, $NODEID in the standard dictionary) is part of the
        // LSS address: it stays what it was at power-on when LSS changes the node-ID.
        self.store.set(R_SERIAL, serial);
    }

    /// An NMT reset: the LSS slave's node-ID for the reset (pending at reset communication,
    /// stored at reset node) becomes the node's.
    fn take_lss_node_id(&mut self, reset_node: bool) {
        let Some(lss) = self.lss.as_mut() else { return };
        if reset_node {
            lss.reset_node();
            self.lss_store = None;
        } else {
            lss.reset_communication();
        }
        self.node_id = lss.active_node_id().unwrap_or(UNCONFIGURED_NODE_ID);
    }

    /// A SYNC, handled `late_us` after it arrived (the runtime read it late). Synchronous TPDOs
    /// are sampled and queued now, unless the synchronous window (0x1007, non-zero) has
    /// already closed: then CiA 301 says they are not sent (counted in 0x2100).
    fn on_sync(&mut self, frame: &CanFrame, clocks: Clocks, late_us: u64) -> FrameEvent {
        let now_us = clocks.app_us;
        let window_us = u64::from(self.store.u32(R_1007));
        let window_closed = window_us > 0 && late_us > window_us;
        let overflow = self.store.u32(R_1019) as u8;
        if let Some(l) = self.quirks.late_sync_statusword_bit15 {
            // a SYNC later than the period 0x1006 allows (docs/quirks.md 3.14)
            let period = u64::from(self.store.u32(R_1006));
            self.qs.late_sync = period != 0
                && self.sync.last_us.is_some_and(|last| {
                    now_us.saturating_sub(last) > period + u64::from(l.late_tolerance_us)
                });
        }
        let (_, watched) = self.watchdog_period();
        self.qs.watchdog_sync(now_us, watched);
        let s = self
            .sync
            .on_sync(now_us, frame.len, frame.data[0], overflow);
        if s.length_error && self.emcy_allowed() {
            self.report(EMCY_SYNC_LENGTH, [frame.len, 0, 0, 0, 0]);
        }
        if s.recovered {
            // the supervision is satisfied again; a fault it caused stays until reset
            self.clear_emcy(EMCY_SYNC_LOSS, Cause::Condition);
        }
        self.pending_sync = Some(now_us);
        if self.nmt == NmtState::Operational {
            for k in 0..self.pdo.rpdo.len() {
                if let Some(data) = self.pdo.take_sync_rpdo(k) {
                    let ok = self.apply_rpdo(k, &data);
                    self.rpdo_value_condition(k, ok);
                }
            }
            let (tx, overflows) = (&mut self.tx, &mut self.tx_overflows);
            let missed = self
                .pdo
                .on_sync(&self.store, clocks.comm_us, window_closed, &mut |f| {
                    push(tx, overflows, f)
                });
            self.sync_window_missed = self.sync_window_missed.wrapping_add(missed);
        }
        self.event(NodeEvent::Sync { counter: s.counter });
        FrameEvent::Sync { counter: s.counter }
    }
}

impl Node {
    /// Build a node (state: initialising; call [`Node::boot`]). Every allocation the node
    /// will ever make happens here.
    pub fn new(cfg: NodeConfig) -> Result<Node, ConfigError> {
        let NodeConfig {
            node_id,
            info,
            od,
            boot_delay_us,
            reset_node_boot_delay_us,
            reset_communication_boot_delay_us,
            sdo_timeout_us,
            lss,
            quirks,
        } = cfg;
        let unconfigured = node_id == UNCONFIGURED_NODE_ID && lss.is_some();
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
        let mut sdo = SdoServer::with_capacity(store.max_capacity());
        sdo.timeout_us = sdo_timeout_us;
        let mut pdo = PdoEngine::new(&od);
        pdo.rules = quirks.pdo_rules();
        let qs = QuirkState::new(&quirks, &od);
        let lss_slave = match lss {
            Some(l) => {
                let identity = LssIdentity {
                    vendor_id: store.u32(idx(0x1018, 1)),
                    product_code: store.u32(idx(0x1018, 2)),
                    revision_number: store.u32(idx(0x1018, 3)),
                    serial_number: store.u32(R_SERIAL),
                };
                let id = (node_id != UNCONFIGURED_NODE_ID).then_some(node_id);
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
        let fe_window_zero_off = od.device.following_error_window_zero_off;
        let si_rows = si_unit_rows(&od);
        let mut core = Core {
            node_id,
            info,
            od,
            store,
            saved,
            has_saved: false,
            nmt: NmtState::Initialising,
            pdo,
            sync: SyncConsumer::default(),
            hb: Producer::default(),
            hbc: Consumer::default(),
            hb_lost: false,
            emcy: Emcy::with_history(history_len),
            cia: Cia402::new(factor, quirks.cia402()).with_device(fe_window_zero_off, si_rows),
            tx: Deque::new(),
            tx_overflows: 0,
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
            hooks: WriteHooks::standard(),
            boot_due_us: None,
            boot_keeps_app: false,
            events: Deque::new(),
            events_dropped: 0,
            lss: lss_slave,
            lss_store_external: lss.is_some_and(|l| l.store_external),
            lss_store: None,
            lss_bit_timing_activated: None,
            seen_cia: State::NotReadyToSwitchOn,
            seen_nmt: NmtState::Initialising,
        };
        core.seen_cia = core.cia.state;
        core.refresh_all();
        Ok(Node { sdo, core })
    }

    /// Power-on: queue the boot-up message and enter pre-operational, after the boot delay
    /// ([`NodeConfig::boot_delay_us`]) if there is one.
    pub fn boot(&mut self, now_us: u64) {
        self.boot_with(Clocks::same(now_us));
    }

    /// [`Node::boot`] with two clocks (the boot delay runs on the communication clock).
    pub fn boot_with(&mut self, clocks: Clocks) {
        self.core.now_us = clocks.app_us;
        self.core.comm_us = clocks.comm_us;
        self.core
            .start_boot(clocks.comm_us, false, self.core.boot_delay_us);
        self.core.observe();
    }

    /// Delay between power-on and the boot-up message, microseconds.
    pub fn boot_delay_us(&self) -> u64 {
        self.core.boot_delay_us
    }

    /// Whether a boot is pending (initialising, the boot delay not over).
    pub fn boot_pending(&self) -> bool {
        self.core.nmt == NmtState::Initialising && self.core.boot_due_us.is_some()
    }

    /// Complete a pending boot now (a lock-step runtime whose simulated time stands still
    /// while the master waits for the boot-up lets the delay pass on the wall clock).
    pub fn finish_boot(&mut self, now_us: u64) {
        if self.boot_pending() {
            self.core.now_us = now_us;
            self.core.comm_us = now_us;
            self.core.boot(now_us);
            self.core.observe();
        }
    }

    fn nmt_command(&mut self, cmd: NmtCommand, now_us: u64, drive: &mut impl Drive) {
        let c = &mut self.core;
        match cmd {
            NmtCommand::ResetNode => {
                // The application resets too: the drive re-initialises its axis.
                drive.reset();
                c.take_lss_node_id(true);
                c.restore_range(0x0000, 0xFFFF);
                let f = Factor::from_info(&c.info).unwrap_or(Factor {
                    inc_per_uu: 1.0,
                    vel_inc_per_uu: 1.0,
                    acc_inc_per_uu: 1.0,
                });
                c.cia = Cia402::new(f, c.quirks.cia402()).with_device(
                    c.od.device.following_error_window_zero_off,
                    si_unit_rows(&c.od),
                );
                c.cw_latch = ControlwordLatch::default();
                c.clear_all_emcy();
                self.sdo.reset();
                let delay = c.reset_node_delay_us;
                c.start_boot(now_us, false, delay);
            }
            NmtCommand::ResetCommunication => {
                c.take_lss_node_id(false);
                c.restore_range(0x1000, 0x1FFF);
                // 0x1001 / 0x1003 keep what the drive is still in FAULT for
                let before = c.emcy.active_codes();
                c.emcy.reset_communication(&mut c.store);
                for code in before {
                    if !c.emcy.is_active(code) {
                        c.event(NodeEvent::EmcyCleared { code });
                    }
                }
                self.sdo.reset();
                let delay = c.reset_comm_delay_us;
                c.start_boot(now_us, true, delay);
            }
            _ => {
                let next = nmt::next_state(cmd);
                if next == NmtState::Operational && c.nmt != NmtState::Operational {
                    c.pdo.restart();
                }
                if next != NmtState::Operational {
                    self.sdo_reset_if_stopped(next);
                }
                self.core.nmt = next;
            }
        }
    }

    fn sdo_reset_if_stopped(&mut self, next: NmtState) {
        if next == NmtState::Stopped {
            self.sdo.reset();
        }
    }

    /// Handle one received frame.
    pub fn handle(&mut self, frame: &CanFrame, now_us: u64, drive: &mut impl Drive) -> FrameEvent {
        self.handle_with(frame, Clocks::same(now_us), 0, drive)
    }

    /// Handle one received frame that arrived `late_us` before `now_us` (a runtime that read it
    /// late says so): a SYNC handled after its synchronous window (0x1007) closed sends no
    /// synchronous TPDOs. Everything else is as [`Node::handle`].
    pub fn handle_late(
        &mut self,
        frame: &CanFrame,
        now_us: u64,
        late_us: u64,
        drive: &mut impl Drive,
    ) -> FrameEvent {
        self.handle_with(frame, Clocks::same(now_us), late_us, drive)
    }

    /// [`Node::handle_late`] with two clocks ([`Clocks`]): a lock-step runtime gives the wall
    /// clock as the communication clock.
    pub fn handle_with(
        &mut self,
        frame: &CanFrame,
        clocks: Clocks,
        late_us: u64,
        drive: &mut impl Drive,
    ) -> FrameEvent {
        let ev = self.handle_frame(frame, clocks, late_us, drive);
        if let Some(t) = self.sdo.take_finished() {
            self.core.event(NodeEvent::SdoTransfer(t));
        }
        self.core.observe();
        ev
    }

    /// A frame, dispatched on what it is for this node ([`RxTable::classify`] on the COB-IDs
    /// configured now) to one function per service, once the NMT and quirk states that hear
    /// little have had their say.
    fn handle_frame(
        &mut self,
        frame: &CanFrame,
        clocks: Clocks,
        late_us: u64,
        drive: &mut impl Drive,
    ) -> FrameEvent {
        self.core.now_us = clocks.app_us;
        self.core.comm_us = clocks.comm_us;
        // everything a frame times here is communication: resets (boot delay), heartbeats,
        // SDO, RTR answers; a SYNC is the exception (on_sync takes both)
        let now_us = clocks.comm_us;
        let rx = self.rx_table().classify(frame);
        match rx {
            Rx::Other => return FrameEvent::Ignored,
            Rx::Lss => return self.lss_frame(frame, now_us, drive),
            _ => {}
        }
        if let Some(ev) = self.hard_of_hearing(frame, now_us, drive) {
            return ev;
        }
        let nmt = self.core.nmt;
        match rx {
            Rx::Nmt => self.nmt_frame(frame, now_us, drive),
            Rx::Sync => self.core.on_sync(frame, clocks, late_us),
            Rx::Heartbeat(node) => {
                self.heartbeat_in(node, now_us);
                FrameEvent::Handled
            }
            _ if nmt == NmtState::Stopped => FrameEvent::Ignored,
            Rx::Sdo => self.sdo_frame(frame, now_us, drive),
            _ if nmt != NmtState::Operational => FrameEvent::Ignored,
            Rx::Rpdo => self.rpdo_frame(frame),
            Rx::Rtr => self.rtr_frame(frame, now_us),
            Rx::Other | Rx::Lss => FrameEvent::Ignored,
        }
    }

    /// The COB-IDs this node receives on, as configured now.
    fn rx_table(&self) -> RxTable {
        RxTable {
            sync: self.sync_cob(),
            sdo_rx: cob::SDO_RX + self.core.node_id as u32,
            lss: self.core.boot_due_us.is_none() && self.core.lss.is_some(),
        }
    }

    /// The SYNC COB-ID (0x1005, 11 bits).
    fn sync_cob(&self) -> u32 {
        self.core.store.u32(R_1005) & 0x7FF
    }

    /// The states that hear little (LSS aside): non-configured, booting, not ready after
    /// boot-up. `Some`: the frame's fate there; `None`: the node hears it.
    fn hard_of_hearing(
        &mut self,
        frame: &CanFrame,
        now_us: u64,
        drive: &mut impl Drive,
    ) -> Option<FrameEvent> {
        if self.lss_unconfigured() {
            // Non-configured: silent but for LSS; a broadcast NMT reset still resets it.
            return Some(match nmt::decode(frame, 0) {
                Some(cmd @ (NmtCommand::ResetNode | NmtCommand::ResetCommunication)) => {
                    self.nmt_command(cmd, now_us, drive);
                    FrameEvent::Handled
                }
                _ => FrameEvent::Ignored,
            });
        }
        let is_sync = frame.id == self.sync_cob() && !frame.rtr;
        if self.core.nmt == NmtState::Initialising {
            // Deaf while booting, but a SYNC still tells a lock-step runtime time goes on.
            if self.core.boot_due_us.is_some() && is_sync {
                return Some(FrameEvent::Sync { counter: None });
            }
            return Some(FrameEvent::Ignored);
        }
        if self.core.qs.not_ready() {
            // not_ready_after_bootup (docs/quirks.md 3.6): only a reset is heard; a SYNC still
            // tells a lock-step runtime that time goes on
            return Some(match nmt::decode(frame, self.core.node_id) {
                Some(cmd @ (NmtCommand::ResetNode | NmtCommand::ResetCommunication))
                    if frame.id == 0 =>
                {
                    self.nmt_command(cmd, now_us, drive);
                    FrameEvent::Handled
                }
                _ if is_sync => FrameEvent::Sync { counter: None },
                _ => FrameEvent::Ignored,
            });
        }
        None
    }

    /// NMT module control (COB-ID 0) addressed to this node or to all.
    fn nmt_frame(&mut self, frame: &CanFrame, now_us: u64, drive: &mut impl Drive) -> FrameEvent {
        match nmt::decode(frame, self.core.node_id) {
            Some(cmd) => {
                self.nmt_command(cmd, now_us, drive);
                FrameEvent::Handled
            }
            None => FrameEvent::Ignored,
        }
    }

    /// An SDO request to this node's server (pre-operational and operational).
    fn sdo_frame(&mut self, frame: &CanFrame, now_us: u64, drive: &mut impl Drive) -> FrameEvent {
        if frame.rtr || frame.len != 8 {
            return FrameEvent::Ignored;
        }
        let in_block = self.sdo.expects_block_segment();
        let c = &mut self.core;
        if c.qs.sdo_request(&c.quirks, &frame.data, in_block) == SdoGate::Drop {
            return FrameEvent::Handled;
        }
        let mut outv: heapless::Vec<[u8; 8], 16> = heapless::Vec::new();
        let mut acc = Access {
            core: &mut self.core,
            drive,
        };
        self.sdo.handle(&frame.data, now_us, &mut acc, &mut |f| {
            let _ = outv.push(f);
        });
        let tx_cob = cob::SDO_TX + self.core.node_id as u32;
        for f in outv {
            self.core.sdo_answer(CanFrame::new(tx_cob, &f), now_us);
        }
        FrameEvent::Handled
    }

    /// A data frame in operational: an RPDO if one is configured on its COB-ID.
    fn rpdo_frame(&mut self, frame: &CanFrame) -> FrameEvent {
        let c = &mut self.core;
        match c.pdo.receive(frame) {
            RxOutcome::NotRpdo => FrameEvent::Ignored,
            RxOutcome::Received {
                k,
                len,
                length_code,
                apply,
            } => {
                let ok = apply.then(|| c.apply_rpdo(k, &frame.data));
                c.rpdo_length_condition(k, length_code, len);
                if let Some(ok) = ok {
                    c.rpdo_value_condition(k, ok);
                }
                FrameEvent::Handled
            }
        }
    }

    /// A remote frame in operational: the TPDO configured on its COB-ID, if it may answer.
    fn rtr_frame(&mut self, frame: &CanFrame, now_us: u64) -> FrameEvent {
        let c = &mut self.core;
        if c.quirks.tpdo_rtr_unsupported.is_some() {
            // no remote frames answered (docs/quirks.md 3.10)
            return FrameEvent::Ignored;
        }
        let (tx, overflows) = (&mut c.tx, &mut c.tx_overflows);
        if c.pdo
            .on_rtr(&c.store, frame, now_us, &mut |f| push(tx, overflows, f))
        {
            return FrameEvent::Handled;
        }
        FrameEvent::Ignored
    }

    /// Non-configured (node-ID 0xFF) and not booting: only LSS is served.
    fn lss_unconfigured(&self) -> bool {
        self.core.node_id == UNCONFIGURED_NODE_ID && self.core.boot_due_us.is_none()
    }

    /// An LSS request (COB-ID 0x7E5), in every NMT state once booted (as Lely and
    /// CANopenNode) and while non-configured.
    fn lss_frame(&mut self, frame: &CanFrame, now_us: u64, drive: &mut impl Drive) -> FrameEvent {
        let Some(lss) = self.core.lss.as_mut() else {
            return FrameEvent::Ignored;
        };
        let out = lss.handle(frame);
        if let Some(f) = out.response {
            self.core.push(f);
        }
        match out.event {
            Some(LssEvent::ResetCommunication { .. }) => {
                // CiA 305: a non-configured node given a node-ID boots with it when switched
                // back to waiting.
                self.nmt_command(NmtCommand::ResetCommunication, now_us, drive);
            }
            Some(LssEvent::StoreRequested {
                node_id,
                bit_timing_index,
            }) => {
                if self.core.lss_store_external {
                    self.core.lss_store = Some(LssStore {
                        node_id,
                        bit_timing_index,
                    });
                } else if let Some(f) = self.core.lss.as_mut().and_then(|l| l.store_done(true)) {
                    self.core.push(f);
                }
            }
            Some(LssEvent::ActivateBitTiming {
                table_index,
                switch_delay_ms,
            }) => self.core.lss_bit_timing_activated = Some((table_index, switch_delay_ms)),
            _ => {}
        }
        FrameEvent::Handled
    }

    fn heartbeat_in(&mut self, id_low: u8, now_us: u64) {
        let node = id_low & 0x7F;
        let c = &mut self.core;
        if c.hbc.is_monitoring(node) {
            c.hbc.on_heartbeat(node, now_us);
            if c.hb_lost {
                c.hb_lost = false;
                c.clear_emcy(EMCY_HEARTBEAT, Cause::Condition);
            }
        }
    }

    /// Timers, the CiA 402 state machine and mode, and exactly one `drive.command(..)`.
    pub fn poll(&mut self, now_us: u64, drive: &mut impl Drive) {
        self.poll_with(Clocks::same(now_us), drive);
    }

    /// [`Node::poll`] with two clocks ([`Clocks`]).
    pub fn poll_with(&mut self, clocks: Clocks, drive: &mut impl Drive) {
        self.poll_timers_and_drive(clocks, drive);
        if let Some(t) = self.sdo.take_finished() {
            self.core.event(NodeEvent::SdoTransfer(t));
        }
        self.core.observe();
    }

    /// The communication timers alone, at `comm_us` on the communication clock: SDO
    /// time-out, a boot whose delay is over, the heartbeat producer and consumer, event-driven
    /// TPDOs, EMCYs held by their inhibit time. No CiA 402 cycle, no command to the drive: a
    /// lock-step runtime calls it between SYNCs, when [`Node::poll_at_comm`] says.
    pub fn poll_comm(&mut self, comm_us: u64, drive: &mut impl Drive) {
        self.core.comm_us = comm_us;
        self.comm_timers_before(comm_us);
        if self.core.nmt != NmtState::Initialising {
            self.core.comm_timers_after(comm_us);
        }
        let _ = drive;
        if let Some(t) = self.sdo.take_finished() {
            self.core.event(NodeEvent::SdoTransfer(t));
        }
        self.core.observe();
    }

    /// The next event (state change, EMCY raised or cleared, SYNC, finished SDO transfer),
    /// oldest first. Events beyond [`EVENT_QUEUE`] unread are dropped and counted in
    /// [`Node::events_dropped`].
    pub fn poll_event(&mut self) -> Option<NodeEvent> {
        self.core.events.pop_front()
    }

    /// Events dropped because the event queue was full.
    pub fn events_dropped(&self) -> u32 {
        self.core.events_dropped
    }

    /// The next time (us, on the clock given to `handle` / `poll`) at which [`Node::poll`]
    /// has a communication deadline: an SDO transfer timeout, the heartbeat producer, a
    /// heartbeat consumer timeout, SYNC supervision (1.5 periods), a TPDO event timer or the
    /// end of a TPDO or EMCY inhibit time holding back a frame. A SYNC received and not yet
    /// processed makes it the time of that SYNC (poll now). `None`: no deadline; the node
    /// then needs `poll` only for its CiA 402 cycle, which the caller runs at its own rate.
    ///
    /// **Contract:** right after `poll(now)`, `poll_at()` is `None` or `> now`: `poll` does
    /// everything due at `now` (every heartbeat consumer that timed out, every EMCY the
    /// inhibit time lets go, every event-driven TPDO due), so a loop that sleeps until
    /// `poll_at()` never spins. With two clocks the same holds for the communication clock:
    /// right after `poll_comm(comm)` or `poll_with(clocks)`, [`Node::poll_at_comm`] is `None`
    /// or `> comm`. A frame that finds the transmit queue full is dropped and counted
    /// ([`Node::tx_overflows`]), never held for a later poll. `handle` may bring the deadline
    /// to `now` or before it (a SYNC to process, a TPDO whose data a received frame changed):
    /// poll then. Checked after every poll by the property tests over the fuzz harness
    /// (`protocol/tests/fuzz/`) and by the `cargo fuzz` target.
    ///
    /// **The clock** is the caller's, in u64 microseconds (584 542 years), and is not assumed
    /// to be monotonic (a clock that goes back delays the timers that started later). It does
    /// not wrap: a period or timeout whose end would lie beyond `u64::MAX` never ends (the
    /// heartbeat producer stops, a stalled SDO transfer is not aborted, a heartbeat, SYNC or
    /// TPDO timer does not expire); the boot-up after a reset and the end of an EMCY inhibit
    /// time are clamped to `u64::MAX`. Nothing overflows, in an overflow-checked build too.
    pub fn poll_at(&self) -> Option<u64> {
        let c = &self.core;
        let mut at = self.poll_at_comm();
        let mut take = |t: Option<u64>| {
            if let Some(t) = t {
                at = Some(at.map_or(t, |a| a.min(t)));
            }
        };
        if c.nmt == NmtState::Initialising {
            return at;
        }
        take(c.pending_sync);
        if c.nmt == NmtState::Operational {
            take(c.sync.deadline_us(c.store.u32(R_1006)));
        }
        take(c.qs.watchdog_deadline(&c.quirks, c.watchdog_period().0));
        at
    }

    /// The communication deadlines of [`Node::poll_at`] alone (on the communication clock):
    /// when [`Node::poll_comm`] has something to do. Right after `poll_comm(comm)` or
    /// `poll_with(clocks)` it is `None` or later than the communication time (the contract
    /// of [`Node::poll_at`]).
    pub fn poll_at_comm(&self) -> Option<u64> {
        let c = &self.core;
        let mut at = self.sdo.deadline_us();
        let mut take = |t: Option<u64>| {
            if let Some(t) = t {
                at = Some(at.map_or(t, |a| a.min(t)));
            }
        };
        if c.nmt == NmtState::Initialising {
            take(c.boot_due_us); // the boot-up after the boot delay
            return at;
        }
        take(c.qs.deadline_comm()); // the vendor switches' heartbeats, delayed SDO answers
        take(c.hb.deadline_us(c.store.u32(R_1017) as u16));
        take(c.hbc.deadline_us());
        if c.nmt == NmtState::Operational {
            for k in 0..c.pdo.tpdo.len() {
                take(c.pdo.deadline_us(&c.store, k, c.comm_us));
            }
        }
        if c.emcy_allowed() {
            take(c.emcy.next_at_us(c.store.u32(R_1015) as u16));
        }
        at
    }

    /// SDO time-out, the boot after its delay, the heartbeat producer and consumer.
    fn comm_timers_before(&mut self, comm_us: u64) {
        {
            let mut outv: heapless::Vec<[u8; 8], 2> = heapless::Vec::new();
            self.sdo.poll(comm_us, &mut |f| {
                let _ = outv.push(f);
            });
            let tx_cob = cob::SDO_TX + self.core.node_id as u32;
            for f in outv {
                self.core.push(CanFrame::new(tx_cob, &f));
            }
        }
        let c = &mut self.core;
        if c.nmt == NmtState::Initialising && c.boot_due_us.is_some_and(|due| comm_us >= due) {
            c.boot(comm_us);
        }
        if c.nmt == NmtState::Initialising {
            return;
        }
        // the vendor switches' heartbeats and delayed SDO answers
        let (qs, quirks, tx, overflows) = (&mut c.qs, &c.quirks, &mut c.tx, &mut c.tx_overflows);
        if qs.poll_comm(quirks, comm_us, c.node_id, c.nmt as u8, &mut |f| {
            push(tx, overflows, f)
        }) {
            c.hb.restart(comm_us, c.store.u32(R_1017) as u16);
        }
        if c.qs.not_ready() {
            return;
        }
        // heartbeat producer
        if c.hb.due(comm_us, c.store.u32(R_1017) as u16) {
            let hb = Heartbeat { state: c.nmt as u8 };
            let f = CanFrame::new(cob::HEARTBEAT + c.node_id as u32, &hb.emit());
            c.push(f);
        }
        // heartbeat consumer: every producer whose time is up (one EMCY, for the first)
        let mut lost = None;
        while let Some(n) = c.hbc.poll(comm_us) {
            lost.get_or_insert(n);
        }
        if let Some(n) = lost {
            c.hb_lost = true;
            c.raise_emcy(EMCY_HEARTBEAT, [n, 0, 0, 0, 0], Cause::Condition);
            c.cia.comm_loss(&c.store, EMCY_HEARTBEAT);
        }
    }

    fn poll_timers_and_drive(&mut self, clocks: Clocks, drive: &mut impl Drive) {
        let now_us = clocks.app_us;
        self.core.now_us = now_us;
        self.core.comm_us = clocks.comm_us;
        let fb = drive.feedback();
        self.comm_timers_before(clocks.comm_us);
        let c = &mut self.core;
        if c.nmt == NmtState::Initialising && !c.boot_keeps_app {
            drive.command(&crate::drive::DriveCommand {
                setpoint: crate::drive::Setpoint::Disabled,
                max_torque_permille: 0.0,
                max_velocity_inc_per_s: 0.0,
            });
            return;
        }
        // SYNC supervision
        if c.nmt == NmtState::Operational && c.sync.poll(now_us, c.store.u32(R_1006)) {
            c.raise_emcy(EMCY_SYNC_LOSS, [0; 5], Cause::Condition);
            c.cia.comm_loss(&c.store, EMCY_SYNC_LOSS);
        }
        // the vendor's SYNC watchdog (docs/quirks.md 3.13): a fault whatever 0x6007 says
        let (wd_period, watched) = c.watchdog_period();
        if let Some(code) = c.qs.watchdog_poll(&c.quirks, now_us, watched, wd_period) {
            c.cia.request_fault(code);
        }
        // CiA 402 (a lost master or SYNC whose reaction is a fault blocks the fault reset)
        c.cia.comm_fault_present = (c.hb_lost || c.sync.lost) && c.store.i32(o402::ABORT_CONN) == 1;
        c.cia.status_extra = if c.qs.late_sync { 0x8000 } else { 0 };
        let period = csp_period_us(&c.store, c.sync.interval_us);
        let sync_at = c.pending_sync.take();
        let (level, latched) = c.cw_latch.for_tick(
            c.store.u32(o402::CONTROLWORD) as u16,
            clocks.comm_us,
            c.quirks.controlword_min_hold,
        );
        let control = crate::cia402::TickControl {
            sync_at,
            csp_period_us: period,
            level,
            latched,
        };
        let out = c.cia.step(&mut c.store, &fb, now_us, control, drive);
        if let Some(code) = out.new_fault {
            c.raise_emcy(code, [0; 5], Cause::Fault);
        }
        if out.fault_cleared {
            // errors a supervision still holds (master still lost) stay active
            c.clear_cause(Cause::Fault);
        }
        drive.command(&out.command);
        if c.nmt != NmtState::Initialising {
            c.comm_timers_after(clocks.comm_us);
        }
    }

    /// A store configuration to write (once per request, with [`LssConfig::store_external`]);
    /// then call [`Node::lss_store_done`].
    pub fn take_lss_store(&mut self) -> Option<LssStore> {
        self.core.lss_store.take()
    }

    /// The outcome of the store handed out by [`Node::take_lss_store`]: the LSS answer is
    /// queued (error 0, or 2 when `stored` is false).
    pub fn lss_store_done(&mut self, stored: bool) {
        if let Some(f) = self.core.lss.as_mut().and_then(|l| l.store_done(stored)) {
            self.core.push(f);
        }
    }

    /// The last LSS activate bit timing not yet taken: (CiA 301 table index, switch delay
    /// ms). A real drive switches its CAN controller; the emulator can only report it.
    pub fn take_lss_bit_timing_activation(&mut self) -> Option<(u8, u16)> {
        self.core.lss_bit_timing_activated.take()
    }

    /// LSS state (waiting or configuration); `None` without LSS.
    pub fn lss_state(&self) -> Option<LssState> {
        self.core.lss.as_ref().map(|l| l.state())
    }

    /// The LSS slave's pending node-ID (active after the next NMT reset communication).
    pub fn lss_pending_node_id(&self) -> Option<u8> {
        self.core.lss.as_ref().and_then(|l| l.pending_node_id())
    }

    /// The next frame to send.
    pub fn pop_tx(&mut self) -> Option<CanFrame> {
        self.core.tx.pop_front()
    }

    /// The application reports a condition of its own that is not a fault (a warning: a
    /// condition monitor's finding, e.g. backlash confirmed): EMCY `code` (manufacturer-specific
    /// 0xFF00..=0xFFFF, say) with `info` in its five manufacturer bytes, sent once, held in
    /// 0x1001 and 0x1003 until [`Node::clear_condition`]; the CiA 402 state does not change.
    /// No allocation (real-time safe).
    pub fn raise_condition(&mut self, code: u16, info: [u8; 5]) {
        self.core.raise_emcy(code, info, Cause::Condition);
    }

    /// The condition of [`Node::raise_condition`] is gone: its error clears (EMCY 0x0000 when
    /// it was the last one).
    pub fn clear_condition(&mut self, code: u16) {
        self.core.clear_emcy(code, Cause::Condition);
    }

    /// Whether error `code` is active (EMCY sent, in 0x1001 / 0x1003).
    pub fn error_active(&self, code: u16) -> bool {
        self.core.emcy.is_active(code)
    }

    /// Set a stored object's value (raw form: signed sign-extended, REAL as bits) from the
    /// application, e.g. the runtime's statistics or the detector's verdict, for SDO reads
    /// and TPDOs. No allocation: fit for the real-time path. A `slot` of another dictionary
    /// is the caller's bug (it panics on an out-of-range slot).
    pub fn set_value(&mut self, slot: Slot, raw: u64) {
        self.core.store.set(slot.get(), raw);
    }

    /// A stored object's value (raw form), `None` for a slot a handler keeps.
    pub fn value(&self, slot: Slot) -> Option<u64> {
        match self.core.od.entry(slot).backing {
            Backing::Stored => Some(self.core.store.raw(slot.get())),
            Backing::Handler(_) => None,
        }
    }

    /// The node's object dictionary.
    pub fn od(&self) -> &ObjectDictionary {
        &self.core.od
    }

    /// The EDS (CiA 306) of this node: every visible object; the objects a handler keeps
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
        crate::od::eds::export(&self.core.od, meta, &mut value_of)
    }

    // ----- read-only accessors -----
    /// Node ID, 1..=127, or 255 while non-configured (LSS).
    pub fn node_id(&self) -> u8 {
        self.core.node_id
    }
    /// NMT state (what the heartbeat reports).
    pub fn nmt_state(&self) -> NmtState {
        self.core.nmt
    }
    /// CiA 402 device state (decoded from statusword 0x6041).
    pub fn cia402_state(&self) -> State {
        self.core.cia.state
    }
    /// Mode of operation display (0x6061).
    pub fn mode(&self) -> i8 {
        self.core.cia.mode_display
    }
    /// Statusword 0x6041 as of the last tick.
    pub fn statusword(&self) -> u16 {
        self.core.cia.statusword
    }
    /// Position actual value 0x6064, user units.
    pub fn position_actual(&self) -> i32 {
        self.core.cia.position_actual_uu
    }
    /// Following error, user units.
    pub fn following_error(&self) -> f64 {
        self.core.cia.following_error_uu
    }
    /// Frames dropped because the TX queue was full.
    pub fn tx_overflows(&self) -> u32 {
        self.core.tx_overflows
    }
    /// Synchronous TPDOs not sent because the synchronous window (0x1007) had closed.
    pub fn sync_window_missed(&self) -> u32 {
        self.core.sync_window_missed
    }
    /// The synchronous window length 0x1007, us (0: none). A runtime that hands frames over
    /// late needs to tell [`Node::handle_late`] how late only when it is non-zero.
    #[inline]
    pub fn sync_window_us(&self) -> u32 {
        self.core.store.u32(R_1007)
    }
    /// Frames waiting in the TX queue.
    pub fn tx_pending(&self) -> usize {
        self.core.tx.len()
    }
    /// Raw value of a stored object (diagnostics and tests), if it exists; truncated to 32
    /// bits (see [`Node::value`] for 64-bit objects).
    pub fn object_raw(&self, index: u16, sub: u8) -> Option<u32> {
        match self.core.od.find(index, sub) {
            Lookup::Found(slot) => self.value(slot).map(|v| v as u32),
            _ => None,
        }
    }
    /// The interpolation time period 0x60C2 written by the master (value x 10^index s), us;
    /// `None` while it is 0 (the default: not set) or the dictionary has no 0x60C2.
    pub fn interpolation_period_us(&self) -> Option<u64> {
        if !matches!(self.core.od.find(0x60C2, 1), Lookup::Found(_)) {
            return None;
        }
        Some(interpolation_period_us(&self.core.store)).filter(|&p| p > 0)
    }
    /// Whether a CiA 402 state has the drive's power stage on.
    pub fn is_enabled(&self) -> bool {
        self.core.cia.state.enabled()
    }
}

/// The interpolation time period 0x60C2 (value x 10^index s), us; 0 when not set.
fn interpolation_period_us(store: &Store) -> u64 {
    let v = store.u32(o402::IP_VALUE) as u64;
    let i = store.i32(o402::IP_INDEX);
    if v > 0 && (-6..=0).contains(&i) {
        let mut p = v;
        for _ in 0..(i + 6) {
            p *= 10;
        }
        return p;
    }
    0
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

/// The CSP interpolation period: 0x60C2, else 0x1006, else the measured SYNC interval.
fn csp_period_us(store: &Store, measured_us: u64) -> u64 {
    let p = interpolation_period_us(store);
    if p > 0 {
        return p;
    }
    let c = store.u32(R_1006) as u64;
    if c > 0 {
        c
    } else {
        measured_us
    }
}

/// The rows of a dictionary's SI unit objects 0x60A8, 0x60A9 and 0x60AA (a vendor's file may
/// have them; the CiA 402 layer applies 0x60A9 and 0x60AA where it can), `None` without
/// 0x60A9 and 0x60AA.
fn si_unit_rows(od: &ObjectDictionary) -> Option<crate::cia402::SiRows> {
    let row = |index: u16| {
        od.get(index, 0)
            .filter(|(_, e)| e.dtype == crate::od::DataType::U32)
            .map(|(s, _)| s.get())
    };
    let rows = crate::cia402::SiRows {
        position: row(0x60A8),
        velocity: row(0x60A9),
        acceleration: row(0x60AA),
    };
    (rows.velocity.is_some() || rows.acceleration.is_some()).then_some(rows)
}
