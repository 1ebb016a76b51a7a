//! EDS export (CiA 306), generated from the object table. Allocates: not for the RT path.

use core::fmt::Write;

use super::{default_value, DataType, Def, Obj, ObjType, OBJECTS};
use crate::drive::DriveInfo;
use crate::params::param_at;

fn fmt_value(o: &Obj, raw: u32) -> String {
    let pdo_map = (0x1600..=0x17FF).contains(&o.index) || (0x1A00..=0x1BFF).contains(&o.index);
    if pdo_map && o.sub > 0 {
        // a mapping entry: index, sub-index, length, as CiA 306 writes it
        format!("0x{raw:08X}")
    } else if o.dtype.signed() {
        format!("{}", raw as i32)
    } else if o.dtype == DataType::Real32 {
        format!("{}", f32::from_bits(raw))
    } else {
        format!("0x{raw:X}")
    }
}

fn name_of(o: &Obj, info: &DriveInfo) -> &'static str {
    if o.otype == ObjType::Var {
        if let Some(p) = param_at(o.index) {
            return if info.rotary { p.rotary_name } else { p.name };
        }
    }
    o.name
}

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
    /// LSS_SerialNumber there is the identity's serial number (0x1018:4 = $NODEID).
    pub node_id: Option<u8>,
    /// Manufacturer parameters (0x2000..): the value the drive has, engineering units, as an
    /// SDO read returns it. Objects not listed keep the table's default.
    pub params: &'a [(u16, f32)],
    /// Notation of REAL32 DefaultValues.
    pub real32: Real32Notation,
}

impl Default for EdsMeta<'_> {
    fn default() -> Self {
        EdsMeta {
            file_name: "drive-emulator.eds",
            description: "Emulated CiA 402 servo drive (generated from the object table)",
            created_by: "drive-protocol",
            time: "12:00AM",
            date: "01-01-2025",
            node_id: None,
            params: &[],
            real32: Real32Notation::Bits,
        }
    }
}

fn write_entry(s: &mut String, o: &Obj, node_id: u8, info: &DriveInfo, meta: &EdsMeta) {
    let params = meta.params;
    let _ = writeln!(s, "ParameterName={}", name_of(o, info));
    let _ = writeln!(s, "ObjectType=0x7");
    let _ = writeln!(s, "DataType=0x{:04X}", o.dtype as u8);
    let _ = writeln!(s, "AccessType={}", o.access.eds());
    match o.default {
        Def::Str(t) => {
            let _ = writeln!(s, "DefaultValue={t}");
        }
        Def::NodeId(b) => {
            let _ = writeln!(s, "DefaultValue=$NODEID+0x{b:X}");
        }
        // REAL32 in the notation asked for (see Real32Notation)
        _ if o.dtype == DataType::Real32 => {
            let v = params
                .iter()
                .find(|(i, _)| *i == o.index && o.otype == ObjType::Var)
                .map_or(default_value(o, node_id, info), |p| p.1.to_bits());
            let _ = match meta.real32 {
                Real32Notation::Bits => writeln!(s, "DefaultValue=0x{v:08X}"),
                // Debug: shortest round-trip text, always with a point or an exponent
                Real32Notation::Decimal => writeln!(s, "DefaultValue={:?}", f32::from_bits(v)),
            };
        }
        _ => {
            let _ = writeln!(
                s,
                "DefaultValue={}",
                fmt_value(o, default_value(o, node_id, info))
            );
        }
    }
    if let Some(l) = o.low {
        let _ = writeln!(s, "LowLimit={l}");
    }
    if let Some(h) = o.high {
        let _ = writeln!(s, "HighLimit={h}");
    }
    let _ = writeln!(s, "PDOMapping={}", o.pdo as u8);
    s.push('\n');
}

/// The EDS text for a node, with the table's defaults and a generic `[FileInfo]`.
pub fn export(node_id: u8, info: &DriveInfo) -> String {
    export_with(node_id, info, &EdsMeta::default())
}

