//! The object dictionary (CiA 301 7.4) as a value, built when the node is built.
//!
//! An [`ObjectDictionary`] is a list of [`Entry`]s, one per (index, sub-index): type,
//! access, PDO mapping, default, limits, and how the value is kept ([`Backing`]): in the
//! node's store, or by a handler of the application (the emulator registers its axis
//! parameters so, and reads or writes them through [`crate::Drive::read_object`] /
//! [`crate::Drive::write_object`], as CANopenNode's `OD_extension_t` does). The SDO server,
//! the PDOs, the CiA 402 layer and the EDS export all read the same dictionary.
//!
//! Where it comes from: [`ObjectDictionary::standard`] gives the CiA 301 / CiA 402 objects the
//! node implements (`standard.rs`); the application inserts its own with
//! [`ObjectDictionary::insert`]; [`ObjectDictionary::from_eds`] builds one from a vendor's
//! EDS or DCF (`from_eds.rs`).
//!
//! Storage: every object the node itself needs has a fixed slot, its row in the standard
//! table (resolved at compile time, so the node's code names them as constants). A vendor
//! dictionary binds its entries to those slots where the (index, sub) is one the node knows,
//! and gives every other entry a slot after them. A standard object a vendor's EDS does not
//! have keeps its slot, hidden: the node still simulates it (with the standard default), no
//! SDO or PDO reaches it. Memory is allocated when the node is built, never on a tick
//! (docs/decisions/0009-object-dictionary.md).

pub mod eds;
/// The EDS reader at its former path (the same items as [`eds`]).
pub use eds as eds_parse;
mod from_eds;
pub(crate) mod placeholders;
mod standard;
mod store;
mod types;

use std::borrow::Cow;

use crate::drive::DriveInfo;
pub use from_eds::{
    BuildReport, EdsBuildError, Fate, ReportLine, WRITABLE_DOMAIN_CAPACITY,
    WRITABLE_STRING_CAPACITY,
};
pub(crate) use standard::idx;
pub(crate) use store::Store;
pub use types::{Access, DataType};

/// The kind of object an entry belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ObjType {
    /// VAR (object code 0x7): a single value at sub-index 0 (a DOMAIN object is a VAR of
    /// type DOMAIN).
    Var,
    /// ARRAY (object code 0x8): sub 0 holds the count, subs 1.. one data type.
    Array,
    /// RECORD (object code 0x9): sub 0 holds the highest sub-index, subs of mixed types.
    Record,
}

impl ObjType {
    /// The CiA 306 object code (`ObjectType=0x7`).
    pub const fn code(self) -> u8 {
        match self {
            ObjType::Var => 7,
            ObjType::Array => 8,
            ObjType::Record => 9,
        }
    }
}

/// The value an entry has after a reset (NMT reset, 0x1011 restore).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DefaultValue {
    /// A number: raw bits, signed types sign-extended to 64 bits, REAL32/REAL64 as their
    /// IEEE 754 bits.
    Value(u64),
    /// `$NODEID + base`: resolved with the node's ID whenever the value is reset (an LSS
    /// master may change the ID).
    NodeId(u64),
    /// The bytes of a string or DOMAIN.
    Bytes(Vec<u8>),
}

/// How an entry's value is kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Backing {
    /// In the node's store (what every EDS object without a behaviour is).
    Stored,
    /// By the application: an SDO read or write goes to [`crate::Drive::read_object`] /
    /// [`crate::Drive::write_object`] with this tag. Not mappable into a PDO.
    Handler(u16),
}

