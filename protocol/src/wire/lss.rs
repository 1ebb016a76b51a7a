//! LSS frames (CiA 305, Layer Setting Services): requests from the LSS master on COB-ID
//! 0x7E5 ([`LSS_REQUEST`]), responses from LSS slaves on 0x7E4 ([`LSS_RESPONSE`]). Every LSS
//! frame has 8 bytes: the command specifier (cs) in byte 0, the service data after it
//! (little-endian), the unused bytes reserved (sent as 0, ignored when read).
//!
//! | cs | request (master -> slave) | response (slave -> master) |
//! |---|---|---|
//! | 0x04 | switch state global: mode (0 waiting, 1 configuration) | - |
//! | 0x40-0x43 | switch state selective: vendor-ID, product code, revision, serial | 0x44 after 0x43 |
//! | 0x11 | configure node-ID: 1..=127, 0xFF = unconfigured | 0x11: error, spec. error |
//! | 0x13 | configure bit timing: table selector, table index | 0x13: error, spec. error |
//! | 0x15 | activate bit timing: switch delay, ms (u16) | - |
//! | 0x17 | store configuration | 0x17: error, spec. error |
//! | 0x5A-0x5D | inquire identity vendor-ID, product code, revision, serial | same cs: the u32 |
//! | 0x5E | inquire node-ID | 0x5E: the active node-ID |
//! | 0x46-0x4B | identify remote slave: vendor, product, revision low/high, serial low/high | 0x4F |
//! | 0x4C | identify non-configured remote slave | 0x50 |
//! | 0x51 | fastscan: IDNumber (u32), BitChecked, LSSSub, LSSNext | 0x4F |
//!
//! [`LssRequest::parse`] and [`LssResponse::parse`] never panic: a payload shorter than its
//! command needs, an unknown command specifier or a field outside its defined values
//! (switch mode 2, BitChecked 40, LSSSub 4) is an [`LssParseError`]. Values a slave must answer
//! with an error code (a node-ID of 0 or 200, an unsupported bit timing) parse: refusing them
//! is the slave's job ([`crate::cia305`]).

use crate::frame::CanFrame;

/// COB-ID of LSS requests, master -> slave.
pub const LSS_REQUEST: u32 = 0x7E5;
/// COB-ID of LSS responses, slave -> master.
pub const LSS_RESPONSE: u32 = 0x7E4;
/// The node-ID of a non-configured device (CiA 305): no valid node-ID.
pub const UNCONFIGURED_NODE_ID: u8 = 0xFF;

/// The error codes of the configure node-ID, configure bit timing and store configuration
/// responses (byte 1; byte 2 is the manufacturer's specific error when byte 1 is 0xFF).
pub mod error {
    /// Protocol successfully completed.
    pub const OK: u8 = 0;
    /// Configure node-ID: the node-ID is outside 1..=127 and not 0xFF.
    pub const NODE_ID_OUT_OF_RANGE: u8 = 1;
    /// Configure bit timing: this bit timing (table selector or index) is not supported.
    pub const BIT_TIMING_NOT_SUPPORTED: u8 = 1;
    /// Store configuration: the device cannot store.
    pub const STORE_NOT_SUPPORTED: u8 = 1;
    /// Store configuration: the storage medium could not be written.
    pub const STORE_ACCESS_FAILED: u8 = 2;
    /// Manufacturer-specific error, the reason in the specific-error byte.
    pub const MANUFACTURER: u8 = 0xFF;
}

/// The bit rate of an index of the CiA 301 / CiA 305 bit timing table (table selector 0),
/// kbit/s: 0 = 1000, 1 = 800, 2 = 500, 3 = 250, 4 = 125, 6 = 50, 7 = 20, 8 = 10. Index 5 is
/// reserved (100 kbit/s in older editions; CANopenNode and Lely refuse it), 9 is automatic bit
/// rate detection (no rate of its own): both give `None`, as does anything above.
pub fn bit_rate_kbit_per_s(table_index: u8) -> Option<u32> {
    match table_index {
        0 => Some(1000),
        1 => Some(800),
        2 => Some(500),
        3 => Some(250),
        4 => Some(125),
        6 => Some(50),
        7 => Some(20),
        8 => Some(10),
        _ => None,
    }
}

/// The LSS state a switch-state-global asks for (byte 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LssMode {
    /// 0: LSS waiting state.
    Waiting,
    /// 1: LSS configuration state.
    Configuration,
}

