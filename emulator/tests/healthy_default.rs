//! Issue 33, item 4: `drive-emu run` with no wear flag serves a healthy axis and says so; wear
//! is one flag or key away and the ready line and the start say when it is on; where the
//! position window 0x6067 the drive serves (here a vendor file's, 10 uu = 0.05 mm on cnc1) is
//! tighter than the gap asked for, the start says so. (That the healthy axis reaches its
//! target within the window: position_window.rs; with the vendor files: vendor_files_python.rs.)

mod socketcand_drive;

use socketcand_drive::Drive;
use std::path::PathBuf;

fn run(extra: &[&str]) -> (serde_json::Value, String) {
    let mut d = Drive::start(extra);
    let worn = node_worn(&mut d);
    let (code, _, stderr) = d.stop();
    assert_eq!(code, Some(0), "{stderr}");
    (worn, stderr)
}

/// The ready line's `worn` of node 5 (Drive::start keeps the line it read).
fn node_worn(d: &mut Drive) -> serde_json::Value {
    d.ready["nodes"][0]["worn"].clone()
}

/// A copy of the factor-2000 file with a position window 0x6067 of 10 uu, in a directory of
/// its own (removed when dropped).
struct TightWindowFile(PathBuf);

impl TightWindowFile {
    fn new() -> Self {
        let src =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/eds/minimal/factor-2000.eds");
        let text = std::fs::read_to_string(src).unwrap();
        let old = "ParameterName=Position window\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=0xFFFFFFFF";
        assert!(text.contains(old), "the file's 0x6067 changed");
        let text = text.replace(old, &old.replace("0xFFFFFFFF", "10"));
        let dir = std::env::temp_dir().join(format!("drive-emu-healthy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("window-10.eds");
        std::fs::write(&p, text).unwrap();
        TightWindowFile(p)
    }
}

impl Drop for TightWindowFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(self.0.parent().unwrap());
    }
}

#[test]
fn run_is_healthy_by_default_and_says_when_it_is_worn() {
    let (worn, err) = run(&[]);
    assert!(worn.is_null(), "{worn}");
    assert!(
        err.contains("node 5: a healthy axis (no backlash)"),
        "{err}"
    );
    assert!(err.contains("--worn"), "{err}");
    assert!(!err.contains("WORN"), "{err}");

    let (worn, err) = run(&["--worn"]);
    assert_eq!(worn, "backlash 0.03 mm");
    assert!(err.contains("node 5: WORN: backlash 0.03 mm"), "{err}");

    let (worn, err) = run(&["--preset", "cnc3", "--set", "backlash_deg=0.01"]);
    assert_eq!(worn, "backlash 0.01 deg");
    assert!(err.contains("WORN: backlash 0.01 deg"), "{err}");
}

#[test]
fn a_vendor_window_tighter_than_the_wear_asked_for_is_said_at_start() {
    let f = TightWindowFile::new();
    let eds = f.0.to_str().unwrap();
    // 1 uu = 1 increment = 5 um on cnc1 (10 mm per 2000 increments): 10 uu = 0.05 mm
    let (worn, err) = run(&["--eds", eds, "--set", "backlash_mm=0.07"]);
    assert_eq!(worn, "backlash 0.07 mm");
    assert!(
        err.contains(
            "position window 0x6067 = 10 uu (0.05 mm) is tighter than the backlash 0.07 mm"
        ),
        "{err}"
    );
    // the shipped 0.03 mm fits in it; a healthy axis has nothing to say
    for extra in [&["--worn"][..], &[]] {
        let args: Vec<&str> = ["--eds", eds].iter().chain(extra).copied().collect();
        let (_, err) = run(&args);
        assert!(!err.contains("is tighter than"), "{extra:?}: {err}");
    }
}
