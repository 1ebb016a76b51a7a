//! EDS export (CiA 306), generated from an [`ObjectDictionary`]. Allocates: not for the RT
//! path.

use core::fmt::Write;

use crate::od::{DataType, DefaultValue, Entry, ObjType, ObjectDictionary};

/// How REAL32 DefaultValues are written. EDS readers disagree: Lely's dcf-tools (dcfchk,
/// dcfgen; what ros2_canopen runs on) read a REAL32 value as the integer of its IEEE 754 bits
/// and reject a decimal; python canopen (2.4.1, `float(value)`) reads only a decimal and
/// leaves a hex default as None. No text is read as the same number by both.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Real32Notation {
    /// The IEEE 754 bit pattern in hex, e.g. kv_per_s 30.0 = `0x41F00000` (Lely's reading).
    #[default]
    Bits,
    /// A decimal with a point or an exponent, e.g. `30.0` (python canopen's reading).
    Decimal,
}

/// What a generated EDS says about itself and the device it describes. The protocol crate has
/// no clock: the caller gives the creation time and date (CiA 306 forms `hh:mmAM`,
/// `MM-DD-YYYY`).
#[derive(Clone, Debug)]
pub struct EdsMeta<'a> {
    /// `[FileInfo]` FileName.
    pub file_name: &'a str,
    /// `[FileInfo]` Description.
    pub description: &'a str,
    /// `[FileInfo]` CreatedBy.
    pub created_by: &'a str,
    /// `[FileInfo]` CreationTime, `hh:mmAM`.
    pub time: &'a str,
    /// `[FileInfo]` CreationDate, `MM-DD-YYYY`.
    pub date: &'a str,
    /// Node ID written to `[DeviceComissioning]` (`None`: a generic EDS, no such section);
    /// LSS_SerialNumber there is the identity's serial number (0x1018:4).
    pub node_id: Option<u8>,
    /// Notation of REAL32 DefaultValues.
    pub real32: Real32Notation,
}

impl Default for EdsMeta<'_> {
    fn default() -> Self {
        EdsMeta {
            file_name: "drive-emulator.eds",
            description: "Emulated CiA 402 servo drive (generated from the object dictionary)",
            created_by: "drive-protocol",
            time: "12:00AM",
            date: "01-01-2025",
            node_id: None,
            real32: Real32Notation::Bits,
        }
    }
}

/// A mapping entry (index, sub-index, length) is written in hex as CiA 306 shows it.
fn is_mapping_entry(e: &Entry) -> bool {
    let pdo_map = (0x1600..=0x17FF).contains(&e.index) || (0x1A00..=0x1BFF).contains(&e.index);
    pdo_map && e.sub > 0
}

/// The text of a raw value of `e`'s type.
fn fmt_raw(e: &Entry, raw: u64, real32: Real32Notation) -> String {
    match e.dtype {
        DataType::Real32 => match real32 {
            Real32Notation::Bits => format!("0x{:08X}", raw as u32),
            // Debug: shortest round-trip text, always with a point or an exponent
            Real32Notation::Decimal => format!("{:?}", f32::from_bits(raw as u32)),
        },
        DataType::Real64 => match real32 {
            Real32Notation::Bits => format!("0x{raw:016X}"),
            Real32Notation::Decimal => format!("{:?}", f64::from_bits(raw)),
        },
        _ if is_mapping_entry(e) => format!("0x{:08X}", raw as u32),
        t if t.signed() => format!("{}", raw as i64),
        _ => format!("0x{raw:X}"),
    }
}

/// Bytes as CiA 306 writes an OCTET_STRING or DOMAIN value: hex digits.
fn hex_bytes(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02X}")).collect()
}

/// The DefaultValue text of an entry; `value` overrides a numeric default (a handler
/// object's current value, as an SDO read returns it).
fn default_text(e: &Entry, value: Option<u64>, real32: Real32Notation) -> String {
    match (&e.default, value) {
        // The base is kept as 64-bit two's complement: `$NODEID-1` is 0xFFFF_FFFF_FFFF_FFFF.
        (DefaultValue::NodeId(b), None) => match *b as i64 {
            o if o < 0 => format!("$NODEID-0x{:X}", o.unsigned_abs()),
            o => format!("$NODEID+0x{o:X}"),
        },
        (DefaultValue::Bytes(b), _) => match e.dtype {
            DataType::VisibleString => String::from_utf8_lossy(b).into_owned(),
            _ => hex_bytes(b),
        },
        (d, v) => {
            let raw = v.unwrap_or(match d {
                DefaultValue::Value(x) => *x,
                _ => 0,
            });
            fmt_raw(e, raw, real32)
        }
    }
}

