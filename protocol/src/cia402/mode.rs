//! Modes of operation (0x6060 / 0x6061, CiA 402 6.2.2): the one registry. Every fact about a
//! mode lives in its row of [`MODES`]: its 0x6060 value, its names, its bit in 0x6502
//! (supported drive modes), whether the emulator simulates it and whether the halt bit
//! (controlword bit 8) applies to it. A new mode is one row here and one file beside this
//! one.

/// A mode of operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// 0: no mode selected.
    NoMode,
    /// 1: profile position (PP).
    ProfilePosition,
    /// 2: velocity (vl, the frequency-converter mode).
    Velocity,
    /// 3: profile velocity (PV).
    ProfileVelocity,
    /// 4: profile torque (PT / TQ).
    ProfileTorque,
    /// 6: homing (HM).
    Homing,
    /// 7: interpolated position (IP).
    InterpolatedPosition,
    /// 8: cyclic synchronous position (CSP).
    CyclicSyncPosition,
    /// 9: cyclic synchronous velocity (CSV).
    CyclicSyncVelocity,
    /// 10: cyclic synchronous torque (CST).
    CyclicSyncTorque,
}

/// One row of the registry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModeInfo {
    /// The mode.
    pub mode: Mode,
    /// Its 0x6060 / 0x6061 value.
    pub value: i8,
    /// Its abbreviation, e.g. `CSP`.
    pub abbrev: &'static str,
    /// Its name, e.g. `cyclic synchronous position`.
    pub name: &'static str,
    /// Its bit in 0x6502 (supported drive modes); `None` for "no mode".
    pub bit: Option<u8>,
    /// The emulator runs it (a mode in 0x6502 of our drive).
    pub simulated: bool,
    /// The halt bit (controlword bit 8) stops the axis in it (CiA 402: PP, PV, PT, HM, IP).
    pub halt: bool,
}

const fn row(
    mode: Mode,
    value: i8,
    abbrev: &'static str,
    name: &'static str,
    bit: Option<u8>,
    simulated: bool,
    halt: bool,
) -> ModeInfo {
    ModeInfo {
        mode,
        value,
        abbrev,
        name,
        bit,
        simulated,
        halt,
    }
}

/// Every mode CiA 402 names, in 0x6060 order. `halt` follows what the emulator's modes do with
/// bit 8 (PP, PV and HM decelerate and hold, PT ramps its torque demand to 0; the cyclic
/// modes follow their set-point, whose master stops the axis).
#[rustfmt::skip]
pub const MODES: [ModeInfo; 10] = [
    //    mode                          value abbrev  name                              0x6502   sim    halt
    row(Mode::NoMode,                    0, "-",    "no mode",                        None,    true,  false),
    row(Mode::ProfilePosition,           1, "PP",   "profile position",               Some(0), true,  true),
    row(Mode::Velocity,                  2, "VL",   "velocity",                       Some(1), false, true),
    row(Mode::ProfileVelocity,           3, "PV",   "profile velocity",               Some(2), true,  true),
    row(Mode::ProfileTorque,             4, "PT",   "profile torque",                 Some(3), true,  true),
    row(Mode::Homing,                    6, "HM",   "homing",                         Some(5), true,  true),
    row(Mode::InterpolatedPosition,      7, "IP",   "interpolated position",          Some(6), true,  true),
    row(Mode::CyclicSyncPosition,        8, "CSP",  "cyclic synchronous position",    Some(7), true,  false),
    row(Mode::CyclicSyncVelocity,        9, "CSV",  "cyclic synchronous velocity",    Some(8), true,  false),
    row(Mode::CyclicSyncTorque,         10, "CST",  "cyclic synchronous torque",      Some(9), true,  false),
];

/// 0x6502 of a drive that runs every mode the emulator simulates.
pub const SIMULATED_MODES_MASK: u32 = simulated_mask();

const fn simulated_mask() -> u32 {
    let mut m = 0;
    let mut i = 0;
    while i < MODES.len() {
        if let (true, Some(b)) = (MODES[i].simulated, MODES[i].bit) {
            m |= 1 << b;
        }
        i += 1;
    }
    m
}

