//! `drive-emu run --detect` on vcan (issue 19, item 4): the drive runs the backlash detector
//! on its own samples while the reference master (`drive-emu demo --iface`, another process)
//! runs it healthy and then worn; the drive's objects (0x2102) say backlash with the limit
//! cycle's frequency, its EMCY 0xFF01 warning is active (0x1001 bit 7, 0x1003), and what it
//! says of the run when it stops is what `drive-emu analyze` says of the same run's
//! `--trace`. Lock-step: nothing depends on how busy the host is.
//!
//! Needs vcan: `./vcan-setup.sh -- cargo nextest run -p e2e --test run_detect`.

use e2e::*;
use std::process::Command;
use std::time::Duration;

const NODE: u8 = 32;

#[test]
fn the_drive_watching_itself_says_what_analyze_says_of_its_trace() {
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let trace = temp_file("run-detect-trace.csv", "");
    let node = NODE.to_string();
    let emu = Emu::spawn(&[
        "--iface",
        &ifname,
        "--node",
        &node,
        "--preset",
        "cnc1",
        "--lockstep",
        "--detect",
        "--trace",
        trace.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        wait_bootup(&sock, NODE, PEER_TIMEOUT),
        "no boot-up; stderr:\n{}",
        emu.stderr_now()
    );
    let demo = Command::new(drive_emu_bin())
        .args([
            "demo", "--iface", &ifname, "--node", &node, "--preset", "cnc1",
        ])
        .args(["--backlash-mm", "0.05", "--cruise-s", "3", "--json"])
        .output()
        .expect("start drive-emu demo");
    assert!(
        demo.status.success(),
        "demo: {}\n{}\ndrive:\n{}",
        demo.status,
        String::from_utf8_lossy(&demo.stderr),
        emu.stderr_now()
    );
    // The demo is done; SYNCs of our own keep the lock-step drive's time (and so its
    // publishing of the detector's results) going for 3 s of drive time.
    for _ in 0..750 {
        send(&sock, 0x080, &[]);
        std::thread::sleep(Duration::from_micros(500));
    }
    sdo_barrier(&sock, NODE);
    let verdict = sdo_u32(&sock, NODE, 0x2102, 1);
    let f_obj = f32::from_bits(sdo_u32(&sock, NODE, 0x2102, 2));
    let analyses = sdo_u32(&sock, NODE, 0x2102, 5);
    eprintln!("0x2102: verdict {verdict}, {f_obj} Hz, {analyses} analyses");
    assert_eq!(verdict, 4, "backlash in 0x2102:1");
    assert!((7.5..=30.0).contains(&f_obj), "0x2102:2 = {f_obj} Hz");
    assert!(analyses >= 2, "{analyses} analyses");
    assert_eq!(sdo_u32(&sock, NODE, 0x1001, 0) & 0x80, 0x80, "0x1001 bit 7");
    // 0x1003 holds it (the newest entry may be another: the demo's heartbeat stopped).
    let n = sdo_u32(&sock, NODE, 0x1003, 0) as u8;
    let history: Vec<u32> = (1..=n).map(|s| sdo_u32(&sock, NODE, 0x1003, s)).collect();
    assert!(
        history.iter().any(|e| e & 0xFFFF == 0xFF01),
        "0x1003: {history:08X?}"
    );
    let exit = emu.stop_clean();
    let out: serde_json::Value = serde_json::from_str(&exit.stdout)
        .unwrap_or_else(|e| panic!("run --json: {e}\n{}", exit.stdout));
    let live = &out["detect"][0]["report"];
    assert_eq!(out["detect"][0]["node_id"], NODE);
    // The same run offline.
    let report_dir = trace.with_extension("report");
    let analyze = Command::new(drive_emu_bin())
        .args([
            "analyze",
            trace.to_str().unwrap(),
            "--kv",
            "30",
            "--json",
            "--out",
        ])
        .arg(&report_dir)
        .output()
        .expect("start drive-emu analyze");
    let offline: serde_json::Value = serde_json::from_slice(&analyze.stdout).unwrap_or_else(|e| {
        panic!(
            "analyze --json: {e}\n{}",
            String::from_utf8_lossy(&analyze.stdout)
        )
    });
    let offline = &offline["report"];
    eprintln!(
        "live: {} {} Hz {} um; analyze: {} {} Hz {} um",
        live["verdict"],
        live["frequency_hz"],
        live["amplitude"],
        offline["verdict"],
        offline["frequency_hz"],
        offline["amplitude"]
    );
    assert_eq!(live["verdict"], "backlash");
    assert_eq!(live["verdict"], offline["verdict"]);
    let (fl, fo) = (
        live["frequency_hz"].as_f64().unwrap(),
        offline["frequency_hz"].as_f64().unwrap(),
    );
    assert!(
        (fl - fo).abs() <= 1e-6 * fo,
        "live {fl} Hz, analyze {fo} Hz"
    );
}