/// One 32-bit part of the LSS address (the identity object 0x1018 sub 1..=4), in the order
/// of the selective switch and of fastscan's LSSSub / LSSNext (0..=3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum IdentityPart {
    /// 0x1018:1, LSSSub 0.
    VendorId,
    /// 0x1018:2, LSSSub 1.
    ProductCode,
    /// 0x1018:3, LSSSub 2.
    RevisionNumber,
    /// 0x1018:4, LSSSub 3.
    SerialNumber,
}

impl IdentityPart {
    /// The four parts in order.
    pub const ALL: [IdentityPart; 4] = [
        IdentityPart::VendorId,
        IdentityPart::ProductCode,
        IdentityPart::RevisionNumber,
        IdentityPart::SerialNumber,
    ];

    /// LSSSub / LSSNext number, 0..=3 (also the 0x1018 sub-index minus 1).
    pub fn index(self) -> u8 {
        self as u8
    }

    /// The part of an LSSSub / LSSNext number; `None` above 3.
    pub fn from_index(i: u8) -> Option<IdentityPart> {
        IdentityPart::ALL.get(usize::from(i)).copied()
    }
}

/// One field of the identify-remote-slave sequence (cs 0x46..=0x4B, in this order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IdentifyField {
    /// 0x46: vendor-ID (equal).
    VendorId,
    /// 0x47: product code (equal).
    ProductCode,
    /// 0x48: lowest revision number (inclusive).
    RevisionLow,
    /// 0x49: highest revision number (inclusive).
    RevisionHigh,
    /// 0x4A: lowest serial number (inclusive).
    SerialLow,
    /// 0x4B: highest serial number (inclusive).
    SerialHigh,
}

impl IdentifyField {
    /// The six fields in the order the master sends them.
    pub const ALL: [IdentifyField; 6] = [
        IdentifyField::VendorId,
        IdentifyField::ProductCode,
        IdentifyField::RevisionLow,
        IdentifyField::RevisionHigh,
        IdentifyField::SerialLow,
        IdentifyField::SerialHigh,
    ];

    /// Position in the sequence, 0..=5.
    pub fn index(self) -> u8 {
        self as u8
    }
}

/// Fastscan's BitChecked (byte 5): which bits of IDNumber the slave compares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BitChecked {
    /// 0x80: every non-configured slave in waiting state answers and restarts its scan at
    /// the vendor-ID (LSSSub 0).
    Reset,
    /// 0..=31: bits 31 down to this one are compared (0: all 32).
    Bits(u8),
}

impl BitChecked {
    /// The byte on the wire.
    pub fn byte(self) -> u8 {
        match self {
            BitChecked::Reset => 0x80,
            BitChecked::Bits(b) => b,
        }
    }
}

/// A fastscan request (cs 0x51).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fastscan {
    /// IDNumber: the bits of the address part the master has found so far.
    pub id_number: u32,
    /// BitChecked.
    pub bit_checked: BitChecked,
    /// LSSSub: the address part compared.
    pub sub: IdentityPart,
    /// LSSNext: the part a matching slave compares from the next request on.
    pub next: IdentityPart,
}

/// An LSS request (master -> slave, COB-ID 0x7E5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LssRequest {
    /// 0x04: switch every slave to waiting or configuration state.
    SwitchStateGlobal(LssMode),
    /// 0x40..=0x43: one part of the address of the slave to switch to configuration state.
    SwitchStateSelective {
        /// Which part (vendor-ID first, serial number last).
        part: IdentityPart,
        /// Its value.
        value: u32,
    },
    /// 0x11: set the pending node-ID.
    ConfigureNodeId {
        /// 1..=127, or 0xFF to unconfigure; anything else is answered with error 1.
        node_id: u8,
    },
    /// 0x13: set the pending bit timing.
    ConfigureBitTiming {
        /// 0: the CiA 301 table ([`bit_rate_kbit_per_s`]); 1..=127 reserved, 128..=255
        /// manufacturer-specific.
        table_selector: u8,
        /// Entry of that table.
        table_index: u8,
    },
    /// 0x15: switch to the pending bit timing: wait the delay, switch, wait it again before
    /// sending anything.
    ActivateBitTiming {
        /// The switch delay, ms.
        switch_delay_ms: u16,
    },
    /// 0x17: store the pending node-ID and bit timing in non-volatile memory.
    StoreConfiguration,
    /// 0x5A..=0x5D: read one part of the LSS address.
    InquireIdentity(IdentityPart),
    /// 0x5E: read the active node-ID.
    InquireNodeId,
    /// 0x46..=0x4B: one field of the address range whose slaves are to answer.
    IdentifyRemoteSlave {
        /// Which field.
        field: IdentifyField,
        /// Its value.
        value: u32,
    },
    /// 0x4C: every non-configured slave is to answer.
    IdentifyNonConfiguredRemoteSlave,
    /// 0x51: one step of fastscan.
    Fastscan(Fastscan),
}

