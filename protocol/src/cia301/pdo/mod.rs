//! The PDO engine: the RPDOs and TPDOs the object dictionary has (4 each in the standard one,
//! up to 512 each from a vendor's EDS; CiA 301 7.2.2), in one place, as CANopenNode's CO_PDO.c
//! owns its PDOs:
//!
//! - [`layout`]: where the communication and mapping parameters (0x1400.., 0x1600..,
//!   0x1800.., 0x1A00..) sit in the store, resolved from the dictionary;
//! - [`mapping`]: mapping validation (dynamic mapping), packing and unpacking;
//! - [`rules`]: the SDO write rules of the PDO parameters (the one place to add checks);
//! - [`rpdo`]: reception (length check, synchronous RPDOs held until SYNC);
//! - [`tpdo`]: transmission (SYNC, RTR, event-driven with inhibit time and event timer).
//!
//! The engine allocates its PDOs when the node is built and never after; frames go out
//! through a callback.

pub mod layout;
pub mod mapping;
pub mod rpdo;
pub mod rules;
pub mod tpdo;

pub use mapping::{check_entry, compile, Mapped};

use crate::frame::CanFrame;
use crate::node::writes::{ObjectWrite, Verdict, WriteHooks};
use crate::node::DriveCore;
use crate::od::{ObjectDictionary, Store};
use layout::{PdoSlots, MAX_ENTRIES};

/// Transmission type (0x14xx / 0x18xx sub 2), CiA 301 table 71/72.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TransmissionType {
    /// 0: synchronous, acyclic (TPDO: at SYNC when the data changed).
    #[default]
    SyncAcyclic,
    /// 1..=240: synchronous, every n-th SYNC.
    SyncCyclic(u8),
    /// 252: sampled at SYNC, sent on RTR (TPDO only).
    RtrSync,
    /// 253: sent on RTR (TPDO only).
    RtrEvent,
    /// 254: event-driven, manufacturer-specific.
    EventManufacturer,
    /// 255: event-driven, device profile.
    EventProfile,
    /// 241..=251: reserved.
    Reserved(u8),
}

impl TransmissionType {
    /// From the object value.
    pub fn from_u8(t: u8) -> TransmissionType {
        match t {
            0 => TransmissionType::SyncAcyclic,
            1..=240 => TransmissionType::SyncCyclic(t),
            252 => TransmissionType::RtrSync,
            253 => TransmissionType::RtrEvent,
            254 => TransmissionType::EventManufacturer,
            255 => TransmissionType::EventProfile,
            _ => TransmissionType::Reserved(t),
        }
    }

    /// Synchronous (0..=240): an RPDO of this type is applied at the next SYNC.
    pub fn is_sync(self) -> bool {
        matches!(
            self,
            TransmissionType::SyncAcyclic | TransmissionType::SyncCyclic(_)
        )
    }

    /// Event-driven (254, 255).
    pub fn is_event(self) -> bool {
        matches!(
            self,
            TransmissionType::EventManufacturer | TransmissionType::EventProfile
        )
    }

    /// Sent on request (252, 253).
    pub fn is_rtr(self) -> bool {
        matches!(self, TransmissionType::RtrSync | TransmissionType::RtrEvent)
    }

    /// Whether a PDO of this direction may have this type (written to sub 2).
    pub fn allowed(self, dir: Direction) -> bool {
        match self {
            TransmissionType::Reserved(_) => false,
            TransmissionType::RtrSync | TransmissionType::RtrEvent => dir == Direction::Tx,
            _ => true,
        }
    }
}

/// Which way a PDO goes, seen from the node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Received (RPDO).
    Rx,
    /// Transmitted (TPDO).
    Tx,
}

/// COB-ID bit 31: PDO not valid.
pub const COB_INVALID: u32 = 0x8000_0000;
/// COB-ID bit 30: no RTR allowed (TPDO).
pub const COB_NO_RTR: u32 = 0x4000_0000;
/// COB-ID bit 29: 29-bit identifier.
pub const COB_EXTENDED: u32 = 0x2000_0000;

