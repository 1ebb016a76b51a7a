//! python canopen 2.4.1 (over python-can's socketcand interface, no kernel CAN) against
//! `drive-emu run --eds FILE` for the minimal files of issue 33 (tests/eds/minimal) and the
//! real vendor files (tests/eds/vendors): every
//! readable object uploads with its type's size, the identity is the file's,
//! `load_configuration()` of the DCF whose default maps take 32 of 64 bits passes, the
//! PDO maps read back as the file says, and BaseNode402 reaches a profile-position target
//! (bit 10, within the position window) in the file's own units wherever 0x6502 offers PP
//! (the placeholder file's 0x607F = 0 and 0x6065 = 0 included) at the speed it asked for (the
//! SI unit velocity 0x60A9 applied), runs a CSV move where 0x6502 offers CSV, and, where the
//! file offers LSS, finds the drive (started non-configured, node-ID 255) by LSS fastscan and
//! gives it its node-ID. Every drive runs on `run`'s default axis: healthy, no wear flag.
//! One drive-emu process per file, one python process
//! for all (tests/python/vendor_file_check.py). Needs python3 with python-can 4.6.1 and
//! canopen 2.4.1 (tests/requirements.txt; `DRIVE_EMU_PYTHON` names another interpreter).

mod socketcand_drive;

use socketcand_drive::Drive;
use std::path::PathBuf;
use std::process::Command;

#[test]
fn python_canopen_uploads_every_object_and_loads_the_configuration_of_each_file() {
    let eds = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/eds");
    let mut paths: Vec<String> = [
        "minimal/short-pdo-map.dcf",
        "minimal/placeholders.eds",
        "minimal/factor-2000.eds",
        "units/velocity-tenth-rpm.eds",
        "minimal/fe-window-zero.dcf",
    ]
    .iter()
    .map(|f| eds.join(f).to_string_lossy().into_owned())
    .collect();
    let minimal = paths.len();
    let mut vendors: Vec<String> = std::fs::read_dir(eds.join("vendors"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("eds" | "dcf")))
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    vendors.sort();
    assert!(vendors.len() >= 7, "{vendors:?}");
    paths.extend(vendors);
    // files that offer LSS: their drive starts non-configured, the master gives it node 5
    let lss: Vec<bool> = paths
        .iter()
        .map(|p| {
            let text = drive_protocol::od::eds_parse::decode_text(&std::fs::read(p).unwrap());
            let f = drive_protocol::od::eds_parse::parse(&text).unwrap();
            f.device_info.lss_supported == Some(true)
        })
        .collect();
    assert!(lss.iter().filter(|&&l| l).count() >= 3, "{lss:?}");
    let drives: Vec<Drive> = paths
        .iter()
        .zip(&lss)
        .map(|(p, &l)| Drive::start(&["--node", if l { "255" } else { "5" }, "--eds", p]))
        .collect();
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/python/vendor_file_check.py"
    );
    let python = std::env::var("DRIVE_EMU_PYTHON").unwrap_or_else(|_| "python3".into());
    let out = Command::new(&python)
        .arg(script)
        .args(["--node", "5"])
        .args(
            drives
                .iter()
                .zip(&paths)
                .zip(&lss)
                .map(|((d, p), &l)| format!("{}:{p}{}", d.port, if l { ":lss" } else { "" })),
        )
        .output()
        .unwrap_or_else(|e| panic!("cannot run {python}: {e}"));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "the master failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    assert_eq!(lines.len(), paths.len(), "{stdout}");
    for ((l, p), &offers_lss) in lines.iter().zip(&paths).zip(&lss) {
        assert_eq!(l["file"], p.as_str(), "{l}");
        assert_eq!(
            l["lss"],
            if offers_lss {
                "fastscan"
            } else {
                "not offered"
            },
            "{l}"
        );
        assert!(l["uploads"].as_u64().unwrap() >= 10, "{l}");
        assert_eq!(l["bad_sizes"], serde_json::json!([]), "{l}");
        assert_eq!(l["identity_ok"], true, "{l}");
        assert_eq!(l["configured"], true, "{l}");
        assert_eq!(l["map_mismatches"], serde_json::json!([]), "{l}");
        assert!(l["pp"] == "reached" || l["pp"] == "not offered", "{l}");
        if l["pp"] == "reached" && !l["pp_speed_ok"].is_null() {
            assert_eq!(l["pp_speed_ok"], true, "{l}");
        }
        assert!(
            l["csv"] == "ran" || l["csv"] == "not offered" || l["pp"] == "not offered",
            "{l}"
        );
    }
    let csv = lines.iter().filter(|l| l["csv"] == "ran").count();
    assert!(csv >= 3, "CSV ran on {csv} files only:\n{stdout}");
    let reached = lines.iter().filter(|l| l["pp"] == "reached").count();
    assert!(
        reached >= 8,
        "PP reached on {reached} files only:\n{stdout}"
    );
    for l in &lines[..minimal] {
        if !l["file"].as_str().unwrap().ends_with("short-pdo-map.dcf") {
            assert_eq!(l["pp"], "reached", "{l}");
            assert_eq!(l["pp_speed_ok"], true, "{l}");
        }
    }
}