fn write_entry(s: &mut String, e: &Entry, value: Option<u64>, meta: &EdsMeta) {
    let _ = writeln!(s, "ParameterName={}", e.name);
    let _ = writeln!(
        s,
        "ObjectType=0x{}",
        if e.dtype == DataType::Domain && e.otype == ObjType::Var {
            2
        } else {
            7
        }
    );
    let _ = writeln!(s, "DataType=0x{:04X}", e.dtype.code());
    let _ = writeln!(s, "AccessType={}", e.access.eds());
    let _ = writeln!(s, "DefaultValue={}", default_text(e, value, meta.real32));
    if let Some(l) = e.low {
        let _ = writeln!(s, "LowLimit={}", fmt_limit(e, l, meta.real32));
    }
    if let Some(h) = e.high {
        let _ = writeln!(s, "HighLimit={}", fmt_limit(e, h, meta.real32));
    }
    let _ = writeln!(s, "PDOMapping={}", e.pdo as u8);
    s.push('\n');
}

fn fmt_limit(e: &Entry, raw: u64, real32: Real32Notation) -> String {
    match e.number(raw) {
        Some(crate::od::Number::Int(v)) => v.to_string(),
        _ => fmt_raw(e, raw, real32),
    }
}

fn node_identity(od: &ObjectDictionary, sub: u8, node_id: u8) -> u64 {
    od.get(0x1018, sub)
        .map_or(0, |(_, e)| e.default_raw(node_id))
}

/// The EDS text of a dictionary. `value_of` gives the current value of the entries a
/// handler keeps (their DefaultValue is what the drive answers to an SDO read); entries it
/// returns `None` for keep the dictionary's default. `node_id` resolves nothing (`$NODEID`
/// stays in the text); `meta.node_id` adds `[DeviceComissioning]`.
pub fn export(
    od: &ObjectDictionary,
    meta: &EdsMeta,
    value_of: &mut dyn FnMut(&Entry) -> Option<u64>,
) -> String {
    let mut s = String::with_capacity(64 * 1024);
    let _ = writeln!(
        s,
        "[FileInfo]\nFileName={}\nFileVersion=1\nFileRevision=0\nEDSVersion=4.0",
        meta.file_name
    );
    let _ = writeln!(s, "Description={}", meta.description);
    let _ = writeln!(
        s,
        "CreationTime={t}\nCreationDate={d}\nCreatedBy={by}\nModificationTime={t}\n\
         ModificationDate={d}\nModifiedBy={by}\n",
        t = meta.time,
        d = meta.date,
        by = meta.created_by
    );
    let dev = &od.device;
    let id_for_info = meta.node_id.unwrap_or(0);
    let _ = writeln!(
        s,
        "[DeviceInfo]\nVendorName={}\nVendorNumber=0x{:X}\nProductName={}\nProductNumber=0x{:X}\n\
         RevisionNumber=0x{:X}\nOrderCode={}",
        dev.vendor_name,
        node_identity(od, 1, id_for_info),
        dev.product_name,
        node_identity(od, 2, id_for_info),
        node_identity(od, 3, id_for_info),
        dev.order_code
    );
    for b in [10u16, 20, 50, 125, 250, 500, 800, 1000] {
        let _ = writeln!(s, "BaudRate_{b}={}", dev.baud_rates_kbit.contains(&b) as u8);
    }
    let rx = (0x1400..=0x15FFu16).filter(|&i| od.has_index(i)).count();
    let tx = (0x1800..=0x19FFu16).filter(|&i| od.has_index(i)).count();
    let _ = writeln!(
        s,
        "SimpleBootUpMaster=0\nSimpleBootUpSlave=1\nGranularity={}\nDynamicChannelsSupported=0\n\
         GroupMessaging=0\nNrOfRXPDO={rx}\nNrOfTXPDO={tx}\nLSS_Supported={}\n",
        dev.granularity, dev.lss_supported as u8
    );
    if let Some(id) = meta.node_id {
        let _ = writeln!(
            s,
            "[DeviceComissioning]\nNodeID={id}\nNodeName=drive-emu node {id}\nBaudrate=1000\n\
             NetNumber=1\nNetworkName=drive-emu\nCANopenManager=0\n\
             LSS_SerialNumber={}\n",
            node_identity(od, 4, id)
        );
    }
    s.push_str("[DummyUsage]\n");
    for t in 1..=7 {
        let _ = writeln!(s, "Dummy000{t}={}", dev.dummy_usage[t] as u8);
    }
    s.push('\n');

    let indices = od.indices();
    let mandatory: Vec<u16> = [0x1000u16, 0x1001, 0x1018]
        .into_iter()
        .filter(|i| indices.contains(i))
        .collect();
    let optional: Vec<u16> = indices
        .iter()
        .copied()
        .filter(|i| !mandatory.contains(i) && !(0x2000..0x6000).contains(i))
        .collect();
    let manufacturer: Vec<u16> = indices
        .iter()
        .copied()
        .filter(|i| (0x2000..0x6000).contains(i))
        .collect();
    for (section, list) in [
        ("MandatoryObjects", &mandatory),
        ("OptionalObjects", &optional),
        ("ManufacturerObjects", &manufacturer),
    ] {
        let _ = writeln!(s, "[{section}]\nSupportedObjects={}", list.len());
        for (i, x) in list.iter().enumerate() {
            let _ = writeln!(s, "{}=0x{x:04X}", i + 1);
        }
        s.push('\n');
    }
    for &index in &indices {
        let rows: Vec<&Entry> = od.object(index).map(|(_, e)| e).collect();
        let first = rows[0];
        let _ = writeln!(s, "[{index:04X}]");
        if first.otype == ObjType::Var {
            write_entry(&mut s, first, value_of(first), meta);
        } else {
            let _ = writeln!(s, "ParameterName={}", first.parent);
            let _ = writeln!(s, "ObjectType=0x{}", first.otype.code());
            let _ = writeln!(s, "SubNumber={}", rows.len());
            s.push('\n');
            for e in rows {
                let _ = writeln!(s, "[{index:04X}sub{:X}]", e.sub);
                write_entry(&mut s, e, value_of(e), meta);
            }
        }
    }
    s
}

