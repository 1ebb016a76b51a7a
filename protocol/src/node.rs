//! The node: glues the CiA 301 services and the CiA 402 layer to the object table.
//! Sans-IO: `handle` takes a received frame, `poll` runs timers and one CiA 402 tick,
//! `pop_tx` hands out frames to send. Nothing here allocates after `Node::new`.

use heapless::Deque;

use crate::cia301::emcy::Emcy;
use crate::cia301::heartbeat::{self, Consumer, Producer};
use crate::cia301::nmt::{self, NmtCommand, NmtState};
use crate::cia301::pdo::{self, Pdo};
use crate::cia301::sdo::{abort, ObjectAccess, SdoServer, BUF};
use crate::cia301::sync::{SyncConsumer, EMCY_SYNC_LENGTH, EMCY_SYNC_LOSS};
use crate::cia402::factor::Factor;
use crate::cia402::{mode, objects as o402, Cia402, State};
use crate::drive::{Drive, DriveInfo, ParamError};
use crate::event::{NodeEvent, EVENT_QUEUE};
use crate::frame::CanFrame;
use crate::od::{self, idx, Lookup, Store, OBJECTS};
use crate::params;
use crate::wire::{cob, Heartbeat};

/// Capacity of the transmit queue; frames beyond it are counted in
/// [`Node::tx_overflows`] and dropped.
pub const TX_QUEUE: usize = 64;

/// EMCY code for a lost heartbeat producer (the master).
pub const EMCY_HEARTBEAT: u16 = 0x8130;
/// EMCY code for an RPDO of the wrong length.
pub const EMCY_PDO_LENGTH: u16 = 0x8210;

const R_1005: usize = idx(0x1005, 0);
const R_1006: usize = idx(0x1006, 0);
const R_1014: usize = idx(0x1014, 0);
const R_1015: usize = idx(0x1015, 0);
const R_1016: usize = idx(0x1016, 1);
const R_1017: usize = idx(0x1017, 0);
const R_1019: usize = idx(0x1019, 0);
const R_STATS: usize = idx(params::STATS_INDEX, 1);

/// Runtime statistics exposed read-only at 0x2100.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RuntimeStats {
    pub ticks: u32,
    pub overruns: u32,
    pub lateness_p50_us: u32,
    pub lateness_p99_us: u32,
    pub lateness_max_us: u32,
    pub dropped_tx_frames: u32,
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
    Sync { counter: Option<u8> },
}

/// Why a node could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConfigError {
    /// Node IDs are 1..=127.
    InvalidNodeId(u8),
    /// A zero in the encoder resolution, gear ratio or feed constant.
    InvalidDriveInfo,
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ConfigError::InvalidNodeId(n) => write!(f, "node id {n} outside 1..=127"),
            ConfigError::InvalidDriveInfo => write!(f, "drive info has a zero in the factor group"),
        }
    }
}

impl std::error::Error for ConfigError {}