/// An LSS response (slave -> master, COB-ID 0x7E4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LssResponse {
    /// 0x44: the slave of the selective switch is in configuration state.
    SwitchStateSelective,
    /// 0x11: result of configure node-ID ([`error`]).
    ConfigureNodeId {
        /// Error code (0 = done, 1 = out of range, 0xFF = see `spec_error`).
        error: u8,
        /// Manufacturer-specific error.
        spec_error: u8,
    },
    /// 0x13: result of configure bit timing.
    ConfigureBitTiming {
        /// Error code (0 = done, 1 = not supported, 0xFF = see `spec_error`).
        error: u8,
        /// Manufacturer-specific error.
        spec_error: u8,
    },
    /// 0x17: result of store configuration.
    StoreConfiguration {
        /// Error code (0 = stored, 1 = not supported, 2 = storage access failed).
        error: u8,
        /// Manufacturer-specific error.
        spec_error: u8,
    },
    /// 0x5A..=0x5D: one part of the LSS address.
    Identity {
        /// Which part.
        part: IdentityPart,
        /// Its value.
        value: u32,
    },
    /// 0x5E: the active node-ID (0xFF: none).
    NodeId {
        /// Node-ID.
        node_id: u8,
    },
    /// 0x4F: answer to identify remote slave and to fastscan.
    IdentifySlave,
    /// 0x50: answer to identify non-configured remote slave.
    IdentifyNonConfiguredSlave,
}

/// Why a payload is not an LSS frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LssParseError {
    /// No bytes at all.
    Empty,
    /// Fewer bytes than the command carries.
    Short {
        /// Command specifier.
        cs: u8,
        /// Bytes received.
        len: usize,
        /// Bytes the command needs.
        need: usize,
    },
    /// No LSS command of this direction has this specifier.
    UnknownCommand(u8),
    /// A field outside its defined values.
    BadField {
        /// Command specifier.
        cs: u8,
        /// Byte position of the field.
        byte: u8,
        /// The value found.
        value: u8,
    },
}

impl core::fmt::Display for LssParseError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LssParseError::Empty => write!(f, "empty LSS frame"),
            LssParseError::Short { cs, len, need } => write!(
                f,
                "LSS command 0x{cs:02X} needs {need} bytes, the frame has {len}"
            ),
            LssParseError::UnknownCommand(cs) => write!(f, "unknown LSS command 0x{cs:02X}"),
            LssParseError::BadField { cs, byte, value } => write!(
                f,
                "LSS command 0x{cs:02X}: byte {byte} = 0x{value:02X} is not a defined value"
            ),
        }
    }
}

impl std::error::Error for LssParseError {}

fn u32_at(p: &[u8]) -> u32 {
    u32::from_le_bytes([p[1], p[2], p[3], p[4]])
}

fn with_u32(cs: u8, v: u32) -> [u8; 8] {
    let b = v.to_le_bytes();
    [cs, b[0], b[1], b[2], b[3], 0, 0, 0]
}

/// `Ok` when `payload` (not empty) has at least `need` bytes for the command it starts with.
fn need(payload: &[u8], need: usize) -> Result<(), LssParseError> {
    if payload.len() < need {
        return Err(LssParseError::Short {
            cs: payload[0],
            len: payload.len(),
            need,
        });
    }
    Ok(())
}

fn part_at(cs: u8, p: &[u8], byte: u8) -> Result<IdentityPart, LssParseError> {
    let value = p[usize::from(byte)];
    IdentityPart::from_index(value).ok_or(LssParseError::BadField { cs, byte, value })
}

