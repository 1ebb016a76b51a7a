//! LSS (CiA 305) with python canopen's `LssMaster` as the master: a drive out of the box
//! (`drive-emu run --node 255`, non-configured) is found by `fast_scan()`, given node-ID 40,
//! stores it and boots with it (tests/python/lss_fastscan.py); then drive-emu is restarted
//! with the same `--lss-store` file, as a drive is powered on again, and boots as node 40.
//!
//! Needs vcan: `./vcan-setup.sh -- cargo nextest run -p e2e --test lss`. Bus 0, node 40.

use e2e::{iface, open_bus, python, repo_root, sdo_u32, wait_bootup, Emu, Peer, PEER_TIMEOUT};
use std::process::Command;

const NODE: u8 = 40;
/// The drive's LSS address: 0x1018 of `--node 255` (vendor 0, product 0x402, revision
/// 0x10000, serial number = the power-on node-ID 255).
const IDENTITY: &str = "0,0x402,0x10000,255";

#[test]
fn python_lss_master_gives_a_non_configured_drive_its_node_id_and_the_store_survives_a_restart() {
    let ifname = iface(0);
    let dir = std::env::temp_dir().join(format!("drive-emu-lss-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let store = dir.join("drive.lss");
    let _ = std::fs::remove_file(&store);
    let store_arg = store.display().to_string();
    let args = [
        "--iface",
        &ifname,
        "--node",
        "255",
        "--preset",
        "cnc1",
        "--lss-store",
        &store_arg,
        "--ready",
    ];

    // ---- 1. out of the box: non-configured; python canopen finds and configures it
    let mut emu = Emu::spawn(&args);
    let ready = emu
        .wait_stdout("\"event\":\"ready\"", PEER_TIMEOUT)
        .unwrap_or_else(|| panic!("no ready line; stderr:\n{}", emu.stderr_now()));
    assert!(ready.contains("\"node_id\":255"), "{ready}");
    let script = repo_root().join("tests/python/lss_fastscan.py");
    let mut cmd = Command::new(python());
    cmd.arg(&script)
        .args(["--iface", ifname.as_str(), &NODE.to_string(), IDENTITY])
        .env("PYTHONUNBUFFERED", "1");
    let mut peer = Peer::spawn("lss_fastscan.py", cmd);
    peer.wait_line("READY", PEER_TIMEOUT).unwrap_or_else(|| {
        panic!(
            "lss_fastscan.py did not start (pip install -r tests/requirements.txt?); output:\n{}",
            peer.output()
        )
    });
    let verdict = peer.wait_line("PASS", 4 * PEER_TIMEOUT);
    let out = peer.output();
    let status = peer.finish(PEER_TIMEOUT);
    let exit = emu.stop_clean();
    eprintln!("lss_fastscan.py output:\n{out}");
    assert!(
        verdict.is_some() && status.success(),
        "lss_fastscan.py failed ({status}); its output:\n{out}\n\ndrive-emu stderr:\n{}",
        exit.stderr
    );
    for step in [
        "STEP node 40: nobody there yet",
        "STEP fast_scan found ['0x0', '0x402', '0x10000', '0xff']",
        "STEP inquiries: node-ID 0xFF",
        "STEP configure_node_id(40) and store_configuration() accepted",
        "STEP booted as node 40",
        "STEP switch state selective by identity",
        "STEP configured drives ignore fastscan",
    ] {
        assert!(out.contains(step), "no `{step}` in the output:\n{out}");
    }
    for said in [
        "node-ID 255: non-configured",
        "nothing stored yet",
        "LSS store configuration: node-ID 40, bit timing index 0 (1000 kbit/s) written to",
    ] {
        assert!(
            exit.stderr.contains(said),
            "no `{said}` in:\n{}",
            exit.stderr
        );
    }
    let text = std::fs::read_to_string(&store).expect("the LSS store file was written");
    assert!(text.contains("node_id = 40"), "{text}");

    // ---- 2. powered on again with the same memory: boots as node 40 at once
    let sock = open_bus(&ifname);
    let mut emu = Emu::spawn(&args);
    assert!(
        wait_bootup(&sock, NODE, PEER_TIMEOUT),
        "no boot-up of node {NODE} after the restart; stderr:\n{}",
        emu.stderr_now()
    );
    let ready = emu
        .wait_stdout("\"event\":\"ready\"", PEER_TIMEOUT)
        .expect("ready line");
    assert!(ready.contains("\"node_id\":40"), "{ready}");
    assert_eq!(sdo_u32(&sock, NODE, 0x1000, 0) & 0xFFFF, 402);
    assert_eq!(
        sdo_u32(&sock, NODE, 0x1018, 4),
        255,
        "the serial number stays"
    );
    let exit = emu.stop_clean();
    assert!(
        exit.stderr
            .contains("node-ID 40, bit timing index 0 (1000 kbit/s) (instead of --node 255)"),
        "{}",
        exit.stderr
    );
    let _ = std::fs::remove_dir_all(&dir);
}
