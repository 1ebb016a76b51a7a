//! The write-hook table: which service rules a write to a stored object, as CANopenNode's
//! `OD_extension_init` attaches a service's read/write functions to its objects.
//!
//! Each service module registers its objects (an index range and one function) when the
//! node is built ([`WriteHooks::standard`]); an SDO download and an RPDO value go through the
//! same [`DriveCore::write_stored`](super::DriveCore::write_stored): the dictionary's type and limits
//! first, then the hook of the object's range, if any. A hook refuses (a CiA 301 abort
//! code), lets the value be stored, or applies it itself. The table is a fixed-size array
//! of ranges; when the node is built it is indexed by the dictionary's rows
//! ([`WriteHooks::index_rows`], the one allocation), so a write finds its hook, or that it
//! has none (0x607A, 0x60FF, ...), with one load instead of a scan of a dozen ranges.

use super::DriveCore;
use crate::od::ObjectDictionary;

/// Ranges a node's table holds at most (a registration beyond it is a bug in this crate,
/// caught by every test that builds a node).
pub(crate) const MAX_HOOKS: usize = 16;

/// Where a write comes from. The rules are the same; a hook that reacts to a value's change
/// (the controlword latch) sees an RPDO that repeats the value as no new write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Origin {
    /// An SDO download (or a front end's object write).
    Sdo,
    /// A value of a received RPDO (or a front end's RxPDO image).
    Rpdo,
}

/// One write to a stored object whose type and dictionary limits were checked.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ObjectWrite {
    /// The object's slot in the store.
    pub row: usize,
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The value (raw form: signed sign-extended, REAL as bits).
    pub raw: u64,
    /// SDO or RPDO.
    pub origin: Origin,
}

/// What a hook decided about a write it accepts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Verdict {
    /// Store the value as written.
    Store,
    /// The hook applied the write itself (or keeps the old value on purpose): store nothing.
    Applied,
}

/// A service's check-and-apply function for the objects it registered.
pub(crate) type Hook = fn(&mut DriveCore, &ObjectWrite) -> Result<Verdict, u32>;

#[derive(Clone, Copy)]
struct Range {
    lo: u16,
    hi: u16,
    hook: Hook,
}

impl core::fmt::Debug for Range {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "0x{:04X}..=0x{:04X}", self.lo, self.hi)
    }
}

/// In [`WriteHooks::by_row`]: the row's object has no hook.
const NO_HOOK: u8 = 0xFF;
/// In [`WriteHooks::by_row`]: the row was not indexed (a hidden entry): look its index up.
const NOT_INDEXED: u8 = 0xFE;

/// Index ranges and the hook that rules each.
#[derive(Clone, Debug)]
pub(crate) struct WriteHooks {
    ranges: [Option<Range>; MAX_HOOKS],
    n: usize,
    /// By dictionary row: the position of its hook's range in `ranges`, [`NO_HOOK`] or
    /// [`NOT_INDEXED`] (filled by [`WriteHooks::index_rows`]; empty before: a row beyond it
    /// is looked up by its index too).
    by_row: Box<[u8]>,
}

impl WriteHooks {
    /// An empty table.
    pub(crate) fn new() -> WriteHooks {
        WriteHooks {
            ranges: [None; MAX_HOOKS],
            n: 0,
            by_row: Box::default(),
        }
    }

    /// Index the table by the rows of `od` (the dictionary the node keeps; its rows do not
    /// change after the node is built): [`WriteHooks::for_row`] is then one load. One walk
    /// over the visible rows in index order beside the ranges in theirs (they do not
    /// overlap), so building a node does not scan the ranges once per row; a hidden row
    /// is left [`NOT_INDEXED`] (looked up by its index, if it is ever written).
    pub(crate) fn index_rows(&mut self, od: &ObjectDictionary) {
        let mut sorted: heapless::Vec<(u16, u16, u8), MAX_HOOKS> = heapless::Vec::new();
        for (k, r) in self.ranges[..self.n].iter().enumerate() {
            if let Some(r) = r {
                let _ = sorted.push((r.lo, r.hi, k as u8));
            }
        }
        sorted.sort_unstable_by_key(|&(lo, _, _)| lo);
        let mut by_row = vec![NOT_INDEXED; od.slot_count()];
        let mut p = 0;
        for (slot, e) in od.iter() {
            while sorted.get(p).is_some_and(|&(_, hi, _)| hi < e.index) {
                p += 1;
            }
            by_row[slot.get()] = match sorted.get(p) {
                Some(&(lo, _, k)) if lo <= e.index => k,
                _ => NO_HOOK,
            };
        }
        self.by_row = by_row.into_boxed_slice();
    }

    /// The hook ruling writes to the object in dictionary row `row` (index `index`).
    #[inline]
    pub(crate) fn for_row(&self, row: usize, index: u16) -> Option<Hook> {
        match self.by_row.get(row).copied() {
            Some(NO_HOOK) => None,
            Some(k) if k != NOT_INDEXED => self.ranges[k as usize].map(|r| r.hook),
            _ => self.find(index),
        }
    }

