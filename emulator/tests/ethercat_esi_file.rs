//! `run --ethercat IFACE --esi FILE`: a vendor's ESI (ETG.2000) served as the slave's own.
//!
//! - round trip: `drive-emu esi -o F`, then the slave built from F (`drive-emu esi --esi F`,
//!   the same slaves `run --ethercat --esi F` serves) describes itself as F says: the same
//!   identity, sync managers and PDO map, byte for byte;
//! - another maker's ESI (tests/esi/other_maker.xml: its identity, hex and decimal numbers,
//!   its own PDO map, an optional TxPdo): SOEM (pysoem) on a veth pair reads that identity
//!   from the SII and from CoE 0x1018, the assignment 0x1C12 / 0x1C13 of its PDOs, maps 7
//!   bytes of outputs and 11 of inputs, and the slave takes the map to SAFE-OP (root; in
//!   CI it must succeed, see ethercat_rig);
//! - three broken ESI files refused with the file, the line and why (exit 2), and --esi
//!   without --ethercat refused (exit 2).

mod ethercat_rig;
use ethercat_rig::*;

use std::path::PathBuf;
use std::process::{Command, Output};

fn esi_dir() -> PathBuf {
    repo().join("tests/esi")
}

fn drive_emu(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(args)
        .output()
        .expect("drive-emu runs")
}

fn ok(out: Output, what: &str) -> String {
    assert!(
        out.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn round_trip_serves_the_same_identity_and_pdo_map() {
    let dir = std::env::temp_dir().join(format!("drive-emu-esi-file-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("drive.xml");
    let written = ok(
        drive_emu(&["esi", "--preset", "cnc1", "-o", file.to_str().unwrap()]),
        "esi -o",
    );
    assert!(written.is_empty(), "{written}");
    let text = std::fs::read_to_string(&file).unwrap();
    let served = ok(
        drive_emu(&["esi", "--preset", "cnc1", "--esi", file.to_str().unwrap()]),
        "esi --esi",
    );
    let _ = std::fs::remove_dir_all(&dir);
    assert!(text.contains("<RxPdo") && text.contains("<TxPdo"), "{text}");
    assert_eq!(served, text);
}

#[test]
fn another_makers_esi_is_what_the_slave_describes() {
    let file = esi_dir().join("other_maker.xml");
    let served = ok(
        drive_emu(&["esi", "--preset", "cnc1", "--esi", file.to_str().unwrap()]),
        "esi --esi other_maker.xml",
    );
    for want in [
        "<Id>#x00000A5C</Id>",
        // RevisionNo="131075" in the file: decimal
        r##"<Type ProductCode="#x00C0FFEE" RevisionNo="#x00020003">EX-SRV-400</Type>"##,
        "<Name>EX servo 400 W</Name>",
        r##"<Sm DefaultSize="7" StartAddress="#x1100""##,
        r##"<Sm DefaultSize="11" StartAddress="#x1180""##,
        "<Index>#x1600</Index>",
        "<Index>#x1A00</Index>",
        "<Index>#x606C</Index>",
    ] {
        assert!(served.contains(want), "{want} not in\n{served}");
    }
    // the optional TxPdo (no Sm attribute) is mapped but not assigned
    assert!(!served.contains("<Index>#x1A01</Index>"), "{served}");
}

#[test]
fn broken_esi_files_are_refused_with_line_and_reason() {
    let cases = [
        (
            "broken_unclosed.xml",
            "line 35: not well-formed XML: expected 'Entry' tag, not 'RxPdo'",
        ),
        (
            "broken_missing_object.xml",
            "line 41: PDO #x1A00 maps 0x2F00:0, an object the drive does not have",
        ),
        (
            "broken_number.xml",
            r#"line 33: BitLen "0x20" is not a number"#,
        ),
    ];
    for (name, why) in cases {
        let file = esi_dir().join(name);
        // the ESI is read before the interface is opened: no root, no such interface needed
        let out = drive_emu(&[
            "run",
            "--ethercat",
            "ecnone0",
            "--preset",
            "cnc1",
            "--esi",
            file.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(name), "{name}: the file is not named: {err}");
        assert!(err.contains(why), "{name}: {why:?} not in {err}");
    }
    let file = esi_dir().join("other_maker.xml");
    let out = drive_emu(&["run", "--preset", "cnc1", "--esi", file.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("it needs --ethercat IFACE"), "{err}");
}

#[test]
fn pysoem_sees_another_makers_identity_and_mapped_lengths() {
    if !may_run("ethercat_esi_file") {
        return;
    }
    let veth = Veth::create('e').unwrap_or_else(|e| panic!("cannot create the veth pair: {e}"));
    let file = esi_dir().join("other_maker.xml");
    let mut emu = Emulator::start(
        &veth.slave,
        &["--preset", "cnc1", "--esi", file.to_str().unwrap()],
    );
    let r = python("ethercat_esi.py", &[&veth.master], 120);
    let (stats, _) = emu.stop();
    let ident = serde_json::json!([0x0A5C, 0x00C0_FFEE, 131_075]);
    assert_eq!(r["sii"], ident, "{r}");
    assert_eq!(r["coe"], ident, "{r}");
    assert_eq!(r["name"], "EX servo 400 W", "{r}");
    assert_eq!(r["rx_assign"], serde_json::json!([0x1600]), "{r}");
    assert_eq!(r["tx_assign"], serde_json::json!([0x1A00]), "{r}");
    // controlword + target position + mode (7), statusword + position + velocity + mode (11)
    assert_eq!(r["outputs"], 7, "{r}");
    assert_eq!(r["inputs"], 11, "{r}");
    assert_eq!(r["image"], 18, "{r}");
    assert_eq!(r["safe_op"], true, "{r}");
    assert_eq!(stats["refused"], 0, "{stats}");
}
