//! The CiA 301 basic data types and the EDS access types (CiA 306): what a value is and who
//! may touch it, for the object table, the EDS export and the EDS/DCF parser alike.

/// CANopen basic data types (CiA 301 table 44, the codes an EDS `DataType=` names).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DataType {
    /// BOOLEAN (0x0001), one byte on the wire.
    Boolean = 0x01,
    /// INTEGER8 (0x0002).
    I8 = 0x02,
    /// INTEGER16 (0x0003).
    I16 = 0x03,
    /// INTEGER32 (0x0004).
    I32 = 0x04,
    /// UNSIGNED8 (0x0005).
    U8 = 0x05,
    /// UNSIGNED16 (0x0006).
    U16 = 0x06,
    /// UNSIGNED32 (0x0007).
    U32 = 0x07,
    /// REAL32, IEEE 754 single (0x0008).
    Real32 = 0x08,
    /// VISIBLE_STRING (0x0009).
    VisibleString = 0x09,
    /// OCTET_STRING (0x000A).
    OctetString = 0x0A,
    /// UNICODE_STRING (0x000B), UTF-16 code units.
    UnicodeString = 0x0B,
    /// TIME_OF_DAY (0x000C), 6 bytes.
    TimeOfDay = 0x0C,
    /// TIME_DIFFERENCE (0x000D), 6 bytes.
    TimeDifference = 0x0D,
    /// DOMAIN (0x000F): bytes of any length.
    Domain = 0x0F,
    /// INTEGER24 (0x0010).
    I24 = 0x10,
    /// REAL64, IEEE 754 double (0x0011).
    Real64 = 0x11,
    /// INTEGER40 (0x0012).
    I40 = 0x12,
    /// INTEGER48 (0x0013).
    I48 = 0x13,
    /// INTEGER56 (0x0014).
    I56 = 0x14,
    /// INTEGER64 (0x0015).
    I64 = 0x15,
    /// UNSIGNED24 (0x0016).
    U24 = 0x16,
    /// UNSIGNED40 (0x0018).
    U40 = 0x18,
    /// UNSIGNED48 (0x0019).
    U48 = 0x19,
    /// UNSIGNED56 (0x001A).
    U56 = 0x1A,
    /// UNSIGNED64 (0x001B).
    U64 = 0x1B,
}

impl DataType {
    /// Every basic type, in code order.
    pub const ALL: [DataType; 25] = [
        DataType::Boolean,
        DataType::I8,
        DataType::I16,
        DataType::I32,
        DataType::U8,
        DataType::U16,
        DataType::U32,
        DataType::Real32,
        DataType::VisibleString,
        DataType::OctetString,
        DataType::UnicodeString,
        DataType::TimeOfDay,
        DataType::TimeDifference,
        DataType::Domain,
        DataType::I24,
        DataType::Real64,
        DataType::I40,
        DataType::I48,
        DataType::I56,
        DataType::I64,
        DataType::U24,
        DataType::U40,
        DataType::U48,
        DataType::U56,
        DataType::U64,
    ];

    /// The type of an EDS `DataType=` code (0x0001..=0x001B), `None` for any other code
    /// (0x000E and 0x0017 are unused; 0x0020.. are complex types or structures).
    pub fn from_code(code: u16) -> Option<DataType> {
        DataType::ALL.iter().copied().find(|t| *t as u16 == code)
    }

    /// The CiA 301 code (`DataType=0x....` in an EDS).
    pub const fn code(self) -> u16 {
        self as u16
    }

    /// Size in bytes of a value on the wire; 0 for the variable-length types (strings,
    /// DOMAIN).
    pub const fn size(self) -> usize {
        match self {
            DataType::Boolean | DataType::I8 | DataType::U8 => 1,
            DataType::I16 | DataType::U16 => 2,
            DataType::I24 | DataType::U24 => 3,
            DataType::I32 | DataType::U32 | DataType::Real32 => 4,
            DataType::I40 | DataType::U40 => 5,
            DataType::I48 | DataType::U48 | DataType::TimeOfDay | DataType::TimeDifference => 6,
            DataType::I56 | DataType::U56 => 7,
            DataType::I64 | DataType::U64 | DataType::Real64 => 8,
            DataType::VisibleString
            | DataType::OctetString
            | DataType::UnicodeString
            | DataType::Domain => 0,
        }
    }

    /// A two's-complement integer type (stored sign-extended).
    pub const fn signed(self) -> bool {
        matches!(
            self,
            DataType::I8
                | DataType::I16
                | DataType::I24
                | DataType::I32
                | DataType::I40
                | DataType::I48
                | DataType::I56
                | DataType::I64
        )
    }

    /// An integer type (BOOLEAN, the INTEGERs and UNSIGNEDs): a number with limits.
    pub const fn integer(self) -> bool {
        self.size() > 0 && !self.float() && !self.time()
    }

    /// REAL32 or REAL64.
    pub const fn float(self) -> bool {
        matches!(self, DataType::Real32 | DataType::Real64)
    }

