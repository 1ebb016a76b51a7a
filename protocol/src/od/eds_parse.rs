//! EDS / DCF parser (CiA 306): the text of an Electronic Data Sheet or a Device Configuration
//! File in, a typed model of every object in it out ([`parse`] gives an [`EdsFile`]). Sans-IO:
//! no file access, no clock; allocates (start-up only, never on the real-time path).
//!
//! # Text
//! [`parse`] takes `&str`. EDS files are ASCII in principle, but vendor files carry Latin-1
//! (`°`, `µ`, umlauts in names) and Windows line ends. A caller that reads a file should turn
//! its bytes into text with [`decode_text`]: valid UTF-8 stays as it is, anything else is read
//! as Latin-1 (ISO 8859-1, each byte one character), which never fails and loses nothing. A
//! UTF-8 byte order mark and CR line ends are accepted by [`parse`].
//!
//! # What is read, and how the readers we follow read it
//! The rules were taken from the two readers masters use, read at their source: python
//! canopen 2.4.1 (`canopen/objectdictionary/eds.py`, a `RawConfigParser` with `;` inline
//! comments and case-sensitive keys) and Lely (`src/co/dcf.c` in C and its python `dcf-tools`
//! 2.4.2: `dcfchk`, `dcfgen`, which ros2_canopen runs; case-insensitive sections and keys).
//! Where both accept something this parser accepts it too; where they disagree we either take
//! the reading of the CiA 306 text or report an error (an ambiguous file), and say which here.
//!
//! - **Lines.** `[section]` headers, `key=value` pairs (spaces around `=` and the value are
//!   trimmed), full-line comments starting with `;` or `#`, blank lines. A `;` after
//!   whitespace starts an inline comment (both readers); a `#` after whitespace ends a
//!   *number* (dcf-tools strips it, python canopen does not, and in a name or a string it is
//!   kept, as python canopen keeps it). Any other line (no `=`, or a key before the first
//!   section) is an error: python canopen would glue an indented line to the previous value.
//! - **Names.** Section names and keys are case-insensitive (Lely; python canopen is
//!   case-sensitive but real files stay in one case). `[1018sub1]`, `[1018Sub1]`,
//!   `[1018SUB01]` name the same sub-index. A section given twice is one section, a key given
//!   twice takes its last value (Lely's reading; python canopen's strict parser refuses
//!   both; `[1018sub1]` and `[1018sub01]` count as twice): a warning at the second.
//!   `[DeviceComissioning]` (CiA 306's spelling) and `[DeviceCommissioning]` are both read.
//! - **Objects.** `[IIII]` is an object; `ObjectType` defaults to VAR (both readers). NULL,
//!   DOMAIN, DEFTYPE and VAR are one value (sub-index 0, attributes in the object's own
//!   section); DEFSTRUCT, ARRAY and RECORD have sub-indices in `[IIIIsubS]` sections or from
//!   `CompactSubObj`. Every sub-index section present is read; a `SubNumber` that does not
//!   count them, or none, is a warning (dcf-tools' `dcfchk` refuses a mismatch; Lely reads
//!   the first SubNumber, python canopen ignores the count). Sub-index 0xFF is refused (reserved for the structure, CiA 301; both Lely
//!   readers refuse or skip it). A sub-index section without its object is an error; one of a
//!   VAR is ignored with a warning (both readers ignore it). Data type objects 0x0001-0x025F
//!   (DEFTYPE, DEFSTRUCT, and the VARs some tools write there) are kept;
//!   [`EdsObject::defines_type`] tells them apart.
//! - **Data types.** The CiA 301 basic types 0x0001-0x001B ([`DataType`]). The complex types
//!   0x0020-0x0023 and a DEFSTRUCT the file defines may not be the type of a sub-index (error,
//!   "complex data type"); any other code is an unknown data type (error; python canopen would
//!   fall back to DOMAIN, Lely fails). `AccessType` is one of ro, wo, rw, rwr, rww, const in
//!   any case; DOMAIN may omit it (Lely), and is then rw (warning).
//! - **CompactSubObj=N** (ARRAY or RECORD; not together with SubNumber, as Lely and dcfchk
//!   refuse) expands to sub 0 `NrOfObjects` (UNSIGNED8, ro, default N) and subs 1..N with the
//!   object's DataType, AccessType, PDOMapping, limits and DefaultValue, named
//!   `ParameterName` + the sub-index (`Error field3`) unless `[IIIIName]` names them: both as
//!   Lely (C and dcf-tools) name them. python canopen names sub 0 `Number of entries`, gives
//!   sub 1 the object's name and creates subs 2..N only when `[IIIIName]` lists them. Values
//!   in `[IIIIValue]` are the sub-indices' **ParameterValue** (a DCF's configured values),
//!   as both Lely readers take them (python canopen ignores the section).
//! - **Values** ([`ValueExpr`]): integers in decimal, `0x` hex or, as CiA 306 and C's
//!   `strtoul` read them, octal with a leading 0 (`010` is 8; python canopen rejects it and
//!   leaves the value None, so it is read but warned about when it differs from the decimal
//!   reading; `08`, not octal, is read as the decimal 8 with a warning). `$NODEID` plus or minus a number, in either order, any case,
//!   with or without spaces (`$NODEID+0x180`, `0x180 + $nodeid`, `$NodeID - 1`): python
//!   canopen accepts the forms with `+` in any order, Lely `$NODEID` first only. REAL32 and
//!   REAL64 from hex IEEE 754 bits (`0x41F00000`, as Lely reads and writes them) or from a
//!   decimal with a point or an exponent (`30.0`, as python canopen reads them); a plain
//!   decimal integer (`30`) is read as the number (python canopen) and warned about, since
//!   Lely reads it as bits. Hex for a signed type above the type's maximum is its two's
//!   complement pattern (`LowLimit=0x80000000` for INTEGER32 is -2^31, as python canopen
//!   reads limits). BOOLEAN is 0 or 1. OCTET_STRING and DOMAIN are hex digit pairs (spaces
//!   between bytes allowed, no `0x`, as python's `bytes.fromhex`). VISIBLE_STRING and
//!   UNICODE_STRING are the text as written (python canopen; no C escapes). TIME_OF_DAY and
//!   TIME_DIFFERENCE are an integer, the 48 raw bits. An empty value is no value (both
//!   readers).
//! - **Checks.** Every value is resolved while parsing (a `$NODEID` one at node IDs 1 and 127),
//!   so a number that is not one or lies outside its type is an error at its line.
//!   LowLimit > HighLimit is an error; a DefaultValue or ParameterValue outside the limits is
//!   a warning (Lely warns about all three).
//! - **Object lists.** `[MandatoryObjects]`, `[OptionalObjects]`, `[ManufacturerObjects]`:
//!   python canopen ignores the lists and reads every section, so a list that does not match
//!   is read past with a warning (an index listed without its section, a missing entry
//!   number, a missing SupportedObjects); an object section no list names is kept with a
//!   warning (Lely drops it).
//! - **Read past, with a warning** (issue 33; `tests/eds/lenient/` has a file per class):
//!   a non-numeric `ObjFlags` (`NV`: read as 0, as Lely's strtoul does), a `PDOMapping` that
//!   is a word or above 1, `[DeviceInfo]` / `[DeviceComissioning]` keys that are no number or
//!   out of range (read as not given; `yes`/`true` for a flag), a `;` comment without a
//!   space before it after a number. Still errors (no reading makes sense): an unknown data
//!   type, a missing DataType or AccessType, a value outside its type, a line that is no
//!   `key=value`, an unclosed section header.
//! - **Other sections.** `[FileInfo]`, `[DeviceInfo]`, `[DummyUsage]`, `[Comments]`,
//!   `[DeviceComissioning]`, `[IIIIName]`, `[IIIIValue]`, `[IIIIObjectLinks]` are read; any
//!   other section (modular devices, `[Tools]`) is ignored with a warning.
//!   `CompactPDO` in `[DeviceInfo]` (implicit PDO objects, Lely only) is kept but not
//!   expanded (warning).
//!
//! # Why not a crate
//! Checked: `canopen-host` (0.6, the EDS reader of `canopen-rs`, whose wire codecs we use)
//! reads only the numeric basic types and skips VISIBLE_STRING, OCTET_STRING and DOMAIN
//! objects, which a vendor file has and a master reads; `canopen` 0.1.0 (2018) is an early,
//! unmaintained stack. An INI crate alone does not do it: EDS needs duplicate detection across
//! spellings (`[1018sub1]`/`[1018sub01]`), CompactSubObj, `$NODEID` forms, typed values and
//! a line for every error. So this module reads the lines itself (a few dozen lines of it).
//!
//! # Bounds
//! At most [`MAX_INPUT_BYTES`] of text, [`MAX_SECTIONS`] sections, [`MAX_OBJECTS`] objects,
//! [`MAX_SUBS`] sub-indices in all (after CompactSubObj) and [`MAX_VALUE_BYTES`] in one name or
//! value; past any of them a clear error. Sections and keys are found through hash maps, so
//! the cost is near-linear in the input.

use std::collections::{HashMap, HashSet};
use std::fmt;

use super::types::{Access, DataType};

/// Largest text [`parse`] accepts: 8 MiB (real EDS files are 20-200 KiB).
pub const MAX_INPUT_BYTES: usize = 8 * 1024 * 1024;
/// Most sections in one file.
pub const MAX_SECTIONS: usize = 100_000;
/// Most objects (object sections) in one file.
pub const MAX_OBJECTS: usize = 8192;
/// Most sub-indices in all objects together, CompactSubObj expanded.
pub const MAX_SUBS: usize = 100_000;
/// Longest name or value, in bytes (a string's text, a DOMAIN's bytes).
pub const MAX_VALUE_BYTES: usize = 65_536;

/// Where something went wrong, and why. Display: `line 42, [1018sub2] DataType: unknown data
/// type 0x0033` (the caller prefixes the file name).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EdsError {
    /// 1-based line of the key, or of the section header when no key is at fault.
    pub line: usize,
    /// The section, as written in the file (without brackets).
    pub section: Option<String>,
    /// The key, as written in the file.
    pub key: Option<String>,
    /// What is wrong.
    pub reason: String,
}

/// Something a tolerant reader accepts but a user should hear about; same location fields
/// and display as [`EdsError`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EdsWarning {
    /// 1-based line.
    pub line: usize,
    /// The section, as written.
    pub section: Option<String>,
    /// The key, as written.
    pub key: Option<String>,
    /// What is odd.
    pub reason: String,
}

/// Longest reason shown, characters (a reason may quote a value of the file).
pub const MAX_REASON_CHARS: usize = 400;

/// `line N, [section] key: reason`, one line: the section, the key and the reason hold the
/// file's own text, so each is rendered by [`crate::quote`] (control characters escaped,
/// length capped).
fn fmt_location(
    f: &mut fmt::Formatter<'_>,
    line: usize,
    section: &Option<String>,
    key: &Option<String>,
    reason: &str,
) -> fmt::Result {
    use crate::quote::{text, text_max};
    write!(f, "line {line}")?;
    let reason = text_max(reason, MAX_REASON_CHARS);
    match (section, key) {
        (Some(s), Some(k)) => write!(f, ", [{}] {}: {reason}", text(s), text(k)),
        (Some(s), None) => write!(f, ", [{}]: {reason}", text(s)),
        (None, Some(k)) => write!(f, ", {}: {reason}", text(k)),
        (None, None) => write!(f, ": {reason}"),
    }
}

