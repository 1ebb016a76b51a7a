//! Vendor behaviour switches (docs/quirks.md) against python canopen, the master of the issue
//! threads: for each case, tests/python/quirks_master.py starts `drive-emu run` with the
//! switch on (a shipped profile or `--quirk`), runs the master code the thread's user ran,
//! asserts how it trips (exception, state, abort code), then starts the drive without the
//! switch and asserts that the same code succeeds. It also checks that the ready line and the
//! start-up message say which profile and switches are on.
//!
//! Needs vcan: `./vcan-setup.sh -- cargo nextest run -p e2e --test quirks`. Bus 0, node IDs
//! 60..=76 (one per case, so the cases run side by side). Nothing here sends SYNC: other tests
//! on bus 0 run drives in lock-step.

use std::process::Command;

use e2e::{drive_emu_bin, iface, python, repo_root, Peer, PEER_TIMEOUT};

/// Run one case of quirks_master.py on node `node`; its output must hold `steps`.
fn case(name: &str, node: u8, steps: &[&str]) {
    let ifname = iface(0);
    let script = repo_root().join("tests/python/quirks_master.py");
    let mut cmd = Command::new(python());
    cmd.arg(&script)
        .args(["--iface", &ifname, "--node", &node.to_string(), "--bin"])
        .arg(drive_emu_bin())
        .arg(name)
        .env("PYTHONUNBUFFERED", "1");
    let mut peer = Peer::spawn("quirks_master.py", cmd);
    peer.wait_line("READY", PEER_TIMEOUT).unwrap_or_else(|| {
        panic!(
            "quirks_master.py did not start (pip install -r tests/requirements.txt?); output:\n{}",
            peer.output()
        )
    });
    let verdict = peer.wait_line("PASS", 8 * PEER_TIMEOUT);
    let out = peer.output();
    let status = peer.finish(PEER_TIMEOUT);
    eprintln!("quirks_master.py {name} output:\n{out}");
    assert!(
        verdict.is_some() && status.success(),
        "quirks_master.py {name} failed ({status}); its output:\n{out}"
    );
    for s in steps {
        assert!(out.contains(s), "no `{s}` in the output:\n{out}");
    }
    assert!(
        out.contains("STEP ready line: profile"),
        "the ready line was not checked:\n{out}"
    );
}

#[test]
fn enable_requires_mode_nanotec_pd4c() {
    case(
        "enable_requires_mode",
        60,
        &[
            "enable without a mode: stays SWITCHED ON",
            "0x6060 = PP: OPERATION ENABLED by itself",
            "enable without a mode: OPERATION ENABLED",
        ],
    );
}

#[test]
fn sdo_response_delay() {
    case(
        "sdo_response_delay",
        61,
        &[
            "delay_ms = 300: every read times out",
            "strict: every read answered",
        ],
    );
}

#[test]
fn sdo_response_delay_every_third_service() {
    case(
        "sdo_response_delay_late_every",
        62,
        &[
            "late_every = 3: reads 3 and 6 time out",
            "strict: every read answered",
        ],
    );
}

#[test]
fn pdo_remap_lenient_and_strict() {
    case(
        "pdo_remap_lenient",
        63,
        &[
            "lenient: entry accepted, TPDO1 carries the statusword alone",
            "entry written while sub 0 = 2: SdoAbortedError 0x06010000",
            "tpdo[1].save() (sub 0 first) accepted",
        ],
    );
}

#[test]
fn pdo_remap_strict_copley_accelnet() {
    case(
        "pdo_remap_copley",
        64,
        &[
            "copley-accelnet: vendor ID 0xAB",
            "entry written while sub 0 = 2: SdoAbortedError 0x06010000",
        ],
    );
}

#[test]
fn tpdo_rtr_unsupported_roboteq() {
    case(
        "tpdo_rtr_unsupported",
        65,
        &[
            "save() without read(): SdoAbortedError 0x06090030",
            "read() first (PR 228): bit 30 kept, save() accepted",
            "strict: save() without read() accepted",
        ],
    );
}

#[test]
fn controlword_min_hold_technosoft() {
    case(
        "controlword_min_hold",
        66,
        &[
            "0x80 then 0x06 back to back: still FAULT",
            "0.2 s apart: READY TO SWITCH ON",
            "strict: READY TO SWITCH ON (15 then 2)",
        ],
    );
}

#[test]
fn quick_stop_skips_active_state() {
    case(
        "quick_stop_skips_active_state",
        67,
        &[
            "straight to SWITCH ON DISABLED, never QUICK STOP ACTIVE",
            "strict: QUICK STOP ACTIVE, then SWITCH ON DISABLED",
        ],
    );
}

#[test]
fn mode_change_blocked_by_halt_engel() {
    case(
        "mode_change_blocked_by_halt",
        68,
        &[
            "halt set: 0x6061 stays PV",
            "strict: 0x6061 = PP with halt set",
        ],
    );
}

#[test]
fn homing_method_zero_faulhaber_ignores() {
    case(
        "homing_method_zero_ignore",
        69,
        &[
            "faulhaber: 0x6098 = 0 confirmed, reads 37",
            "strict: 0x6098 = 0 stored",
        ],
    );
}

#[test]
fn homing_method_zero_epos4_refuses() {
    case(
        "homing_method_zero_refuse",
        70,
        &[
            "epos4: 0x6098 = 0 aborted 0x06090030",
            "strict: 0x6098 = 0 stored",
        ],
    );
}

#[test]
fn homing_status_bits_missing() {
    case(
        "homing_status_bits_missing",
        71,
        &["homing(): False", "strict: homing() True"],
    );
}

#[test]
fn bootup_then_heartbeat_nanotec() {
    case(
        "bootup_then_heartbeat",
        72,
        &[
            "reset communication: [0, 127] within 50 ms",
            "strict: the boot-up comes during wait_for_bootup()",
        ],
    );
}

#[test]
fn not_ready_after_bootup() {
    case(
        "not_ready_after_bootup",
        73,
        &[
            "SDO right after the boot-up: SdoCommunicationError",
            "after the 0x7F heartbeat: 0x1000 read",
            "strict: 0x1000 read at once",
        ],
    );
}

#[test]
fn sdo_first_upload_dropped() {
    case(
        "sdo_first_upload_dropped",
        74,
        &[
            "first read of 0x6061: timeout; second: 0",
            "strict: both reads answered",
        ],
    );
}

#[test]
fn sdo_silent_objects() {
    case(
        "sdo_silent_objects",
        75,
        &[
            "setup_402_state_machine(): SdoCommunicationError",
            "strict: setup_402_state_machine() returns",
        ],
    );
}

#[test]
fn unmappable_objects() {
    case(
        "unmappable_objects",
        76,
        &[
            "tpdo[3].save() with 0x6077: SdoAbortedError 0x06040041",
            "strict: 0x6077 mapped",
        ],
    );
}
