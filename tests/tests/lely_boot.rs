//! Lely's CANopen master (what ros2_canopen runs) boots the drive and moves it: Lely is not in
//! the package registries, so tests/python/lely_boot.py replays its boot from the files Lely's
//! `dcfgen -rS` makes of a bus.yml and our EDS, in Lely's order and with its timeouts (NMT
//! reset, boot-up, 0x1000 and 0x1018 against the DCF, the concise DCF as SDO downloads,
//! heartbeat within the master's consumer time or boot error 'K', NMT start), then enables the
//! drive and makes a short CSP move with SYNC at the bus.yml's period, and fails on a heartbeat
//! event after the boot.
//!
//! Cases: the user's bus.yml (tests/ros2/one_drive.bus.yml: SYNC 10 ms, heartbeat 1000 ms, no
//! 0x1006) with the drive in real time and in plain lock-step (`run --lockstep`, no
//! --sync-period-us); the project's ros2_canopen bus.yml (tests/ros2/bus.yml, heartbeat
//! 100 ms, mode of operation in an RPDO) in plain lock-step. The lock-step cases fail with
//! boot error 'K' until the drive's heartbeat is timed as on a real drive whatever the SYNC
//! period (issue 22, item 1): the drive takes 1 ms per SYNC while SYNC comes every 10 ms.
//!
//! Needs vcan and dcfgen (dcf-tools, tests/requirements.txt):
//! `./vcan-setup.sh -- cargo nextest run -p e2e --test lely_boot`. Node 5 on bus 0. The
//! master's SDO timeout is 1 s here, not Lely's default 100 ms (an application setting,
//! BasicMaster::SetTimeout): user-mode Linux on a loaded host stalls the drive for longer.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use e2e::{
    drive_emu_bin, iface, open_bus, python, repo_root, wait_bootup, Emu, Peer, PEER_TIMEOUT,
};

const NODE: u8 = 5;

/// `dcfgen` on PATH, or a clear failure (CI installs it from tests/requirements.txt).
fn dcfgen() -> PathBuf {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .map(|d| d.join("dcfgen"))
        .find(|p| p.is_file())
        .unwrap_or_else(|| {
            panic!(
                "`dcfgen` (Lely's dcf-tools) not found on PATH: run `pip install -r \
                 tests/requirements.txt`"
            )
        })
}