/// One (index, sub-index) of the dictionary.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// Object index (e.g. 0x6040).
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// VAR, ARRAY or RECORD.
    pub otype: ObjType,
    /// Name of the whole array/record (the same on every entry of it); the VAR's name.
    pub parent: Cow<'static, str>,
    /// Name of this entry (the EDS ParameterName of the sub-index).
    pub name: Cow<'static, str>,
    /// Data type of the value.
    pub dtype: DataType,
    /// SDO access.
    pub access: Access,
    /// May be mapped into a PDO (EDS PDOMapping=1).
    pub pdo: bool,
    /// Value after reset.
    pub default: DefaultValue,
    /// Lowest value a write may set (raw form as [`DefaultValue::Value`]), EDS LowLimit.
    pub low: Option<u64>,
    /// Highest value a write may set, EDS HighLimit.
    pub high: Option<u64>,
    /// Where the value lives.
    pub backing: Backing,
    /// Bytes kept for a value of variable length (strings, DOMAIN): at least the default's.
    pub capacity: usize,
}

/// Bytes a string or DOMAIN entry keeps unless it says otherwise.
pub const DEFAULT_VARIABLE_CAPACITY: usize = 64;

impl Entry {
    /// A VAR at sub 0, stored, no PDO mapping, default 0 (or empty).
    pub fn var(
        index: u16,
        name: impl Into<Cow<'static, str>>,
        dtype: DataType,
        access: Access,
    ) -> Entry {
        let name = name.into();
        Entry::member(index, 0, ObjType::Var, name.clone(), name, dtype, access)
    }

    /// An entry of an ARRAY or RECORD (or a VAR at sub 0), stored, no PDO mapping, default 0.
    pub fn member(
        index: u16,
        sub: u8,
        otype: ObjType,
        parent: impl Into<Cow<'static, str>>,
        name: impl Into<Cow<'static, str>>,
        dtype: DataType,
        access: Access,
    ) -> Entry {
        let default = if dtype.variable() {
            DefaultValue::Bytes(Vec::new())
        } else {
            DefaultValue::Value(0)
        };
        Entry {
            index,
            sub,
            otype,
            parent: parent.into(),
            name: name.into(),
            dtype,
            access,
            pdo: false,
            default,
            low: None,
            high: None,
            backing: Backing::Stored,
            capacity: if dtype.variable() {
                DEFAULT_VARIABLE_CAPACITY
            } else {
                0
            },
        }
    }

    /// The same entry, mappable into a PDO or not.
    pub fn with_pdo(mut self, pdo: bool) -> Entry {
        self.pdo = pdo;
        self
    }

    /// The same entry with this default (a string's default also raises its capacity).
    pub fn with_default(mut self, default: DefaultValue) -> Entry {
        if let DefaultValue::Bytes(b) = &default {
            self.capacity = self.capacity.max(b.len());
        }
        self.default = default;
        self
    }

    /// The same entry with limits (numbers in the entry's type; `None`: no limit).
    pub fn with_limits(mut self, low: Option<i128>, high: Option<i128>) -> Entry {
        self.low = low.map(|v| v as i64 as u64);
        self.high = high.map(|v| v as i64 as u64);
        self
    }

    /// The same entry with limits in raw form (as [`DefaultValue::Value`]; any type).
    pub fn with_raw_limits(mut self, low: Option<u64>, high: Option<u64>) -> Entry {
        self.low = low;
        self.high = high;
        self
    }

    /// The same entry, its value kept by the application under `tag`.
    pub fn with_handler(mut self, tag: u16) -> Entry {
        self.backing = Backing::Handler(tag);
        self
    }

    /// The same entry keeping up to `bytes` for a variable-length value.
    pub fn with_capacity(mut self, bytes: usize) -> Entry {
        self.capacity = bytes;
        self
    }

    /// Raw value of the default for a node (0 for strings).
    pub fn default_raw(&self, node_id: u8) -> u64 {
        match &self.default {
            DefaultValue::Value(v) => *v,
            DefaultValue::NodeId(b) => b.wrapping_add(node_id as u64),
            DefaultValue::Bytes(_) => 0,
        }
    }

    /// Decode little-endian wire bytes of this entry's type into the raw form.
    pub fn decode(&self, bytes: &[u8]) -> u64 {
        decode(self.dtype, bytes)
    }

