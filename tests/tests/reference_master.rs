//! The built-in reference master over a CAN interface: `drive-emu demo --iface` against
//! `drive-emu run --iface` in another process, on vcan. Two runs, as in the embedded demo:
//! backlash 0 and 0.05 mm, each set over SDO (0x2000) on the running drive. What the
//! master received in its TPDOs must show the paper's claim: no limit cycle on the healthy
//! axis, a fundamental inside k_v/4 .. k_v on the worn one. The capture of the whole
//! conversation (candump) is then analysed with `drive-emu analyze`, decoded with the
//! drive's PDO mapping.

use e2e::*;
use std::process::Command;
use std::time::{Duration, Instant};

const NODE: u8 = 30;
const KV_PER_S: f64 = 30.0; // preset cnc1

/// Start `candump -L` writing to `path`, and wait until it demonstrably captures (resend a
/// marker frame until it shows in the file).
fn start_capture(ifname: &str, sock: &socketcan::CanSocket, path: &std::path::Path) -> Peer {
    let mut cmd = Command::new("sh");
    cmd.args([
        "-c",
        // Line-buffered: a block-buffered stdout would lose its tail when candump is killed.
        // One write per frame is slow in a loaded UML, so candump falls behind the bus; a
        // 64 MiB receive buffer (SO_RCVBUFFORCE, root in UML: about 64k frames, the whole run)
        // lets it catch up instead of losing frames (with 4 MiB it lost 12 % of the SYNCs).
        &format!(
            "exec stdbuf -oL candump -L -r 67108864 {ifname} > {}",
            path.display()
        ),
    ]);
    let dump = Peer::spawn("candump", cmd);
    wait_for_marker(sock, path, 0x7A1);
    dump
}

/// Send a marker frame until the capture in `path` shows it.
fn wait_for_marker(sock: &socketcan::CanSocket, path: &std::path::Path, id: u16) {
    let deadline = Instant::now() + PEER_TIMEOUT;
    let needle = format!(" {id:03X}#AA");
    loop {
        send(sock, id, &[0xAA]);
        std::thread::sleep(Duration::from_millis(200));
        if std::fs::read_to_string(path).is_ok_and(|t| t.contains(&needle)) {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "candump never captured marker {id:03X}"
        );
    }
}