impl fmt::Display for EdsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt_location(f, self.line, &self.section, &self.key, &self.reason)
    }
}

impl std::error::Error for EdsError {}

impl fmt::Display for EdsWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt_location(f, self.line, &self.section, &self.key, &self.reason)
    }
}

/// A parsed EDS or DCF.
#[derive(Clone, Debug, PartialEq)]
pub struct EdsFile {
    /// `[FileInfo]`.
    pub file_info: FileInfo,
    /// `[DeviceInfo]`.
    pub device_info: DeviceInfo,
    /// `[DummyUsage]`: `dummy_usage[t]` says whether data type `t` (1..=7) may be mapped as a
    /// dummy entry into an RPDO. Index 0 is unused (always false).
    pub dummy_usage: [bool; 8],
    /// `[Comments]` `Line1..LineN`, in order.
    pub comments: Vec<String>,
    /// `[DeviceComissioning]` (a DCF's node ID, bit rate, names); `None` in a plain EDS.
    pub commissioning: Option<Commissioning>,
    /// Every object, sorted by index.
    pub objects: Vec<EdsObject>,
    /// What a user should hear about (the file was read all the same), in line order.
    pub warnings: Vec<EdsWarning>,
}

impl EdsFile {
    /// The object at `index`.
    pub fn object(&self, index: u16) -> Option<&EdsObject> {
        self.objects
            .binary_search_by_key(&index, |o| o.index)
            .ok()
            .map(|i| &self.objects[i])
    }

    /// The sub-index `sub` of object `index`.
    pub fn sub(&self, index: u16, sub: u8) -> Option<&EdsSub> {
        self.object(index).and_then(|o| o.sub(sub))
    }

    /// The node ID of a DCF (`[DeviceComissioning] NodeID`), if it gives one.
    pub fn node_id(&self) -> Option<u8> {
        self.commissioning.as_ref().and_then(|c| c.node_id)
    }
}

/// `[FileInfo]`, as written (CiA 306 gives dates and versions as text).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FileInfo {
    /// FileName.
    pub file_name: Option<String>,
    /// FileVersion.
    pub file_version: Option<String>,
    /// FileRevision.
    pub file_revision: Option<String>,
    /// EDSVersion.
    pub eds_version: Option<String>,
    /// Description.
    pub description: Option<String>,
    /// CreationTime.
    pub creation_time: Option<String>,
    /// CreationDate.
    pub creation_date: Option<String>,
    /// CreatedBy.
    pub created_by: Option<String>,
    /// ModificationTime.
    pub modification_time: Option<String>,
    /// ModificationDate.
    pub modification_date: Option<String>,
    /// ModifiedBy.
    pub modified_by: Option<String>,
    /// LastEDS (a DCF's source EDS).
    pub last_eds: Option<String>,
}

/// `[DeviceInfo]`, typed as CiA 306 types it. A key the file does not give is `None`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DeviceInfo {
    /// VendorName.
    pub vendor_name: Option<String>,
    /// VendorNumber (the CiA vendor-ID, 0x1018:1).
    pub vendor_number: Option<u32>,
    /// ProductName.
    pub product_name: Option<String>,
    /// ProductNumber (0x1018:2).
    pub product_number: Option<u32>,
    /// RevisionNumber (0x1018:3).
    pub revision_number: Option<u32>,
    /// OrderCode.
    pub order_code: Option<String>,
    /// The bit rates whose `BaudRate_<kbit/s>` is 1, in kbit/s, ascending (of 10, 20, 50,
    /// 125, 250, 500, 800, 1000).
    pub baud_rates_kbit: Vec<u16>,
    /// SimpleBootUpMaster.
    pub simple_boot_up_master: Option<bool>,
    /// SimpleBootUpSlave.
    pub simple_boot_up_slave: Option<bool>,
    /// Granularity (PDO mapping granularity in bits; 0: not mappable).
    pub granularity: Option<u8>,
    /// DynamicChannelsSupported (number of dynamic channels).
    pub dynamic_channels_supported: Option<u8>,
    /// GroupMessaging.
    pub group_messaging: Option<bool>,
    /// NrOfRXPDO.
    pub nr_of_rx_pdo: Option<u16>,
    /// NrOfTXPDO.
    pub nr_of_tx_pdo: Option<u16>,
    /// LSS_Supported.
    pub lss_supported: Option<bool>,
    /// CompactPDO (bit mask of implicit PDO sub-indices; kept, not expanded).
    pub compact_pdo: Option<u8>,
}

/// `[DeviceComissioning]` of a DCF.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Commissioning {
    /// NodeID (1..=127).
    pub node_id: Option<u8>,
    /// NodeName.
    pub node_name: Option<String>,
    /// Baudrate in kbit/s.
    pub baudrate_kbit: Option<u16>,
    /// NetNumber.
    pub net_number: Option<u32>,
    /// NetworkName.
    pub network_name: Option<String>,
    /// CANopenManager.
    pub canopen_manager: Option<bool>,
    /// LSS_SerialNumber (0x1018:4).
    pub lss_serial_number: Option<u32>,
}

/// CiA 301 object codes (`ObjectType=`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ObjectCode {
    /// NULL (0x0): no data.
    Null = 0,
    /// DOMAIN (0x2): a block of bytes.
    Domain = 2,
    /// DEFTYPE (0x5): a data type definition.
    DefType = 5,
    /// DEFSTRUCT (0x6): a record type definition.
    DefStruct = 6,
    /// VAR (0x7): one value.
    Var = 7,
    /// ARRAY (0x8): sub 0 the count, subs 1.. of one type.
    Array = 8,
    /// RECORD (0x9): sub 0 the highest sub-index, subs of mixed types.
    Record = 9,
}

impl ObjectCode {
    /// The object code of an `ObjectType=` number.
    pub fn from_code(code: u8) -> Option<ObjectCode> {
        Some(match code {
            0 => ObjectCode::Null,
            2 => ObjectCode::Domain,
            5 => ObjectCode::DefType,
            6 => ObjectCode::DefStruct,
            7 => ObjectCode::Var,
            8 => ObjectCode::Array,
            9 => ObjectCode::Record,
            _ => return None,
        })
    }

    /// Whether the object has sub-indices in their own sections (DEFSTRUCT, ARRAY, RECORD);
    /// the others are one value at sub-index 0.
    pub const fn structured(self) -> bool {
        matches!(
            self,
            ObjectCode::DefStruct | ObjectCode::Array | ObjectCode::Record
        )
    }
}

/// One object of the file.
#[derive(Clone, Debug, PartialEq)]
pub struct EdsObject {
    /// Object index.
    pub index: u16,
    /// ParameterName (Denotation of a DCF, if given, is on [`EdsObject::denotation`]).
    pub name: String,
    /// Denotation (DCF): the name the integrator gave it.
    pub denotation: Option<String>,
    /// ObjectType.
    pub code: ObjectCode,
    /// DataType of the object section: the value's type for a VAR / DOMAIN / DEFTYPE, the
    /// sub-indices' type for an ARRAY that gives one (CompactSubObj); `None` otherwise.
    pub data_type: Option<DataType>,
    /// The sub-indices, sorted; a VAR has one, sub 0, carrying its attributes.
    pub subs: Vec<EdsSub>,
    /// `[IIIIObjectLinks]`: indices of objects this one links to.
    pub object_links: Vec<u16>,
    /// Line of the `[IIII]` header.
    pub line: usize,
}

impl EdsObject {
    /// The sub-index `sub`.
    pub fn sub(&self, sub: u8) -> Option<&EdsSub> {
        self.subs
            .binary_search_by_key(&sub, |s| s.sub)
            .ok()
            .map(|i| &self.subs[i])
    }

    /// A data type definition (index 0x0001-0x025F: DEFTYPE, DEFSTRUCT, or the VARs some
    /// tools write there), not an object a master reads or writes.
    pub fn defines_type(&self) -> bool {
        (0x0001..=0x025F).contains(&self.index)
    }
}

/// One sub-index (for a VAR, the object itself at sub-index 0).
#[derive(Clone, Debug, PartialEq)]
pub struct EdsSub {
    /// Sub-index.
    pub sub: u8,
    /// ParameterName.
    pub name: String,
    /// DataType.
    pub data_type: DataType,
    /// AccessType.
    pub access: Access,
    /// PDOMapping=1.
    pub pdo_mapping: bool,
    /// DefaultValue.
    pub default: Option<ValueExpr>,
    /// ParameterValue (DCF; from `[IIIIValue]` for a CompactSubObj array).
    pub parameter_value: Option<ValueExpr>,
    /// LowLimit.
    pub low: Option<ValueExpr>,
    /// HighLimit.
    pub high: Option<ValueExpr>,
    /// Denotation (DCF).
    pub denotation: Option<String>,
    /// ObjFlags (CiA 306: bit 0 refuse write on download, bit 1 refuse read on scan).
    pub obj_flags: u32,
    /// UploadFile (DOMAIN): the file an upload of this object reads.
    pub upload_file: Option<String>,
    /// DownloadFile (DOMAIN): the file a download writes.
    pub download_file: Option<String>,
    /// Line of the section that describes it (`[IIIIsubS]`, or `[IIII]` for a VAR and for
    /// CompactSubObj sub-indices).
    pub line: usize,
}

/// A value as the file writes it, before it is turned into wire bytes for a type and a node
/// ID by [`ValueExpr::resolve`].
#[derive(Clone, Debug, PartialEq)]
pub enum ValueExpr {
    /// A decimal or octal integer, or a negative hex one: the number it says.
    Integer(i128),
    /// A hexadecimal integer without sign (`0x1F`): the number for an integer type (for a
    /// signed type, a pattern above the type's maximum is its two's complement), the IEEE 754
    /// bits for REAL32 and REAL64 (Lely's notation).
    Hex(u128),
    /// `$NODEID` plus this offset (negative for `$NODEID-1`).
    NodeIdPlus(i128),
    /// A decimal with a point or an exponent (`30.0`, `1e-3`): REAL32 / REAL64 (python
    /// canopen's notation).
    Decimal(f64),
    /// The text of a VISIBLE_STRING or UNICODE_STRING.
    Text(String),
    /// The bytes of an OCTET_STRING or DOMAIN, written as hex digit pairs.
    Octets(Vec<u8>),
}

impl ValueExpr {
    /// Read the text of a value of type `dtype` (`Ok(None)` for an empty value). The error
    /// says why the text is not a value of that type; range is checked by
    /// [`ValueExpr::resolve`].
    pub fn parse(text: &str, dtype: DataType) -> Result<Option<ValueExpr>, String> {
        let t = text.trim();
        if t.is_empty() {
            return Ok(None);
        }
        if t.len() > MAX_VALUE_BYTES {
            return Err(format!(
                "value of {} bytes, more than the {MAX_VALUE_BYTES} allowed",
                t.len()
            ));
        }
        match dtype {
            DataType::VisibleString | DataType::UnicodeString => {
                Ok(Some(ValueExpr::Text(t.to_string())))
            }
            DataType::OctetString | DataType::Domain => parse_octets(t).map(Some),
            _ => parse_number(strip_hash_comment(t)).map(Some),
        }
    }

    /// Whether the value depends on the node ID (`$NODEID`).
    pub fn uses_node_id(&self) -> bool {
        matches!(self, ValueExpr::NodeIdPlus(_))
    }

