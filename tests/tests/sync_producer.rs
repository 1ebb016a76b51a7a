//! The drive as SYNC producer (0x1005 bit 30, 0x1006, 0x1019 set over SDO), seen with
//! python-can: its SYNC frames on 0x1005's CAN-ID with the counter 1..=0x1019, CiA 301's
//! aborts, its synchronous TPDO2 after each of its SYNCs. The checks live in
//! tests/python/sync_producer.py.
//!
//! Needs vcan: `./vcan-setup.sh -- cargo nextest run -p e2e --test sync_producer`. Node 38 on bus 0.

use std::process::Command;

use e2e::{drive_emu_bin, iface, python, repo_root, temp_file, Emu, Peer, PEER_TIMEOUT};

#[test]
fn python_can_sees_the_drives_own_sync() {
    let ifname = iface(0);
    let eds = Command::new(drive_emu_bin())
        .args(["eds", "--preset", "cnc1", "--node", "38"])
        .output()
        .expect("run drive-emu eds");
    assert!(
        eds.status.success(),
        "drive-emu eds failed: {}",
        String::from_utf8_lossy(&eds.stderr)
    );
    let eds_path = temp_file("node38.eds", &String::from_utf8_lossy(&eds.stdout));
    let mut cmd = Command::new(python());
    cmd.arg(repo_root().join("tests/python/sync_producer.py"))
        .args([&ifname, "38"])
        .arg(&eds_path)
        .env("PYTHONUNBUFFERED", "1");
    let mut peer = Peer::spawn("sync_producer.py", cmd);
    peer.wait_line("READY", PEER_TIMEOUT).unwrap_or_else(|| {
        panic!(
            "sync_producer.py did not start (pip install -r tests/requirements.txt?):\n{}",
            peer.output()
        )
    });
    // started after the script listens, so that it sees the boot-up; in lock-step with no
    // SYNC on the bus but its own: the producer runs on the communication (wall) clock
    let emu = Emu::spawn(&[
        "--iface",
        &ifname,
        "--node",
        "38",
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
    eprintln!("sync_producer.py output:\n{out}");
    assert!(
        verdict.is_some() && status.success(),
        "sync_producer.py failed ({status}); its output:\n{out}\n\ndrive-emu stderr:\n{}",
        exit.stderr
    );
    for step in [
        "STEP SYNC on 0x80",
        "STEP 0x1019 while",
        "STEP operational: TPDO2",
        "STEP stopped, restarted on 0x90",
    ] {
        assert!(out.contains(step), "no `{step}` in the output:\n{out}");
    }
}