/// Everything but the SDO server (so the server can borrow it as its object access).
#[derive(Clone, Debug)]
struct Core {
    node_id: u8,
    info: DriveInfo,
    store: Store,
    saved: Option<Box<Store>>,
    nmt: NmtState,
    rpdo: [Pdo; 4],
    tpdo: [Pdo; 4],
    sync: SyncConsumer,
    hb: Producer,
    hbc: Consumer,
    hb_lost: bool,
    emcy: Emcy,
    cia: Cia402,
    tx: Deque<CanFrame, TX_QUEUE>,
    tx_overflows: u32,
    pending_sync: Option<u64>,
    injected_fault: u16,
    now_us: u64,
    events: Deque<NodeEvent, EVENT_QUEUE>,
    events_dropped: u32,
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

fn lookup(index: u16, sub: u8) -> Result<usize, u32> {
    match od::find(index, sub) {
        Lookup::Found(r) => Ok(r),
        Lookup::NoObject => Err(abort::NO_OBJECT),
        Lookup::NoSub => Err(abort::NO_SUB),
    }
}

fn param_error(e: ParamError, value: f64) -> u32 {
    match e {
        ParamError::OutOfRange { min, max } => {
            if value > max {
                abort::VALUE_HIGH
            } else if value < min {
                abort::VALUE_LOW
            } else {
                abort::VALUE_RANGE
            }
        }
        ParamError::Unsupported => abort::NO_OBJECT,
    }
}

impl<D: Drive> ObjectAccess for Access<'_, D> {
    fn read(&mut self, index: u16, sub: u8, buf: &mut [u8; BUF]) -> Result<usize, u32> {
        let row = lookup(index, sub)?;
        let obj = &OBJECTS[row];
        if !obj.access.readable() {
            return Err(abort::WRITE_ONLY);
        }
        if let Some(p) = params::param_at(index) {
            let scale = if self.core.info.rotary {
                p.rotary_scale
            } else {
                p.scale
            };
            let v = self.drive.param(p.param).map_err(|e| param_error(e, 0.0))?;
            buf[..4].copy_from_slice(&((v * scale) as f32).to_le_bytes());
            return Ok(4);
        }
        Ok(self.core.store.read_bytes(row, buf))
    }

    fn check_write(&mut self, index: u16, sub: u8, size: Option<usize>) -> Result<(), u32> {
        let row = lookup(index, sub)?;
        let obj = &OBJECTS[row];
        if !obj.access.writable() {
            return Err(abort::READ_ONLY);
        }
        let n = obj.dtype.size();
        match size {
            Some(s) if n > 0 && s > n => Err(abort::TOO_LONG),
            Some(s) if n > 0 && s < n => Err(abort::TOO_SHORT),
            _ => Ok(()),
        }
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), u32> {
        self.check_write(index, sub, Some(data.len()))?;
        let row = lookup(index, sub)?;
        let obj = &OBJECTS[row];
        let raw = obj.decode(data);
        if let Some(p) = params::param_at(index) {
            let scale = if self.core.info.rotary {
                p.rotary_scale
            } else {
                p.scale
            };
            let v = f32::from_bits(raw) as f64;
            if !v.is_finite() {
                return Err(abort::VALUE_RANGE);
            }
            let si = v / scale;
            return self
                .drive
                .set_param(p.param, si)
                .map_err(|e| param_error(e, si));
        }
        if let Err(high) = obj.check_limits(raw) {
            return Err(if high {
                abort::VALUE_HIGH
            } else {
                abort::VALUE_LOW
            });
        }
        self.core.write_checked(row, index, sub, raw)
    }
}

fn pdo_slot(index: u16) -> Option<(usize, bool, bool)> {
    // (number, tx, mapping)
    match index {
        0x1400..=0x1403 => Some(((index - 0x1400) as usize, false, false)),
        0x1600..=0x1603 => Some(((index - 0x1600) as usize, false, true)),
        0x1800..=0x1803 => Some(((index - 0x1800) as usize, true, false)),
        0x1A00..=0x1A03 => Some(((index - 0x1A00) as usize, true, true)),
        _ => None,
    }
}

fn comm_row(k: usize, tx: bool) -> usize {
    if tx {
        idx(0x1800, 0) + k * 5
    } else {
        idx(0x1400, 0) + k * 3
    }
}

