//! The emulator's own objects in the drive's object dictionary, registered when the node is
//! built ([`register`]), at a base index (0x2000 unless a vendor's EDS has objects there):
//!
//! - base + 0x00 ..= 0x0E: the axis parameters of [`AxisParam`], one REAL32 each, in the
//!   unit the object's name says (`backlash_mm`, `kv_per_s`, ...): the parameter registry's
//!   spelling (`drive_physics::params`, one name everywhere); the drive keeps them (a handler:
//!   an SDO read or write converts with the spelling's SI scale and goes to
//!   [`AxisDrive::param`] / [`AxisDrive::set_param`]). Rotary axes use the rotary spelling (SI
//!   is rad there).
//! - base + 0x100: the runtime's loop statistics (RECORD of U32, read-only, mappable, subs
//!   named by [`STATS_NAMES`]), stored values the runtime publishes ([`EmuObjects::stats`]).
//! - base + 0x101: fault injection (U16, write-only): a non-zero value is a drive fault with
//!   that error code until 0 is written (a fault reset meanwhile is refused).
//! - base + 0x102: the backlash detector's result (`run --detect`, RECORD, read-only,
//!   mappable, stored values the detector publishes ([`EmuObjects::detector`]); subs named
//!   by [`DETECTOR_NAMES`]): 1 verdict (U8: 0 nothing analysed yet, 1 inconclusive, 2 ok, 3
//!   backlash suspected, 4 backlash), 2 frequency of the limit cycle (REAL32, Hz; 0 when none),
//!   3 its amplitude (REAL32, displacement-equivalent, um or mdeg), 4 the k_v it was judged
//!   against (REAL32, 1/s: the drive's, or the master's own position loop where the master
//!   closes it), 5 analyses done (U32, counts up with each result). With backlash confirmed
//!   the drive sends EMCY [`EMCY_BACKLASH`] (a warning: no fault) once, held in 0x1001 /
//!   0x1003 until the verdict drops below backlash.
//!
//! [`AxisDrive::param`]: super::axis_drive::AxisDrive::param
//! [`AxisDrive::set_param`]: super::axis_drive::AxisDrive::set_param

use drive_protocol::od::{
    Access, DataType, DefaultValue, Entry, ObjType, ObjectDictionary, OdError, Slot,
};

/// Where the emulator's objects start unless told otherwise.
pub const DEFAULT_BASE: u16 = 0x2000;
/// Offset of the loop statistics record from the base.
pub const STATS_OFFSET: u16 = 0x100;
/// Offset of the fault injection object from the base.
pub const INJECT_OFFSET: u16 = 0x101;
/// Handler tag of the fault injection object; a parameter object's tag is its offset.
pub const INJECT_TAG: u16 = 0x100;
/// Offset of the backlash detector's record from the base.
pub const DETECTOR_OFFSET: u16 = 0x102;
/// Subs 1.. of the detector's record (names in the EDS).
pub const DETECTOR_NAMES: [&str; 5] = [
    "verdict",
    "frequency_hz",
    "amplitude_um",
    "kv_per_s",
    "analyses",
];
/// Manufacturer-specific EMCY the drive sends when its detector confirms backlash (a
/// warning: the drive keeps running). Its manufacturer bytes: the verdict, the frequency in
/// 0.01 Hz (U16), the amplitude in 0.1 um or 0.1 mdeg (U16).
pub const EMCY_BACKLASH: u16 = 0xFF01;

/// The axis parameters (the registry's live rows, `drive_physics::params`).
pub use drive_physics::params::AxisParam;
use drive_physics::params::{ParamSpec, PARAMS};

/// Why the drive refused a parameter value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParamError {
    /// The value is outside what the drive accepts (SDO abort 0x06090030..32).
    OutOfRange {
        /// Smallest accepted value, SI units.
        min: f64,
        /// Largest accepted value, SI units.
        max: f64,
    },
}

impl ParamError {
    /// The SDO abort code for `value` (SI): too high, too low, or out of range.
    pub fn abort_code(self, value: f64) -> u32 {
        use drive_protocol::wire::sdo::abort;
        match self {
            ParamError::OutOfRange { min, max } => {
                if value > max {
                    abort::VALUE_HIGH
                } else if value < min {
                    abort::VALUE_LOW
                } else {
                    abort::VALUE_RANGE
                }
            }
        }
    }
}

