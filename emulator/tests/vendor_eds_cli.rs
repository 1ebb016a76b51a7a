//! A vendor's file on the command line (issue 33): what the parser read past is said with the
//! file, line, section and key; placeholders say which and why; a file without LSS and
//! `--node 255` says the file is the reason and names `--force-lss`, which gets past it.
//! (Refused or stopped before any bus is opened: the interface does not exist.)

use std::path::PathBuf;
use std::process::{Command, Output};

fn eds_dir(sub: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/eds")
        .join(sub)
}

fn drive_emu(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(args)
        .output()
        .expect("run drive-emu")
}

#[test]
fn eds_from_names_file_line_section_and_key_of_what_it_read_past() {
    let path = eds_dir("lenient").join("objflags-word.eds");
    let p = path.to_str().unwrap();
    let out = drive_emu(&["eds", "--from", p]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let want = format!("warning: {p}: line 14, [1000] ObjFlags: 'NV' is not a 32-bit number");
    assert!(stderr.contains(&want), "`{want}` missing in:\n{stderr}");
}

#[test]
fn eds_from_says_which_placeholders_were_taken_from_the_axis_and_why() {
    let path = eds_dir("minimal").join("placeholders.eds");
    let out = drive_emu(&["eds", "--from", path.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    for (index, what) in [
        ("0x607F", "would clamp every profile move to zero speed"),
        ("0x6065", "would fault the drive at the first motion"),
        ("0x6072", "would allow the motor no torque"),
        ("0x60C5", "would allow no acceleration"),
    ] {
        let line = stderr
            .lines()
            .find(|l| l.trim_start().starts_with(index))
            .unwrap_or_else(|| panic!("no line for {index} in:\n{stderr}"));
        assert!(
            line.contains("the file's default 0 is a placeholder") && line.contains(what),
            "{line}"
        );
    }
    assert!(
        stderr.contains("0xFFFFFFFF: the window is off (CiA 402)"),
        "{stderr}"
    );
    // the served EDS carries the axis's values, not the placeholders
    let eds = String::from_utf8_lossy(&out.stdout);
    let at = eds.find("[607F]").expect("607F exported");
    let section = &eds[at..eds[at + 1..].find("\n[").map_or(eds.len(), |e| at + 1 + e)];
    assert!(!section.contains("DefaultValue=0\n"), "{section}");
}

#[test]
fn node_255_with_a_file_without_lss_names_the_file_and_the_flag() {
    let path = eds_dir("minimal").join("placeholders.eds");
    let p = path.to_str().unwrap();
    let args = [
        "run",
        "--iface",
        "nonexistent0",
        "--eds",
        p,
        "--node",
        "255",
    ];
    let out = drive_emu(&args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    for n in [p, "LSS_Supported=0", "--force-lss", "1..=127"] {
        assert!(stderr.contains(n), "`{n}` missing in:\n{stderr}");
    }
    // with the flag the drive is built; only the missing interface stops it
    let mut forced = args.to_vec();
    forced.push("--force-lss");
    let out = drive_emu(&forced);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(!stderr.contains("LSS_Supported"), "{stderr}");
    assert!(stderr.contains("nonexistent0"), "{stderr}");
}

#[test]
fn eds_from_says_what_one_user_unit_is() {
    let path = eds_dir("minimal").join("factor-2000.eds");
    let out = drive_emu(&["eds", "--from", path.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let note = stderr
        .lines()
        .find(|l| l.contains("note: 1 uu = "))
        .unwrap_or_else(|| panic!("no user-unit note in:\n{stderr}"));
    assert!(
        note.contains("1 uu = 1 increments of the motor encoder = ")
            && note.contains(" mm of the simulated axis"),
        "{note}"
    );
    // the SI unit velocity rev/min is the velocity user unit (issue 33, item 2)
    assert!(
        note.contains(
            "0x60A9 SI unit velocity = 0x00B44700 (rev/min): applied, velocities in that unit, \
             accelerations in that unit per second"
        ) && !note.contains("speeds in uu/s"),
        "{note}"
    );
    assert!(
        note.contains("0x60A8 SI unit position = 0x00B50000 (unit 0xB5)"),
        "{note}"
    );
    // a unit the drive cannot tell in increments: said, velocities in uu/s
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("DefaultValue=0x00B44700", "DefaultValue=0x00B49900");
    let dir = std::env::temp_dir().join(format!("drive-emu-units-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let other = dir.join("unknown-time.eds");
    std::fs::write(&other, text).unwrap();
    let out = drive_emu(&["eds", "--from", other.to_str().unwrap()]);
    let _ = std::fs::remove_dir_all(&dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let note = stderr
        .lines()
        .find(|l| l.contains("note: 1 uu = "))
        .unwrap();
    assert!(
        note.contains("0x60A9 SI unit velocity = 0x00B49900 (rev/0x99): not applied")
            && note.ends_with("; speeds in uu/s, accelerations in uu/s^2"),
        "{note}"
    );
}

/// Issue 33, item 3: `eds --from` says how a vendor's SI units are taken. 0x60A8 = um with no
/// feed constant in the file: 1 uu is one um of the simulated axis (the feed constant derived
/// from it, said); 0x60AA = rev/s per second: accelerations in it; a placeholder maximum
/// velocity is filled in 0x60A9's unit, and the report says so.
#[test]
fn eds_from_says_how_the_si_units_are_applied() {
    let path = eds_dir("units").join("position-micrometre.eds");
    let out = drive_emu(&["eds", "--from", path.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let note = stderr
        .lines()
        .find(|l| l.contains("note: 1 uu = "))
        .unwrap_or_else(|| panic!("no user-unit note in:\n{stderr}"));
    assert!(
        note.contains("= 0.001 mm of the simulated axis")
            && note.contains("0x60A8 SI unit position = 0xFA010000 (1e-6 m): applied, 1 uu = 1 um")
            && note.contains("0x60A9 SI unit velocity = 0xFD010300 (1e-3 m/s): applied"),
        "{note}"
    );
    assert!(
        stderr.contains(
            "0x60A8 SI unit position = 0xFA010000 applied: the file has no feed constant 0x6092"
        ),
        "{stderr}"
    );
    let line = stderr
        .lines()
        .find(|l| l.contains("0x607F sub 0"))
        .unwrap_or_else(|| panic!("no 0x607F line in:\n{stderr}"));
    assert!(
        line.contains("in 0x60A9's unit, the simulated axis's value (0x607F)"),
        "{line}"
    );

    let path = eds_dir("units").join("acceleration-rev-s2.eds");
    let out = drive_emu(&["eds", "--from", path.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let note = stderr
        .lines()
        .find(|l| l.contains("note: 1 uu = "))
        .unwrap();
    assert!(
        note.contains(
            "0x60AA SI unit acceleration = 0x00B40300 (rev/s): applied, accelerations in that \
             unit per second"
        ) && note.contains("0x60A8 SI unit position = 0x00B50000 (unit 0xB5): positions stay"),
        "{note}"
    );
    let line = stderr
        .lines()
        .find(|l| l.contains("0x60C5 sub 0"))
        .unwrap_or_else(|| panic!("no 0x60C5 line in:\n{stderr}"));
    assert!(line.contains("in 0x60AA's unit"), "{line}");
}
