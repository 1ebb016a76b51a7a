//! The ESI XML of the slave as served: well-formed (python's xml.etree reads it), its
//! identity that of 0x1018, its sync managers the SII's, its PDOs the assignment with the
//! mapping's entries, names and types from the dictionary; after a remap in PRE-OP, the new
//! mapping.
mod common;
use common::*;
use std::io::Write;
use std::process::{Command, Stdio};

/// What python's ElementTree reads from the file: one JSON line.
fn parse(xml: &str) -> serde_json::Value {
    let script = r#"
import json, sys, xml.etree.ElementTree as ET
root = ET.fromstring(sys.stdin.read())
dev = root.find("Descriptions/Devices/Device")
t = dev.find("Type")
def pdos(tag):
    return [{"index": p.findtext("Index"), "sm": p.get("Sm"),
             "entries": [[e.findtext("Index"), int(e.findtext("SubIndex")),
                          int(e.findtext("BitLen")), e.findtext("Name"),
                          e.findtext("DataType")] for e in p.findall("Entry")]}
            for p in dev.findall(tag)]
print(json.dumps({
    "vendor": root.findtext("Vendor/Id"),
    "product": t.get("ProductCode"), "revision": t.get("RevisionNo"),
    "sms": [[s.text, s.get("StartAddress"), s.get("ControlByte")] for s in dev.findall("Sm")],
    "rx": pdos("RxPdo"), "tx": pdos("TxPdo"),
    "coe": dev.find("Mailbox/CoE").attrib,
}))
"#;
    let mut child = Command::new("python3")
        .args(["-c", script])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 runs");
    child
        .stdin
        .take()
        .unwrap()
        .write_all(xml.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "the ESI does not parse: {}\n{xml}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn hex(v: u32, digits: usize) -> String {
    format!("#x{v:0digits$X}")
}

#[test]
fn esi_says_what_the_sii_and_coe_say() {
    let mut m = preop(1);
    let node = m.seg.slaves[0].node();
    let id: Vec<u32> = (1..=3)
        .map(|s| node.object_raw(0x1018, s).unwrap())
        .collect();
    let esi = parse(&m.seg.slaves[0].esi_xml().unwrap());
    assert_eq!(esi["vendor"], hex(id[0], 8));
    assert_eq!(esi["product"], hex(id[1], 8));
    assert_eq!(esi["revision"], hex(id[2], 8));
    // the sync managers: where the SII puts them
    let st = Master::station(0);
    let mb = m.eeprom(st, 0x0018);
    let sms = esi["sms"].as_array().unwrap();
    assert_eq!(sms.len(), 4);
    assert_eq!(sms[0][0], "MBoxOut");
    assert_eq!(
        sms[0][1],
        hex(u32::from(u16::from_le_bytes([mb[0], mb[1]])), 4)
    );
    assert_eq!(
        sms[1][1],
        hex(u32::from(u16::from_le_bytes([mb[4], mb[5]])), 4)
    );
    assert_eq!(
        (sms[2][0].as_str(), sms[3][0].as_str()),
        (Some("Outputs"), Some("Inputs"))
    );
    // the default assignment: 0x1601 controlword + target position, 0x1A01 statusword +
    // position actual, names and types from the dictionary
    let rx = &esi["rx"][0];
    assert_eq!(rx["index"], "#x1601");
    assert_eq!(rx["sm"], "2");
    assert_eq!(
        rx["entries"],
        serde_json::json!([
            ["#x6040", 0, 16, "Controlword", "UINT"],
            ["#x607A", 0, 32, "Target position", "DINT"]
        ])
    );
    assert_eq!(esi["tx"][0]["index"], "#x1A01");
    assert_eq!(esi["tx"][0]["entries"][1][0], "#x6064");
    assert_eq!(esi["coe"]["CompleteAccess"], "true");
    assert_eq!(esi["coe"]["PdoConfig"], "true");

    // remapped in PRE-OP: the file follows
    m.sdo_write(0, 0x1A01, 0, false, &[0]).unwrap();
    m.sdo_write(0, 0x1A01, 1, false, &0x6041_0010u32.to_le_bytes())
        .unwrap();
    m.sdo_write(0, 0x1A01, 2, false, &0x606C_0020u32.to_le_bytes())
        .unwrap();
    m.sdo_write(0, 0x1A01, 3, false, &0x6061_0008u32.to_le_bytes())
        .unwrap();
    m.sdo_write(0, 0x1A01, 0, false, &[3]).unwrap();
    let esi = parse(&m.seg.slaves[0].esi_xml().unwrap());
    assert_eq!(
        esi["tx"][0]["entries"],
        serde_json::json!([
            ["#x6041", 0, 16, "Statusword", "UINT"],
            ["#x606C", 0, 32, "Velocity actual value", "DINT"],
            ["#x6061", 0, 8, "Modes of operation display", "SINT"]
        ])
    );
}