    /// The wire bytes of this value as type `dtype` (little-endian; exactly `dtype.size()`
    /// bytes for the fixed-size types; the text's bytes for VISIBLE_STRING (UTF-8), UTF-16LE
    /// code units for UNICODE_STRING, the bytes for OCTET_STRING and DOMAIN), with `$NODEID`
    /// replaced by `node_id`. Errors: a value outside the type's range, `$NODEID` without a
    /// node ID, a value of the wrong kind for the type.
    pub fn resolve(&self, dtype: DataType, node_id: Option<u8>) -> Result<Vec<u8>, String> {
        match dtype {
            DataType::VisibleString => match self {
                ValueExpr::Text(s) => Ok(s.as_bytes().to_vec()),
                other => Err(format!("{} is not a VISIBLE_STRING value", other.kind())),
            },
            DataType::UnicodeString => match self {
                ValueExpr::Text(s) => Ok(s.encode_utf16().flat_map(|u| u.to_le_bytes()).collect()),
                other => Err(format!("{} is not a UNICODE_STRING value", other.kind())),
            },
            DataType::OctetString | DataType::Domain => match self {
                ValueExpr::Octets(b) => Ok(b.clone()),
                other => Err(format!("{} is not a {} value", other.kind(), dtype.name())),
            },
            DataType::Real32 => {
                let bits = match self {
                    ValueExpr::Hex(u) => u32::try_from(*u)
                        .map_err(|_| format!("0x{u:X} is more than the 32 bits of a REAL32"))?,
                    ValueExpr::Decimal(f) => real32_from_f64(*f)?,
                    ValueExpr::Integer(i) => real32_from_f64(*i as f64)?,
                    other => return Err(format!("{} is not a REAL32 value", other.kind())),
                };
                Ok(bits.to_le_bytes().to_vec())
            }
            DataType::Real64 => {
                let bits = match self {
                    ValueExpr::Hex(u) => u64::try_from(*u)
                        .map_err(|_| format!("0x{u:X} is more than the 64 bits of a REAL64"))?,
                    ValueExpr::Decimal(f) if f.is_finite() => f.to_bits(),
                    ValueExpr::Decimal(f) => return Err(format!("{f} is not a finite REAL64")),
                    ValueExpr::Integer(i) => (*i as f64).to_bits(),
                    other => return Err(format!("{} is not a REAL64 value", other.kind())),
                };
                Ok(bits.to_le_bytes().to_vec())
            }
            DataType::TimeOfDay | DataType::TimeDifference => {
                let v: i128 = match self {
                    ValueExpr::Integer(i) => *i,
                    ValueExpr::Hex(u) => i128::try_from(*u).unwrap_or(i128::MAX),
                    other => {
                        return Err(format!("{} is not a {} value", other.kind(), dtype.name()))
                    }
                };
                if !(0..(1i128 << 48)).contains(&v) {
                    return Err(format!("{v} is outside the 48 bits of a {}", dtype.name()));
                }
                Ok(v.to_le_bytes()[..6].to_vec())
            }
            _ => {
                // BOOLEAN and the integers
                let (lo, hi) = dtype.range().unwrap_or((0, 0));
                let v: i128 = match self {
                    ValueExpr::Integer(i) => *i,
                    ValueExpr::Hex(u) => {
                        let u = i128::try_from(*u).unwrap_or(i128::MAX);
                        let bits = (dtype.size() * 8) as u32;
                        if dtype.signed() && u > hi && u < (1i128 << bits) {
                            // two's complement pattern of the type's width
                            u - (1i128 << bits)
                        } else {
                            u
                        }
                    }
                    ValueExpr::NodeIdPlus(off) => match node_id {
                        Some(n) => *off + n as i128,
                        None => return Err("$NODEID in a value, but no node ID to put in".into()),
                    },
                    other => {
                        return Err(format!("{} is not a {} value", other.kind(), dtype.name()))
                    }
                };
                if v < lo || v > hi {
                    return Err(format!(
                        "{v} is outside the range of {} ({lo}..={hi})",
                        dtype.name()
                    ));
                }
                Ok(v.to_le_bytes()[..dtype.size()].to_vec())
            }
        }
    }

    fn kind(&self) -> String {
        match self {
            ValueExpr::Integer(i) => format!("the integer {i}"),
            ValueExpr::Hex(u) => format!("0x{u:X}"),
            ValueExpr::NodeIdPlus(o) => format!("$NODEID{o:+}"),
            ValueExpr::Decimal(f) => format!("the decimal {f}"),
            ValueExpr::Text(_) => "a text".into(),
            ValueExpr::Octets(_) => "a byte string".into(),
        }
    }
}

fn real32_from_f64(f: f64) -> Result<u32, String> {
    if !f.is_finite() || f.abs() > f32::MAX as f64 {
        return Err(format!("{f} is outside the range of REAL32"));
    }
    Ok((f as f32).to_bits())
}

/// Text from the bytes of a file: UTF-8 if the bytes are UTF-8, else Latin-1 (ISO 8859-1,
/// each byte the character of the same code), which every byte string is. EDS tools write
/// Latin-1 (Windows-1252 in practice) in names and comments; reading those as Latin-1 keeps
/// every byte and needs no guess.
pub fn decode_text(bytes: &[u8]) -> String {
    match std::str::from_utf8(bytes) {
        Ok(s) => s.to_string(),
        Err(_) => bytes.iter().map(|&b| b as char).collect(),
    }
}

// ---------------------------------------------------------------------------------------
// numbers

/// A `#` after whitespace ends a number (dcf-tools' inline comment), and so does a `;`
/// anywhere (a comment written without the space before it; the reader warns).
fn strip_hash_comment(t: &str) -> &str {
    let b = t.as_bytes();
    for i in 1..b.len() {
        if (b[i] == b'#' && b[i - 1].is_ascii_whitespace()) || b[i] == b';' {
            return t[..i].trim_end();
        }
    }
    t
}

fn parse_octets(t: &str) -> Result<ValueExpr, String> {
    let mut out = Vec::with_capacity(t.len() / 2);
    let mut hi: Option<u8> = None;
    for c in t.chars() {
        if c.is_whitespace() {
            if hi.is_some() {
                return Err(format!(
                    "'{t}' is not hex digit pairs (an odd digit before a space)"
                ));
            }
            continue;
        }
        let d = c.to_digit(16).ok_or_else(|| {
            format!("'{t}' is not hex digit pairs ('{c}' is not a hex digit; no 0x prefix)")
        })? as u8;
        match hi.take() {
            None => hi = Some(d),
            Some(h) => out.push(h << 4 | d),
        }
    }
    if hi.is_some() {
        return Err(format!("'{t}' has an odd number of hex digits"));
    }
    Ok(ValueExpr::Octets(out))
}

/// An unsigned integer literal: `0x` hex, leading-0 octal, decimal. Returns the value and
/// whether it was hex (and whether octal, for the warning).
fn parse_uint(t: &str) -> Result<(u128, Radix), String> {
    let (digits, radix) = if let Some(h) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        (h, Radix::Hex)
    } else if t.len() > 1 && t.starts_with('0') {
        (&t[1..], Radix::Octal)
    } else {
        (t, Radix::Decimal)
    };
    let base = match radix {
        Radix::Hex => 16,
        Radix::Octal => 8,
        Radix::Decimal => 10,
    };
    if digits.is_empty() {
        return Err(format!("'{t}' is not a number"));
    }
    let mut v: u128 = 0;
    for c in digits.chars() {
        let d = match c.to_digit(base) {
            Some(d) => d,
            // '08', '09': not octal; the decimal reading is the only one (python canopen and
            // Lely stop; the value_key warning says so)
            None if radix == Radix::Octal && digits.bytes().all(|b| b.is_ascii_digit()) => {
                return parse_uint(digits.trim_start_matches('0'))
                    .map(|(v, _)| (v, Radix::Decimal));
            }
            None => return Err(format!("'{t}' is not a number")),
        };
        v = v
            .checked_mul(base as u128)
            .and_then(|v| v.checked_add(d as u128))
            .ok_or_else(|| format!("'{t}' is too large a number"))?;
    }
    Ok((v, radix))
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Radix {
    Decimal,
    Hex,
    Octal,
}

fn is_decimal_float(t: &str) -> bool {
    let body = t.strip_prefix(['-', '+']).unwrap_or(t);
    if body.starts_with("0x") || body.starts_with("0X") {
        return false;
    }
    let has_mark = body.contains(['.', 'e', 'E']);
    has_mark
        && body
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_digit() || c == '.')
        && body
            .chars()
            .all(|c| c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '-' | '+'))
}

/// A number or a `$NODEID` expression.
fn parse_number(t: &str) -> Result<ValueExpr, String> {
    if t.to_ascii_uppercase().contains("$NODEID") {
        return parse_nodeid_expr(t);
    }
    if is_decimal_float(t) {
        return t
            .parse::<f64>()
            .ok()
            .filter(|f| f.is_finite())
            .map(ValueExpr::Decimal)
            .ok_or_else(|| format!("'{t}' is not a number"));
    }
    let (neg, body) = match t.as_bytes()[0] {
        b'-' => (true, t[1..].trim_start()),
        b'+' => (false, t[1..].trim_start()),
        _ => (false, t),
    };
    let (v, radix) = parse_uint(body)?;
    if radix == Radix::Hex && !neg {
        return Ok(ValueExpr::Hex(v));
    }
    let v = i128::try_from(v).map_err(|_| format!("'{t}' is too large a number"))?;
    Ok(ValueExpr::Integer(if neg { -v } else { v }))
}

/// `$NODEID`, `$NODEID+N`, `$NODEID-N`, `N+$NODEID`, with any spaces and case.
fn parse_nodeid_expr(t: &str) -> Result<ValueExpr, String> {
    let bad = |why: &str| format!("'{t}' is not a $NODEID expression: {why}");
    let upper = t.to_ascii_uppercase();
    let pos = upper.find("$NODEID").unwrap_or(0);
    if upper[pos + 7..].contains("$NODEID") {
        return Err(bad("$NODEID twice"));
    }
    let before = t[..pos].trim();
    let after = t[pos + 7..].trim();
    let offset = match (before.is_empty(), after.is_empty()) {
        (true, true) => 0,
        (true, false) => {
            // $NODEID +/- N
            let (neg, rest) = match after.as_bytes()[0] {
                b'+' => (false, after[1..].trim_start()),
                b'-' => (true, after[1..].trim_start()),
                _ => return Err(bad("expected + or - after $NODEID")),
            };
            let v = signed_literal(rest).map_err(|e| bad(&e))?;
            if neg {
                -v
            } else {
                v
            }
        }
        (false, true) => {
            // N + $NODEID
            let Some(n) = before.strip_suffix('+') else {
                return Err(bad("expected + before $NODEID"));
            };
            signed_literal(n.trim_end()).map_err(|e| bad(&e))?
        }
        (false, false) => return Err(bad("text on both sides of $NODEID")),
    };
    Ok(ValueExpr::NodeIdPlus(offset))
}

fn signed_literal(t: &str) -> Result<i128, String> {
    let (neg, body) = match t.as_bytes().first() {
        Some(b'-') => (true, t[1..].trim_start()),
        Some(b'+') => (false, t[1..].trim_start()),
        Some(_) => (false, t),
        None => return Err("a number is missing".into()),
    };
    let (v, _) = parse_uint(body)?;
    let v = i128::try_from(v).map_err(|_| format!("'{t}' is too large a number"))?;
    Ok(if neg { -v } else { v })
}

