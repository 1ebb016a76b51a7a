//! `drive-emu esi`: the ESI of the drive as `run --ethercat` serves it, well-formed (python's
//! ElementTree reads it), with the identity the same drive's EDS gives (`drive-emu eds`), and
//! the sync managers and PDOs of the slave; `--set` and `-o` as elsewhere.

use std::process::Command;

fn drive_emu(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "drive-emu {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn eds_number(eds: &str, key: &str) -> u32 {
    let v = eds
        .lines()
        .find_map(|l| l.strip_prefix(&format!("{key}=")))
        .unwrap_or_else(|| panic!("{key} in the EDS"))
        .trim();
    match v.strip_prefix("0x").or_else(|| v.strip_prefix("0X")) {
        Some(h) => u32::from_str_radix(h, 16).unwrap(),
        None => v.parse().unwrap(),
    }
}

fn parse(xml: &str) -> Vec<String> {
    let script = r#"
import sys, xml.etree.ElementTree as ET
root = ET.parse(sys.argv[1]).getroot()
dev = root.find("Descriptions/Devices/Device")
print(root.findtext("Vendor/Id"))
print(dev.find("Type").get("ProductCode"))
print(dev.find("Type").get("RevisionNo"))
print(",".join(s.text for s in dev.findall("Sm")))
print(dev.find("RxPdo").findtext("Index"), dev.find("TxPdo").findtext("Index"))
"#;
    let dir = std::env::temp_dir().join(format!("drive-emu-esi-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("drive.xml");
    std::fs::write(&path, xml).unwrap();
    let out = Command::new("python3")
        .args(["-c", script])
        .arg(&path)
        .output()
        .expect("python3 runs");
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        out.status.success(),
        "the ESI does not parse: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect()
}

#[test]
fn esi_of_the_served_drive_has_the_eds_identity() {
    let esi = drive_emu(&["esi", "--preset", "cnc1"]);
    let eds = drive_emu(&["eds", "--preset", "cnc1"]);
    let got = parse(&esi);
    assert_eq!(
        got[0],
        format!("#x{:08X}", eds_number(&eds, "VendorNumber"))
    );
    assert_eq!(
        got[1],
        format!("#x{:08X}", eds_number(&eds, "ProductNumber"))
    );
    assert_eq!(
        got[2],
        format!("#x{:08X}", eds_number(&eds, "RevisionNumber"))
    );
    assert_eq!(got[3], "MBoxOut,MBoxIn,Outputs,Inputs");
    assert_eq!(got[4], "#x1601 #x1A01");
    // -o writes the same text to a file
    let dir = std::env::temp_dir().join(format!("drive-emu-esi-o-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("cnc1.xml");
    drive_emu(&["esi", "--preset", "cnc1", "-o", file.to_str().unwrap()]);
    let written = std::fs::read_to_string(&file).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(written, esi);
}

#[test]
fn esi_refuses_a_bad_override_with_its_reason() {
    let out = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(["esi", "--preset", "cnc1", "--set", "no_such_key=1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(out.stdout.is_empty());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no_such_key"), "{err}");
}