fn map_row(k: usize, tx: bool) -> usize {
    if tx {
        idx(0x1A00, 0) + k * 9
    } else {
        idx(0x1600, 0) + k * 9
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

    fn raise_emcy(&mut self, code: u16, info: [u8; 5]) {
        if self.emcy.raise(&mut self.store, code, info) {
            self.event(NodeEvent::EmcyRaised { code });
        }
    }

    fn clear_emcy(&mut self, code: u16) {
        if self.emcy.clear(&mut self.store, code) {
            self.event(NodeEvent::EmcyCleared { code });
        }
    }

    fn clear_all_emcy(&mut self) {
        let active: heapless::Vec<u16, 8> = self.emcy.active().iter().copied().collect();
        self.emcy.clear_all(&mut self.store);
        for code in active {
            self.event(NodeEvent::EmcyCleared { code });
        }
    }

    fn push(&mut self, f: CanFrame) {
        if self.tx.push_back(f).is_err() {
            self.tx_overflows = self.tx_overflows.wrapping_add(1);
        }
    }

    fn pdo_valid(&self, k: usize, tx: bool) -> bool {
        self.store.u32(comm_row(k, tx) + 1) & 0x8000_0000 == 0
    }

    /// Semantic checks and side effects of an SDO write (limits and type already checked).
    /// One arm per object with a rule; the `if`s stay inside the arms for readability.
    #[allow(clippy::collapsible_match)]
    fn write_checked(&mut self, row: usize, index: u16, sub: u8, raw: u32) -> Result<(), u32> {
        if let Some((k, tx, mapping)) = pdo_slot(index) {
            let valid = self.pdo_valid(k, tx);
            if mapping {
                if valid {
                    return Err(abort::UNSUPPORTED_ACCESS);
                }
                let mrow = map_row(k, tx);
                if sub == 0 {
                    pdo::compile(&self.store, mrow, raw as usize, tx)?;
                } else {
                    if self.store.u32(mrow) != 0 {
                        return Err(abort::UNSUPPORTED_ACCESS);
                    }
                    if raw != 0 {
                        pdo::check_entry(raw, tx)?;
                    }
                }
            } else {
                match sub {
                    1 => {
                        let cur = self.store.u32(row);
                        let new_valid = raw & 0x8000_0000 == 0;
                        if raw & 0x2000_0000 != 0 || raw & 0x1FFF_F800 != 0 {
                            return Err(abort::VALUE_RANGE);
                        }
                        if valid && new_valid && (raw & 0x7FF) != (cur & 0x7FF) {
                            return Err(abort::VALUE_RANGE);
                        }
                    }
                    2 => {
                        if !pdo::valid_ttype(raw, tx) {
                            return Err(abort::VALUE_RANGE);
                        }
                    }
                    3 => {
                        if valid {
                            return Err(abort::UNSUPPORTED_ACCESS);
                        }
                    }
                    _ => {}
                }
            }
            self.store.set(row, raw);
            self.refresh_pdo(k, tx);
            return Ok(());
        }
        match (index, sub) {
            (0x1003, 0) => {
                if raw != 0 {
                    return Err(abort::VALUE_RANGE);
                }
                for s in 0..=8 {
                    self.store.set(row + s, 0);
                }
                return Ok(());
            }
            (0x1005, _) | (0x1014, _) => {
                if raw & 0x6000_0000 != 0 || raw & 0x1FFF_F800 != 0 {
                    return Err(abort::VALUE_RANGE);
                }
            }
            (0x1010, 1) => {
                if raw != 0x6576_6173 {
                    return Err(abort::CANNOT_STORE);
                }
                self.saved = Some(Box::new(self.store.clone()));
                return Ok(());
            }
            (0x1011, 1) => {
                if raw != 0x6461_6F6C {
                    return Err(abort::CANNOT_STORE);
                }
                self.saved = None;
                return Ok(());
            }
            (0x1016, s) => {
                let mut entries = [0u32; 4];
                for (i, e) in entries.iter_mut().enumerate() {
                    *e = self.store.u32(R_1016 + i);
                }
                let i = s as usize - 1;
                if heartbeat::conflicts(&entries, i, raw) {
                    return Err(abort::PARAM_INCOMPATIBLE);
                }
                self.hbc.configure(i, raw);
            }
            (0x1017, _) => self.hb.restart(self.now_us, raw as u16),
            (0x1019, _) => {
                if self.store.u32(R_1006) != 0 {
                    return Err(abort::DEVICE_STATE);
                }
                if raw == 1 {
                    return Err(abort::VALUE_RANGE);
                }
            }
            (0x6060, _) => {
                if !mode::supported(raw as i32 as i8) {
                    return Err(abort::VALUE_RANGE);
                }
            }
            (0x607D, 1) => {
                if raw as i32 > self.store.i32(o402::SW_LIMIT_MAX) {
                    return Err(abort::MAX_LT_MIN);
                }
            }
            (0x607D, 2) => {
                if (raw as i32) < self.store.i32(o402::SW_LIMIT_MIN) {
                    return Err(abort::MAX_LT_MIN);
                }
            }
            (params::INJECT_FAULT_INDEX, _) => {
                self.injected_fault = raw as u16;
                return Ok(());
            }
            _ => {}
        }
        self.store.set(row, raw);
        Ok(())
    }

    fn refresh_pdo(&mut self, k: usize, tx: bool) {
        let c = comm_row(k, tx);
        let m = map_row(k, tx);
        let cob = self.store.u32(c + 1);
        let ttype = self.store.u32(c + 2) as u8;
        let count = self.store.u32(m) as usize;
        let p = if tx {
            &mut self.tpdo[k]
        } else {
            &mut self.rpdo[k]
        };
        p.cob = cob;
        p.ttype = ttype;
        match pdo::compile(&self.store, m, count, tx) {
            Ok((map, n, len)) => {
                p.map = map;
                p.n = n;
                p.len = len;
                p.valid = cob & 0x8000_0000 == 0;
            }
            Err(_) => {
                p.n = 0;
                p.len = 0;
                p.valid = false;
            }
        }
        p.has_last = false;
        p.sync_count = 0;
        p.rx_pending = false;
    }

    fn refresh_all(&mut self) {
        for k in 0..4 {
            self.refresh_pdo(k, false);
            self.refresh_pdo(k, true);
        }
        for i in 0..4 {
            let e = self.store.u32(R_1016 + i);
            self.hbc.configure(i, e);
        }
    }

    fn emcy_allowed(&self) -> bool {
        matches!(self.nmt, NmtState::PreOperational | NmtState::Operational)
            && self.store.u32(R_1014) & 0x8000_0000 == 0
    }

    /// Report a communication event without keeping it active (history + EMCY frame).
    fn report(&mut self, code: u16, info: [u8; 5]) {
        self.raise_emcy(code, info);
        self.clear_emcy(code);
    }

    fn boot(&mut self, now_us: u64) {
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
    }

    fn restore_range(&mut self, lo: u16, hi: u16) {
        match &self.saved {
            Some(s) => {
                for (i, obj) in OBJECTS.iter().enumerate() {
                    if obj.index >= lo && obj.index <= hi {
                        self.store.vals[i] = s.vals[i];
                    }
                }
            }
            None => self.store.reset_range(lo, hi, self.node_id, &self.info),
        }
    }

    /// When event-driven TPDO `k` has to be looked at: its event timer, or the end of its
    /// inhibit time when its data changed meanwhile.
    fn tpdo_deadline_us(&self, k: usize) -> Option<u64> {
        let p = &self.tpdo[k];
        if !p.valid || p.ttype < 254 {
            return None;
        }
        let Some(last) = p.last_tx_us else {
            return Some(self.now_us);
        };
        let crow = comm_row(k, true);
        let inhibit = self.store.u32(crow + 3) as u64 * 100;
        let timer = self.store.u32(crow + 4) as u64 * 1000;
        let mut at = (timer > 0).then(|| (last + timer).max(last + inhibit));
        let mut d = [0u8; 8];
        let n = p.pack(&self.store, &mut d);
        if !p.has_last || d[..n] != p.last[..n] {
            let t = last + inhibit;
            at = Some(at.map_or(t, |a: u64| a.min(t)));
        }
        at
    }

    fn send_tpdo(&mut self, k: usize, now_us: u64) {
        let p = &self.tpdo[k];
        let mut d = [0u8; 8];
        let n = p.pack(&self.store, &mut d);
        let f = CanFrame::new(p.cob & 0x7FF, &d[..n]);
        let p = &mut self.tpdo[k];
        p.last = d;
        p.has_last = true;
        p.last_tx_us = Some(now_us);
        self.push(f);
    }

    fn on_sync(&mut self, frame: &CanFrame, now_us: u64) -> FrameEvent {
        let overflow = self.store.u32(R_1019) as u8;
        let s = self
            .sync
            .on_sync(now_us, frame.len, frame.data[0], overflow);
        if self.emcy_allowed() {
            if s.length_error {
                self.report(EMCY_SYNC_LENGTH, [frame.len, 0, 0, 0, 0]);
            }
            if s.recovered {
                self.clear_emcy(EMCY_SYNC_LOSS);
            }
        }
        self.pending_sync = Some(now_us);
        if self.nmt == NmtState::Operational {
            for k in 0..4 {
                let p = &mut self.rpdo[k];
                if p.valid && p.rx_pending && p.is_sync_rx() {
                    p.rx_pending = false;
                    let (p, data) = (*p, p.rx);
                    p.unpack(&mut self.store, &data[..p.len as usize]);
                }
            }
            for k in 0..4 {
                let p = self.tpdo[k];
                if !p.valid {
                    continue;
                }
                match p.ttype {
                    0 => {
                        let mut d = [0u8; 8];
                        let n = p.pack(&self.store, &mut d);
                        if !p.has_last || d[..n] != p.last[..n] {
                            self.send_tpdo(k, now_us);
                        }
                    }
                    1..=240 => {
                        let p = &mut self.tpdo[k];
                        p.sync_count = p.sync_count.saturating_add(1);
                        if p.sync_count >= p.ttype {
                            p.sync_count = 0;
                            self.send_tpdo(k, now_us);
                        }
                    }
                    252 => {
                        let mut d = [0u8; 8];
                        p.pack(&self.store, &mut d);
                        self.tpdo[k].sampled = d;
                    }
                    _ => {}
                }
            }
        }
        self.event(NodeEvent::Sync { counter: s.counter });
        FrameEvent::Sync { counter: s.counter }
    }
}

impl Node {
    /// Build a node (state: initialising; call [`Node::boot`]).
    pub fn new(node_id: u8, info: DriveInfo) -> Result<Node, ConfigError> {
        if !(1..=127).contains(&node_id) {
            return Err(ConfigError::InvalidNodeId(node_id));
        }
        let factor = Factor::from_info(&info).ok_or(ConfigError::InvalidDriveInfo)?;
        let store = Store::new(node_id, &info);
        let mut core = Core {
            node_id,
            info,
            store,
            saved: None,
            nmt: NmtState::Initialising,
            rpdo: [Pdo::default(); 4],
            tpdo: [Pdo::default(); 4],
            sync: SyncConsumer::default(),
            hb: Producer::default(),
            hbc: Consumer::default(),
            hb_lost: false,
            emcy: Emcy::default(),
            cia: Cia402::new(factor),
            tx: Deque::new(),
            tx_overflows: 0,
            pending_sync: None,
            injected_fault: 0,
            now_us: 0,
            events: Deque::new(),
            events_dropped: 0,
            seen_cia: State::NotReadyToSwitchOn,
            seen_nmt: NmtState::Initialising,
        };
        core.seen_cia = core.cia.state;
        core.refresh_all();
        Ok(Node {
            sdo: SdoServer::default(),
            core,
        })
    }

    /// Queue the boot-up message and enter pre-operational.
    pub fn boot(&mut self, now_us: u64) {
        self.core.now_us = now_us;
        self.core.boot(now_us);
        self.core.observe();
    }

    fn nmt_command(&mut self, cmd: NmtCommand, now_us: u64, drive: &mut impl Drive) {
        let c = &mut self.core;
        match cmd {
            NmtCommand::ResetNode => {
                // The application resets too: the drive re-initialises its axis.
                drive.reset();
                c.restore_range(0x0000, 0xFFFF);
                let f = Factor::from_info(&c.info).unwrap_or(Factor { inc_per_uu: 1.0 });
                c.cia = Cia402::new(f);
                c.clear_all_emcy();
                c.emcy.reset(&mut c.store);
                c.injected_fault = 0;
                self.sdo.reset();
                c.boot(now_us);
            }
            NmtCommand::ResetCommunication => {
                c.restore_range(0x1000, 0x1FFF);
                c.clear_all_emcy();
                c.emcy.reset(&mut c.store);
                self.sdo.reset();
                c.boot(now_us);
            }
            _ => {
                let next = nmt::next_state(cmd);
                if next == NmtState::Operational && c.nmt != NmtState::Operational {
                    for p in c.tpdo.iter_mut().chain(c.rpdo.iter_mut()) {
                        p.has_last = false;
                        p.sync_count = 0;
                        p.rx_pending = false;
                    }
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
        let ev = self.handle_frame(frame, now_us, drive);
        if let Some(t) = self.sdo.take_finished() {
            self.core.event(NodeEvent::SdoTransfer(t));
        }
        self.core.observe();
        ev
    }

    fn handle_frame(
        &mut self,
        frame: &CanFrame,
        now_us: u64,
        drive: &mut impl Drive,
    ) -> FrameEvent {
        self.core.now_us = now_us;
        if frame.extended || frame.id > 0x7FF || self.core.nmt == NmtState::Initialising {
            return FrameEvent::Ignored;
        }
        let id = frame.id;
        if id == 0 {
            return match nmt::decode(frame, self.core.node_id) {
                Some(cmd) => {
                    self.nmt_command(cmd, now_us, drive);
                    FrameEvent::Handled
                }
                None => FrameEvent::Ignored,
            };
        }
        let nmt = self.core.nmt;
        let sync_cob = self.core.store.u32(R_1005) & 0x7FF;
        if id == sync_cob && !frame.rtr {
            return self.core.on_sync(frame, now_us);
        }
        if nmt == NmtState::Stopped {
            if (0x701..=0x77F).contains(&id) && !frame.rtr && frame.len >= 1 {
                self.heartbeat_in(id as u8, now_us);
                return FrameEvent::Handled;
            }
            return FrameEvent::Ignored;
        }
        if id == cob::SDO_RX + self.core.node_id as u32 {
            if frame.rtr || frame.len != 8 {
                return FrameEvent::Ignored;
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
                self.core.push(CanFrame::new(tx_cob, &f));
            }
            return FrameEvent::Handled;
        }
        if (0x701..=0x77F).contains(&id) && !frame.rtr && frame.len >= 1 {
            self.heartbeat_in(id as u8, now_us);
            return FrameEvent::Handled;
        }
        if nmt != NmtState::Operational {
            return FrameEvent::Ignored;
        }
        let c = &mut self.core;
        for k in 0..4 {
            let p = c.rpdo[k];
            if p.valid && !frame.rtr && p.cob & 0x7FF == id {
                if frame.len != p.len {
                    if !c.rpdo[k].len_error {
                        c.rpdo[k].len_error = true;
                        if c.emcy_allowed() {
                            c.report(EMCY_PDO_LENGTH, [k as u8 + 1, frame.len, p.len, 0, 0]);
                        }
                    }
                    return FrameEvent::Handled;
                }
                c.rpdo[k].len_error = false;
                if p.is_sync_rx() {
                    c.rpdo[k].rx = frame.data;
                    c.rpdo[k].rx_pending = true;
                } else {
                    p.unpack(&mut c.store, frame.payload());
                }
                return FrameEvent::Handled;
            }
        }
        for k in 0..4 {
            let p = c.tpdo[k];
            if p.valid && frame.rtr && p.cob & 0x7FF == id && matches!(p.ttype, 252 | 253) {
                if p.ttype == 252 {
                    let f = CanFrame::new(p.cob & 0x7FF, &p.sampled[..p.len as usize]);
                    c.push(f);
                } else {
                    c.send_tpdo(k, now_us);
                }
                return FrameEvent::Handled;
            }
        }
        FrameEvent::Ignored
    }

    fn heartbeat_in(&mut self, id_low: u8, now_us: u64) {
        let node = id_low & 0x7F;
        let c = &mut self.core;
        if c.hbc.is_monitoring(node) {
            c.hbc.on_heartbeat(node, now_us);
            if c.hb_lost {
                c.hb_lost = false;
                c.clear_emcy(EMCY_HEARTBEAT);
            }
        }
    }

    /// Timers, the CiA 402 state machine and mode, and exactly one `drive.command(..)`.
    pub fn poll(&mut self, now_us: u64, drive: &mut impl Drive) {
        self.poll_timers_and_drive(now_us, drive);
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
    pub fn poll_at(&self) -> Option<u64> {
        let c = &self.core;
        let mut at = self.sdo.deadline_us();
        let mut take = |t: Option<u64>| {
            if let Some(t) = t {
                at = Some(at.map_or(t, |a| a.min(t)));
            }
        };
        if c.nmt == NmtState::Initialising {
            return at;
        }
        take(c.pending_sync);
        take(c.hb.deadline_us(c.store.u32(R_1017) as u16));
        take(c.hbc.deadline_us());
        if c.nmt == NmtState::Operational {
            take(c.sync.deadline_us(c.store.u32(R_1006)));
            for k in 0..4 {
                take(c.tpdo_deadline_us(k));
            }
        }
        if c.emcy_allowed() {
            take(c.emcy.next_at_us(c.store.u32(R_1015) as u16));
        }
        at
    }

    fn poll_timers_and_drive(&mut self, now_us: u64, drive: &mut impl Drive) {
        self.core.now_us = now_us;
        let fb = drive.feedback();
        // SDO timeout
        {
            let mut outv: heapless::Vec<[u8; 8], 2> = heapless::Vec::new();
            self.sdo.poll(now_us, &mut |f| {
                let _ = outv.push(f);
            });
            let tx_cob = cob::SDO_TX + self.core.node_id as u32;
            for f in outv {
                self.core.push(CanFrame::new(tx_cob, &f));
            }
        }
        let c = &mut self.core;
        if c.nmt == NmtState::Initialising {
            drive.command(&crate::drive::DriveCommand {
                setpoint: crate::drive::Setpoint::Disabled,
                max_torque_permille: 0.0,
                max_velocity_inc_per_s: 0.0,
            });
            return;
        }
        // heartbeat producer
        if c.hb.due(now_us, c.store.u32(R_1017) as u16) {
            let hb = Heartbeat { state: c.nmt as u8 };
            let f = CanFrame::new(cob::HEARTBEAT + c.node_id as u32, &hb.emit());
            c.push(f);
        }
        // heartbeat consumer
        if let Some(n) = c.hbc.poll(now_us) {
            c.hb_lost = true;
            c.raise_emcy(EMCY_HEARTBEAT, [n, 0, 0, 0, 0]);
            c.cia.comm_loss(&c.store, EMCY_HEARTBEAT);
        }
        // SYNC supervision
        if c.nmt == NmtState::Operational && c.sync.poll(now_us, c.store.u32(R_1006)) {
            c.raise_emcy(EMCY_SYNC_LOSS, [0; 5]);
            c.cia.comm_loss(&c.store, EMCY_SYNC_LOSS);
        }
        if c.injected_fault != 0 {
            c.cia.request_fault(c.injected_fault);
        }
        // CiA 402
        let period = csp_period_us(&c.store, c.sync.interval_us);
        let sync_at = c.pending_sync.take();
        let out = c
            .cia
            .step(&mut c.store, &fb, now_us, sync_at, period, drive);
        if let Some(code) = out.new_fault {
            c.raise_emcy(code, [0; 5]);
        }
        if out.fault_cleared {
            c.clear_all_emcy();
        }
        drive.command(&out.command);
        // event-driven TPDOs
        if c.nmt == NmtState::Operational {
            for k in 0..4 {
                let p = c.tpdo[k];
                if !p.valid || p.ttype < 254 {
                    continue;
                }
                let crow = comm_row(k, true);
                let inhibit = c.store.u32(crow + 3) as u64 * 100;
                let timer = c.store.u32(crow + 4) as u64 * 1000;
                let inhibit_ok = p.last_tx_us.is_none_or(|l| now_us >= l + inhibit);
                let timer_due = timer > 0 && p.last_tx_us.is_none_or(|l| now_us >= l + timer);
                if !inhibit_ok {
                    continue;
                }
                let mut d = [0u8; 8];
                let n = p.pack(&c.store, &mut d);
                if !p.has_last || d[..n] != p.last[..n] || timer_due {
                    c.send_tpdo(k, now_us);
                }
            }
        }
        // EMCY
        if c.emcy_allowed() {
            let inhibit = c.store.u32(R_1015) as u16;
            while let Some(d) = c.emcy.next(now_us, inhibit) {
                let f = CanFrame::new(c.store.u32(R_1014) & 0x7FF, &d);
                c.push(f);
            }
        }
    }

    /// Timeout of a stalled SDO transfer (default 1 s).
    pub fn set_sdo_timeout_us(&mut self, timeout_us: u64) {
        self.sdo.timeout_us = timeout_us;
    }

    /// The next frame to send.
    pub fn pop_tx(&mut self) -> Option<CanFrame> {
        self.core.tx.pop_front()
    }

    /// Publish the runtime's statistics at 0x2100.
    pub fn set_runtime_stats(&mut self, s: RuntimeStats) {
        let v = [
            s.ticks,
            s.overruns,
            s.lateness_p50_us,
            s.lateness_p99_us,
            s.lateness_max_us,
            s.dropped_tx_frames,
            self.core.tx_overflows,
        ];
        for (i, x) in v.iter().enumerate() {
            self.core.store.set(R_STATS + i, *x);
        }
    }

    /// The EDS (CiA 306) of this node, generated from the object table.
    pub fn export_eds(&self) -> String {
        od::eds::export(self.core.node_id, &self.core.info)
    }

    // ----- read-only accessors -----
    pub fn node_id(&self) -> u8 {
        self.core.node_id
    }
    pub fn nmt_state(&self) -> NmtState {
        self.core.nmt
    }
    pub fn cia402_state(&self) -> State {
        self.core.cia.state
    }
    /// Mode of operation display (0x6061).
    pub fn mode(&self) -> i8 {
        self.core.cia.mode_display
    }
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
    /// Frames waiting in the TX queue.
    pub fn tx_pending(&self) -> usize {
        self.core.tx.len()
    }
    /// Raw value of an object as stored (diagnostics and tests), if it exists.
    pub fn object_raw(&self, index: u16, sub: u8) -> Option<u32> {
        match od::find(index, sub) {
            Lookup::Found(r) => Some(self.core.store.u32(r)),
            _ => None,
        }
    }
    /// Whether a CiA 402 state has the drive's power stage on.
    pub fn is_enabled(&self) -> bool {
        self.core.cia.state.enabled()
    }
}

/// The CSP interpolation period: 0x60C2, else 0x1006, else the measured SYNC interval.
fn csp_period_us(store: &Store, measured_us: u64) -> u64 {
    let v = store.u32(o402::IP_VALUE) as u64;
    let i = store.i32(o402::IP_INDEX);
    if v > 0 && (-6..=0).contains(&i) {
        let mut p = v;
        for _ in 0..(i + 6) {
            p *= 10;
        }
        return p;
    }
    let c = store.u32(R_1006) as u64;
    if c > 0 {
        c
    } else {
        measured_us
    }
}