/// A plain unsigned integer key (SubNumber, NrOfRXPDO...): decimal, hex or octal.
fn parse_plain_uint(t: &str) -> Result<u128, String> {
    let t = strip_hash_comment(t.trim());
    let body = t.strip_prefix('+').unwrap_or(t);
    parse_uint(body).map(|(v, _)| v)
}

// ---------------------------------------------------------------------------------------
// lines and sections

struct Entry<'a> {
    key: &'a str,
    value: &'a str,
    line: usize,
}

struct Section<'a> {
    name: &'a str,
    line: usize,
    entries: Vec<Entry<'a>>,
    keys: HashMap<String, usize>,
}

impl<'a> Section<'a> {
    fn get(&self, key: &str) -> Option<&Entry<'a>> {
        let i = *self.keys.get(&key.to_ascii_lowercase())?;
        Some(&self.entries[i])
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Kind {
    FileInfo,
    DeviceInfo,
    DummyUsage,
    Comments,
    Commissioning,
    List(u8),
    Object(u16),
    Sub(u16, u8),
    Names(u16),
    Values(u16),
    Links(u16),
    Other,
}

fn hex4(s: &str) -> Option<u16> {
    if s.len() == 4 && s.bytes().all(|b| b.is_ascii_hexdigit()) {
        u16::from_str_radix(s, 16).ok()
    } else {
        None
    }
}

fn kind_counts_object(k: Kind) -> bool {
    matches!(k, Kind::Object(_))
}

/// What a section name (lowercase) is; `Err` for a sub-index out of range.
fn classify(lc: &str) -> Result<Kind, String> {
    Ok(match lc {
        "fileinfo" => Kind::FileInfo,
        "deviceinfo" => Kind::DeviceInfo,
        "dummyusage" => Kind::DummyUsage,
        "comments" => Kind::Comments,
        "devicecomissioning" | "devicecommissioning" => Kind::Commissioning,
        "mandatoryobjects" => Kind::List(0),
        "optionalobjects" => Kind::List(1),
        "manufacturerobjects" => Kind::List(2),
        _ => {
            if let Some(i) = hex4(lc) {
                return Ok(Kind::Object(i));
            }
            if lc.len() < 4 || !lc.is_char_boundary(4) {
                return Ok(Kind::Other);
            }
            let Some(index) = hex4(&lc[..4]) else {
                return Ok(Kind::Other);
            };
            let rest = &lc[4..];
            if let Some(s) = rest.strip_prefix("sub") {
                if !s.is_empty() && s.bytes().all(|b| b.is_ascii_hexdigit()) {
                    let v = u32::from_str_radix(s.trim_start_matches('0'), 16).unwrap_or(
                        if s.trim_start_matches('0').is_empty() {
                            0
                        } else {
                            u32::MAX
                        },
                    );
                    if v > 0xFE {
                        return Err(format!(
                            "sub-index 0x{} is out of range (0..=0xFE; 0xFF is reserved for the structure, CiA 301)",
                            s.to_ascii_uppercase()
                        ));
                    }
                    return Ok(Kind::Sub(index, v as u8));
                }
                return Ok(Kind::Other);
            }
            match rest {
                "name" => Kind::Names(index),
                "value" => Kind::Values(index),
                "objectlinks" => Kind::Links(index),
                _ => Kind::Other,
            }
        }
    })
}

/// Keys CiA 306 (and the tools) define for an object or sub-index section.
const OBJECT_KEYS: &[&str] = &[
    "subnumber",
    "parametername",
    "objecttype",
    "datatype",
    "accesstype",
    "lowlimit",
    "highlimit",
    "defaultvalue",
    "pdomapping",
    "objflags",
    "compactsubobj",
    "parametervalue",
    "uploadfile",
    "downloadfile",
    "denotation",
    "paramrefd",
    "storagelocation",
];

struct Ctx<'a> {
    sections: Vec<Section<'a>>,
    by_kind: HashMap<Kind, usize>,
    warnings: Vec<EdsWarning>,
}

fn err(
    line: usize,
    section: Option<&str>,
    key: Option<&str>,
    reason: impl Into<String>,
) -> EdsError {
    EdsError {
        line,
        section: section.map(str::to_string),
        key: key.map(str::to_string),
        reason: reason.into(),
    }
}

impl<'a> Ctx<'a> {
    fn warn(
        &mut self,
        line: usize,
        section: Option<&str>,
        key: Option<&str>,
        reason: impl Into<String>,
    ) {
        self.warnings.push(EdsWarning {
            line,
            section: section.map(str::to_string),
            key: key.map(str::to_string),
            reason: reason.into(),
        });
    }

    fn section(&self, kind: Kind) -> Option<&Section<'a>> {
        self.by_kind.get(&kind).map(|&i| &self.sections[i])
    }
}

fn key_err(s: &Section, e: &Entry, reason: impl Into<String>) -> EdsError {
    err(e.line, Some(s.name), Some(e.key), reason)
}

/// A warning of the lexer (no [`Ctx`] yet).
fn lex_warn(
    out: &mut Vec<EdsWarning>,
    line: usize,
    section: Option<&str>,
    key: Option<&str>,
    reason: String,
) {
    out.push(EdsWarning {
        line,
        section: section.map(str::to_string),
        key: key.map(str::to_string),
        reason,
    });
}

/// Put `entry` into `sec`: a key given twice is read as the last one gives it (Lely's
/// reading; python canopen's strict parser refuses the file), with a warning.
fn add_entry<'a>(
    sec: &mut Section<'a>,
    written_in: &str,
    entry: Entry<'a>,
    warnings: &mut Vec<EdsWarning>,
) {
    let lc = entry.key.to_ascii_lowercase();
    if let Some(&first) = sec.keys.get(&lc) {
        let old = &sec.entries[first];
        let reason = if old.value == entry.value {
            format!(
                "key given twice in this section (first at line {}), same value; read once",
                old.line
            )
        } else {
            format!(
                "key given twice in this section (first at line {}, '{}'): the last one, '{}', is read (as Lely reads it; python canopen refuses the file)",
                old.line,
                clip(old.value),
                clip(entry.value)
            )
        };
        lex_warn(
            warnings,
            entry.line,
            Some(written_in),
            Some(entry.key),
            reason,
        );
        sec.entries[first] = entry;
        return;
    }
    sec.keys.insert(lc, sec.entries.len());
    sec.entries.push(entry);
}

/// Split the text into sections (step 1: lines only). A section given twice is one section
/// (its keys read into the first, as Lely reads it), with a warning.
fn lex(text: &str) -> Result<(Vec<Section<'_>>, Vec<EdsWarning>), EdsError> {
    let text = text.strip_prefix('\u{FEFF}').unwrap_or(text);
    let mut sections: Vec<Section> = Vec::new();
    let mut warnings = Vec::new();
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut current: Option<usize> = None;
    for (n, raw) in text.split('\n').enumerate() {
        let line_no = n + 1;
        let line = raw.strip_suffix('\r').unwrap_or(raw).trim();
        if line.is_empty() || line.starts_with(';') || line.starts_with('#') {
            continue;
        }
        if let Some(rest) = line.strip_prefix('[') {
            let Some(close) = rest.find(']') else {
                return Err(err(
                    line_no,
                    None,
                    None,
                    format!("section header '{line}' has no closing ]"),
                ));
            };
            let name = rest[..close].trim();
            let tail = rest[close + 1..].trim();
            if !(tail.is_empty() || tail.starts_with(';') || tail.starts_with('#')) {
                return Err(err(
                    line_no,
                    Some(name),
                    None,
                    format!("text '{tail}' after the section header"),
                ));
            }
            if name.is_empty() {
                return Err(err(line_no, None, None, "empty section name []"));
            }
            if name.len() > 256 {
                return Err(err(
                    line_no,
                    None,
                    None,
                    "section name longer than 256 bytes",
                ));
            }
            let lc = name.to_ascii_lowercase();
            if let Some(&first) = seen.get(&lc) {
                lex_warn(
                    &mut warnings,
                    line_no,
                    Some(name),
                    None,
                    format!(
                        "section given twice (first at line {}): its keys are read as part of the first (as Lely reads it; python canopen refuses the file)",
                        sections[first].line
                    ),
                );
                current = Some(first);
                continue;
            }
            if sections.len() >= MAX_SECTIONS {
                return Err(err(
                    line_no,
                    Some(name),
                    None,
                    format!("more than {MAX_SECTIONS} sections"),
                ));
            }
            seen.insert(lc, sections.len());
            current = Some(sections.len());
            sections.push(Section {
                name,
                line: line_no,
                entries: Vec::new(),
                keys: HashMap::new(),
            });
            continue;
        }
        let Some(eq) = line.find('=') else {
            let section = current.map(|i| sections[i].name);
            return Err(err(
                line_no,
                section,
                None,
                format!(
                    "'{}' is neither a [section], a key=value pair nor a comment",
                    clip(line)
                ),
            ));
        };
        let key = line[..eq].trim();
        let mut value = line[eq + 1..].trim();
        // inline comment: ';' after whitespace (python canopen and dcf-tools)
        if let Some(p) = value
            .as_bytes()
            .windows(2)
            .position(|w| w[0].is_ascii_whitespace() && w[1] == b';')
        {
            value = value[..p].trim_end();
        }
        let Some(sec) = current.map(|i| &mut sections[i]) else {
            return Err(err(
                line_no,
                None,
                Some(key),
                "key=value before the first [section]",
            ));
        };
        if key.is_empty() {
            return Err(err(
                line_no,
                Some(sec.name),
                None,
                "a key is missing before '='",
            ));
        }
        if value.len() > MAX_VALUE_BYTES {
            return Err(err(
                line_no,
                Some(sec.name),
                Some(key),
                format!(
                    "value of {} bytes, more than the {MAX_VALUE_BYTES} allowed",
                    value.len()
                ),
            ));
        }
        let written_in = sec.name;
        add_entry(
            sec,
            written_in,
            Entry {
                key,
                value,
                line: line_no,
            },
            &mut warnings,
        );
    }
    Ok((sections, warnings))
}

fn clip(s: &str) -> String {
    if s.chars().count() > 40 {
        let mut c: String = s.chars().take(40).collect();
        c.push('…');
        c
    } else {
        s.to_string()
    }
}

