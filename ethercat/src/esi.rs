//! The ESI (EtherCAT Slave Information, ETG.2000) of the slave as served: the XML file masters
//! such as TwinCAT or IgH's tools import, as a CANopen master imports an EDS. Written from the
//! same [`SiiConfig`] the EEPROM image is generated from, so the file, the SII and CoE agree:
//! identity (0x1018), sync managers, FMMUs, the assigned PDOs with their entries, CoE details.

use core::fmt::Write;

use crate::sii::{SiiConfig, COE_DETAILS};

/// The ETG.2000 name of a CoE data type code (0 for an unknown code: its bit length decides).
pub fn data_type_name(code: u8, bits: u8) -> &'static str {
    match code {
        0x01 => "BOOL",
        0x02 => "SINT",
        0x03 => "INT",
        0x04 => "DINT",
        0x05 => "USINT",
        0x06 => "UINT",
        0x07 => "UDINT",
        0x08 => "REAL",
        0x11 => "LREAL",
        0x15 => "LINT",
        0x1B => "ULINT",
        _ => match bits {
            1 => "BOOL",
            8 => "USINT",
            16 => "UINT",
            32 => "UDINT",
            _ => "ULINT",
        },
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The ESI XML of one device. `entry_name(index, sub)` names a mapped object (the object
/// dictionary's name).
pub fn xml(cfg: &SiiConfig, entry_name: impl Fn(u16, u8) -> String) -> String {
    let id = &cfg.identity;
    let mut x = String::with_capacity(8192);
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(x, r#"<EtherCATInfo Version="1.6">"#);
    let _ = writeln!(
        x,
        "  <Vendor>\n    <Id>#x{:08X}</Id>\n    <Name>drive-emu</Name>\n  </Vendor>",
        id.vendor
    );
    let _ = writeln!(x, "  <Descriptions>");
    let group = escape(&cfg.group);
    let _ = writeln!(
        x,
        "    <Groups>\n      <Group>\n        <Type>{group}</Type>\n        <Name>{group}</Name>\n      </Group>\n    </Groups>"
    );
    let _ = writeln!(x, "    <Devices>");
    let _ = writeln!(x, r#"      <Device Physics="YY">"#);
    let _ = writeln!(
        x,
        r##"        <Type ProductCode="#x{:08X}" RevisionNo="#x{:08X}">{}</Type>"##,
        id.product,
        id.revision,
        escape(&cfg.order)
    );
    let _ = writeln!(x, "        <Name>{}</Name>", escape(&cfg.name));
    let _ = writeln!(x, "        <GroupType>{group}</GroupType>");
    for f in ["Outputs", "Inputs", "MBoxState"] {
        let _ = writeln!(x, "        <Fmmu>{f}</Fmmu>");
    }
    for sm in &cfg.sms {
        let kind = match sm.kind {
            1 => "MBoxOut",
            2 => "MBoxIn",
            3 => "Outputs",
            _ => "Inputs",
        };
        let size = if sm.kind <= 2 {
            format!(r#" MinSize="34" MaxSize="{0}" DefaultSize="{0}""#, sm.len)
        } else {
            format!(r#" DefaultSize="{}""#, sm.len)
        };
        let _ = writeln!(
            x,
            r##"        <Sm{size} StartAddress="#x{:04X}" ControlByte="#x{:02X}" Enable="{}">{kind}</Sm>"##,
            sm.start, sm.control, sm.enable
        );
    }
    for (tag, pdos) in [("RxPdo", &cfg.rx_pdos), ("TxPdo", &cfg.tx_pdos)] {
        for p in pdos {
            let _ = writeln!(
                x,
                r#"        <{tag} Fixed="0" Mandatory="1" Sm="{}">"#,
                p.sm
            );
            let _ = writeln!(x, "          <Index>#x{:04X}</Index>", p.index);
            let _ = writeln!(
                x,
                "          <Name>{} 0x{:04X}</Name>",
                if tag == "RxPdo" { "RxPDO" } else { "TxPDO" },
                p.index
            );
            for e in &p.entries {
                let _ = writeln!(
                    x,
                    "          <Entry>\n            <Index>#x{:04X}</Index>\n            <SubIndex>{}</SubIndex>\n            <BitLen>{}</BitLen>\n            <Name>{}</Name>\n            <DataType>{}</DataType>\n          </Entry>",
                    e.index,
                    e.sub,
                    e.bits,
                    escape(&entry_name(e.index, e.sub)),
                    data_type_name(e.data_type, e.bits)
                );
            }
            let _ = writeln!(x, "        </{tag}>");
        }
    }
    let flag = |bit: u8| {
        if COE_DETAILS & bit != 0 {
            "true"
        } else {
            "false"
        }
    };
    let _ = writeln!(
        x,
        r#"        <Mailbox DataLinkLayer="true">
          <CoE SdoInfo="{}" PdoAssign="{}" PdoConfig="{}" CompleteAccess="{}"/>
        </Mailbox>"#,
        flag(0x02),
        flag(0x04),
        flag(0x08),
        flag(0x20)
    );
    let _ = writeln!(
        x,
        "      </Device>\n    </Devices>\n  </Descriptions>\n</EtherCATInfo>"
    );
    x
}
