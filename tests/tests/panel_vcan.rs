//! The live panel in a real browser against `drive-emu run --panel` on vcan0, moved by a
//! python canopen master (tests/python/panel_master.py, BaseNode402 in profile position):
//! Debian's Chromium headless shell through chromium-driver's WebDriver API (the client
//! shared with the host test, emulator/tests/webdriver). The page shows OPERATION ENABLED; at
//! each target the master reached, the position the page plotted last equals 0x6064 the
//! master read over SDO; a backlash set with the page's control reads back over SDO from
//! 0x2000 in the master. Run inside user-mode Linux by ./test-all.sh (docs/vcan.md). With
//! `DRIVE_EMU_PANEL_VCAN_SCREENSHOT=PATH` the page's screenshot at the end is written there
//! (the README's second picture, docs/img/panel-vcan.png).

#[path = "../../emulator/tests/webdriver/mod.rs"]
mod webdriver;

use e2e::{drive_emu_bin, iface, python, repo_root, Emu, Peer};
use serde_json::{json, Value};
use std::process::Command;
use std::time::Duration;
use webdriver::Driver;

/// The JSON line of the master's that has `key`.
fn line_with(master: &mut Peer, key: &str, timeout: Duration) -> Value {
    let l = master
        .wait_line(&format!("\"{key}\""), timeout)
        .unwrap_or_else(|| panic!("the master never said {key}:\n{}", master.output()));
    serde_json::from_str(&l).unwrap()
}

#[test]
fn the_page_shows_a_drive_on_vcan_moved_by_python_canopen() {
    let bus = iface(0);
    let dir = std::env::temp_dir().join(format!("drive-emu-panel-vcan-{}", std::process::id()));
    // Under user-mode Linux the process IDs repeat from boot to boot: a run that failed left
    // its go-N files here, which would let the master run ahead of this one.
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let eds = dir.join("drive.eds");
    let out = Command::new(drive_emu_bin())
        .args([
            "eds", "--preset", "cnc1", "--node", "5", "--real32", "decimal",
        ])
        .output()
        .unwrap();
    assert!(out.status.success());
    std::fs::write(&eds, &out.stdout).unwrap();
    let port = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let addr = format!("127.0.0.1:{port}");
    // The browser first: it is the slowest to start in user-mode Linux, and starting it
    // beside the drive's 1 kHz loop and python importing canopen slowed all three.
    let d = Driver::start();
    let emu = Emu::spawn(&[
        "--iface",
        &bus,
        "--node",
        "5",
        "--set",
        "backlash_mm=0",
        "--panel",
        &addr,
        "--panel-dir",
        dir.to_str().unwrap(),
    ]);
    let mut cmd = Command::new(python());
    cmd.arg(repo_root().join("tests/python/panel_master.py"))
        .args(["--iface", &bus, "--node", "5", "--eds"])
        .arg(&eds)
        .arg("--dir")
        .arg(&dir);
    let mut master = Peer::spawn("panel_master.py", cmd);
    // The panel listens once the drive runs.
    let t0 = std::time::Instant::now();
    while std::net::TcpStream::connect(&addr).is_err() {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "no panel on {addr}: {}",
            emu.stderr_now()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    d.go(&format!("http://{addr}/"));
    line_with(&mut master, "enabled", Duration::from_secs(120));
    // Record the moves: a CSV per axis and a capture of the bus.
    let post = |path: &str, body: Value| -> Value {
        let mut r = ureq::post(&format!("http://{addr}{path}"))
            .send_json(body)
            .unwrap_or_else(|e| panic!("{path}: {e}"));
        r.body_mut().read_json().unwrap()
    };
    let rec = post("/api/record", json!({"action": "start"}));
    assert_eq!(rec["active"]["capture"], "rec-1.log", "{rec}");
    let st = d.wait_js(
        Duration::from_secs(60),
        "return panel.state(0) === 'OPERATION ENABLED' ? panel.state(0) : null",
    );
    assert_eq!(st, "OPERATION ENABLED");
    for i in 0..2 {
        std::fs::write(dir.join(format!("go-{i}")), "").unwrap();
        let at = line_with(&mut master, "at", Duration::from_secs(120));
        let sdo = at["position"].as_f64().unwrap();
        // The page's last plotted position, once the plot shows the axis standing there.
        let v = d.wait_js(
            Duration::from_secs(120),
            &format!("const p = panel.plotted(0); return p && Math.abs(p.position_actual_uu - {sdo}) <= 3 ? p : null"),
        );
        assert!(
            v["position_actual_uu"].is_number(),
            "target {}: 0x6064 over SDO {sdo}, the page plots {:?}",
            at["at"],
            d.js("return panel.plotted(0)", json!([]))
        );
    }
    let rec = post("/api/record", json!({"action": "stop"}));
    assert_eq!(
        rec["files"],
        json!(["rec-1-node5.csv", "rec-1.log"]),
        "{rec}"
    );
    // Both downloadable, and both read by `drive-emu analyze`.
    for name in ["rec-1-node5.csv", "rec-1.log"] {
        let text = ureq::get(&format!("http://{addr}/api/record/file/{name}"))
            .call()
            .unwrap()
            .body_mut()
            .read_to_string()
            .unwrap();
        assert!(
            text.lines().count() > 100,
            "{name}: {} lines",
            text.lines().count()
        );
        let file = dir.join(format!("download-{name}"));
        std::fs::write(&file, &text).unwrap();
        let out = Command::new(drive_emu_bin())
            .args(["analyze", "--preset", "cnc1", "--json", "--out"])
            .arg(dir.join(format!("analyze-{name}")))
            .arg(&file)
            .output()
            .unwrap();
        // 0: a verdict, 3: inconclusive (PP moves hold no long constant speed); 2 and 4
        // would be a file it cannot read.
        assert!(
            matches!(out.status.code(), Some(0) | Some(3)),
            "analyze {name}: {:?} {}",
            out.status.code(),
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert!(v.is_object(), "{v}");
    }
    assert_eq!(
        line_with(&mut master, "backlash_mm", Duration::from_secs(120))["backlash_mm"],
        0.0
    );
    d.click("#param-key option[value='backlash_mm']");
    d.type_into("#param-value", "0.042");
    d.click("#param-set");
    let b = line_with(&mut master, "backlash_mm", Duration::from_secs(60));
    assert_eq!(
        b["backlash_mm"], 0.042,
        "0x2000 read over SDO by the master"
    );
    // The picture for the README: both moves, at a 30 s span.
    d.select("#span", "30");
    let logged = d.wait_js(
        Duration::from_secs(60),
        "const li = document.querySelector('#injections li'); \
         return li && li.textContent.includes('backlash_mm = 0.042') ? li.textContent : null",
    );
    assert!(logged.is_string(), "the page logged {logged}");
    d.screenshot_to("DRIVE_EMU_PANEL_VCAN_SCREENSHOT");
    std::fs::write(dir.join("done"), "").unwrap();
    let status = master.finish(Duration::from_secs(30));
    assert!(status.success(), "the master failed");
    drop(d);
    let exit = emu.stop_clean();
    assert!(
        exit.stdout.contains("panel: t="),
        "the injection on stdout: {}",
        exit.stdout
    );
    let _ = std::fs::remove_dir_all(&dir);
}