impl LssRequest {
    /// Parse the payload of a 0x7E5 frame (any length; bytes past the command's are
    /// ignored).
    pub fn parse(payload: &[u8]) -> Result<LssRequest, LssParseError> {
        let &cs = payload.first().ok_or(LssParseError::Empty)?;
        let part = |base: u8| IdentityPart::from_index(cs - base).unwrap_or(IdentityPart::VendorId);
        Ok(match cs {
            0x04 => {
                need(payload, 2)?;
                LssRequest::SwitchStateGlobal(match payload[1] {
                    0 => LssMode::Waiting,
                    1 => LssMode::Configuration,
                    value => return Err(LssParseError::BadField { cs, byte: 1, value }),
                })
            }
            0x40..=0x43 => {
                need(payload, 5)?;
                LssRequest::SwitchStateSelective {
                    part: part(0x40),
                    value: u32_at(payload),
                }
            }
            0x11 => {
                need(payload, 2)?;
                LssRequest::ConfigureNodeId {
                    node_id: payload[1],
                }
            }
            0x13 => {
                need(payload, 3)?;
                LssRequest::ConfigureBitTiming {
                    table_selector: payload[1],
                    table_index: payload[2],
                }
            }
            0x15 => {
                need(payload, 3)?;
                LssRequest::ActivateBitTiming {
                    switch_delay_ms: u16::from_le_bytes([payload[1], payload[2]]),
                }
            }
            0x17 => LssRequest::StoreConfiguration,
            0x5A..=0x5D => LssRequest::InquireIdentity(part(0x5A)),
            0x5E => LssRequest::InquireNodeId,
            0x46..=0x4B => {
                need(payload, 5)?;
                LssRequest::IdentifyRemoteSlave {
                    field: IdentifyField::ALL[usize::from(cs - 0x46)],
                    value: u32_at(payload),
                }
            }
            0x4C => LssRequest::IdentifyNonConfiguredRemoteSlave,
            0x51 => {
                need(payload, 8)?;
                let bit_checked = match payload[5] {
                    0x80 => BitChecked::Reset,
                    b @ 0..=31 => BitChecked::Bits(b),
                    value => return Err(LssParseError::BadField { cs, byte: 5, value }),
                };
                LssRequest::Fastscan(Fastscan {
                    id_number: u32_at(payload),
                    bit_checked,
                    sub: part_at(cs, payload, 6)?,
                    next: part_at(cs, payload, 7)?,
                })
            }
            _ => return Err(LssParseError::UnknownCommand(cs)),
        })
    }

    /// The 8 payload bytes (reserved bytes 0).
    pub fn emit(&self) -> [u8; 8] {
        match *self {
            LssRequest::SwitchStateGlobal(m) => {
                [0x04, (m == LssMode::Configuration) as u8, 0, 0, 0, 0, 0, 0]
            }
            LssRequest::SwitchStateSelective { part, value } => {
                with_u32(0x40 + part.index(), value)
            }
            LssRequest::ConfigureNodeId { node_id } => [0x11, node_id, 0, 0, 0, 0, 0, 0],
            LssRequest::ConfigureBitTiming {
                table_selector,
                table_index,
            } => [0x13, table_selector, table_index, 0, 0, 0, 0, 0],
            LssRequest::ActivateBitTiming { switch_delay_ms } => {
                let d = switch_delay_ms.to_le_bytes();
                [0x15, d[0], d[1], 0, 0, 0, 0, 0]
            }
            LssRequest::StoreConfiguration => [0x17, 0, 0, 0, 0, 0, 0, 0],
            LssRequest::InquireIdentity(part) => [0x5A + part.index(), 0, 0, 0, 0, 0, 0, 0],
            LssRequest::InquireNodeId => [0x5E, 0, 0, 0, 0, 0, 0, 0],
            LssRequest::IdentifyRemoteSlave { field, value } => {
                with_u32(0x46 + field.index(), value)
            }
            LssRequest::IdentifyNonConfiguredRemoteSlave => [0x4C, 0, 0, 0, 0, 0, 0, 0],
            LssRequest::Fastscan(f) => {
                let mut b = with_u32(0x51, f.id_number);
                b[5] = f.bit_checked.byte();
                b[6] = f.sub.index();
                b[7] = f.next.index();
                b
            }
        }
    }

    /// The frame on [`LSS_REQUEST`].
    pub fn to_frame(&self) -> CanFrame {
        CanFrame::new(LSS_REQUEST, &self.emit())
    }
}