/// Parse the text of an EDS or DCF (CiA 306). See the module documentation for what is
/// accepted and what is an error.
pub fn parse(text: &str) -> Result<EdsFile, EdsError> {
    if text.len() > MAX_INPUT_BYTES {
        let line = text.as_bytes()[..MAX_INPUT_BYTES]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1;
        return Err(err(
            line,
            None,
            None,
            format!(
                "input of {} bytes, more than the {} MiB an EDS may have (limit reached at this line)",
                text.len(),
                MAX_INPUT_BYTES >> 20
            ),
        ));
    }
    let (sections, lex_warnings) = lex(text)?;
    let mut cx = Ctx {
        sections,
        by_kind: HashMap::new(),
        warnings: lex_warnings,
    };
    // classify every section
    let mut n_objects = 0usize;
    for i in 0..cx.sections.len() {
        let (name, line) = (cx.sections[i].name, cx.sections[i].line);
        let kind =
            classify(&name.to_ascii_lowercase()).map_err(|r| err(line, Some(name), None, r))?;
        if let Kind::Object(0) = kind {
            return Err(err(
                line,
                Some(name),
                None,
                "object index 0x0000 does not exist",
            ));
        }
        if let Kind::Sub(0, _) = kind {
            return Err(err(
                line,
                Some(name),
                None,
                "object index 0x0000 does not exist",
            ));
        }
        if kind == Kind::Other {
            cx.warn(
                line,
                Some(name),
                None,
                "section not known to CiA 306 EDS/DCF readers here; ignored",
            );
            continue;
        }
        if let Kind::Object(_) = kind {
            n_objects += 1;
            if n_objects > MAX_OBJECTS {
                return Err(err(
                    line,
                    Some(name),
                    None,
                    format!("more than {MAX_OBJECTS} objects"),
                ));
            }
        }
        if let Some(&first) = cx.by_kind.get(&kind) {
            // [1018sub1] and [1018sub01]: one section, read as Lely reads a section twice
            let (fname, fline) = (cx.sections[first].name, cx.sections[first].line);
            cx.warn(
                line,
                Some(name),
                None,
                format!(
                    "names the same thing as [{fname}] at line {fline}: its keys are read as part of [{fname}] (as Lely reads a section given twice)"
                ),
            );
            let entries = std::mem::take(&mut cx.sections[i].entries);
            cx.sections[i].keys.clear();
            let mut w = Vec::new();
            for e in entries {
                add_entry(&mut cx.sections[first], name, e, &mut w);
            }
            cx.warnings.append(&mut w);
            if kind_counts_object(kind) {
                n_objects -= 1;
            }
            continue;
        }
        cx.by_kind.insert(kind, i);
    }

    let file_info = read_file_info(&cx);
    let device_info = read_device_info(&mut cx)?;
    let dummy_usage = read_dummy_usage(&mut cx)?;
    let comments = read_comments(&mut cx)?;
    let commissioning = read_commissioning(&mut cx)?;

    // DEFSTRUCTs the file defines: their codes are complex types
    let mut structs: HashSet<u16> = HashSet::new();
    for (kind, &i) in &cx.by_kind {
        if let Kind::Object(index) = kind {
            let s = &cx.sections[i];
            if let Some(e) = s.get("ObjectType") {
                if parse_plain_uint(e.value).ok() == Some(6) {
                    structs.insert(*index);
                }
            }
        }
    }

    // sub-index sections per object, and orphans
    let mut subs_of: HashMap<u16, Vec<(u8, usize)>> = HashMap::new();
    let mut orphan: Option<(usize, usize)> = None; // (line, section idx)
    for (kind, &i) in &cx.by_kind {
        let index = match *kind {
            Kind::Sub(index, sub) => {
                subs_of.entry(index).or_default().push((sub, i));
                index
            }
            Kind::Names(index) | Kind::Values(index) | Kind::Links(index) => index,
            _ => continue,
        };
        // the first (by line) section whose object is missing
        let line = cx.sections[i].line;
        if !cx.by_kind.contains_key(&Kind::Object(index)) && orphan.is_none_or(|(l, _)| line < l) {
            orphan = Some((line, i));
        }
    }
    if let Some((line, i)) = orphan {
        let s = &cx.sections[i];
        return Err(err(
            line,
            Some(s.name),
            None,
            format!("section without its object [{}]", &s.name[..4]),
        ));
    }

    // the objects, in index order
    let mut indices: Vec<(u16, usize)> = cx
        .by_kind
        .iter()
        .filter_map(|(k, &i)| match k {
            Kind::Object(index) => Some((*index, i)),
            _ => None,
        })
        .collect();
    indices.sort_unstable();
    let mut objects = Vec::with_capacity(indices.len());
    let mut n_subs = 0usize;
    for &(index, si) in &indices {
        let mut subs = subs_of.remove(&index).unwrap_or_default();
        subs.sort_unstable();
        let obj = read_object(&mut cx, index, si, &subs, &structs)?;
        n_subs += obj.subs.len();
        if n_subs > MAX_SUBS {
            return Err(err(
                obj.line,
                Some(cx.sections[si].name),
                None,
                format!("more than {MAX_SUBS} sub-indices in all objects"),
            ));
        }
        objects.push(obj);
    }

    check_lists(&mut cx, &indices)?;
    warn_unknown_keys(&mut cx);

    let mut warnings = std::mem::take(&mut cx.warnings);
    warnings.sort_by_key(|w| w.line); // stable: same-line warnings keep their order
    Ok(EdsFile {
        file_info,
        device_info,
        dummy_usage,
        comments,
        commissioning,
        objects,
        warnings,
    })
}

// ---------------------------------------------------------------------------------------
// the fixed sections

fn text_of(s: Option<&Section>, key: &str) -> Option<String> {
    s.and_then(|s| s.get(key)).map(|e| e.value.to_string())
}

fn read_file_info(cx: &Ctx) -> FileInfo {
    let s = cx.section(Kind::FileInfo);
    FileInfo {
        file_name: text_of(s, "FileName"),
        file_version: text_of(s, "FileVersion"),
        file_revision: text_of(s, "FileRevision"),
        eds_version: text_of(s, "EDSVersion"),
        description: text_of(s, "Description"),
        creation_time: text_of(s, "CreationTime"),
        creation_date: text_of(s, "CreationDate"),
        created_by: text_of(s, "CreatedBy"),
        modification_time: text_of(s, "ModificationTime"),
        modification_date: text_of(s, "ModificationDate"),
        modified_by: text_of(s, "ModifiedBy"),
        last_eds: text_of(s, "LastEDS"),
    }
}

/// A number key of a fixed section, range-checked; empty is `None`. A value that is not a
/// number, or above `max`, is read as not given, with a warning (these keys describe the
/// file; the objects say what the device does).
fn num_key(w: &mut Vec<EdsWarning>, s: Option<&Section>, key: &str, max: u128) -> Option<u128> {
    let s = s?;
    let e = s.get(key)?;
    if e.value.is_empty() {
        return None;
    }
    let why = match parse_plain_uint(e.value) {
        Ok(v) if v <= max => return Some(v),
        Ok(v) => format!("{v} is more than {max}"),
        Err(r) => r,
    };
    lex_warn(
        w,
        e.line,
        Some(s.name),
        Some(e.key),
        format!("{why}: read as not given"),
    );
    None
}

/// A 0/1 key; `true`/`yes` and `false`/`no` and any non-zero number are read too, with a
/// warning.
fn bool_key(w: &mut Vec<EdsWarning>, s: Option<&Section>, key: &str) -> Option<bool> {
    let e = s?.get(key)?;
    let word = match e.value.to_ascii_lowercase().as_str() {
        "true" | "yes" => Some(true),
        "false" | "no" => Some(false),
        _ => None,
    };
    let (v, note) = match word {
        Some(b) => (b, true),
        None => {
            let v = num_key(w, s, key, u128::MAX)?;
            (v != 0, v > 1)
        }
    };
    if note {
        lex_warn(
            w,
            e.line,
            s.map(|s| s.name),
            Some(e.key),
            format!(
                "'{}' where CiA 306 writes 0 or 1: read as {}",
                e.value, v as u8
            ),
        );
    }
    Some(v)
}

fn read_device_info(cx: &mut Ctx) -> Result<DeviceInfo, EdsError> {
    let Some(&si) = cx.by_kind.get(&Kind::DeviceInfo) else {
        cx.warn(
            1,
            None,
            None,
            "no [DeviceInfo] section (CiA 306 makes it mandatory)",
        );
        return Ok(DeviceInfo::default());
    };
    let s = Some(&cx.sections[si]);
    let w = &mut cx.warnings;
    let mut baud_rates_kbit = Vec::new();
    for kbit in [10u16, 20, 50, 125, 250, 500, 800, 1000] {
        if bool_key(w, s, &format!("BaudRate_{kbit}")) == Some(true) {
            baud_rates_kbit.push(kbit);
        }
    }
    let d = DeviceInfo {
        vendor_name: text_of(s, "VendorName"),
        vendor_number: num_key(w, s, "VendorNumber", u32::MAX as u128).map(|v| v as u32),
        product_name: text_of(s, "ProductName"),
        product_number: num_key(w, s, "ProductNumber", u32::MAX as u128).map(|v| v as u32),
        revision_number: num_key(w, s, "RevisionNumber", u32::MAX as u128).map(|v| v as u32),
        order_code: text_of(s, "OrderCode"),
        baud_rates_kbit,
        simple_boot_up_master: bool_key(w, s, "SimpleBootUpMaster"),
        simple_boot_up_slave: bool_key(w, s, "SimpleBootUpSlave"),
        granularity: num_key(w, s, "Granularity", 64).map(|v| v as u8),
        dynamic_channels_supported: num_key(w, s, "DynamicChannelsSupported", 255).map(|v| v as u8),
        group_messaging: bool_key(w, s, "GroupMessaging"),
        nr_of_rx_pdo: num_key(w, s, "NrOfRXPDO", 512).map(|v| v as u16),
        nr_of_tx_pdo: num_key(w, s, "NrOfTXPDO", 512).map(|v| v as u16),
        lss_supported: bool_key(w, s, "LSS_Supported"),
        compact_pdo: num_key(w, s, "CompactPDO", 255).map(|v| v as u8),
    };
    if d.compact_pdo.is_some_and(|m| m != 0) {
        let (line, name) = (cx.sections[si].line, cx.sections[si].name);
        cx.warn(
            line,
            Some(name),
            Some("CompactPDO"),
            "implicit PDO objects (CompactPDO) are not expanded: only the PDO objects the file lists exist",
        );
    }
    Ok(d)
}

fn read_dummy_usage(cx: &mut Ctx) -> Result<[bool; 8], EdsError> {
    let mut d = [false; 8];
    let s = cx.by_kind.get(&Kind::DummyUsage).map(|&i| &cx.sections[i]);
    let w = &mut cx.warnings;
    for (t, slot) in d.iter_mut().enumerate().skip(1) {
        *slot = bool_key(w, s, &format!("Dummy{t:04X}")) == Some(true);
    }
    Ok(d)
}

fn read_comments(cx: &mut Ctx) -> Result<Vec<String>, EdsError> {
    let Some(&si) = cx.by_kind.get(&Kind::Comments) else {
        return Ok(Vec::new());
    };
    let s = &cx.sections[si];
    let n = num_key(&mut cx.warnings, Some(s), "Lines", 65_535).unwrap_or(0) as usize;
    let mut lines = Vec::with_capacity(n);
    let mut missing = None;
    for i in 1..=n {
        match s.get(&format!("Line{i}")) {
            Some(e) => lines.push(e.value.to_string()),
            None => {
                missing.get_or_insert(i);
                lines.push(String::new());
            }
        }
    }
    let extra = s
        .entries
        .len()
        .saturating_sub(1 + n - missing.map_or(0, |_| 1));
    let (line, name) = (s.line, s.name);
    if let Some(i) = missing {
        cx.warn(
            line,
            Some(name),
            None,
            format!("Lines={n} but Line{i} is missing (read as empty)"),
        );
    } else if extra > 0 && s.get("Lines").is_some() {
        cx.warn(
            line,
            Some(name),
            None,
            format!("more Line entries than Lines={n}; the extra ones are ignored"),
        );
    }
    Ok(lines)
}