/// The EDS text for a node: complete `[FileInfo]` from `meta`, `[DeviceComissioning]` when
/// `meta.node_id` is set, manufacturer parameter defaults from `meta.params`.
pub fn export_with(node_id: u8, info: &DriveInfo, meta: &EdsMeta) -> String {
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
    s.push_str("[DeviceInfo]\nVendorName=drive-emulator\nVendorNumber=0\nProductName=drive-emulator CiA402 servo\n");
    s.push_str("ProductNumber=0x402\nRevisionNumber=0x10000\nOrderCode=-\n");
    for b in ["10", "20", "50", "125", "250", "500", "800", "1000"] {
        let _ = writeln!(s, "BaudRate_{b}=1");
    }
    s.push_str(
        "SimpleBootUpMaster=0\nSimpleBootUpSlave=1\nGranularity=8\nDynamicChannelsSupported=0\n",
    );
    s.push_str("GroupMessaging=0\nNrOfRXPDO=4\nNrOfTXPDO=4\nLSS_Supported=1\n\n");
    if let Some(id) = meta.node_id {
        let _ = writeln!(
            s,
            "[DeviceComissioning]\nNodeID={id}\nNodeName=drive-emu node {id}\nBaudrate=1000\n\
             NetNumber=1\nNetworkName=drive-emu\nCANopenManager=0\n\
             LSS_SerialNumber={id}\n"
        );
    }
    s.push_str("[DummyUsage]\nDummy0001=0\nDummy0002=0\nDummy0003=0\nDummy0004=0\nDummy0005=0\nDummy0006=0\nDummy0007=0\n\n");

    // distinct indices in order
    let mut indices: Vec<u16> = OBJECTS.iter().map(|o| o.index).collect();
    indices.dedup();
    let mandatory = [0x1000u16, 0x1001, 0x1018];
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
        ("MandatoryObjects", mandatory.to_vec()),
        ("OptionalObjects", optional),
        ("ManufacturerObjects", manufacturer),
    ] {
        let _ = writeln!(s, "[{section}]\nSupportedObjects={}", list.len());
        for (i, x) in list.iter().enumerate() {
            let _ = writeln!(s, "{}=0x{x:04X}", i + 1);
        }
        s.push('\n');
    }
    for &index in &indices {
        let rows: Vec<&Obj> = OBJECTS.iter().filter(|o| o.index == index).collect();
        let first = rows[0];
        if first.otype == ObjType::Var {
            let _ = writeln!(s, "[{index:04X}]");
            write_entry(&mut s, first, node_id, info, meta);
        } else {
            let _ = writeln!(s, "[{index:04X}]");
            let _ = writeln!(s, "ParameterName={}", first.parent);
            let _ = writeln!(
                s,
                "ObjectType=0x{}",
                if first.otype == ObjType::Array { 8 } else { 9 }
            );
            let _ = writeln!(s, "SubNumber={}", rows.len());
            s.push('\n');
            for o in rows {
                let _ = writeln!(s, "[{index:04X}sub{:X}]", o.sub);
                write_entry(&mut s, o, node_id, info, meta);
            }
        }
    }
    s
}

/// The object list as JSON (index, sub, data type, access) for the EDS check.
pub fn objects_json() -> String {
    let mut s = String::from("[");
    for (i, o) in OBJECTS.iter().enumerate() {
        if i > 0 {
            s.push(',');
        }
        let _ = write!(
            s,
            "{{\"index\":{},\"sub\":{},\"otype\":\"{}\",\"data_type\":{},\"access\":\"{}\",\"pdo\":{}}}",
            o.index,
            o.sub,
            match o.otype {
                ObjType::Var => "var",
                ObjType::Array => "array",
                ObjType::Record => "record",
            },
            o.dtype as u8,
            o.access.eds(),
            o.pdo
        );
    }
    s.push(']');
    s
}

/// A Markdown list of every object (docs/objects.md is this text; a test keeps it current).
pub fn objects_markdown(node_id: u8, info: &DriveInfo) -> String {
    let mut s = String::from(
        "# Object dictionary\n\nGenerated from `protocol/src/od/table.rs` (do not edit; run \
         `UPDATE_OBJECTS_MD=1 cargo test -p drive-protocol --test eds`). Defaults shown for the \
         test drive of `protocol/tests/common` (65536 inc/rev, 10 mm screw, user unit 1 µm) and \
         node ID 5.\n\n| Index | Sub | Name | Type | Access | PDO | Default | Limits |\n\
         |---|---|---|---|---|---|---|---|\n",
    );
    for o in OBJECTS {
        let name = if o.otype == ObjType::Var {
            name_of(o, info).to_string()
        } else {
            format!("{}: {}", o.parent, o.name)
        };
        let default = match o.default {
            Def::Str(t) => format!("\"{t}\""),
            Def::NodeId(b) => format!("$NODEID+0x{b:X}"),
            _ => fmt_value(o, default_value(o, node_id, info)),
        };
        let limits = match (o.low, o.high) {
            (Some(l), Some(h)) => format!("{l}..={h}"),
            _ => String::new(),
        };
        let _ = writeln!(
            s,
            "| 0x{:04X} | {} | {} | {:?} | {} | {} | {} | {} |",
            o.index,
            o.sub,
            name,
            o.dtype,
            o.access.eds(),
            if o.pdo { "yes" } else { "" },
            default,
            limits
        );
    }
    s
}
