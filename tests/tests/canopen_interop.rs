//! python `canopen` (the pinned version of tests/requirements.txt) as the master of the
//! emulator: BaseNode402 state machine, mode switches, a PP move, every EDS object over
//! SDO, a TPDO remap received on SYNC, heartbeat loss -> EMCY 0x8130 and the configured
//! reaction. The checks live in tests/python/interop_402.py; this drives it.
//!
//! Needs vcan: `./vcan-setup.sh -- cargo nextest run -p e2e --test canopen_interop`.
//! Node id 10 on bus 0.

use std::process::Command;

use e2e::{drive_emu_bin, iface, python, repo_root, temp_file, Emu, Peer, PEER_TIMEOUT};

#[test]
fn python_canopen_base_node_402_drives_the_emulator() {
    let ifname = iface(0);
    let eds = Command::new(drive_emu_bin())
        .args(["eds", "--preset", "cnc1", "--node", "10"])
        .output()
        .expect("run drive-emu eds");
    assert!(
        eds.status.success(),
        "drive-emu eds failed: {}",
        String::from_utf8_lossy(&eds.stderr)
    );
    let eds_path = temp_file("node10.eds", &String::from_utf8_lossy(&eds.stdout));

    let script = repo_root().join("tests/python/interop_402.py");
    let mut cmd = Command::new(python());
    cmd.arg(&script)
        .args([&ifname, "10"])
        .arg(&eds_path)
        .env("PYTHONUNBUFFERED", "1");
    let mut peer = Peer::spawn("interop_402.py", cmd);
    peer.wait_line("READY", PEER_TIMEOUT).unwrap_or_else(|| {
        panic!(
            "interop_402.py did not start (pip install -r tests/requirements.txt?); output:\n{}",
            peer.output()
        )
    });
    // started after the master listens, so that it sees the boot-up
    // lock-step with the script's 10 ms SYNC: the drive's physics do not depend on the
    // host's load (in real time, a loaded UML skips ticks and the PP move overshoots)
    let emu = Emu::spawn(&[
        "--iface",
        &ifname,
        "--node",
        "10",
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
    eprintln!("interop_402.py output:\n{out}");
    assert!(
        verdict.is_some() && status.success(),
        "interop_402.py failed ({status}); its output:\n{out}\n\ndrive-emu stderr:\n{}",
        exit.stderr
    );
    for step in [
        "STEP SDO: read all",
        "STEP remapped TPDO3 received on SYNC",
        "STEP OPERATION ENABLED",
        "STEP modes PV -> CSP -> PP",
        "STEP PP move",
        "STEP EMCY",
        "STEP reaction: FAULT",
    ] {
        assert!(out.contains(step), "no `{step}` in the output:\n{out}");
    }
}