    /// Whether `raw` is inside the entry's limits. `Err(true)`: above the high limit.
    pub fn check_limits(&self, raw: u64) -> Result<(), bool> {
        if let Some(h) = self.high {
            if compare(self.dtype, raw, h) == Some(core::cmp::Ordering::Greater) {
                return Err(true);
            }
        }
        if let Some(l) = self.low {
            if compare(self.dtype, raw, l) == Some(core::cmp::Ordering::Less) {
                return Err(false);
            }
        }
        Ok(())
    }

    /// The value as a number for text (signed as signed, REAL as a float); `None` for
    /// strings and DOMAIN.
    pub fn number(&self, raw: u64) -> Option<Number> {
        number(self.dtype, raw)
    }
}

/// A value read as a number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Number {
    /// An integer type.
    Int(i128),
    /// REAL32.
    Real32(f32),
    /// REAL64.
    Real64(f64),
}

impl Number {
    /// The value as an f64 (an integer beyond 2^53 rounds).
    pub fn as_f64(self) -> f64 {
        match self {
            Number::Int(v) => v as f64,
            Number::Real32(v) => v as f64,
            Number::Real64(v) => v,
        }
    }
}

impl core::fmt::Display for Number {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Number::Int(v) => write!(f, "{v}"),
            // the shortest text that reads back as the same value of the type
            Number::Real32(v) => write!(f, "{v}"),
            Number::Real64(v) => write!(f, "{v}"),
        }
    }
}

/// Decode little-endian wire bytes of `dtype` into the raw form (sign-extended to 64 bits).
pub fn decode(dtype: DataType, bytes: &[u8]) -> u64 {
    let mut v = [0u8; 8];
    let n = bytes.len().min(8).min(dtype.size().max(1));
    v[..n].copy_from_slice(&bytes[..n]);
    let raw = u64::from_le_bytes(v);
    let size = dtype.size();
    if dtype.signed() && (1..8).contains(&size) {
        let shift = 64 - 8 * size as u32;
        (((raw << shift) as i64) >> shift) as u64
    } else {
        raw
    }
}

/// A raw value as a number of its type (`None` for strings, DOMAIN and the time types).
pub fn number(dtype: DataType, raw: u64) -> Option<Number> {
    match dtype {
        DataType::Real32 => Some(Number::Real32(f32::from_bits(raw as u32))),
        DataType::Real64 => Some(Number::Real64(f64::from_bits(raw))),
        t if t.integer() && t.signed() => Some(Number::Int(raw as i64 as i128)),
        t if t.integer() => Some(Number::Int(raw as i128)),
        _ => None,
    }
}

/// Order of two raw values of `dtype` (`None` where the type has no order or a float is NaN).
pub fn compare(dtype: DataType, a: u64, b: u64) -> Option<core::cmp::Ordering> {
    match (number(dtype, a)?, number(dtype, b)?) {
        (Number::Int(x), Number::Int(y)) => Some(x.cmp(&y)),
        (x, y) => x.as_f64().partial_cmp(&y.as_f64()),
    }
}

/// A handle on one entry's storage, valid for the dictionary (and the node) it came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Slot(u32);

impl Slot {
    pub(crate) const fn at(i: usize) -> Slot {
        Slot(i as u32)
    }
    pub(crate) const fn get(self) -> usize {
        self.0 as usize
    }
}

/// Lookup result for an (index, sub) that came off the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lookup {
    /// The entry exists: its slot.
    Found(Slot),
    /// No object at this index (SDO abort 0x06020000).
    NoObject,
    /// The object exists but not this sub-index (SDO abort 0x06090011).
    NoSub,
}