impl LssResponse {
    /// Parse the payload of a 0x7E4 frame (any length; bytes past the command's are
    /// ignored).
    pub fn parse(payload: &[u8]) -> Result<LssResponse, LssParseError> {
        let &cs = payload.first().ok_or(LssParseError::Empty)?;
        let codes = |p: &[u8]| -> Result<(u8, u8), LssParseError> {
            need(p, 3)?;
            Ok((p[1], p[2]))
        };
        Ok(match cs {
            0x44 => LssResponse::SwitchStateSelective,
            0x11 => {
                let (error, spec_error) = codes(payload)?;
                LssResponse::ConfigureNodeId { error, spec_error }
            }
            0x13 => {
                let (error, spec_error) = codes(payload)?;
                LssResponse::ConfigureBitTiming { error, spec_error }
            }
            0x17 => {
                let (error, spec_error) = codes(payload)?;
                LssResponse::StoreConfiguration { error, spec_error }
            }
            0x5A..=0x5D => {
                need(payload, 5)?;
                LssResponse::Identity {
                    part: IdentityPart::from_index(cs - 0x5A).unwrap_or(IdentityPart::VendorId),
                    value: u32_at(payload),
                }
            }
            0x5E => {
                need(payload, 2)?;
                LssResponse::NodeId {
                    node_id: payload[1],
                }
            }
            0x4F => LssResponse::IdentifySlave,
            0x50 => LssResponse::IdentifyNonConfiguredSlave,
            _ => return Err(LssParseError::UnknownCommand(cs)),
        })
    }

    /// The 8 payload bytes (reserved bytes 0).
    pub fn emit(&self) -> [u8; 8] {
        match *self {
            LssResponse::SwitchStateSelective => [0x44, 0, 0, 0, 0, 0, 0, 0],
            LssResponse::ConfigureNodeId { error, spec_error } => {
                [0x11, error, spec_error, 0, 0, 0, 0, 0]
            }
            LssResponse::ConfigureBitTiming { error, spec_error } => {
                [0x13, error, spec_error, 0, 0, 0, 0, 0]
            }
            LssResponse::StoreConfiguration { error, spec_error } => {
                [0x17, error, spec_error, 0, 0, 0, 0, 0]
            }
            LssResponse::Identity { part, value } => with_u32(0x5A + part.index(), value),
            LssResponse::NodeId { node_id } => [0x5E, node_id, 0, 0, 0, 0, 0, 0],
            LssResponse::IdentifySlave => [0x4F, 0, 0, 0, 0, 0, 0, 0],
            LssResponse::IdentifyNonConfiguredSlave => [0x50, 0, 0, 0, 0, 0, 0, 0],
        }
    }