fn read_commissioning(cx: &mut Ctx) -> Result<Option<Commissioning>, EdsError> {
    let Some(&si) = cx.by_kind.get(&Kind::Commissioning) else {
        return Ok(None);
    };
    let s = Some(&cx.sections[si]);
    let w = &mut cx.warnings;
    let mut node_id = num_key(w, s, "NodeID", 255);
    if let Some(id) = node_id.filter(|id| !(1..=127).contains(id)) {
        let e = s.and_then(|s| s.get("NodeID")).expect("read above");
        lex_warn(
            w,
            e.line,
            s.map(|s| s.name),
            Some(e.key),
            format!("node ID {id} is outside 1..=127: read as not given (the node ID comes from the command line)"),
        );
        node_id = None;
    }
    Ok(Some(Commissioning {
        node_id: node_id.map(|v| v as u8),
        node_name: text_of(s, "NodeName"),
        baudrate_kbit: num_key(w, s, "Baudrate", 1000).map(|v| v as u16),
        net_number: num_key(w, s, "NetNumber", u32::MAX as u128).map(|v| v as u32),
        network_name: text_of(s, "NetworkName"),
        canopen_manager: bool_key(w, s, "CANopenManager"),
        lss_serial_number: num_key(w, s, "LSS_SerialNumber", u32::MAX as u128).map(|v| v as u32),
    }))
}

// ---------------------------------------------------------------------------------------
// objects

fn data_type_of(s: &Section, e: &Entry, structs: &HashSet<u16>) -> Result<DataType, EdsError> {
    let code = parse_plain_uint(e.value).map_err(|r| key_err(s, e, r))?;
    if code > 0xFFFF {
        return Err(key_err(s, e, format!("unknown data type 0x{code:X}")));
    }
    let code = code as u16;
    if let Some(t) = DataType::from_code(code) {
        return Ok(t);
    }
    let complex = match code {
        0x20 => Some("PDO_COMMUNICATION_PARAMETER"),
        0x21 => Some("PDO_MAPPING"),
        0x22 => Some("SDO_PARAMETER"),
        0x23 => Some("IDENTITY"),
        _ if structs.contains(&code) => Some("a DEFSTRUCT of this file"),
        _ => None,
    };
    Err(key_err(
        s,
        e,
        match complex {
            Some(what) => format!(
                "complex data type 0x{code:04X} ({what}) on a sub-index: a sub-index holds a basic type"
            ),
            None => format!("unknown data type 0x{code:04X}"),
        },
    ))
}

/// The attributes a value has in its section (VAR object, sub-index, CompactSubObj array).
struct Attrs {
    data_type: DataType,
    access: Access,
    pdo_mapping: bool,
    default: Option<ValueExpr>,
    parameter_value: Option<ValueExpr>,
    low: Option<ValueExpr>,
    high: Option<ValueExpr>,
    obj_flags: u32,
    upload_file: Option<String>,
    download_file: Option<String>,
}

fn value_key(
    cx: &mut Ctx,
    si: usize,
    key: &str,
    dtype: DataType,
) -> Result<Option<ValueExpr>, EdsError> {
    let s = &cx.sections[si];
    let Some(e) = s.get(key) else { return Ok(None) };
    let v = ValueExpr::parse(e.value, dtype).map_err(|r| key_err(s, e, r))?;
    let Some(mut v) = v else { return Ok(None) };
    let mut notes = Vec::new();
    if let Err(e2) = check_value(s, e, &v, dtype) {
        // A limit beyond the type's range limits nothing: python canopen takes it as it is,
        // Lely clamps it with a warning; read it as the type's bound (dcfchk refuses it).
        let clamped = match (is_limit(key), dtype.range(), &v) {
            (true, Some((lo, hi)), ValueExpr::Integer(_) | ValueExpr::Hex(_)) => {
                let x = match v {
                    ValueExpr::Integer(i) => i,
                    ValueExpr::Hex(u) => i128::try_from(u).unwrap_or(i128::MAX),
                    _ => 0,
                };
                Some(x.clamp(lo, hi))
            }
            _ => None,
        };
        let Some(c) = clamped else { return Err(e2) };
        notes.push(format!(
            "{} is outside the range of {}: read as {c} (Lely clamps it likewise)",
            e.value,
            dtype.name()
        ));
        v = ValueExpr::Integer(c);
    }
    let (line, name, k, text) = (e.line, s.name, e.key, e.value);
    if !dtype.variable() && text.contains(';') {
        notes.push(format!(
            "'{}': a ';' comment without a space before it; the number before it is read (python canopen reads such a value as text and fails)",
            clip(text)
        ));
    }
    if matches!(v, ValueExpr::Integer(_)) {
        let digits = strip_hash_comment(text).trim_start_matches(['-', '+']);
        if digits.len() > 1
            && digits.starts_with('0')
            && digits.bytes().all(|b| b.is_ascii_digit())
            && digits.bytes().any(|b| b >= b'8')
        {
            notes.push(format!(
                "'{text}' has a leading 0 (octal in CiA 306) but an 8 or 9: read as the decimal {} (python canopen and Lely stop here)",
                digits.trim_start_matches('0')
            ));
        }
    }
    if dtype.float() && matches!(v, ValueExpr::Integer(i) if i != 0) {
        notes.push(format!(
            "{} value '{text}' is a plain decimal integer: read as the number (python canopen); Lely reads it as IEEE 754 bits",
            dtype.name()
        ));
    }
    if let (ValueExpr::Integer(i), Some(t)) = (&v, strip_hash_comment(text).strip_prefix('0')) {
        if !t.is_empty()
            && t.bytes().all(|b| b.is_ascii_digit())
            && i.to_string() != t.trim_start_matches('0')
        {
            notes.push(format!(
                "'{text}' is octal (CiA 306, Lely): {i}; python canopen rejects it"
            ));
        }
    }
    for n in notes {
        cx.warn(line, Some(name), Some(k), n);
    }
    Ok(Some(v))
}

fn is_limit(key: &str) -> bool {
    key == "LowLimit" || key == "HighLimit"
}

/// Resolve a value as the node would (at node IDs 1 and 127 if it uses $NODEID).
fn check_value(s: &Section, e: &Entry, v: &ValueExpr, dtype: DataType) -> Result<(), EdsError> {
    if dtype.integer() && v.uses_node_id() {
        for id in [1u8, 127] {
            v.resolve(dtype, Some(id))
                .map_err(|r| key_err(s, e, format!("{r} (with $NODEID = {id})")))?;
        }
    } else if v.uses_node_id() {
        return Err(key_err(
            s,
            e,
            format!("$NODEID in a {} value", dtype.name()),
        ));
    } else {
        v.resolve(dtype, None).map_err(|r| key_err(s, e, r))?;
    }
    Ok(())
}

/// A value as a number for comparisons (at a node ID), `None` for strings.
fn numeric(v: &ValueExpr, dtype: DataType, node_id: u8) -> Option<f64> {
    let b = v.resolve(dtype, Some(node_id)).ok()?;
    Some(match dtype {
        DataType::Real32 => f32::from_le_bytes(b[..4].try_into().ok()?) as f64,
        DataType::Real64 => f64::from_le_bytes(b[..8].try_into().ok()?),
        t if t.integer() => {
            let mut buf = [0u8; 16];
            buf[..b.len()].copy_from_slice(&b);
            let mut v = i128::from_le_bytes(buf);
            if t.signed() {
                let bits = (b.len() * 8) as u32;
                v = (v << (128 - bits)) >> (128 - bits);
            }
            v as f64
        }
        _ => return None,
    })
}

fn read_attrs(
    cx: &mut Ctx,
    si: usize,
    dtype: DataType,
    code: ObjectCode,
) -> Result<Attrs, EdsError> {
    let s = &cx.sections[si];
    let (line, name) = (s.line, s.name);
    let access = match s.get("AccessType") {
        Some(e) if !e.value.is_empty() => Access::from_eds(e.value).ok_or_else(|| {
            key_err(
                s,
                e,
                format!(
                    "'{}' is not an access type (ro, wo, rw, rwr, rww, const)",
                    e.value
                ),
            )
        })?,
        _ if dtype == DataType::Domain || code == ObjectCode::Domain => {
            cx.warn(
                line,
                Some(name),
                Some("AccessType"),
                "DOMAIN without AccessType: read as rw (Lely)",
            );
            Access::Rw
        }
        _ => {
            return Err(err(
                line,
                Some(name),
                Some("AccessType"),
                "AccessType is missing",
            ))
        }
    };
    let s = &cx.sections[si];
    // PDOMapping and ObjFlags are read past as Lely reads them (strtoul: a word is 0, any
    // non-zero number is set); python canopen reads PDOMapping with bool(int()), ignores
    // ObjFlags
    let mut notes: Vec<(usize, &str, String)> = Vec::new();
    let pdo_mapping = match s.get("PDOMapping") {
        Some(e) if !e.value.is_empty() => match parse_plain_uint(e.value) {
            Ok(v) if v <= 1 => v == 1,
            Ok(v) => {
                notes.push((e.line, e.key, format!("PDOMapping is 0 or 1, not {v}: read as 1 (mappable), as python canopen and Lely read it")));
                true
            }
            Err(_) => {
                let yes = matches!(e.value.to_ascii_lowercase().as_str(), "true" | "yes");
                notes.push((
                    e.line,
                    e.key,
                    format!(
                        "'{}' is not 0 or 1: read as {} ({})",
                        e.value,
                        yes as u8,
                        if yes {
                            "the word says so"
                        } else {
                            "not mappable, as Lely reads a word"
                        }
                    ),
                ));
                yes
            }
        },
        _ => false,
    };
    let obj_flags = match s.get("ObjFlags") {
        Some(e) if !e.value.is_empty() => match parse_plain_uint(e.value)
            .ok()
            .and_then(|v| u32::try_from(v).ok())
        {
            Some(v) => v,
            None => {
                notes.push((e.line, e.key, format!("'{}' is not a 32-bit number (CiA 306: bit 0 refuse write on download, bit 1 refuse read on scan): read as 0, as Lely reads it (python canopen ignores ObjFlags)", clip(e.value))));
                0
            }
        },
        _ => 0,
    };
    for (l, k, why) in notes {
        cx.warn(l, Some(name), Some(k), why);
    }
    let numeric_type = dtype.integer() || dtype.float();
    let mut low = None;
    let mut high = None;
    if numeric_type {
        low = value_key(cx, si, "LowLimit", dtype)?;
        high = value_key(cx, si, "HighLimit", dtype)?;
    } else {
        for key in ["LowLimit", "HighLimit"] {
            let s = &cx.sections[si];
            if let Some(e) = s.get(key).filter(|e| !e.value.is_empty()) {
                let (l, n, k) = (e.line, s.name, e.key);
                cx.warn(
                    l,
                    Some(n),
                    Some(k),
                    format!("a {} has no limits; ignored", dtype.name()),
                );
            }
        }
    }
    let default = value_key(cx, si, "DefaultValue", dtype)?;
    let parameter_value = value_key(cx, si, "ParameterValue", dtype)?;
    let s = &cx.sections[si];
    let mut upload_file = text_of(Some(s), "UploadFile").filter(|t| !t.is_empty());
    let mut download_file = text_of(Some(s), "DownloadFile").filter(|t| !t.is_empty());
    if dtype != DataType::Domain && (upload_file.is_some() || download_file.is_some()) {
        cx.warn(
            line,
            Some(name),
            None,
            "UploadFile/DownloadFile on a type other than DOMAIN; ignored",
        );
        upload_file = None;
        download_file = None;
    }

    // limits
    if let (Some(l), Some(h)) = (&low, &high) {
        let at = |id| (numeric(l, dtype, id), numeric(h, dtype, id));
        let bad: Vec<u8> = [1u8, 127]
            .into_iter()
            .filter(|&id| matches!(at(id), (Some(a), Some(b)) if a > b))
            .collect();
        if bad.len() == 2 {
            let s = &cx.sections[si];
            let e = s.get("LowLimit").expect("read above");
            return Err(key_err(s, e, "LowLimit is greater than HighLimit"));
        } else if bad.len() == 1 {
            cx.warn(
                line,
                Some(name),
                Some("LowLimit"),
                format!("LowLimit is greater than HighLimit at node ID {}", bad[0]),
            );
        }
    }
    for (key, v) in [
        ("DefaultValue", &default),
        ("ParameterValue", &parameter_value),
    ] {
        let Some(v) = v else { continue };
        for id in [1u8, 127] {
            let x = numeric(v, dtype, id);
            let below = matches!((x, low.as_ref().and_then(|l| numeric(l, dtype, id))), (Some(x), Some(l)) if x < l);
            let above = matches!((x, high.as_ref().and_then(|h| numeric(h, dtype, id))), (Some(x), Some(h)) if x > h);
            if below || above {
                let s = &cx.sections[si];
                let l = s.get(key).map_or(line, |e| e.line);
                cx.warn(
                    l,
                    Some(name),
                    Some(key),
                    format!(
                        "{key} is {} the limits{}",
                        if below { "below" } else { "above" },
                        if v.uses_node_id() {
                            format!(" at node ID {id}")
                        } else {
                            String::new()
                        }
                    ),
                );
                break;
            }
        }
    }
    Ok(Attrs {
        data_type: dtype,
        access,
        pdo_mapping,
        default,
        parameter_value,
        low,
        high,
        obj_flags,
        upload_file,
        download_file,
    })
}

