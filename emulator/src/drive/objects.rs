//! The emulator's own objects in the drive's object dictionary, registered when the node is
//! built ([`register`]), at a base index (0x2000 unless a vendor's EDS has objects there):
//!
//! - base + 0x00 ..= 0x0D: the axis parameters of [`AxisParam`], one REAL32 each, in the
//!   engineering unit the object's name says (`backlash_mm`, `kv_per_s`, ...); the drive keeps
//!   them (a handler: an SDO read or write converts `engineering = SI * scale` and goes to
//!   [`AxisDrive::param`] / [`AxisDrive::set_param`]). Rotary axes use the `rotary_name` /
//!   `rotary_scale` column (SI is rad there).
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
/// Handler tag of the fault injection object; parameter `i` of [`PARAMS`] has tag `i`.
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

/// Axis parameters the master may read and write while the axis runs, in SI units.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AxisParam {
    /// Backlash at the load, m (linear) or rad (rotary).
    Backlash,
    /// Drive-train stiffness at the load, N/m (linear) or N m/rad (rotary).
    Stiffness,
    /// Drive-train damping at the load, N s/m or N m s/rad.
    Damping,
    /// Coulomb friction at the load, N or N m.
    LoadCoulombFriction,
    /// Viscous friction at the load, N s/m or N m s/rad.
    LoadViscousFriction,
    /// Coulomb friction at the motor, N m.
    MotorCoulombFriction,
    /// External load force/torque at the load (cutting force), N or N m.
    ExternalLoad,
    /// Position-loop gain k_v, 1/s.
    Kv,
    /// Speed-loop proportional gain, N m s/rad.
    SpeedKp,
    /// Speed-loop integral time, s.
    SpeedTi,
    /// Motor-encoder noise, standard deviation in increments.
    MotorEncoderNoise,
    /// Direct-encoder noise, standard deviation in m or rad.
    DirectEncoderNoise,
    /// Direct-encoder offset (thermal drift of a linear scale), m or rad.
    DirectEncoderOffset,
    /// 1.0 = the direct encoder closes the position loop, 0.0 = the motor encoder does.
    PositionFromDirect,
}

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

/// One parameter object.
#[derive(Clone, Copy, Debug)]
pub struct ParamDef {
    /// Offset from the base index.
    pub offset: u16,
    /// The parameter.
    pub param: AxisParam,
    /// Name (and unit) on a linear axis.
    pub name: &'static str,
    /// Engineering units per SI unit on a linear axis.
    pub scale: f64,
    /// Name on a rotary axis.
    pub rotary_name: &'static str,
    /// Engineering units per SI unit on a rotary axis.
    pub rotary_scale: f64,
}

impl ParamDef {
    /// Name and scale for the axis kind.
    pub fn unit(&self, rotary: bool) -> (&'static str, f64) {
        if rotary {
            (self.rotary_name, self.rotary_scale)
        } else {
            (self.name, self.scale)
        }
    }
}

const DEG: f64 = 180.0 / core::f64::consts::PI;
const ARCSEC: f64 = DEG * 3600.0;

const fn p(
    offset: u16,
    param: AxisParam,
    name: &'static str,
    scale: f64,
    rotary_name: &'static str,
    rotary_scale: f64,
) -> ParamDef {
    ParamDef {
        offset,
        param,
        name,
        scale,
        rotary_name,
        rotary_scale,
    }
}

/// The parameter objects, in offset order (tag = position).
#[rustfmt::skip]
pub const PARAMS: [ParamDef; 14] = [
    //  offset  parameter                          linear name (unit)                 scale  rotary name                         scale
    p(0x00, AxisParam::Backlash,             "backlash_mm",                      1e3,  "backlash_deg",                     DEG),
    p(0x01, AxisParam::Stiffness,            "stiffness_N_per_um",               1e-6, "stiffness_Nm_per_rad",             1.0),
    p(0x02, AxisParam::Damping,              "damping_Ns_per_m",                 1.0,  "damping_Nms_per_rad",              1.0),
    p(0x03, AxisParam::LoadCoulombFriction,  "load_coulomb_friction_N",          1.0,  "load_coulomb_friction_Nm",         1.0),
    p(0x04, AxisParam::LoadViscousFriction,  "load_viscous_friction_Ns_per_m",   1.0,  "load_viscous_friction_Nms_per_rad",1.0),
    p(0x05, AxisParam::MotorCoulombFriction, "motor_coulomb_friction_Nm",        1.0,  "motor_coulomb_friction_Nm",        1.0),
    p(0x06, AxisParam::ExternalLoad,         "external_load_N",                  1.0,  "external_load_Nm",                 1.0),
    p(0x07, AxisParam::Kv,                   "kv_per_s",                         1.0,  "kv_per_s",                         1.0),
    p(0x08, AxisParam::SpeedKp,              "speed_kp_Nms_per_rad",             1.0,  "speed_kp_Nms_per_rad",             1.0),
    p(0x09, AxisParam::SpeedTi,              "speed_ti_ms",                      1e3,  "speed_ti_ms",                      1e3),
    p(0x0A, AxisParam::MotorEncoderNoise,    "motor_encoder_noise_inc",          1.0,  "motor_encoder_noise_inc",          1.0),
    p(0x0B, AxisParam::DirectEncoderNoise,   "direct_encoder_noise_um",          1e6,  "direct_encoder_noise_arcsec",      ARCSEC),
    p(0x0C, AxisParam::DirectEncoderOffset,  "direct_encoder_offset_um",         1e6,  "direct_encoder_offset_arcsec",     ARCSEC),
    p(0x0D, AxisParam::PositionFromDirect,   "position_from_direct",             1.0,  "position_from_direct",             1.0),
];

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
pub fn param_at(base: u16, index: u16) -> Option<(u16, &'static ParamDef)> {
    let off = index.checked_sub(base)?;
    PARAMS
        .iter()
        .position(|d| d.offset == off)
        .map(|i| (i as u16, &PARAMS[i]))
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
    for (tag, d) in PARAMS.iter().enumerate() {
        let (name, _) = d.unit(rotary);
        od.insert(
            Entry::var(base + d.offset, name, DataType::Real32, Access::Rw)
                .with_handler(tag as u16),
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
