//! The object dictionary: one static table of object definitions ([`OBJECTS`], in
//! `table.rs`) and the per-node value store (`Store`, private to the crate). The SDO server, the PDOs, the CiA 402
//! layer and the EDS export (`eds.rs`) all read the same table.

pub mod eds;
pub mod eds_parse;
mod table;
mod types;

use crate::drive::DriveInfo;
pub use table::OBJECTS;

pub use types::{Access, DataType};

/// The kind of object a row belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObjType {
    /// VAR (object code 0x7): a single value at sub-index 0.
    Var,
    /// ARRAY (object code 0x8): sub 0 holds the count, subs 1.. one data type.
    Array,
    /// RECORD (object code 0x9): sub 0 holds the highest sub-index, subs of mixed types.
    Record,
}

/// A default value.
#[derive(Clone, Copy, Debug)]
pub enum Def {
    /// A plain value (raw bits; signed values sign-extended to 32 bits).
    V(u32),
    /// `$NODEID + base`.
    NodeId(u32),
    /// Derived from the drive's static facts.
    Info(fn(&DriveInfo) -> u32),
    /// A constant string (VISIBLE_STRING objects).
    Str(&'static str),
}

/// One row of the object table: one (index, sub-index).
#[derive(Clone, Copy, Debug)]
pub struct Obj {
    /// Object index (e.g. 0x6040).
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Whether the object is a VAR, ARRAY or RECORD.
    pub otype: ObjType,
    /// Name of the whole array/record (same on every row of it); the VAR's name for a VAR.
    pub parent: &'static str,
    /// Name of this row (the EDS ParameterName of the sub-index).
    pub name: &'static str,
    /// Data type of the value.
    pub dtype: DataType,
    /// SDO access.
    pub access: Access,
    /// May be mapped into a PDO (EDS PDOMapping=1).
    pub pdo: bool,
    /// Value after reset (0x1011 restore, NMT reset node / communication).
    pub default: Def,
    /// Lowest value an SDO or RPDO write may set (EDS LowLimit).
    pub low: Option<i64>,
    /// Highest value an SDO or RPDO write may set (EDS HighLimit).
    pub high: Option<i64>,
}

impl Obj {
    /// Decode raw little-endian bytes of this object's type into the stored form.
    pub fn decode(&self, b: &[u8]) -> u32 {
        let mut v = [0u8; 4];
        let n = b.len().min(4);
        v[..n].copy_from_slice(&b[..n]);
        let raw = u32::from_le_bytes(v);
        match self.dtype {
            DataType::I8 => raw as u8 as i8 as i32 as u32,
            DataType::I16 => raw as u16 as i16 as i32 as u32,
            _ => raw,
        }
    }

    /// Whether `raw` (stored form) is inside the row's limits. Err(true) = too high.
    pub fn check_limits(&self, raw: u32) -> Result<(), bool> {
        let v: i64 = if self.dtype.signed() {
            raw as i32 as i64
        } else {
            raw as i64
        };
        if let Some(h) = self.high {
            if v > h {
                return Err(true);
            }
        }
        if let Some(l) = self.low {
            if v < l {
                return Err(false);
            }
        }
        Ok(())
    }
}

/// Number of rows in the table.
pub(crate) const N_OBJ: usize = OBJECTS.len();

/// The row of (index, sub), at compile time. Fails to compile if the object is missing.
pub(crate) const fn idx(index: u16, sub: u8) -> usize {
    let mut i = 0;
    while i < OBJECTS.len() {
        if OBJECTS[i].index == index && OBJECTS[i].sub == sub {
            return i;
        }
        i += 1;
    }
    panic!("object not in table")
}

/// Lookup result for an (index, sub) that came off the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lookup {
    /// The object exists: its row in [`OBJECTS`].
    Found(usize),
    /// No object at this index (SDO abort 0x06020000).
    NoObject,
    /// The object exists but not this sub-index (SDO abort 0x06090011).
    NoSub,
}

/// Binary search of the sorted table.
pub fn find(index: u16, sub: u8) -> Lookup {
    match OBJECTS.binary_search_by(|o| (o.index, o.sub).cmp(&(index, sub))) {
        Ok(i) => Lookup::Found(i),
        Err(i) => {
            let before = i > 0 && OBJECTS[i - 1].index == index;
            let after = i < OBJECTS.len() && OBJECTS[i].index == index;
            if before || after {
                Lookup::NoSub
            } else {
                Lookup::NoObject
            }
        }
    }
}

/// Default value of a row in stored form.
pub(crate) fn default_value(o: &Obj, node_id: u8, info: &DriveInfo) -> u32 {
    match o.default {
        Def::V(v) => v,
        Def::NodeId(b) => b + node_id as u32,
        Def::Info(f) => f(info),
        Def::Str(_) => 0,
    }
}

/// The values of one node's objects. Every row has a 32-bit slot (raw bits, signed types
/// sign-extended); strings are constant and read from the table.
#[derive(Clone, Debug)]
pub(crate) struct Store {
    vals: [u32; N_OBJ],
}

impl Store {
    pub fn new(node_id: u8, info: &DriveInfo) -> Store {
        let mut s = Store { vals: [0; N_OBJ] };
        s.reset_range(0x0000, 0xFFFF, node_id, info);
        s
    }

    /// Reset the rows with index in `lo..=hi` to their defaults.
    pub fn reset_range(&mut self, lo: u16, hi: u16, node_id: u8, info: &DriveInfo) {
        for (i, o) in OBJECTS.iter().enumerate() {
            if o.index >= lo && o.index <= hi {
                self.vals[i] = default_value(o, node_id, info);
            }
        }
    }

    /// Copy the rows with index in `lo..=hi` from `from` (restore of saved parameters, 0x1011).
    pub fn copy_range(&mut self, from: &Store, lo: u16, hi: u16) {
        for (i, o) in OBJECTS.iter().enumerate() {
            if o.index >= lo && o.index <= hi {
                self.vals[i] = from.vals[i];
            }
        }
    }

    #[inline]
    pub fn u32(&self, i: usize) -> u32 {
        self.vals[i]
    }
    #[inline]
    pub fn i32(&self, i: usize) -> i32 {
        self.vals[i] as i32
    }
    #[inline]
    pub fn set(&mut self, i: usize, v: u32) {
        self.vals[i] = v;
    }
    #[inline]
    pub fn set_i32(&mut self, i: usize, v: i32) {
        self.vals[i] = v as u32;
    }

    /// Raw little-endian bytes of row `i` into `out`; returns the length.
    pub fn read_bytes(&self, i: usize, out: &mut [u8]) -> usize {
        let o = &OBJECTS[i];
        if let Def::Str(s) = o.default {
            let n = s.len().min(out.len());
            out[..n].copy_from_slice(&s.as_bytes()[..n]);
            return n;
        }
        let n = o.dtype.size();
        out[..n].copy_from_slice(&self.vals[i].to_le_bytes()[..n]);
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_sorted_and_unique() {
        for w in OBJECTS.windows(2) {
            assert!(
                (w[0].index, w[0].sub) < (w[1].index, w[1].sub),
                "table not sorted at {:04X}sub{}",
                w[1].index,
                w[1].sub
            );
        }
    }

    #[test]
    fn find_distinguishes_object_and_sub() {
        assert_eq!(find(0x1000, 0), Lookup::Found(idx(0x1000, 0)));
        assert_eq!(find(0x1000, 1), Lookup::NoSub);
        assert_eq!(find(0x1234, 0), Lookup::NoObject);
        assert_eq!(find(0x1800, 4), Lookup::NoSub);
    }
}