    /// The frame on [`LSS_RESPONSE`].
    pub fn to_frame(&self) -> CanFrame {
        CanFrame::new(LSS_RESPONSE, &self.emit())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every command specifier with varied payloads: a known command parses and emitting it
    /// gives the same value back (reserved bytes dropped); an unknown one is an error, and
    /// so is a field outside its values; nothing panics.
    #[test]
    fn parse_emit_parse_is_stable_for_every_command_byte() {
        let requests = [
            0x04u8, 0x11, 0x13, 0x15, 0x17, 0x40, 0x41, 0x42, 0x43, 0x46, 0x47, 0x48, 0x49, 0x4A,
            0x4B, 0x4C, 0x51, 0x5A, 0x5B, 0x5C, 0x5D, 0x5E,
        ];
        let responses = [
            0x11u8, 0x13, 0x17, 0x44, 0x4F, 0x50, 0x5A, 0x5B, 0x5C, 0x5D, 0x5E,
        ];
        for cs in 0..=255u8 {
            for pat in [
                [0u8; 7],
                [0xFF; 7],
                [1, 2, 3, 4, 5, 6, 7],
                [1, 0, 0, 0, 0x1F, 3, 2],
            ] {
                let mut f = [cs, 0, 0, 0, 0, 0, 0, 0];
                f[1..].copy_from_slice(&pat);
                match LssRequest::parse(&f) {
                    Ok(r) => {
                        assert!(requests.contains(&cs), "{f:02X?}");
                        assert_eq!(r.emit()[0], cs);
                        assert_eq!(LssRequest::parse(&r.emit()), Ok(r), "{f:02X?}");
                    }
                    Err(LssParseError::UnknownCommand(c)) => {
                        assert_eq!(c, cs);
                        assert!(!requests.contains(&cs), "{f:02X?}");
                    }
                    Err(LssParseError::BadField { cs: c, .. }) => {
                        assert!(c == cs && (cs == 0x04 || cs == 0x51), "{f:02X?}")
                    }
                    Err(e) => panic!("{f:02X?}: {e}"),
                }
                match LssResponse::parse(&f) {
                    Ok(r) => {
                        assert!(responses.contains(&cs), "{f:02X?}");
                        assert_eq!(LssResponse::parse(&r.emit()), Ok(r), "{f:02X?}");
                    }
                    Err(e) => {
                        assert_eq!(e, LssParseError::UnknownCommand(cs));
                        assert!(!responses.contains(&cs));
                    }
                }
            }
        }
    }

    /// A frame cut short before the end of its command's data is an error that names the
    /// command and both lengths; the empty frame is `Empty`.
    #[test]
    fn short_frames_are_errors() {
        let fastscan = [0x51, 1, 2, 3, 4, 5, 1, 2];
        for len in 0..8 {
            let e = LssRequest::parse(&fastscan[..len]).unwrap_err();
            if len == 0 {
                assert_eq!(e, LssParseError::Empty);
            } else {
                assert_eq!(
                    e,
                    LssParseError::Short {
                        cs: 0x51,
                        len,
                        need: 8
                    }
                );
                assert!(e.to_string().contains("0x51") && e.to_string().contains("needs 8"));
            }
        }
        assert!(LssRequest::parse(&fastscan).is_ok());
        assert!(LssRequest::parse(&[0x40, 1, 2, 3]).is_err());
        assert!(LssRequest::parse(&[0x04]).is_err());
        assert!(LssResponse::parse(&[0x11, 0]).is_err());
        assert!(LssResponse::parse(&[0x5A, 1, 2, 3]).is_err());
        // one byte is all these commands carry
        for cs in [0x17u8, 0x4C, 0x5A, 0x5E] {
            assert!(LssRequest::parse(&[cs]).is_ok(), "{cs:02X}");
        }
        assert_eq!(LssResponse::parse(&[0x4F]), Ok(LssResponse::IdentifySlave));
    }

    #[test]
    fn fields_outside_their_values_are_named() {
        assert_eq!(
            LssRequest::parse(&[0x04, 2, 0, 0, 0, 0, 0, 0]),
            Err(LssParseError::BadField {
                cs: 0x04,
                byte: 1,
                value: 2
            })
        );
        for (byte, bad) in [(5u8, 32u8), (5, 0x7F), (5, 0x81), (6, 4), (7, 0xFF)] {
            let mut f = [0x51, 0, 0, 0, 0, 0, 0, 0];
            f[usize::from(byte)] = bad;
            let e = LssRequest::parse(&f).unwrap_err();
            assert_eq!(
                e,
                LssParseError::BadField {
                    cs: 0x51,
                    byte,
                    value: bad
                }
            );
            assert!(e.to_string().contains(&format!("byte {byte}")), "{e}");
        }
    }

    /// The exact bytes of a few frames, as CiA 305 lays them out (python canopen's
    /// `struct.pack('<BIBBB', ...)` for fastscan).
    #[test]
    fn known_frames() {
        assert_eq!(
            LssRequest::Fastscan(Fastscan {
                id_number: 0x1234_5678,
                bit_checked: BitChecked::Reset,
                sub: IdentityPart::VendorId,
                next: IdentityPart::SerialNumber,
            })
            .emit(),
            [0x51, 0x78, 0x56, 0x34, 0x12, 0x80, 0, 3]
        );
        assert_eq!(
            LssRequest::ActivateBitTiming {
                switch_delay_ms: 0x0102
            }
            .emit(),
            [0x15, 0x02, 0x01, 0, 0, 0, 0, 0]
        );
        assert_eq!(
            LssResponse::Identity {
                part: IdentityPart::SerialNumber,
                value: 0xAABB_CCDD
            }
            .to_frame(),
            CanFrame::new(0x7E4, &[0x5D, 0xDD, 0xCC, 0xBB, 0xAA, 0, 0, 0])
        );
        assert_eq!(
            LssRequest::SwitchStateSelective {
                part: IdentityPart::RevisionNumber,
                value: 7
            }
            .to_frame(),
            CanFrame::new(0x7E5, &[0x42, 7, 0, 0, 0, 0, 0, 0])
        );
    }

    #[test]
    fn bit_timing_table() {
        let rates: Vec<_> = (0..=10).map(bit_rate_kbit_per_s).collect();
        assert_eq!(
            rates,
            [
                Some(1000),
                Some(800),
                Some(500),
                Some(250),
                Some(125),
                None,
                Some(50),
                Some(20),
                Some(10),
                None,
                None
            ]
        );
    }

    mod roundtrip {
        use super::super::*;
        use proptest::prelude::*;

        fn part() -> impl Strategy<Value = IdentityPart> {
            (0u8..4).prop_map(|i| IdentityPart::from_index(i).unwrap())
        }

        fn request() -> impl Strategy<Value = LssRequest> {
            let bit_checked = prop_oneof![
                Just(BitChecked::Reset),
                (0u8..=31).prop_map(BitChecked::Bits)
            ];
            prop_oneof![
                prop_oneof![Just(LssMode::Waiting), Just(LssMode::Configuration)]
                    .prop_map(LssRequest::SwitchStateGlobal),
                (part(), any::<u32>())
                    .prop_map(|(part, value)| LssRequest::SwitchStateSelective { part, value }),
                any::<u8>().prop_map(|node_id| LssRequest::ConfigureNodeId { node_id }),
                (any::<u8>(), any::<u8>()).prop_map(|(table_selector, table_index)| {
                    LssRequest::ConfigureBitTiming {
                        table_selector,
                        table_index,
                    }
                }),
                any::<u16>()
                    .prop_map(|switch_delay_ms| LssRequest::ActivateBitTiming { switch_delay_ms }),
                Just(LssRequest::StoreConfiguration),
                part().prop_map(LssRequest::InquireIdentity),
                Just(LssRequest::InquireNodeId),
                (0usize..6, any::<u32>()).prop_map(|(i, value)| {
                    LssRequest::IdentifyRemoteSlave {
                        field: IdentifyField::ALL[i],
                        value,
                    }
                }),
                Just(LssRequest::IdentifyNonConfiguredRemoteSlave),
                (any::<u32>(), bit_checked, part(), part()).prop_map(
                    |(id_number, bit_checked, sub, next)| LssRequest::Fastscan(Fastscan {
                        id_number,
                        bit_checked,
                        sub,
                        next
                    })
                ),
            ]
        }

        fn response() -> impl Strategy<Value = LssResponse> {
            prop_oneof![
                Just(LssResponse::SwitchStateSelective),
                (any::<u8>(), any::<u8>()).prop_map(|(error, spec_error)| {
                    LssResponse::ConfigureNodeId { error, spec_error }
                }),
                (any::<u8>(), any::<u8>()).prop_map(|(error, spec_error)| {
                    LssResponse::ConfigureBitTiming { error, spec_error }
                }),
                (any::<u8>(), any::<u8>()).prop_map(|(error, spec_error)| {
                    LssResponse::StoreConfiguration { error, spec_error }
                }),
                (part(), any::<u32>())
                    .prop_map(|(part, value)| LssResponse::Identity { part, value }),
                any::<u8>().prop_map(|node_id| LssResponse::NodeId { node_id }),
                Just(LssResponse::IdentifySlave),
                Just(LssResponse::IdentifyNonConfiguredSlave),
            ]
        }

        proptest! {
            #![proptest_config(ProptestConfig::with_cases(2000))]

            /// parse(emit(x)) == x for every request variant with any field values.
            #[test]
            fn request_parse_of_emit_is_identity(r in request()) {
                prop_assert_eq!(LssRequest::parse(&r.emit()), Ok(r));
            }

            /// parse(emit(x)) == x for every response variant with any field values.
            #[test]
            fn response_parse_of_emit_is_identity(r in response()) {
                prop_assert_eq!(LssResponse::parse(&r.emit()), Ok(r));
            }

            /// Any bytes of any length: a value or an error, never a panic; a value emits
            /// to bytes that parse to it again.
            #[test]
            fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..=8)) {
                if let Ok(r) = LssRequest::parse(&bytes) {
                    prop_assert_eq!(LssRequest::parse(&r.emit()), Ok(r));
                }
                if let Ok(r) = LssResponse::parse(&bytes) {
                    prop_assert_eq!(LssResponse::parse(&r.emit()), Ok(r));
                }
            }
        }
    }
}
