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
//!
//! The writer is [`export`] ([`EdsMeta`], [`Real32Notation`]): an EDS generated from an
//! [`ObjectDictionary`](super::ObjectDictionary).

mod check;
mod export;
mod lex;
mod object;
mod parse;
mod value;

use std::fmt;

use super::types::{Access, DataType};

pub use export::{export, objects_json, objects_markdown, EdsMeta, Real32Notation};
pub use parse::parse;
pub use value::{decode_text, ValueExpr};

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