/// The parameter object with handler tag `tag`: the registry row whose object sits `tag`
/// above the base (`drive_physics::params::PARAMS`, `object_offset`).
pub fn param_of_tag(tag: u16) -> Option<&'static ParamSpec> {
    PARAMS.iter().find(|p| p.object_offset == Some(tag))
}

pub use crate::runtime::stats::STATS_NAMES;

/// Where the emulator's objects of one node are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EmuObjects {
    /// The base index.
    pub base: u16,
    /// Slots of the statistics record's subs 1.. (for [`drive_protocol::Node::set_value`]).
    pub stats: [Slot; STATS_NAMES.len()],
    /// Slots of the detector record's subs 1.. ([`DETECTOR_NAMES`]).
    pub detector: [Slot; DETECTOR_NAMES.len()],
}

/// The index range the emulator's objects take at `base`.
pub fn range(base: u16) -> core::ops::RangeInclusive<u16> {
    base..=base + DETECTOR_OFFSET
}

/// The parameter (with its tag) at `index` for objects at `base`.
pub fn param_at(base: u16, index: u16) -> Option<(u16, &'static ParamSpec)> {
    let off = index.checked_sub(base)?;
    param_of_tag(off).map(|p| (off, p))
}

/// Add the emulator's objects to `od` at `base` (names for a rotary axis if `rotary`).
pub fn register(od: &mut ObjectDictionary, base: u16, rotary: bool) -> Result<EmuObjects, OdError> {
    if base.checked_add(DETECTOR_OFFSET).is_none() {
        return Err(OdError::Invalid {
            index: base,
            sub: 0,
            reason: "the emulator's objects do not fit above this base".into(),
        });
    }
    for p in PARAMS {
        let Some(off) = p.object_offset else { continue };
        od.insert(
            Entry::var(base + off, p.form(rotary).key, DataType::Real32, Access::Rw)
                .with_handler(off),
        )?;
    }
    let index = base + STATS_OFFSET;
    let name = "Runtime statistics";
    od.insert(
        Entry::member(
            index,
            0,
            ObjType::Record,
            name,
            "Highest sub-index supported",
            DataType::U8,
            Access::Const,
        )
        .with_default(DefaultValue::Value(STATS_NAMES.len() as u64)),
    )?;
    let mut stats = Vec::with_capacity(STATS_NAMES.len());
    for (s, n) in STATS_NAMES.iter().enumerate() {
        stats.push(
            od.insert(
                Entry::member(
                    index,
                    s as u8 + 1,
                    ObjType::Record,
                    name,
                    *n,
                    DataType::U32,
                    Access::Ro,
                )
                .with_pdo(true),
            )?,
        );
    }
    let stats: [Slot; STATS_NAMES.len()] = stats.try_into().expect("one slot per name");
    od.insert(
        Entry::var(
            base + INJECT_OFFSET,
            "inject_fault_code",
            DataType::U16,
            Access::Wo,
        )
        .with_handler(INJECT_TAG),
    )?;
    let detector = register_detector(od, base + DETECTOR_OFFSET, rotary)?;
    Ok(EmuObjects {
        base,
        stats,
        detector,
    })
}

/// The detector's record at `index` (see the module doc).
fn register_detector(
    od: &mut ObjectDictionary,
    index: u16,
    rotary: bool,
) -> Result<[Slot; DETECTOR_NAMES.len()], OdError> {
    let name = "Backlash detector";
    od.insert(
        Entry::member(
            index,
            0,
            ObjType::Record,
            name,
            "Highest sub-index supported",
            DataType::U8,
            Access::Const,
        )
        .with_default(DefaultValue::Value(DETECTOR_NAMES.len() as u64)),
    )?;
    let mut slots = Vec::with_capacity(DETECTOR_NAMES.len());
    for (s, n) in DETECTOR_NAMES.iter().enumerate() {
        let dtype = match s {
            0 => DataType::U8,
            4 => DataType::U32,
            _ => DataType::Real32,
        };
        let sub_name = if rotary && *n == "amplitude_um" {
            "amplitude_mdeg"
        } else {
            n
        };
        slots.push(
            od.insert(
                Entry::member(
                    index,
                    s as u8 + 1,
                    ObjType::Record,
                    name,
                    sub_name,
                    dtype,
                    Access::Ro,
                )
                .with_pdo(true),
            )?,
        );
    }
    Ok(slots.try_into().expect("one slot per name"))
}