    /// The table of every service a node has: CiA 301 (EMCY, SYNC, heartbeat, store and
    /// restore, the PDO parameters) and CiA 402.
    pub(crate) fn standard() -> WriteHooks {
        let mut t = WriteHooks::new();
        crate::cia301::emcy::register_writes(&mut t);
        crate::cia301::sync::register_writes(&mut t);
        crate::cia301::heartbeat::register_writes(&mut t);
        crate::cia301::store::register_writes(&mut t);
        crate::cia301::pdo::register_writes(&mut t);
        crate::cia402::register_writes(&mut t);
        t
    }

    /// A service rules writes to `lo..=hi`. Ranges do not overlap: one owner per object.
    /// Panics on an overlap or a full table (a bug in the services' registrations, not
    /// something a dictionary or a bus peer can cause).
    pub(crate) fn register(&mut self, lo: u16, hi: u16, hook: Hook) {
        assert!(lo <= hi, "write hook range 0x{lo:04X}..=0x{hi:04X}");
        assert!(
            self.find(lo).is_none() && self.find(hi).is_none(),
            "write hook range 0x{lo:04X}..=0x{hi:04X} overlaps one registered before"
        );
        assert!(self.n < MAX_HOOKS, "write hook table full");
        self.ranges[self.n] = Some(Range { lo, hi, hook });
        self.n += 1;
    }

    /// The hook ruling writes to `index`, if a service registered one.
    pub(crate) fn find(&self, index: u16) -> Option<Hook> {
        self.position(index)
            .and_then(|k| self.ranges[k])
            .map(|r| r.hook)
    }

    /// The position in `ranges` of the range holding `index`.
    fn position(&self, index: u16) -> Option<usize> {
        self.ranges[..self.n]
            .iter()
            .position(|r| r.is_some_and(|r| (r.lo..=r.hi).contains(&index)))
    }

    /// The registered ranges (tests and the decision record's table).
    #[cfg(test)]
    pub(crate) fn ranges(&self) -> impl Iterator<Item = (u16, u16)> + '_ {
        self.ranges[..self.n].iter().flatten().map(|r| (r.lo, r.hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_object_with_a_rule_has_exactly_one_owner() {
        let t = WriteHooks::standard();
        for index in [
            0x1003u16, 0x1005, 0x1010, 0x1011, 0x1014, 0x1016, 0x1017, 0x1019, 0x1400, 0x1A03,
            0x6040, 0x6060, 0x607D, 0x6098,
        ] {
            assert_eq!(
                t.ranges()
                    .filter(|&(lo, hi)| (lo..=hi).contains(&index))
                    .count(),
                1,
                "0x{index:04X}"
            );
        }
        // objects without a rule are stored as the dictionary's limits allow
        for index in [0x1000u16, 0x1006, 0x1C00, 0x6041, 0x607A, 0x6081, 0x2000] {
            assert!(t.find(index).is_none(), "0x{index:04X}");
        }
    }

    #[test]
    fn the_row_index_finds_what_the_ranges_find() {
        let info = crate::drive::DriveInfo {
            encoder_increments_per_rev: 4096,
            gear_motor_revs: 1,
            gear_shaft_revs: 1,
            feed_user_units: 1000,
            feed_shaft_revs: 1,
            rated_torque_mnm: 1000,
            rated_current_ma: 1000,
            max_motor_speed_rpm: 3000,
            rotary: false,
        };
        let od = ObjectDictionary::standard(&info);
        let mut t = WriteHooks::standard();
        t.index_rows(&od);
        let (mut hooked, mut plain) = (0, 0);
        for (slot, e) in od.iter() {
            let want = t.position(e.index);
            let got = t.by_row[slot.get()];
            assert_eq!(got, want.map_or(NO_HOOK, |k| k as u8), "0x{:04X}", e.index);
            assert_eq!(t.for_row(slot.get(), e.index).is_some(), want.is_some());
            if want.is_some() {
                hooked += 1;
            } else {
                plain += 1;
            }
        }
        assert!(hooked > 10 && plain > 10, "{hooked} {plain}");
        // a row the index does not know is looked up by its index
        assert!(t.for_row(usize::MAX, 0x6040).is_some());
        assert!(t.for_row(usize::MAX, 0x607A).is_none());
    }

    #[test]
    #[should_panic(expected = "overlaps")]
    fn an_overlapping_registration_is_a_bug() {
        fn keep(_: &mut DriveCore, _: &ObjectWrite) -> Result<Verdict, u32> {
            Ok(Verdict::Store)
        }
        let mut t = WriteHooks::new();
        t.register(0x1400, 0x1BFF, keep);
        t.register(0x1A00, 0x1A00, keep);
    }
}
