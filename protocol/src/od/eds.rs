//! EDS export (CiA 306), generated from the object table. Allocates: not for the RT path.

use core::fmt::Write;

use super::{default_value, DataType, Def, Obj, ObjType, OBJECTS};
use crate::drive::DriveInfo;
use crate::params::param_at;

fn fmt_value(o: &Obj, raw: u32) -> String {
    if o.dtype.signed() {
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

fn write_entry(s: &mut String, o: &Obj, node_id: u8, info: &DriveInfo) {
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

/// The EDS text for a node.
pub fn export(node_id: u8, info: &DriveInfo) -> String {
    let mut s = String::with_capacity(64 * 1024);
    s.push_str(
        "[FileInfo]\nFileName=drive-emulator.eds\nFileVersion=1\nFileRevision=0\nEDSVersion=4.0\n",
    );
    s.push_str("Description=Emulated CiA 402 servo drive (generated from the object table)\n");
    s.push_str("CreatedBy=drive-protocol\n\n");
    s.push_str("[DeviceInfo]\nVendorName=drive-emulator\nVendorNumber=0\nProductName=drive-emulator CiA402 servo\n");
    s.push_str("ProductNumber=0x402\nRevisionNumber=0x10000\nOrderCode=-\n");
    for b in ["10", "20", "50", "125", "250", "500", "800", "1000"] {
        let _ = writeln!(s, "BaudRate_{b}=1");
    }
    s.push_str(
        "SimpleBootUpMaster=0\nSimpleBootUpSlave=1\nGranularity=8\nDynamicChannelsSupported=0\n",
    );
    s.push_str("GroupMessaging=0\nNrOfRXPDO=4\nNrOfTXPDO=4\nLSS_Supported=0\n\n");
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
            write_entry(&mut s, first, node_id, info);
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
                write_entry(&mut s, o, node_id, info);
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
         test drive of `protocol/tests/common` (65536 inc/rev, 10 mm screw, user unit 1 um) and \
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
