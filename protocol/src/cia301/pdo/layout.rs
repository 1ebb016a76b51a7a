//! Where a PDO's parameters sit: the slots of its communication record (0x1400+n /
//! 0x1800+n) and mapping record (0x1600+n / 0x1A00+n), resolved from the object dictionary
//! when the node is built. A sub-index the dictionary lacks (a vendor EDS without an event
//! timer, say) has no slot and reads as 0.

use super::Direction;
use crate::od::ObjectDictionary;

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
    /// Every PDO of `dir` the dictionary has, by number, with its slots: a PDO
    /// exists where the dictionary has its COB-ID (communication sub 1) and its mapping count
    /// (mapping sub 0). Found in one pass over the dictionary's PDO records, not by looking up
    /// all 16 parameters of all 512 numbers (`Node::new` pays this for each direction; the
    /// tests keep that lookup as the reference).
    pub fn all(od: &ObjectDictionary, dir: Direction) -> Vec<(u16, PdoSlots)> {
        let (comm, map) = bases(dir);
        let mut found: Vec<(u16, PdoSlots)> = Vec::new();
        // Sorted by (index, sub): the communication records come first, in number order,
        // then the mapping records, in number order.
        let records = od
            .iter()
            .skip_while(|(_, e)| e.index < comm)
            .take_while(|(_, e)| e.index < map + MAX_PDOS);
        let mut cursor = 0;
        for (slot, e) in records {
            let slot = Some(slot.get() as u32);
            if e.index < comm + MAX_PDOS {
                let number = e.index - comm;
                if found.last().map(|(n, _)| *n) != Some(number) {
                    found.push((number, PdoSlots::default()));
                }
                if let Some(c) = found
                    .last_mut()
                    .and_then(|(_, p)| p.comm.get_mut(e.sub as usize))
                {
                    *c = slot;
                }
            } else if e.index >= map {
                let number = e.index - map;
                while cursor < found.len() && found[cursor].0 < number {
                    cursor += 1;
                }
                let Some((n, p)) = found.get_mut(cursor) else {
                    break;
                };
                if *n != number {
                    continue;
                }
                match e.sub {
                    0 => p.count = slot,
                    k if (k as usize) <= MAX_ENTRIES => p.entries[k as usize - 1] = slot,
                    _ => {}
                }
            }
        }
        found.retain(|(_, p)| p.comm[COB_ID as usize].is_some() && p.count.is_some());
        found
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::od::{Access, DataType, Entry, Lookup};
    use crate::DriveInfo;

    fn info() -> DriveInfo {
        DriveInfo {
            encoder_increments_per_rev: 1 << 20,
            gear_motor_revs: 1,
            gear_shaft_revs: 1,
            feed_user_units: 10_000,
            feed_shaft_revs: 1,
            rated_torque_mnm: 5000,
            rated_current_ma: 8000,
            max_motor_speed_rpm: 3000,
            rotary: false,
        }
    }

    /// The slots of PDO `number` of `dir` looked up one by one (the reference `all` is checked
    /// against: a PDO where its COB-ID and its mapping count are).
    fn resolve(od: &ObjectDictionary, dir: Direction, number: u16) -> Option<PdoSlots> {
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

    /// What `resolve` gives, number by number.
    fn by_resolve(od: &ObjectDictionary, dir: Direction) -> Vec<(u16, PdoSlots)> {
        (0..MAX_PDOS)
            .filter_map(|n| resolve(od, dir, n).map(|p| (n, p)))
            .collect()
    }

    fn sub(index: u16, sub: u8, dtype: DataType) -> Entry {
        Entry {
            sub,
            ..Entry::var(index, "x", dtype, Access::Rw)
        }
    }

    #[test]
    fn all_is_resolve_for_every_number_on_the_standard_and_a_gappy_dictionary() {
        let mut od = ObjectDictionary::standard(&info());
        for dir in [Direction::Rx, Direction::Tx] {
            let all = PdoSlots::all(&od, dir);
            assert_eq!(all.len(), 4, "{dir:?}");
            assert_eq!(all, by_resolve(&od, dir), "{dir:?}");
        }
        // RPDO 2 without its COB-ID, TPDO 3 without its count, RPDO 1 without its transmission
        // type and mapping sub 8; a mapping record with no communication record (0x1605),
        // a communication record with no mapping record (0x1806), PDOs at 0x1410/0x1610 and
        // at the last number (0x19FF/0x1BFF), one with a sub beyond the known ones.
        assert!(od.remove(0x1401, COB_ID));
        assert!(od.remove(0x1A02, 0));
        assert!(od.remove(0x1400, TRANSMISSION_TYPE));
        assert!(od.remove(0x1600, 8));
        for e in [
            sub(0x1605, 0, DataType::U8),
            sub(0x1806, COB_ID, DataType::U32),
            sub(0x1410, COB_ID, DataType::U32),
            sub(0x1410, 9, DataType::U8),
            sub(0x1610, 0, DataType::U8),
            sub(0x1610, 3, DataType::U32),
            sub(0x1610, 9, DataType::U32),
            sub(0x19FF, COB_ID, DataType::U32),
            sub(0x19FF, TRANSMISSION_TYPE, DataType::U8),
            sub(0x1BFF, 0, DataType::U8),
            sub(0x1BFF, 1, DataType::U32),
        ] {
            od.insert(e).unwrap();
        }
        let rx = PdoSlots::all(&od, Direction::Rx);
        assert_eq!(
            rx.iter().map(|(n, _)| *n).collect::<Vec<_>>(),
            [0, 2, 3, 0x10]
        );
        assert_eq!(rx[0].1.comm[TRANSMISSION_TYPE as usize], None);
        assert_eq!(rx[0].1.entries[7], None);
        assert!(rx[3].1.entries[2].is_some() && rx[3].1.entries[0].is_none());
        assert_eq!(rx, by_resolve(&od, Direction::Rx));
        let tx = PdoSlots::all(&od, Direction::Tx);
        assert_eq!(
            tx.iter().map(|(n, _)| *n).collect::<Vec<_>>(),
            [0, 1, 3, 0x1FF]
        );
        assert_eq!(tx, by_resolve(&od, Direction::Tx));
    }
}