/// What the EDS `[DeviceInfo]` says of the device beyond its objects.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceDescription {
    /// VendorName.
    pub vendor_name: String,
    /// ProductName.
    pub product_name: String,
    /// OrderCode.
    pub order_code: String,
    /// BaudRate_* the device supports, kbit/s.
    pub baud_rates_kbit: Vec<u16>,
    /// Granularity of PDO mapping, bits (8: whole bytes).
    pub granularity: u8,
    /// LSS_Supported.
    pub lss_supported: bool,
    /// `[DummyUsage]`: which of the data types 0x0001..=0x0007 an RPDO may map as a dummy
    /// (index 1..=7 of this array; 0 unused).
    pub dummy_usage: [bool; 8],
    /// RPDO mapping entries the device ships that map a read-only object (a vendor's default
    /// mapping CiA 301 would refuse, e.g. a scanned SCHUNK file): accepted as the device
    /// accepts them, a received value for such an object ignored.
    pub shipped_read_only_rpdo_entries: Vec<u32>,
    /// Mapping entries of the device's default PDO maps (RPDO or TPDO) that map fewer whole
    /// bytes of an object than it has (32 bits of a 64-bit object): taken as the device takes
    /// them, the low bytes of the value (a received value zero-extended).
    pub shipped_short_entries: Vec<u32>,
    /// The file's following-error window 0x6065 is 0 (its default, a placeholder, or a DCF's
    /// ParameterValue): its vendor documents 0 as "off", so a 0 in 0x6065 switches the
    /// following-error check off on this device, as 0xFFFFFFFF does in CiA 402.
    pub following_error_window_zero_off: bool,
    /// PDO communication records (0x1400.., 0x1800..) whose COB-ID the file marks read-only:
    /// served writable for bit 31 (valid) only (`placeholders::read_only_pdo_cob_id`).
    pub fixed_pdo_can_ids: Vec<u16>,
    /// The file's EMCY COB-ID 0x1014 is 0 (its default or a DCF's ParameterValue; SEVCON's
    /// Gen4): the device's "EMCY on the predefined CAN-ID", $NODEID + 0x80. A 0 in 0x1014
    /// reads back as 0 and sends EMCY there; a master may write 0 back. Elsewhere CiA 301's
    /// refusal of CAN-ID 0 (NMT's) holds.
    pub emcy_cob_id_zero_predefined: bool,
    /// PDO CAN-IDs the device's own file gives (communication record index, CAN-ID) in a
    /// range CiA 301 restricts (a Gen4 DCF's TPDOs on 0x120, 0x145, 0x178, read from a live
    /// controller): taken as the device takes them, for that PDO.
    pub shipped_pdo_can_ids: Vec<(u16, u32)>,
    /// Mapping entries of index 0, sub-index 0 are padding (an EtherCAT ESI's gap entries):
    /// a gap of whole bytes in an RPDO or TPDO, sent as zeros, skipped when received. Not on
    /// CAN (CiA 301 has dummy entries for that).
    pub padding_entries: bool,
}

impl Default for DeviceDescription {
    fn default() -> Self {
        DeviceDescription {
            vendor_name: "drive-emulator".into(),
            product_name: "drive-emulator CiA402 servo".into(),
            order_code: "-".into(),
            baud_rates_kbit: vec![10, 20, 50, 125, 250, 500, 800, 1000],
            granularity: 8,
            lss_supported: true,
            dummy_usage: [false; 8],
            shipped_read_only_rpdo_entries: Vec::new(),
            shipped_short_entries: Vec::new(),
            following_error_window_zero_off: false,
            fixed_pdo_can_ids: Vec::new(),
            emcy_cob_id_zero_predefined: false,
            shipped_pdo_can_ids: Vec::new(),
            padding_entries: false,
        }
    }
}

/// Why an entry could not be added.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OdError {
    /// The (index, sub) is in the dictionary already.
    Duplicate {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// The entry contradicts itself (default of the wrong kind or outside its limits, a
    /// string longer than its capacity, a handler on a PDO-mappable entry, ...).
    Invalid {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        reason: String,
    },
}

impl core::fmt::Display for OdError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            OdError::Duplicate { index, sub } => {
                write!(
                    f,
                    "0x{index:04X} sub {sub} is in the object dictionary already"
                )
            }
            OdError::Invalid { index, sub, reason } => {
                write!(f, "0x{index:04X} sub {sub}: {reason}")
            }
        }
    }
}

impl std::error::Error for OdError {}