/// The object list as JSON (index, sub, data type, access) for the EDS check.
pub fn objects_json(od: &ObjectDictionary) -> String {
    let mut s = String::from("[");
    for (i, (_, e)) in od.iter().enumerate() {
        if i > 0 {
            s.push(',');
        }
        let _ = write!(
            s,
            "{{\"index\":{},\"sub\":{},\"otype\":\"{}\",\"data_type\":{},\"access\":\"{}\",\"pdo\":{}}}",
            e.index,
            e.sub,
            match e.otype {
                ObjType::Var => "var",
                ObjType::Array => "array",
                ObjType::Record => "record",
            },
            e.dtype.code(),
            e.access.eds(),
            e.pdo
        );
    }
    s.push(']');
    s
}

/// A Markdown list of every object (docs/objects.md is this text for the emulator's default
/// drive; a test keeps it current). `value_of` as for [`export`].
pub fn objects_markdown(
    od: &ObjectDictionary,
    intro: &str,
    value_of: &mut dyn FnMut(&Entry) -> Option<u64>,
) -> String {
    let mut s = format!(
        "# Object dictionary\n\n{intro}\n\n| Index | Sub | Name | Type | Access | PDO | Default | Limits |\n\
         |---|---|---|---|---|---|---|---|\n"
    );
    for (_, e) in od.iter() {
        let name = if e.otype == ObjType::Var {
            e.name.to_string()
        } else {
            format!("{}: {}", e.parent, e.name)
        };
        let default = match &e.default {
            DefaultValue::Bytes(b) if e.dtype == DataType::VisibleString => {
                format!("\"{}\"", String::from_utf8_lossy(b))
            }
            _ => default_text(e, value_of(e), Real32Notation::Decimal),
        };
        let limits = match (e.low, e.high) {
            (Some(l), Some(h)) => format!(
                "{}..={}",
                fmt_limit(e, l, Real32Notation::Decimal),
                fmt_limit(e, h, Real32Notation::Decimal)
            ),
            _ => String::new(),
        };
        let _ = writeln!(
            s,
            "| 0x{:04X} | {} | {} | {:?} | {} | {} | {} | {} |",
            e.index,
            e.sub,
            name,
            e.dtype,
            e.access.eds(),
            if e.pdo { "yes" } else { "" },
            default,
            limits
        );
    }
    s
}