/// A fresh directory with the EDS, the bus.yml (its `@BUS_CONFIG_PATH@` set to the
/// directory, as ros2_canopen's cmake does) and what `dcfgen -rS` makes of them.
fn bus_config(bus_yml: &str, tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("drive-emu-lely-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    let eds = Command::new(drive_emu_bin())
        .args(["eds", "--preset", "cnc1", "--node", "5"])
        .output()
        .expect("run drive-emu eds");
    assert!(
        eds.status.success(),
        "drive-emu eds failed: {}",
        String::from_utf8_lossy(&eds.stderr)
    );
    std::fs::write(dir.join("drive-emu-cnc1.eds"), &eds.stdout).expect("write the EDS");
    let yml = std::fs::read_to_string(repo_root().join(bus_yml))
        .unwrap_or_else(|e| panic!("{bus_yml}: {e}"))
        .replace("@BUS_CONFIG_PATH@", &dir.display().to_string());
    std::fs::write(dir.join("bus.yml"), yml).expect("write bus.yml");
    let out = Command::new(dcfgen())
        .args(["-rS", "-d", &dir.display().to_string(), "bus.yml"])
        .current_dir(&dir)
        .output()
        .expect("run dcfgen");
    assert!(
        out.status.success(),
        "dcfgen -rS {bus_yml} failed ({}):\n{}{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    for f in ["master.dcf", "master.bin"] {
        assert!(
            dir.join(f).is_file(),
            "dcfgen wrote no {f} in {}",
            dir.display()
        );
    }
    dir
}

/// Boot and move the drive (`drive-emu run ARGS`) with the Lely-style client; returns the
/// client's output. Panics, with the client's and the drive's output, unless it passed.
fn lely_boots_and_moves(dir: &Path, run_args: &[&str]) -> String {
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let mut args = vec![
        "--iface",
        ifname.as_str(),
        "--node",
        "5",
        "--preset",
        "cnc1",
    ];
    args.extend_from_slice(run_args);
    let emu = Emu::spawn(&args);
    assert!(
        wait_bootup(&sock, NODE, PEER_TIMEOUT),
        "the drive sent no boot-up after its start"
    );
    let mut cmd = Command::new(python());
    cmd.arg(repo_root().join("tests/python/lely_boot.py"))
        .args(["--iface", &ifname, "--node", "5"])
        .args(["--master-dcf", "master.dcf", "--master-bin", "master.bin"])
        .args(["--sdo-timeout-ms", "1000"])
        .current_dir(dir)
        .env("PYTHONUNBUFFERED", "1");
    let mut client = Peer::spawn("lely_boot.py", cmd);
    // every line until the verdict (or the client's end); the client bounds its own waits
    let mut verdict = None;
    while let Some(line) = client.wait_line("", 4 * PEER_TIMEOUT) {
        if line.starts_with("PASS") || line.starts_with("FAIL") || line.starts_with("BOOT ERROR") {
            verdict = Some(line);
            break;
        }
    }
    let out = client.output();
    let status = client.finish(Duration::from_secs(30));
    let exit = emu.stop_clean();
    eprintln!("lely_boot.py output:\n{out}");
    assert!(
        verdict.as_deref() == Some("PASS") && status.success(),
        "Lely's boot and CSP move failed ({status}): {}\nclient output:\n{out}\n\n\
         drive-emu stderr:\n{}",
        verdict.as_deref().unwrap_or("no verdict"),
        exit.stderr
    );
    out
}

fn assert_steps(out: &str, steps: &[&str]) {
    for s in steps {
        assert!(out.contains(s), "no `{s}` in the client's output:\n{out}");
    }
}

const BOOT_STEPS: &[&str] = &[
    "0x1000 = 0x00020192",
    "configuration done",
    "start error control",
    "BOOTED node 5",
    "NMT start node 5",
    "OPERATION ENABLED",
    "CSP move of 5000 uu",
];

#[test]
fn lely_boots_a_real_time_drive_with_a_users_bus_yml() {
    let dir = bus_config("tests/ros2/one_drive.bus.yml", "user-rt");
    let out = lely_boots_and_moves(&dir, &[]);
    assert_steps(&out, BOOT_STEPS);
    assert_steps(&out, &["waiting 3000 ms for a heartbeat", "written by SDO"]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Fails with boot error 'K' until issue 22 item 1 (heartbeat timed as on a real drive in
/// lock-step whatever the SYNC period).
#[test]
fn lely_boots_a_lockstep_drive_with_a_users_bus_yml() {
    let dir = bus_config("tests/ros2/one_drive.bus.yml", "user-ls");
    let out = lely_boots_and_moves(&dir, &["--lockstep"]);
    assert_steps(&out, BOOT_STEPS);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The README's ros2_canopen bus.yml: 0x1017 = 100 ms, consumed at 300 ms; mode of operation
/// and interpolation period through the concise DCF and an RPDO. Fails with boot error 'K'
/// until issue 22 item 1, like the case above.
#[test]
fn lely_boots_a_lockstep_drive_with_the_ros2_bus_yml() {
    let dir = bus_config("tests/ros2/bus.yml", "ros2-ls");
    let out = lely_boots_and_moves(&dir, &["--lockstep"]);
    assert_steps(&out, BOOT_STEPS);
    assert_steps(&out, &["waiting 300 ms for a heartbeat", "written by RPDO"]);
    let _ = std::fs::remove_dir_all(&dir);
}