#[test]
fn reference_master_over_vcan_sees_the_backlash_limit_cycle() {
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let log = temp_file("reference-master.log", "");
    let dump = start_capture(&ifname, &sock, &log);
    let node = NODE.to_string();
    let emu = Emu::spawn(&[
        "--iface",
        &ifname,
        "--node",
        &node,
        "--preset",
        "cnc1",
        "--lockstep",
    ]);
    assert!(
        wait_bootup(&sock, NODE, PEER_TIMEOUT),
        "no boot-up from drive-emu; stderr:\n{}",
        emu.stderr_now()
    );

    let out = Command::new(drive_emu_bin())
        .args([
            "demo",
            "--iface",
            &ifname,
            "--node",
            &node,
            "--preset",
            "cnc1",
            "--backlash-mm",
            "0.05",
            "--cruise-s",
            "3",
            "--json",
        ])
        .output()
        .expect("start drive-emu demo");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "demo --iface failed: {}\nstderr:\n{stderr}\ndrive stderr:\n{}",
        out.status,
        emu.stderr_now()
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "demo --json output: {e}\n{}",
            String::from_utf8_lossy(&out.stdout)
        )
    });
    let runs = report["runs"].as_array().expect("runs");
    let (healthy, worn) = (&runs[0], &runs[1]);
    assert_eq!(healthy["backlash"].as_f64(), Some(0.0));
    assert!(
        healthy["fundamental_hz"].is_null(),
        "the healthy axis vibrates: {healthy}"
    );
    let f = worn["fundamental_hz"]
        .as_f64()
        .unwrap_or_else(|| panic!("no limit cycle with 0.05 mm backlash: {worn}"));
    assert!(
        (KV_PER_S / 4.0..KV_PER_S).contains(&f),
        "f = {f} Hz outside k_v/4 .. k_v"
    );
    // 10 mm/s commanded: a vibration of a few per cent of it, not quantisation noise.
    let amp = worn["velocity_amplitude"].as_f64().unwrap();
    assert!(amp > 0.3, "speed amplitude {amp} mm/s");
    assert!(
        worn["current_amplitude_permille"].as_f64().unwrap() > 5.0,
        "{worn}"
    );

    let syncs_sent: u64 = runs
        .iter()
        .map(|r| r["bus"]["syncs_sent"].as_u64().expect("bus statistics"))
        .sum();

    // Lock-step: the drive works through the SYNCs in its receive queue in order. On a loaded
    // host (UML runs every process on one virtual CPU) it may still be behind when the master
    // is done, so a stop now would cut its queue. An SDO answer to a request sent after the
    // last SYNC says every SYNC before it has been handled.
    sdo_barrier(&sock, NODE);
    let exit = emu.stop_clean();
    // Everything before our end marker is in the file once the marker is.
    wait_for_marker(&sock, &log, 0x7A2);
    drop(dump);
    // The drive counted one tick per SYNC the master sent (lock-step): nothing was lost.
    assert!(exit.stderr.contains("tx dropped 0"), "{}", exit.stderr);
    let ticks = exit.ticks();
    // How many SYNCs a run takes depends on how busy the host is; what must hold is that
    // each run sent some and the drive ticked once for each.
    assert!(
        runs.iter()
            .all(|r| r["bus"]["syncs_sent"].as_u64().is_some_and(|n| n > 0)),
        "a run sent no SYNC: {report}"
    );
    assert_eq!(ticks, syncs_sent, "drive ticks vs SYNCs the master sent");
    // candump, a third busy process in a loaded UML, may miss a few frames; the analysis
    // below then runs on a slightly shorter time base, well inside its 5 % tolerance.
    let capture = std::fs::read_to_string(&log).unwrap();
    let syncs = capture.lines().filter(|l| l.ends_with(" 080#")).count() as u64;
    assert!(
        syncs * 100 >= syncs_sent * 97,
        "candump saw {syncs} of {syncs_sent} SYNCs"
    );

    // The capture, decoded with the drive's PDO mapping (the master remapped it over SDO, twice),
    // gives the detector the same limit cycle the master measured.
    let report_dir = log.with_extension("report");
    let analyze = Command::new(drive_emu_bin())
        .args([
            "analyze",
            log.to_str().unwrap(),
            "--kv",
            "30",
            "--node",
            &node,
        ])
        .args(["--preset", "cnc1", "--out", report_dir.to_str().unwrap()])
        .output()
        .expect("start drive-emu analyze");
    let text = String::from_utf8_lossy(&analyze.stdout);
    eprintln!("{text}");
    assert!(
        analyze.status.success(),
        "analyze: {}\n{text}\n{}",
        analyze.status,
        String::from_utf8_lossy(&analyze.stderr)
    );
    let det: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report_dir.join("detector.json")).unwrap())
            .unwrap();
    let f_log = det["frequency_hz"].as_f64().expect("a frequency");
    assert!(
        (f_log - f).abs() / f < 0.05,
        "from the capture {f_log} Hz, the master saw {f} Hz"
    );
    // Windows in both runs: the healthy ones quiet, the worn ones flagged.
    let levels: Vec<&str> = det["windows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["level"].as_str().unwrap())
        .collect();
    assert!(levels.len() >= 2, "{levels:?}\n{text}");
    assert_eq!(levels[0], "ok", "the healthy run: {levels:?}");
    assert_ne!(levels[levels.len() - 1], "ok", "the worn run: {levels:?}");
    // And the capture's verdict is the machine's state at its end: worn (it once said "ok"
    // because the worn run's one long window could not confirm itself).
    let verdict = det["verdict"].as_str().unwrap();
    assert!(
        verdict == "backlash" || verdict == "backlash_suspected",
        "verdict {verdict}: {}",
        det["reasons"]
    );
}