/// Runtime state of one PDO.
#[derive(Clone, Copy, Debug, Default)]
pub struct Pdo {
    /// PDO number, 0-based (0x1400 + number / 0x1800 + number).
    pub number: u16,
    /// Where its parameters are stored.
    pub slots: PdoSlots,
    /// Valid (COB-ID bit 31 clear and the mapping compiles).
    pub valid: bool,
    /// COB-ID entry (sub 1).
    pub cob: u32,
    /// Transmission type (sub 2).
    pub ttype: TransmissionType,
    /// Compiled mapping.
    pub map: [Mapped; MAX_ENTRIES],
    /// Mapped entries.
    pub n: u8,
    /// Data length in bytes.
    pub len: u8,
    /// Some mapped entry is not whole bytes: the values sit at bit positions
    /// ([`mapping::Compiled::bitwise`]).
    pub bitwise: bool,
    // TPDO
    /// Data of the last transmission.
    pub last: [u8; 8],
    /// `last` holds data.
    pub has_last: bool,
    /// SYNCs since the last transmission (types 1..=240).
    pub sync_count: u8,
    /// Time of the last transmission.
    pub last_tx_us: Option<u64>,
    /// Data sampled at the last SYNC (type 252).
    pub sampled: [u8; 8],
    // RPDO
    /// Data received, waiting for SYNC (synchronous RPDO).
    pub rx: [u8; 8],
    /// `rx` waits for SYNC.
    pub rx_pending: bool,
    /// EMCY code of the length error this RPDO holds (0 = none; until a good frame).
    pub len_error: u16,
    /// The last RPDO carried a value the drive refused (EMCY held until a valid one).
    pub value_error: bool,
}

impl Pdo {
    /// Pack the mapped values into `out`; returns the length.
    pub fn pack(&self, store: &Store, out: &mut [u8]) -> usize {
        mapping::pack(self, store, out)
    }

    /// The compiled mapping an RPDO's data is unpacked with (a copy: the writes it leads to
    /// may reconfigure the PDO): the entries, how many, the length in bytes, and whether the
    /// values sit at bit positions.
    pub fn rx_map(&self) -> ([Mapped; MAX_ENTRIES], usize, usize, bool) {
        (self.map, self.n as usize, self.len as usize, self.bitwise)
    }

    /// Whether the data to send differs from the last transmission (or none was sent).
    fn changed(&self, store: &Store) -> bool {
        let mut d = [0u8; 8];
        let n = self.pack(store, &mut d);
        !self.has_last || d[..n] != self.last[..n]
    }

    /// The 11-bit identifier.
    pub fn id(&self) -> u32 {
        self.cob & 0x7FF
    }

    /// A communication parameter as stored (0 where the dictionary lacks the sub-index).
    pub fn comm_value(&self, store: &Store, sub: u8) -> u32 {
        self.slots.comm(sub).map_or(0, |s| store.u32(s))
    }
}

/// The node's PDOs.
#[derive(Clone, Debug, Default)]
pub struct PdoEngine {
    /// The RPDOs the dictionary has, by number.
    pub rpdo: Vec<Pdo>,
    /// The TPDOs the dictionary has, by number.
    pub tpdo: Vec<Pdo>,
    /// The write rules a vendor profile changes (docs/quirks.md 3.9, 3.10, 3.15).
    pub(crate) rules: crate::quirks::PdoRules,
    /// Bytes a PDO may carry: [`mapping::CAN_MAX_LEN`] on CAN (a front end whose PDOs are not
    /// CAN frames, EtherCAT, sets more with [`crate::Node::set_pdo_max_len`]).
    pub max_len: usize,
}

impl PdoEngine {
    /// The PDOs of `od` (a PDO exists where its COB-ID and mapping count do).
    pub fn new(od: &ObjectDictionary) -> PdoEngine {
        let list = |dir| {
            PdoSlots::all(od, dir)
                .into_iter()
                .map(|(number, slots)| Pdo {
                    number,
                    slots,
                    ..Pdo::default()
                })
                .collect()
        };
        PdoEngine {
            rpdo: list(Direction::Rx),
            tpdo: list(Direction::Tx),
            rules: Default::default(),
            max_len: mapping::CAN_MAX_LEN,
        }
    }

    fn list_mut(&mut self, dir: Direction) -> &mut Vec<Pdo> {
        match dir {
            Direction::Rx => &mut self.rpdo,
            Direction::Tx => &mut self.tpdo,
        }
    }

    fn list(&self, dir: Direction) -> &[Pdo] {
        match dir {
            Direction::Rx => &self.rpdo,
            Direction::Tx => &self.tpdo,
        }
    }

