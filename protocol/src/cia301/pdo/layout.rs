//! Where a PDO's parameters sit: the slots of its communication record (0x1400+n /
//! 0x1800+n) and mapping record (0x1600+n / 0x1A00+n), resolved from the object dictionary
//! when the node is built. A sub-index the dictionary lacks (a vendor EDS without an event
//! timer, say) has no slot and reads as 0.

use super::Direction;
use crate::od::{Lookup, ObjectDictionary};

/// Sub-index of the COB-ID in a communication record.
pub const COB_ID: u8 = 1;
/// Sub-index of the transmission type.
pub const TRANSMISSION_TYPE: u8 = 2;
/// Sub-index of the inhibit time (100 us units; TPDO only).
pub const INHIBIT_TIME: u8 = 3;
/// Sub-index of the event timer (ms; sub 4 is reserved).
pub const EVENT_TIMER: u8 = 5;
/// Mapping entries a PDO can have (8 bytes of data at a granularity of 8 bits).
pub const MAX_ENTRIES: usize = 8;
/// PDOs of one direction CiA 301 allows (0x1400..=0x15FF).
pub const MAX_PDOS: u16 = 512;

/// The slots of one PDO's parameters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PdoSlots {
    /// Communication record, subs 0..=6 (`None`: not in the dictionary).
    pub comm: [Option<u32>; 7],
    /// Mapping record sub 0: the number of mapped objects.
    pub count: Option<u32>,
    /// Mapping record subs 1..=8.
    pub entries: [Option<u32>; MAX_ENTRIES],
}

impl PdoSlots {
    /// The slots of PDO `number` (0-based) of `dir`, if the dictionary has that PDO (its
    /// COB-ID and its mapping count).
    pub fn resolve(od: &ObjectDictionary, dir: Direction, number: u16) -> Option<PdoSlots> {
        let (comm, map) = bases(dir);
        let slot = |index: u16, sub: u8| match od.find(index, sub) {
            Lookup::Found(s) => Some(s.get() as u32),
            _ => None,
        };
        let mut p = PdoSlots::default();
        for (sub, c) in p.comm.iter_mut().enumerate() {
            *c = slot(comm + number, sub as u8);
        }
        p.count = slot(map + number, 0);
        for (k, e) in p.entries.iter_mut().enumerate() {
            *e = slot(map + number, k as u8 + 1);
        }
        (p.comm[COB_ID as usize].is_some() && p.count.is_some()).then_some(p)
    }

    /// Slot of communication sub `sub`.
    pub fn comm(&self, sub: u8) -> Option<usize> {
        self.comm
            .get(sub as usize)
            .copied()
            .flatten()
            .map(|s| s as usize)
    }
}

/// Communication and mapping record indices of PDO 0 of `dir`.
pub const fn bases(dir: Direction) -> (u16, u16) {
    match dir {
        Direction::Rx => (0x1400, 0x1600),
        Direction::Tx => (0x1800, 0x1A00),
    }
}

/// Which PDO parameter an object index is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Param {
    /// PDO number, 0-based (0x1400 + number).
    pub number: u16,
    /// RPDO or TPDO.
    pub dir: Direction,
    /// Mapping record (else communication record).
    pub mapping: bool,
}

impl Param {
    /// The PDO parameter at `index`, if it is one.
    pub fn of(index: u16) -> Option<Param> {
        let (base, dir, mapping) = match index {
            0x1400..=0x15FF => (0x1400, Direction::Rx, false),
            0x1600..=0x17FF => (0x1600, Direction::Rx, true),
            0x1800..=0x19FF => (0x1800, Direction::Tx, false),
            0x1A00..=0x1BFF => (0x1A00, Direction::Tx, true),
            _ => return None,
        };
        Some(Param {
            number: index - base,
            dir,
            mapping,
        })
    }
}