impl Mode {
    /// The registry row.
    pub fn info(self) -> &'static ModeInfo {
        // every variant has exactly one row (test `every_mode_has_one_row`)
        MODES.iter().find(|r| r.mode == self).unwrap_or(&MODES[0])
    }
    /// The mode of a 0x6060 / 0x6061 value, `None` for a reserved or manufacturer-specific
    /// value.
    pub fn from_value(value: i8) -> Option<Mode> {
        MODES.iter().find(|r| r.value == value).map(|r| r.mode)
    }
    /// Its 0x6060 value.
    pub fn value(self) -> i8 {
        self.info().value
    }
    /// Its abbreviation, e.g. `CSP`.
    pub fn abbrev(self) -> &'static str {
        self.info().abbrev
    }
    /// The mode a user names: its abbreviation or name in any case (`csp`, `CSP`,
    /// `cyclic synchronous position`, `cyclic_synchronous_position`) or its number.
    pub fn parse(text: &str) -> Option<Mode> {
        let t = text.trim();
        if let Ok(v) = t.parse::<i8>() {
            return Mode::from_value(v);
        }
        let norm = |s: &str| s.to_ascii_lowercase().replace(['_', '-'], " ");
        let t = norm(t);
        MODES
            .iter()
            .find(|r| r.bit.is_some() && (norm(r.abbrev) == t || norm(r.name) == t))
            .map(|r| r.mode)
    }
    /// Its bit in 0x6502.
    pub fn bit(self) -> Option<u8> {
        self.info().bit
    }
    /// Whether the emulator runs it.
    pub fn simulated(self) -> bool {
        self.info().simulated
    }
    /// Whether the halt bit stops the axis in it.
    pub fn halts(self) -> bool {
        self.info().halt
    }
    /// Whether a drive whose 0x6502 is `supported` accepts it in 0x6060 ("no mode" always).
    pub fn in_mask(self, supported: u32) -> bool {
        self.bit().is_none_or(|b| supported & (1 << b) != 0)
    }
}

/// "CSP (cyclic synchronous position)" for a 0x6060 / 0x6061 value; a value without a mode
/// is said with its kind: "manufacturer-specific mode" (negative) or "reserved mode".
pub fn describe(value: i8) -> &'static str {
    // the long forms, kept here so every caller says a mode the same way
    match Mode::from_value(value) {
        Some(Mode::NoMode) => "no mode",
        Some(Mode::ProfilePosition) => "PP (profile position)",
        Some(Mode::Velocity) => "VL (velocity)",
        Some(Mode::ProfileVelocity) => "PV (profile velocity)",
        Some(Mode::ProfileTorque) => "PT (profile torque)",
        Some(Mode::Homing) => "HM (homing)",
        Some(Mode::InterpolatedPosition) => "IP (interpolated position)",
        Some(Mode::CyclicSyncPosition) => "CSP (cyclic synchronous position)",
        Some(Mode::CyclicSyncVelocity) => "CSV (cyclic synchronous velocity)",
        Some(Mode::CyclicSyncTorque) => "CST (cyclic synchronous torque)",
        None if value < 0 => "manufacturer-specific mode",
        None => "reserved mode",
    }
}

/// The 0x6060 values (`pub const`s) of the modes, for code that speaks in wire values.
pub mod value {
    /// No mode selected.
    pub const NONE: i8 = 0;
    /// Profile position mode.
    pub const PP: i8 = 1;
    /// Profile velocity mode.
    pub const PV: i8 = 3;
    /// Profile torque mode.
    pub const PT: i8 = 4;
    /// Homing mode.
    pub const HM: i8 = 6;
    /// Interpolated position mode.
    pub const IP: i8 = 7;
    /// Cyclic synchronous position mode.
    pub const CSP: i8 = 8;
    /// Cyclic synchronous velocity mode.
    pub const CSV: i8 = 9;
    /// Cyclic synchronous torque mode.
    pub const CST: i8 = 10;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_mode_has_one_row_and_the_values_agree() {
        for r in MODES {
            assert_eq!(MODES.iter().filter(|x| x.mode == r.mode).count(), 1);
            assert_eq!(Mode::from_value(r.value), Some(r.mode));
            assert_eq!(r.mode.info(), &r);
            assert!(describe(r.value).starts_with(if r.bit.is_some() { r.abbrev } else { "no" }));
        }
        assert_eq!(value::CSP, Mode::CyclicSyncPosition.value());
        assert_eq!(value::PV, Mode::ProfileVelocity.value());
        // PP, PV, PT, HM, IP, CSP, CSV, CST
        assert_eq!(SIMULATED_MODES_MASK, 0x3ED);
        assert_eq!(value::PT, Mode::ProfileTorque.value());
    }

    #[test]
    fn modes_parse_by_abbreviation_name_and_number() {
        assert_eq!(Mode::parse("csp"), Some(Mode::CyclicSyncPosition));
        assert_eq!(Mode::parse("Profile_Velocity"), Some(Mode::ProfileVelocity));
        assert_eq!(Mode::parse("6"), Some(Mode::Homing));
        assert_eq!(Mode::parse("5"), None);
        assert_eq!(Mode::parse("-"), None);
        assert!(Mode::NoMode.in_mask(0));
        assert!(!Mode::CyclicSyncTorque.in_mask(0x1E5));
        assert!(Mode::CyclicSyncTorque.in_mask(0x3A5));
    }
}