    /// Position in its list of the PDO a parameter index belongs to.
    fn position(&self, param: layout::Param) -> Option<usize> {
        self.list(param.dir)
            .iter()
            .position(|p| p.number == param.number)
    }

    /// Position of the RPDO whose parameter `index` is (0x1400.. / 0x1600..), if it is one.
    pub fn rpdo_of(&self, index: u16) -> Option<usize> {
        let param = layout::Param::of(index)?;
        if param.dir != Direction::Rx {
            return None;
        }
        self.position(param)
    }

    /// Rebuild PDO `k` (position in its list) from its parameters in the store.
    pub fn refresh(&mut self, od: &ObjectDictionary, store: &Store, k: usize, dir: Direction) {
        let max_len = self.max_len;
        let p = &mut self.list_mut(dir)[k];
        let cob = p.comm_value(store, layout::COB_ID);
        let ttype = TransmissionType::from_u8(p.comm_value(store, layout::TRANSMISSION_TYPE) as u8);
        let count = p.slots.count.map_or(0, |s| store.u32(s as usize)) as usize;
        p.cob = cob;
        p.ttype = ttype;
        match compile(od, store, &p.slots, count, dir == Direction::Tx, max_len) {
            Ok(c) => {
                p.map = c.map;
                p.n = c.n;
                p.len = c.len;
                p.bitwise = c.bitwise;
                p.valid = cob & COB_INVALID == 0;
            }
            Err(_) => {
                p.n = 0;
                p.len = 0;
                p.bitwise = false;
                p.valid = false;
            }
        }
        p.has_last = false;
        p.sync_count = 0;
        p.rx_pending = false;
    }

    /// Rebuild every PDO.
    pub fn refresh_all(&mut self, od: &ObjectDictionary, store: &Store) {
        for k in 0..self.rpdo.len() {
            self.refresh(od, store, k, Direction::Rx);
        }
        for k in 0..self.tpdo.len() {
            self.refresh(od, store, k, Direction::Tx);
        }
    }

    /// Entering operational: forget what was sent and received before.
    pub fn restart(&mut self) {
        for p in self.tpdo.iter_mut().chain(self.rpdo.iter_mut()) {
            p.has_last = false;
            p.sync_count = 0;
            p.rx_pending = false;
        }
    }

    /// An SDO write to a PDO parameter (0x1400..=0x1BFF), after type and limits were
    /// checked: `None` when `index` is not a parameter of a PDO the node has, else the
    /// outcome (the value is stored and the PDO rebuilt when the rules accept it).
    pub fn write(
        &mut self,
        od: &ObjectDictionary,
        store: &mut Store,
        slot: usize,
        index: u16,
        sub: u8,
        raw: u64,
    ) -> Option<Result<(), u32>> {
        let param = layout::Param::of(index)?;
        let k = self.position(param)?;
        let pdo = self.list(param.dir)[k];
        Some(
            rules::check_write(od, store, &pdo, param, sub, raw, &self.rules, self.max_len).map(
                |()| {
                    store.set(slot, raw);
                    self.refresh(od, store, k, param.dir);
                },
            ),
        )
    }
}

/// Send through `out` the frame of TPDO `k` with its current data.
pub(crate) fn send(p: &mut Pdo, store: &Store, now_us: u64, out: &mut impl FnMut(CanFrame)) {
    let mut d = [0u8; 8];
    let n = p.pack(store, &mut d);
    p.last = d;
    p.has_last = true;
    p.last_tx_us = Some(now_us);
    out(CanFrame::new(p.id(), &d[..n]));
}

/// The PDO parameters (0x1400..=0x1BFF), ruled by [`rules`]: a write to an RPDO's parameter
/// also starts that RPDO without the errors it held (they are reported again).
pub(crate) fn register_writes(t: &mut WriteHooks) {
    t.register(0x1400, 0x1BFF, write_parameter);
}

fn write_parameter(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    if let Some(k) = c.pdo.rpdo_of(w.index) {
        c.rpdo_conditions_reset(k);
    }
    match c
        .pdo
        .write(&c.od, &mut c.store, w.row, w.index, w.sub, w.raw)
    {
        Some(r) => r.map(|()| Verdict::Applied),
        // an index in the range of a PDO the dictionary does not have
        None => Ok(Verdict::Store),
    }
}
