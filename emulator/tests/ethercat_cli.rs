//! What `run --ethercat` and the scenario runners refuse, before any socket is opened (no
//! root, no interface needed): `--panel` with `--ethercat`; a scenario's EtherCAT faults on
//! CAN (live or offline), with the file's event line and the way to run it.

use std::process::Command;

fn drive_emu(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(args)
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .output()
        .expect("drive-emu runs");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn ethercat_faults_and_the_panel_are_refused_where_they_cannot_work() {
    // the panel's own checks hold on EtherCAT as on CAN, before the port opens: off
    // loopback without a token it is refused (the same reason and status as on CAN)
    let (code, err) = drive_emu(&["run", "--ethercat", "no-such-if0", "--panel", "0.0.0.0:0"]);
    let (can_code, can_err) =
        drive_emu(&["run", "--iface", "no-such-can0", "--panel", "0.0.0.0:0"]);
    assert_eq!(code, can_code, "{err}\n{can_err}");
    for e in [&err, &can_err] {
        assert!(
            e.contains("not a loopback address") && e.contains("--panel-token"),
            "{e}"
        );
    }
    // the scenario's first event (lost frames) is the one named
    let file = "scenarios/ethercat-faults.toml";
    let (code, err) = drive_emu(&["run", "--iface", "no-such-can0", "--scenario", file]);
    assert_eq!(code, Some(2), "{err}");
    for want in [
        "line 24",
        "the next 20 frames lost",
        "drive-emu run --ethercat IFACE --scenario FILE",
    ] {
        assert!(err.contains(want), "{want:?} missing: {err}");
    }
    let dir = std::env::temp_dir().join(format!("ecat-cli-{}", std::process::id()));
    let (code, err) = drive_emu(&[
        "scenario",
        file,
        "--quiet",
        "--no-plots",
        "-o",
        dir.to_str().unwrap(),
    ]);
    let _ = std::fs::remove_dir_all(&dir);
    assert_ne!(code, Some(0), "{err}");
    assert!(
        err.contains("line 24") && err.contains("run --ethercat"),
        "{err}"
    );
}