#[derive(Clone, Debug)]
struct SlotEntry {
    entry: Entry,
    /// Reachable over SDO and PDO (a standard object a vendor dictionary lacks is not).
    visible: bool,
}

/// The object dictionary of one node.
#[derive(Clone, Debug)]
pub struct ObjectDictionary {
    /// Every entry by slot: first the standard table's rows (some maybe hidden), then the rest.
    slots: Vec<SlotEntry>,
    /// Slots of the visible entries, sorted by (index, sub).
    sorted: Vec<u32>,
    /// The `[DeviceInfo]` facts.
    pub device: DeviceDescription,
}

impl ObjectDictionary {
    /// The CiA 301 communication objects and CiA 402 profile objects the node implements,
    /// with the defaults `info` gives (factor group, rated values, limits).
    pub fn standard(info: &DriveInfo) -> ObjectDictionary {
        let mut od = ObjectDictionary {
            slots: standard::entries(info)
                .into_iter()
                .map(|entry| SlotEntry {
                    entry,
                    visible: true,
                })
                .collect(),
            sorted: Vec::new(),
            device: DeviceDescription::default(),
        };
        od.resort();
        od
    }

    /// The standard slots, every one hidden: the start of a dictionary built from an EDS.
    pub(crate) fn standard_hidden(info: &DriveInfo) -> ObjectDictionary {
        let mut od = ObjectDictionary::standard(info);
        for s in &mut od.slots {
            s.visible = false;
        }
        od.resort();
        od
    }

    fn resort(&mut self) {
        let mut v: Vec<u32> = (0..self.slots.len() as u32)
            .filter(|&i| self.slots[i as usize].visible)
            .collect();
        v.sort_by_key(|&i| {
            let e = &self.slots[i as usize].entry;
            (e.index, e.sub)
        });
        self.sorted = v;
    }

    /// Check an entry on its own.
    fn validate(e: &Entry) -> Result<(), OdError> {
        let bad = |reason: String| OdError::Invalid {
            index: e.index,
            sub: e.sub,
            reason,
        };
        match (&e.default, e.dtype.variable()) {
            (DefaultValue::Bytes(b), true) if b.len() > e.capacity => {
                return Err(bad(format!(
                    "default of {} bytes, capacity {}",
                    b.len(),
                    e.capacity
                )))
            }
            (DefaultValue::Bytes(_), false) => {
                return Err(bad(format!("a byte string default for {}", e.dtype.name())))
            }
            (DefaultValue::Value(_) | DefaultValue::NodeId(_), true) => {
                return Err(bad(format!("a number default for {}", e.dtype.name())))
            }
            _ => {}
        }
        if let DefaultValue::Value(v) = e.default {
            if let Err(high) = e.check_limits(v) {
                return Err(bad(format!(
                    "default {} is {} its limit",
                    e.number(v)
                        .map_or_else(|| format!("{v:#x}"), |n| n.to_string()),
                    if high { "above" } else { "below" }
                )));
            }
        }
        if e.pdo && matches!(e.backing, Backing::Handler(_)) {
            return Err(bad("a handler object cannot be mapped into a PDO".into()));
        }
        if e.pdo && e.dtype.variable() {
            return Err(bad(format!(
                "{} cannot be mapped into a PDO",
                e.dtype.name()
            )));
        }
        Ok(())
    }

    /// Add an entry. One the node knows (a standard (index, sub) that is hidden) takes the
    /// node's slot, so the node simulates it with these attributes; any other gets a new slot.
    pub fn insert(&mut self, e: Entry) -> Result<Slot, OdError> {
        let slot = self.insert_unsorted(e)?;
        self.resort();
        Ok(slot)
    }