    /// TIME_OF_DAY or TIME_DIFFERENCE (6 bytes, no arithmetic here).
    pub const fn time(self) -> bool {
        matches!(self, DataType::TimeOfDay | DataType::TimeDifference)
    }

    /// A type of variable length: VISIBLE_STRING, OCTET_STRING, UNICODE_STRING, DOMAIN.
    pub const fn variable(self) -> bool {
        self.size() == 0
    }

    /// The CiA 301 name, e.g. `UNSIGNED32`.
    pub const fn name(self) -> &'static str {
        match self {
            DataType::Boolean => "BOOLEAN",
            DataType::I8 => "INTEGER8",
            DataType::I16 => "INTEGER16",
            DataType::I32 => "INTEGER32",
            DataType::U8 => "UNSIGNED8",
            DataType::U16 => "UNSIGNED16",
            DataType::U32 => "UNSIGNED32",
            DataType::Real32 => "REAL32",
            DataType::VisibleString => "VISIBLE_STRING",
            DataType::OctetString => "OCTET_STRING",
            DataType::UnicodeString => "UNICODE_STRING",
            DataType::TimeOfDay => "TIME_OF_DAY",
            DataType::TimeDifference => "TIME_DIFFERENCE",
            DataType::Domain => "DOMAIN",
            DataType::I24 => "INTEGER24",
            DataType::Real64 => "REAL64",
            DataType::I40 => "INTEGER40",
            DataType::I48 => "INTEGER48",
            DataType::I56 => "INTEGER56",
            DataType::I64 => "INTEGER64",
            DataType::U24 => "UNSIGNED24",
            DataType::U40 => "UNSIGNED40",
            DataType::U48 => "UNSIGNED48",
            DataType::U56 => "UNSIGNED56",
            DataType::U64 => "UNSIGNED64",
        }
    }

    /// Smallest and largest value of an integer type, as i128 (BOOLEAN: 0..=1); `None`
    /// for the other types.
    pub const fn range(self) -> Option<(i128, i128)> {
        if !self.integer() {
            return None;
        }
        if matches!(self, DataType::Boolean) {
            return Some((0, 1));
        }
        let bits = (self.size() * 8) as u32;
        Some(if self.signed() {
            (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1)
        } else {
            (0, (1i128 << bits) - 1)
        })
    }
}

/// Access type as written in the EDS (CiA 306 `AccessType=`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// Read only (`ro`).
    Ro,
    /// Write only (`wo`).
    Wo,
    /// Read/write (`rw`).
    Rw,
    /// Read/write, mappable into a TPDO.
    Rwr,
    /// Read/write, mappable into an RPDO.
    Rww,
    /// Read only and never changes (`const`).
    Const,
}

impl Access {
    /// An SDO upload may read it.
    pub const fn readable(self) -> bool {
        !matches!(self, Access::Wo)
    }
    /// An SDO download may write it.
    pub const fn writable(self) -> bool {
        matches!(self, Access::Wo | Access::Rw | Access::Rwr | Access::Rww)
    }
    /// The AccessType string of the EDS (CiA 306).
    pub const fn eds(self) -> &'static str {
        match self {
            Access::Ro => "ro",
            Access::Wo => "wo",
            Access::Rw => "rw",
            Access::Rwr => "rwr",
            Access::Rww => "rww",
            Access::Const => "const",
        }
    }
    /// The access of an EDS `AccessType=` text (case-insensitive, as the EDS readers take
    /// it), `None` if it is none of the six.
    pub fn from_eds(text: &str) -> Option<Access> {
        let t = text.trim();
        [
            Access::Ro,
            Access::Wo,
            Access::Rw,
            Access::Rwr,
            Access::Rww,
            Access::Const,
        ]
        .into_iter()
        .find(|a| a.eds().eq_ignore_ascii_case(t))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_sizes_match_cia301() {
        for t in DataType::ALL {
            assert_eq!(DataType::from_code(t.code()), Some(t));
        }
        assert_eq!(DataType::from_code(0x0E), None);
        assert_eq!(DataType::from_code(0x17), None);
        assert_eq!(DataType::from_code(0x20), None);
        assert_eq!(DataType::U24.size(), 3);
        assert_eq!(DataType::I56.size(), 7);
        assert_eq!(DataType::Real64.size(), 8);
        assert_eq!(DataType::Domain.size(), 0);
        assert_eq!(DataType::I24.range(), Some((-(1 << 23), (1 << 23) - 1)));
        assert_eq!(DataType::U64.range(), Some((0, u64::MAX as i128)));
        assert_eq!(DataType::Real32.range(), None);
    }

    #[test]
    fn access_from_eds_text() {
        assert_eq!(Access::from_eds("RW"), Some(Access::Rw));
        assert_eq!(Access::from_eds(" const "), Some(Access::Const));
        assert_eq!(Access::from_eds("rwx"), None);
    }
}
