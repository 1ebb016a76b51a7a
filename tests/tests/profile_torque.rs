//! python `canopen` runs the drive in profile torque mode (0x6060 = 4): BaseNode402 to
//! OPERATION ENABLED in PT, target torque 0x6071 written, the demand 0x6074 at it (bit 10),
//! the actual torque 0x6077 and velocity 0x606C following it both ways, halt to 0. The checks
//! live in tests/python/profile_torque.py.
//!
//! Needs vcan: `./vcan-setup.sh -- cargo nextest run -p e2e --test profile_torque`. Node 37 on bus 0.

use std::process::Command;

use e2e::{drive_emu_bin, iface, python, repo_root, temp_file, Emu, Peer, PEER_TIMEOUT};

#[test]
fn python_canopen_runs_the_drive_in_profile_torque() {
    let ifname = iface(0);
    let eds = Command::new(drive_emu_bin())
        .args(["eds", "--preset", "cnc1", "--node", "37"])
        .output()
        .expect("run drive-emu eds");
    assert!(
        eds.status.success(),
        "drive-emu eds failed: {}",
        String::from_utf8_lossy(&eds.stderr)
    );
    let eds_path = temp_file("node37.eds", &String::from_utf8_lossy(&eds.stdout));
    let mut cmd = Command::new(python());
    cmd.arg(repo_root().join("tests/python/profile_torque.py"))
        .args([&ifname, "37"])
        .arg(&eds_path)
        .env("PYTHONUNBUFFERED", "1");
    let mut peer = Peer::spawn("profile_torque.py", cmd);
    peer.wait_line("READY", PEER_TIMEOUT).unwrap_or_else(|| {
        panic!(
            "profile_torque.py did not start (pip install -r tests/requirements.txt?):\n{}",
            peer.output()
        )
    });
    // started after the script listens, so that it sees the boot-up; lock-step with the
    // script's 10 ms SYNC: the drive's physics do not depend on the host's load
    let emu = Emu::spawn(&[
        "--iface",
        &ifname,
        "--node",
        "37",
        "--preset",
        "cnc1",
        "--lockstep",
        "--sync-period-us",
        "10000",
    ]);
    let verdict = peer.wait_line("PASS", 4 * PEER_TIMEOUT);
    let out = peer.output();
    let status = peer.finish(PEER_TIMEOUT);
    let exit = emu.stop_clean();
    eprintln!("profile_torque.py output:\n{out}");
    assert!(
        verdict.is_some() && status.success(),
        "profile_torque.py failed ({status}); its output:\n{out}\n\ndrive-emu stderr:\n{}",
        exit.stderr
    );
    for step in [
        "STEP PT, OPERATION ENABLED",
        "STEP +200 per mille",
        "STEP -200 per mille",
        "STEP halt",
    ] {
        assert!(out.contains(step), "no `{step}` in the output:\n{out}");
    }
}