    /// [`ObjectDictionary::insert`] without re-sorting (a build that adds many entries
    /// sorts once at the end with `resort`).
    fn insert_unsorted(&mut self, e: Entry) -> Result<Slot, OdError> {
        ObjectDictionary::validate(&e)?;
        let i = match self.find_any(e.index, e.sub) {
            Some(i) if self.slots[i].visible => {
                return Err(OdError::Duplicate {
                    index: e.index,
                    sub: e.sub,
                })
            }
            Some(i) => {
                self.slots[i] = SlotEntry {
                    entry: e,
                    visible: true,
                };
                i
            }
            None => {
                self.slots.push(SlotEntry {
                    entry: e,
                    visible: true,
                });
                self.slots.len() - 1
            }
        };
        Ok(Slot::at(i))
    }

    /// Give the visible entry at (index, sub) another default (e.g. the identity's serial
    /// number); the entry's checks apply (kind, limits, capacity).
    pub fn set_default(
        &mut self,
        index: u16,
        sub: u8,
        default: DefaultValue,
    ) -> Result<(), OdError> {
        let Lookup::Found(slot) = self.find(index, sub) else {
            return Err(OdError::Invalid {
                index,
                sub,
                reason: "no such entry".into(),
            });
        };
        let e = self.slots[slot.get()].entry.clone().with_default(default);
        ObjectDictionary::validate(&e)?;
        self.slots[slot.get()].entry = e;
        Ok(())
    }

    /// Take an entry out of reach (SDO, PDO, EDS); a standard one keeps its slot, hidden.
    pub fn remove(&mut self, index: u16, sub: u8) -> bool {
        match self.find_any(index, sub) {
            Some(i) if self.slots[i].visible => {
                self.slots[i].visible = false;
                self.resort();
                true
            }
            _ => false,
        }
    }

    /// Any slot (visible or hidden) with this key.
    fn find_any(&self, index: u16, sub: u8) -> Option<usize> {
        standard::slot_of(index, sub).or_else(|| {
            let extra = &self.slots[standard::len()..];
            extra
                .iter()
                .position(|s| s.entry.index == index && s.entry.sub == sub)
                .map(|p| p + standard::len())
        })
    }

    /// Look up an (index, sub) among the visible entries.
    pub fn find(&self, index: u16, sub: u8) -> Lookup {
        let key = |&i: &u32| {
            let e = &self.slots[i as usize].entry;
            (e.index, e.sub)
        };
        match self.sorted.binary_search_by(|i| key(i).cmp(&(index, sub))) {
            Ok(p) => Lookup::Found(Slot(self.sorted[p])),
            Err(p) => {
                let before = p > 0 && key(&self.sorted[p - 1]).0 == index;
                let after = p < self.sorted.len() && key(&self.sorted[p]).0 == index;
                if before || after {
                    Lookup::NoSub
                } else {
                    Lookup::NoObject
                }
            }
        }
    }

    /// The visible entry at (index, sub).
    pub fn get(&self, index: u16, sub: u8) -> Option<(Slot, &Entry)> {
        match self.find(index, sub) {
            Lookup::Found(s) => Some((s, self.entry(s))),
            _ => None,
        }
    }

    /// Whether any visible entry has this index.
    pub fn has_index(&self, index: u16) -> bool {
        self.find(index, 0) != Lookup::NoObject
    }

    /// The entry of a slot.
    pub fn entry(&self, slot: Slot) -> &Entry {
        &self.slots[slot.get()].entry
    }

