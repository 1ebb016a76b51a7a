//! Where the PDO parameters sit in the object table: one row per sub-index, rows of one
//! record contiguous, records of the same kind evenly spaced. The strides and offsets are
//! computed from the table at compile time, not written down.

use super::Direction;
use crate::od::idx;

/// Row offset of the COB-ID (sub 1) in a communication record.
pub const COB_ID: usize = idx(0x1800, 1) - idx(0x1800, 0);
/// Row offset of the transmission type (sub 2).
pub const TRANSMISSION_TYPE: usize = idx(0x1800, 2) - idx(0x1800, 0);
/// Row offset of the inhibit time (sub 3, 100 us units; TPDO only).
pub const INHIBIT_TIME: usize = idx(0x1800, 3) - idx(0x1800, 0);
/// Row offset of the event timer (sub 5, ms; TPDO only: sub 4 does not exist).
pub const EVENT_TIMER: usize = idx(0x1800, 5) - idx(0x1800, 0);

const RPDO_COMM: usize = idx(0x1400, 0);
const RPDO_COMM_STRIDE: usize = idx(0x1401, 0) - idx(0x1400, 0);
const TPDO_COMM: usize = idx(0x1800, 0);
const TPDO_COMM_STRIDE: usize = idx(0x1801, 0) - idx(0x1800, 0);
const RPDO_MAP: usize = idx(0x1600, 0);
const RPDO_MAP_STRIDE: usize = idx(0x1601, 0) - idx(0x1600, 0);
const TPDO_MAP: usize = idx(0x1A00, 0);
const TPDO_MAP_STRIDE: usize = idx(0x1A01, 0) - idx(0x1A00, 0);

// The RPDO records have the same first three subs as the TPDO ones.
const _: () = assert!(idx(0x1400, 1) - idx(0x1400, 0) == COB_ID);
const _: () = assert!(idx(0x1400, 2) - idx(0x1400, 0) == TRANSMISSION_TYPE);

/// Row of sub 0 of PDO `k`'s communication record (0x1400 + k / 0x1800 + k).
pub const fn comm_row(k: usize, dir: Direction) -> usize {
    match dir {
        Direction::Rx => RPDO_COMM + k * RPDO_COMM_STRIDE,
        Direction::Tx => TPDO_COMM + k * TPDO_COMM_STRIDE,
    }
}

/// Row of sub 0 (entry count) of PDO `k`'s mapping record (0x1600 + k / 0x1A00 + k).
pub const fn map_row(k: usize, dir: Direction) -> usize {
    match dir {
        Direction::Rx => RPDO_MAP + k * RPDO_MAP_STRIDE,
        Direction::Tx => TPDO_MAP + k * TPDO_MAP_STRIDE,
    }
}

/// Which PDO parameter an object index is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slot {
    /// PDO number - 1 (0..4).
    pub number: usize,
    /// RPDO or TPDO.
    pub dir: Direction,
    /// Mapping record (else communication record).
    pub mapping: bool,
}

impl Slot {
    /// The PDO parameter at `index`, if it is one.
    pub fn of(index: u16) -> Option<Slot> {
        let (base, dir, mapping) = match index {
            0x1400..=0x1403 => (0x1400, Direction::Rx, false),
            0x1600..=0x1603 => (0x1600, Direction::Rx, true),
            0x1800..=0x1803 => (0x1800, Direction::Tx, false),
            0x1A00..=0x1A03 => (0x1A00, Direction::Tx, true),
            _ => return None,
        };
        Some(Slot {
            number: (index - base) as usize,
            dir,
            mapping,
        })
    }
}