fn sub_from(
    attrs: Attrs,
    sub: u8,
    name: String,
    denotation: Option<String>,
    line: usize,
) -> EdsSub {
    EdsSub {
        sub,
        name,
        data_type: attrs.data_type,
        access: attrs.access,
        pdo_mapping: attrs.pdo_mapping,
        default: attrs.default,
        parameter_value: attrs.parameter_value,
        low: attrs.low,
        high: attrs.high,
        denotation,
        obj_flags: attrs.obj_flags,
        upload_file: attrs.upload_file,
        download_file: attrs.download_file,
        line,
    }
}

fn name_of(s: &Section) -> Result<String, EdsError> {
    match s.get("ParameterName") {
        Some(e) if !e.value.is_empty() => Ok(e.value.to_string()),
        _ => Err(err(
            s.line,
            Some(s.name),
            Some("ParameterName"),
            "ParameterName is missing",
        )),
    }
}

fn read_object(
    cx: &mut Ctx,
    index: u16,
    si: usize,
    subs: &[(u8, usize)],
    structs: &HashSet<u16>,
) -> Result<EdsObject, EdsError> {
    let s = &cx.sections[si];
    let (line, sname) = (s.line, s.name);
    let name = name_of(s)?;
    let denotation = text_of(Some(s), "Denotation").filter(|t| !t.is_empty());
    let code = match s.get("ObjectType") {
        Some(e) if !e.value.is_empty() => {
            let v = parse_plain_uint(e.value).map_err(|r| key_err(s, e, r))?;
            u8::try_from(v)
                .ok()
                .and_then(ObjectCode::from_code)
                .ok_or_else(|| {
                    key_err(s, e, format!("object type {v} is none of NULL 0, DOMAIN 2, DEFTYPE 5, DEFSTRUCT 6, VAR 7, ARRAY 8, RECORD 9"))
                })?
        }
        _ => ObjectCode::Var,
    };
    let object_links = read_links(cx, index)?;

    if !code.structured() {
        let s = &cx.sections[si];
        let dtype = match s.get("DataType").filter(|e| !e.value.is_empty()) {
            Some(e) => data_type_of(s, e, structs)?,
            None if code == ObjectCode::Domain => DataType::Domain,
            None => {
                return Err(err(
                    line,
                    Some(sname),
                    Some("DataType"),
                    "DataType is missing",
                ))
            }
        };
        if let Some(&(_, sub_si)) = subs.first() {
            let ss = &cx.sections[sub_si];
            let (l, n) = (ss.line, ss.name);
            cx.warn(l, Some(n), None, format!("sub-index section of a {:?} object; ignored (a VAR's attributes are in [{:04X}])", code, index));
        }
        for key in ["SubNumber", "CompactSubObj"] {
            let s = &cx.sections[si];
            if let Some(e) = s
                .get(key)
                .filter(|e| parse_plain_uint(e.value).is_ok_and(|v| v != 0))
            {
                let (l, k) = (e.line, e.key);
                cx.warn(
                    l,
                    Some(sname),
                    Some(k),
                    format!("{key} on a {code:?} object; ignored"),
                );
            }
        }
        let attrs = read_attrs(cx, si, dtype, code)?;
        let sub = sub_from(attrs, 0, name.clone(), denotation.clone(), line);
        return Ok(EdsObject {
            index,
            name,
            denotation,
            code,
            data_type: Some(dtype),
            subs: vec![sub],
            object_links,
            line,
        });
    }

    // DEFSTRUCT / ARRAY / RECORD
    let s = &cx.sections[si];
    let sub_number = match s.get("SubNumber").filter(|e| !e.value.is_empty()) {
        Some(e) => {
            let v = parse_plain_uint(e.value).map_err(|r| key_err(s, e, r))?;
            if v > 255 {
                return Err(key_err(s, e, format!("SubNumber {v} is more than 255")));
            }
            Some((v as usize, e.line))
        }
        None => None,
    }
    .filter(|(v, _)| *v != 0);
    let compact = match s.get("CompactSubObj").filter(|e| !e.value.is_empty()) {
        Some(e) => {
            let v = parse_plain_uint(e.value).map_err(|r| key_err(s, e, r))?;
            if v > 254 {
                return Err(key_err(
                    s,
                    e,
                    format!("CompactSubObj {v} is more than 254 sub-indices"),
                ));
            }
            Some((v as u8, e.line))
        }
        None => None,
    }
    .filter(|(v, _)| *v != 0);
    let data_type = match s.get("DataType").filter(|e| !e.value.is_empty()) {
        Some(e) if compact.is_some() => Some(data_type_of(s, e, structs)?),
        Some(e) => parse_plain_uint(e.value)
            .ok()
            .and_then(|c| u16::try_from(c).ok())
            .and_then(DataType::from_code),
        None => None,
    };

    let mut out_subs: Vec<EdsSub> = Vec::new();
    if let Some((n, cline)) = compact {
        if let Some((_, l)) = sub_number {
            return Err(err(
                l,
                Some(sname),
                Some("SubNumber"),
                "both SubNumber and CompactSubObj given (Lely and dcfchk refuse this)",
            ));
        }
        if let Some(&(_, sub_si)) = subs.first() {
            let ss = &cx.sections[sub_si];
            return Err(err(
                ss.line,
                Some(ss.name),
                None,
                format!("sub-index section of an object with CompactSubObj (line {cline})"),
            ));
        }
        let Some(dtype) = data_type else {
            return Err(err(
                line,
                Some(sname),
                Some("DataType"),
                "DataType is missing (CompactSubObj needs the sub-indices' type)",
            ));
        };
        let attrs = read_attrs(cx, si, dtype, code)?;
        let names = read_compact_names(cx, index, n)?;
        let values = read_compact_values(cx, index, n, dtype)?;
        out_subs.reserve(n as usize + 1);
        out_subs.push(EdsSub {
            sub: 0,
            name: "NrOfObjects".into(),
            data_type: DataType::U8,
            access: Access::Ro,
            pdo_mapping: false,
            default: Some(ValueExpr::Integer(n as i128)),
            parameter_value: None,
            low: None,
            high: None,
            denotation: None,
            obj_flags: 0,
            upload_file: None,
            download_file: None,
            line,
        });
        for i in 1..=n {
            let sub_name = names[i as usize]
                .clone()
                .unwrap_or_else(|| format!("{name}{i}"));
            out_subs.push(EdsSub {
                sub: i,
                name: sub_name,
                data_type: dtype,
                access: attrs.access,
                pdo_mapping: attrs.pdo_mapping,
                default: attrs.default.clone(),
                parameter_value: values[i as usize]
                    .clone()
                    .or_else(|| attrs.parameter_value.clone()),
                low: attrs.low.clone(),
                high: attrs.high.clone(),
                denotation: None,
                obj_flags: attrs.obj_flags,
                upload_file: None,
                download_file: None,
                line,
            });
        }
    } else {
        for kind in [Kind::Names(index), Kind::Values(index)] {
            if let Some(ss) = cx.section(kind) {
                let (l, n) = (ss.line, ss.name);
                cx.warn(
                    l,
                    Some(n),
                    None,
                    format!("[{sname}] has no CompactSubObj; this section is ignored"),
                );
            }
        }
        match sub_number {
            Some((n, l)) if n > subs.len() => {
                cx.warn(
                    l,
                    Some(sname),
                    Some("SubNumber"),
                    format!(
                        "SubNumber={n} but only {} sub-index sections are present; those are read (Lely and python canopen read them alike)",
                        subs.len()
                    ),
                );
            }
            Some((n, l)) if n < subs.len() => {
                let listed: Vec<String> = subs.iter().map(|(s, _)| format!("{s:X}")).collect();
                cx.warn(
                    l,
                    Some(sname),
                    Some("SubNumber"),
                    format!(
                        "SubNumber={n} but {} sub-index sections are present (sub {}): all are read, as python canopen reads them (Lely reads the first {n})",
                        subs.len(),
                        listed.join(", ")
                    ),
                );
            }
            None if subs.is_empty() => {
                return Err(err(line, Some(sname), None, format!("{code:?} object with neither SubNumber nor CompactSubObj nor sub-index sections")));
            }
            None => {
                cx.warn(
                    line,
                    Some(sname),
                    Some("SubNumber"),
                    format!(
                        "SubNumber missing; the {} sub-index sections present are read",
                        subs.len()
                    ),
                );
            }
            _ => {}
        }
        for &(sub, sub_si) in subs {
            let ss = &cx.sections[sub_si];
            let sub_line = ss.line;
            let sub_name = name_of(ss)?;
            let sub_den = text_of(Some(ss), "Denotation").filter(|t| !t.is_empty());
            // a sub-index is a VAR (0x7); tools write DOMAIN (0x2) for a DOMAIN sub-index
            if let Some(e) = ss
                .get("ObjectType")
                .filter(|e| !matches!(parse_plain_uint(e.value), Ok(7) | Ok(2)))
            {
                let (l, n, k) = (e.line, ss.name, e.key);
                cx.warn(
                    l,
                    Some(n),
                    Some(k),
                    "a sub-index is a VAR (ObjectType=0x7); the value is ignored",
                );
            }
            let ss = &cx.sections[sub_si];
            let dtype = match ss.get("DataType").filter(|e| !e.value.is_empty()) {
                Some(e) => data_type_of(ss, e, structs)?,
                None => {
                    return Err(err(
                        sub_line,
                        Some(ss.name),
                        Some("DataType"),
                        "DataType is missing",
                    ))
                }
            };
            let attrs = read_attrs(cx, sub_si, dtype, ObjectCode::Var)?;
            out_subs.push(sub_from(attrs, sub, sub_name, sub_den, sub_line));
        }
        if let Some(s0) = out_subs.first().filter(|s| s.sub == 0) {
            if s0.data_type != DataType::U8 {
                let (l, n) = (s0.line, cx.sections[subs[0].1].name);
                cx.warn(
                    l,
                    Some(n),
                    Some("DataType"),
                    "sub-index 0 of an ARRAY/RECORD should be UNSIGNED8 (highest sub-index)",
                );
            }
        } else {
            cx.warn(
                line,
                Some(sname),
                None,
                "no sub-index 0 (highest sub-index supported)",
            );
        }
    }
    Ok(EdsObject {
        index,
        name,
        denotation,
        code,
        data_type,
        subs: out_subs,
        object_links,
        line,
    })
}