    /// The visible entries, sorted by (index, sub).
    pub fn iter(&self) -> impl Iterator<Item = (Slot, &Entry)> + '_ {
        self.sorted
            .iter()
            .map(|&i| (Slot(i), &self.slots[i as usize].entry))
    }

    /// The visible indices, sorted, each once.
    pub fn indices(&self) -> Vec<u16> {
        let mut v: Vec<u16> = self.iter().map(|(_, e)| e.index).collect();
        v.dedup();
        v
    }

    /// Number of visible entries.
    pub fn len(&self) -> usize {
        self.sorted.len()
    }

    /// No visible entry.
    pub fn is_empty(&self) -> bool {
        self.sorted.is_empty()
    }

    /// Whether the slot is reachable from the bus.
    pub fn visible(&self, slot: Slot) -> bool {
        self.slots.get(slot.get()).is_some_and(|s| s.visible)
    }

    /// Every slot (visible or not), for the store.
    pub(crate) fn all_slots(&self) -> impl Iterator<Item = &Entry> + '_ {
        self.slots.iter().map(|s| &s.entry)
    }

    /// Number of slots (visible or not).
    pub(crate) fn slot_count(&self) -> usize {
        self.slots.len()
    }

    /// The visible entries of one object (index), sorted by sub.
    pub fn object(&self, index: u16) -> impl Iterator<Item = (Slot, &Entry)> + '_ {
        self.iter().filter(move |(_, e)| e.index == index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info() -> DriveInfo {
        DriveInfo {
            encoder_increments_per_rev: 1 << 20,
            gear_motor_revs: 1,
            gear_shaft_revs: 1,
            feed_user_units: 10_000,
            feed_shaft_revs: 1,
            rated_torque_mnm: 10_000,
            rated_current_ma: 10_000,
            max_motor_speed_rpm: 3000,
            rotary: false,
        }
    }

    #[test]
    fn standard_is_sorted_and_finds_object_and_sub() {
        let od = ObjectDictionary::standard(&info());
        let keys: Vec<_> = od.iter().map(|(_, e)| (e.index, e.sub)).collect();
        assert!(keys.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(od.find(0x1000, 0), Lookup::Found(Slot::at(idx(0x1000, 0))));
        assert_eq!(od.find(0x1000, 1), Lookup::NoSub);
        assert_eq!(od.find(0x1234, 0), Lookup::NoObject);
        assert_eq!(od.find(0x1800, 4), Lookup::NoSub);
    }

    #[test]
    fn insert_refuses_duplicates_and_contradictions_and_hidden_standard_slots_come_back() {
        let mut od = ObjectDictionary::standard(&info());
        assert!(matches!(
            od.insert(Entry::var(0x6040, "x", DataType::U16, Access::Rw)),
            Err(OdError::Duplicate { .. })
        ));
        let bad = Entry::var(0x2000, "x", DataType::U8, Access::Rw)
            .with_limits(Some(1), Some(5))
            .with_default(DefaultValue::Value(9));
        assert!(matches!(od.insert(bad), Err(OdError::Invalid { .. })));
        let s = od
            .insert(
                Entry::var(0x2000, "x", DataType::I16, Access::Rw)
                    .with_default(DefaultValue::Value(-3i64 as u64)),
            )
            .unwrap();
        assert_eq!(od.find(0x2000, 0), Lookup::Found(s));
        assert!(od.remove(0x6067, 0));
        assert_eq!(od.find(0x6067, 0), Lookup::NoObject);
        let back = od
            .insert(Entry::var(
                0x6067,
                "Position window",
                DataType::U32,
                Access::Rw,
            ))
            .unwrap();
        assert_eq!(back, Slot::at(idx(0x6067, 0)));
    }

    #[test]
    fn decode_sign_extends_every_signed_size_and_limits_compare_by_type() {
        assert_eq!(decode(DataType::I24, &[0xFF, 0xFF, 0xFF]) as i64, -1);
        assert_eq!(decode(DataType::U24, &[0xFF, 0xFF, 0xFF]), 0xFF_FFFF);
        assert_eq!(
            decode(DataType::I56, &[0, 0, 0, 0, 0, 0, 0x80]) as i64,
            -(1i64 << 55)
        );
        assert_eq!(decode(DataType::I8, &[0x80, 0x11]) as i64, -128);
        let e = Entry::var(0x2000, "x", DataType::I16, Access::Rw).with_limits(Some(-10), Some(10));
        assert_eq!(e.check_limits(-11i64 as u64), Err(false));
        assert_eq!(e.check_limits(11), Err(true));
        assert_eq!(e.check_limits(-10i64 as u64), Ok(()));
        let f = Entry::var(0x2001, "f", DataType::Real32, Access::Rw).with_limits(None, None);
        assert_eq!(f.check_limits(1.5f32.to_bits() as u64), Ok(()));
    }
}