/// `[IIIIName]`: names of CompactSubObj sub-indices (slot i for sub i).
fn read_compact_names(cx: &mut Ctx, index: u16, n: u8) -> Result<Vec<Option<String>>, EdsError> {
    let mut names = vec![None; n as usize + 1];
    let Some(&si) = cx.by_kind.get(&Kind::Names(index)) else {
        return Ok(names);
    };
    let s = &cx.sections[si];
    let mut count = 0usize;
    for e in &s.entries {
        if e.key.eq_ignore_ascii_case("NrOfEntries") {
            continue;
        }
        let sub = parse_plain_uint(e.key)
            .map_err(|_| key_err(s, e, "a key here is a sub-index number or NrOfEntries"))?;
        if sub == 0 || sub > n as u128 {
            return Err(key_err(
                s,
                e,
                format!("names sub-index {sub}, but CompactSubObj={n}"),
            ));
        }
        names[sub as usize] = Some(e.value.to_string());
        count += 1;
    }
    let nr = num_key(&mut cx.warnings, Some(s), "NrOfEntries", 255);
    if nr.is_some_and(|v| v as usize != count) {
        let (l, name) = (s.line, s.name);
        cx.warn(
            l,
            Some(name),
            Some("NrOfEntries"),
            format!("NrOfEntries={} but {count} entries", nr.unwrap_or(0)),
        );
    }
    Ok(names)
}

/// `[IIIIValue]`: ParameterValues of CompactSubObj sub-indices.
fn read_compact_values(
    cx: &mut Ctx,
    index: u16,
    n: u8,
    dtype: DataType,
) -> Result<Vec<Option<ValueExpr>>, EdsError> {
    let mut values = vec![None; n as usize + 1];
    let Some(&si) = cx.by_kind.get(&Kind::Values(index)) else {
        return Ok(values);
    };
    let s = &cx.sections[si];
    let mut count = 0usize;
    for e in &s.entries {
        if e.key.eq_ignore_ascii_case("NrOfEntries") {
            continue;
        }
        let sub = parse_plain_uint(e.key)
            .map_err(|_| key_err(s, e, "a key here is a sub-index number or NrOfEntries"))?;
        if sub == 0 || sub > n as u128 {
            return Err(key_err(
                s,
                e,
                format!("gives sub-index {sub} a value, but CompactSubObj={n}"),
            ));
        }
        let v = ValueExpr::parse(e.value, dtype).map_err(|r| key_err(s, e, r))?;
        if let Some(v) = &v {
            check_value(s, e, v, dtype)?;
        }
        values[sub as usize] = v;
        count += 1;
    }
    let nr = num_key(&mut cx.warnings, Some(s), "NrOfEntries", 255);
    if nr.is_some_and(|v| v as usize != count) {
        let (l, name) = (s.line, s.name);
        cx.warn(
            l,
            Some(name),
            Some("NrOfEntries"),
            format!("NrOfEntries={} but {count} entries", nr.unwrap_or(0)),
        );
    }
    Ok(values)
}

fn read_links(cx: &mut Ctx, index: u16) -> Result<Vec<u16>, EdsError> {
    let Some(&si) = cx.by_kind.get(&Kind::Links(index)) else {
        return Ok(Vec::new());
    };
    let s = &cx.sections[si];
    let n = num_key(&mut cx.warnings, Some(s), "ObjectLinks", 65_535).unwrap_or(0) as usize;
    let mut links = Vec::with_capacity(n.min(1024));
    for e in &s.entries {
        if e.key.eq_ignore_ascii_case("ObjectLinks") {
            continue;
        }
        let i = parse_plain_uint(e.key)
            .map_err(|_| key_err(s, e, "a key here is a link number or ObjectLinks"))?;
        if i == 0 || i as usize > n {
            return Err(key_err(s, e, format!("link {i} beyond ObjectLinks={n}")));
        }
        let v = parse_plain_uint(e.value).map_err(|r| key_err(s, e, r))?;
        let v = u16::try_from(v)
            .map_err(|_| key_err(s, e, format!("0x{v:X} is not an object index")))?;
        links.push(v);
    }
    if links.len() != n {
        let (l, name) = (s.line, s.name);
        cx.warn(
            l,
            Some(name),
            Some("ObjectLinks"),
            format!("ObjectLinks={n} but {} links", links.len()),
        );
    }
    Ok(links)
}

/// The object lists against the object sections. Python canopen reads every object section
/// and ignores the lists, so a list that does not match the sections is read past with a
/// warning: an entry without its section, a missing entry number, a missing count.
fn check_lists(cx: &mut Ctx, objects: &[(u16, usize)]) -> Result<(), EdsError> {
    let mut listed: HashMap<u16, (usize, usize)> = HashMap::new(); // index -> (list section, line)
    for list in 0..3u8 {
        let Some(&si) = cx.by_kind.get(&Kind::List(list)) else {
            continue;
        };
        let s = &cx.sections[si];
        let name = s.name;
        let mut notes: Vec<(usize, Option<&str>, String)> = Vec::new();
        let counted = num_key(&mut cx.warnings, Some(s), "SupportedObjects", 65_535);
        let numbered = |e: &&Entry| e.key.parse::<usize>().is_ok_and(|i| i > 0);
        let n = match counted {
            Some(n) => n as usize,
            None => {
                let n = s
                    .entries
                    .iter()
                    .filter(numbered)
                    .filter_map(|e| e.key.parse::<usize>().ok())
                    .max()
                    .unwrap_or(0);
                notes.push((
                    s.line,
                    Some("SupportedObjects"),
                    format!("SupportedObjects is missing or unreadable: the {n} numbered entries are read"),
                ));
                n
            }
        };
        let mut dups = Vec::new();
        for i in 1..=n {
            let Some(e) = s.get(&i.to_string()) else {
                notes.push((
                    s.line,
                    None,
                    format!("SupportedObjects={n} but entry {i} is missing; the entries present are read"),
                ));
                continue;
            };
            let index = match parse_plain_uint(e.value) {
                Ok(v) => match u16::try_from(v).ok().filter(|&x| x != 0) {
                    Some(x) => x,
                    None => {
                        notes.push((
                            e.line,
                            Some(e.key),
                            format!("0x{v:X} is not an object index; entry ignored"),
                        ));
                        continue;
                    }
                },
                Err(r) => {
                    notes.push((e.line, Some(e.key), format!("{r}; entry ignored")));
                    continue;
                }
            };
            if !cx.by_kind.contains_key(&Kind::Object(index)) {
                notes.push((
                    e.line,
                    Some(e.key),
                    format!("object 0x{index:04X} is listed but has no section [{index:04X}]; entry ignored (python canopen reads the sections, not the lists)"),
                ));
                continue;
            }
            if let Some(&(first_si, first_line)) = listed.get(&index) {
                dups.push((e.line, e.key, index, cx.sections[first_si].name, first_line));
            } else {
                listed.insert(index, (si, e.line));
            }
        }
        for e in s.entries.iter().filter(|e| {
            !e.key.eq_ignore_ascii_case("SupportedObjects")
                && e.key.parse::<usize>().map_or(true, |i| i == 0 || i > n)
        }) {
            notes.push((
                e.line,
                Some(e.key),
                format!("entry beyond SupportedObjects={n}; ignored"),
            ));
        }
        for (line, key, index, first, first_line) in dups {
            notes.push((
                line,
                Some(key),
                format!(
                    "object 0x{index:04X} listed twice (also in [{first}] at line {first_line})"
                ),
            ));
        }
        for (line, key, why) in notes {
            cx.warn(line, Some(name), key, why);
        }
    }
    let mut unlisted = Vec::new();
    for &(index, si) in objects {
        if !listed.contains_key(&index) {
            unlisted.push((cx.sections[si].line, cx.sections[si].name));
        }
    }
    for (line, name) in unlisted {
        cx.warn(line, Some(name), None, "object not named in [MandatoryObjects], [OptionalObjects] or [ManufacturerObjects]; kept");
    }
    Ok(())
}

/// One warning per unknown key name in object and sub-index sections.
fn warn_unknown_keys(cx: &mut Ctx) {
    let mut seen: HashSet<String> = HashSet::new();
    let mut out = Vec::new();
    let mut kinds: Vec<(usize, Kind)> = cx.by_kind.iter().map(|(k, &i)| (i, *k)).collect();
    kinds.sort_unstable_by_key(|(i, _)| *i);
    for (si, kind) in kinds {
        if !matches!(kind, Kind::Object(_) | Kind::Sub(..)) {
            continue;
        }
        let s = &cx.sections[si];
        for e in &s.entries {
            let lc = e.key.to_ascii_lowercase();
            if !OBJECT_KEYS.contains(&lc.as_str()) && seen.insert(lc) {
                out.push((e.line, s.name, e.key));
            }
        }
    }
    for (line, name, key) in out {
        cx.warn(
            line,
            Some(name),
            Some(key),
            "key not defined by CiA 306; ignored (first of its kind)",
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers() {
        let p = |t: &str| parse_number(t).unwrap();
        assert_eq!(p("10"), ValueExpr::Integer(10));
        assert_eq!(p("010"), ValueExpr::Integer(8));
        assert_eq!(p("0"), ValueExpr::Integer(0));
        assert_eq!(p("0x1F"), ValueExpr::Hex(0x1F));
        assert_eq!(p("-0x10"), ValueExpr::Integer(-16));
        assert_eq!(p("-5"), ValueExpr::Integer(-5));
        assert_eq!(p("$NODEID"), ValueExpr::NodeIdPlus(0));
        assert_eq!(p("$NODEID+0x180"), ValueExpr::NodeIdPlus(0x180));
        assert_eq!(p("$NodeID + 0x80"), ValueExpr::NodeIdPlus(0x80));
        assert_eq!(p("0x200+$nodeid"), ValueExpr::NodeIdPlus(0x200));
        assert_eq!(p("$NODEID-1"), ValueExpr::NodeIdPlus(-1));
        assert_eq!(p("30.0"), ValueExpr::Decimal(30.0));
        assert_eq!(p("-1e-3"), ValueExpr::Decimal(-1e-3));
        assert_eq!(p(strip_hash_comment("12 # twelve")), ValueExpr::Integer(12));
        assert_eq!(p("08"), ValueExpr::Integer(8)); // not octal: the decimal (warned)
        for bad in [
            "0x",
            "12a",
            "$NODEID+$NODEID",
            "-$NODEID",
            "1.2.3",
            "0b101",
            "$NODEID*2",
        ] {
            assert!(parse_number(strip_hash_comment(bad)).is_err(), "{bad}");
        }
    }
}
