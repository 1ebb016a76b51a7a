//! The live panel on EtherCAT: `drive-emu run --ethercat IFACE --panel ADDR` on a veth pair,
//! SOEM (pysoem, tests/python/ethercat_panel.py) holding the slave enabled in OP, clients over
//! real HTTP. The panel says the run is on EtherCAT and offers EtherCAT's faults, not CAN's;
//! its stream shows the slave's drive (published from the EtherCAT loop through the same
//! observation fan-out as on CAN); a CAN fault is refused with the reason; a parameter set on
//! the panel reads back over CoE in the master; frames corrupted from the panel show in the
//! slave's RX error counter (0x0300) the master reads and clears; an EtherCAT fault from the
//! panel (the slave out of OP with an AL status code) is what the master sees; the saved
//! session replays them.
//!
//! Root (or CI, where a veth pair that cannot be made fails the test): see ethercat_rig.

mod ethercat_rig;
mod panel_rig;

use drive_emu::bus::ethercat::EcatFault;
use drive_emu::scenario::timeline::Action;
use ethercat_rig::*;
use panel_rig::SseReader;
use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Read};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(20)))
        .build()
        .into()
}

fn get(url: &str) -> Value {
    agent()
        .get(url)
        .call()
        .unwrap()
        .body_mut()
        .read_json()
        .unwrap()
}

fn inject(base: &str, body: Value) -> (u16, Value) {
    let mut r = agent()
        .post(&format!("{base}/api/inject"))
        .send_json(&body)
        .unwrap();
    (r.status().as_u16(), r.body_mut().read_json().unwrap())
}

/// The master's next JSON line with `key`, within `timeout`.
fn line_with(rx: &mpsc::Receiver<String>, key: &str, timeout: Duration) -> Value {
    let end = std::time::Instant::now() + timeout;
    loop {
        let left = end.saturating_duration_since(std::time::Instant::now());
        let l = rx
            .recv_timeout(left)
            .unwrap_or_else(|_| panic!("the master never said {key}"));
        if let Ok(v) = serde_json::from_str::<Value>(&l) {
            if v.get(key).is_some() {
                return v;
            }
        }
    }
}

#[test]
fn the_panel_shows_and_injects_into_an_ethercat_slave_pysoem_holds_in_op() {
    if !may_run("ethercat_panel") {
        return;
    }
    let veth = Veth::create('p').unwrap_or_else(|e| panic!("cannot create the veth pair: {e}"));
    let port = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let addr = format!("127.0.0.1:{port}");
    let base = format!("http://{addr}");
    let dir = std::env::temp_dir().join(format!("drive-emu-ecat-panel-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut emu = Emulator::start(
        &veth.slave,
        &[
            "--set",
            "backlash_mm=0",
            "--panel",
            &addr,
            "--panel-dir",
            dir.to_str().unwrap(),
        ],
    );

    // The run is on EtherCAT, its bus faults are EtherCAT's.
    let t0 = std::time::Instant::now();
    while std::net::TcpStream::connect(&addr).is_err() {
        assert!(t0.elapsed() < Duration::from_secs(60), "no panel on {addr}");
        std::thread::sleep(Duration::from_millis(50));
    }
    let hello = get(&format!("{base}/api/info"));
    assert_eq!(hello["bus"], "ethercat", "{hello}");
    assert!(
        hello["controls"]["ethercat"]["out_of_op"].is_object(),
        "{hello}"
    );
    assert!(hello["controls"].get("can").is_none(), "{hello}");
    let (code, v) = inject(&base, json!({"can": "sync_loss"}));
    assert_eq!(code, 400, "{v}");
    assert_eq!(v["key"], "can", "{v}");
    assert!(
        v["error"].as_str().unwrap().contains("EtherCAT"),
        "the reason names the run's bus: {v}"
    );

    // SOEM takes the slave to OP and enables it; its lines come through a channel.
    let mut master = Command::new("timeout")
        .arg("180")
        .arg("python3")
        .arg(repo().join("tests/python/ethercat_panel.py"))
        .arg(&veth.master)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 runs");
    let (tx, rx) = mpsc::channel();
    let out = master.stdout.take().unwrap();
    std::thread::spawn(move || {
        for l in BufReader::new(out).lines().map_while(Result::ok) {
            if tx.send(l).is_err() {
                break;
            }
        }
    });
    let op = line_with(&rx, "op", Duration::from_secs(120));
    assert_eq!(op["statusword"].as_u64().unwrap() & 0x6F, 0x27, "{op}");

    // The stream shows the slave's drive enabled: published from the EtherCAT loop.
    let resp = agent().get(&format!("{base}/api/stream")).call().unwrap();
    let reader: Box<dyn Read + Send + Sync> = Box::new(resp.into_body().into_reader());
    let mut sse = SseReader {
        reader: BufReader::new(reader),
    };
    let mut enabled = None;
    for _ in 0..2000 {
        let (ev, data) = sse.next_event().expect("the stream ended");
        if ev != "samples" {
            continue;
        }
        let v: Value = serde_json::from_str(&data).unwrap();
        let st = &v["axes"][0]["state"];
        if st["cia402_state"] == "OPERATION ENABLED" && st["nmt_name"].is_string() {
            enabled = Some(v);
            break;
        }
    }
    let enabled = enabled.expect("the stream never showed the slave's drive OPERATION ENABLED");
    assert_eq!(enabled["axes"][0]["state"]["mode"], 8, "CSP: {enabled}");
    drop(sse);

    // A parameter set on the panel reads back over CoE.
    assert_eq!(
        line_with(&rx, "backlash_mm", Duration::from_secs(60))["backlash_mm"],
        0.0
    );
    let (code, v) = inject(&base, json!({"set": "backlash_mm", "value": 0.042}));
    assert_eq!(code, 200, "{v}");
    assert_eq!(
        line_with(&rx, "backlash_mm", Duration::from_secs(60))["backlash_mm"],
        0.042,
        "0x2000 read over CoE by SOEM"
    );

    // Frames corrupted on the wire: no answer, and the slave's RX error counter says how many.
    let (code, v) = inject(&base, json!({"ethercat": "corrupt", "frames": 5}));
    assert_eq!(code, 200, "{v}");
    let errors = line_with(&rx, "rx_errors", Duration::from_secs(60));
    assert_eq!(errors["rx_errors"], 5, "0x0300 read by SOEM: {errors}");
    assert_eq!(
        errors["forwarded"], 0,
        "one slave: nothing forwarded: {errors}"
    );
    let cleared = line_with(&rx, "rx_errors_after_clear", Duration::from_secs(60));
    assert_eq!(
        cleared["rx_errors_after_clear"], 0,
        "a write to 0x0300 clears: {cleared}"
    );

    // An EtherCAT fault from the panel: the slave drops out of OP with its AL status code.
    let (code, v) = inject(&base, json!({"ethercat": "out_of_op", "al_code": "0x001A"}));
    assert_eq!(code, 200, "{v}");
    let left = line_with(&rx, "al_status", Duration::from_secs(60));
    assert_eq!(left["al_status"], 0x14, "SAFE-OP + error: {left}");
    assert_eq!(left["al_status_code"], 0x001A, "{left}");
    let status = master.wait().unwrap();
    let mut err = String::new();
    master
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert!(status.success(), "the master failed: {err}");

    // The saved session replays both injections on EtherCAT.
    let session = agent()
        .get(&format!("{base}/api/session"))
        .call()
        .unwrap()
        .body_mut()
        .read_to_string()
        .unwrap();
    assert!(session.contains("backlash_mm"), "{session}");
    assert!(session.contains("ethercat = \"out_of_op\""), "{session}");
    let file = dir.join("session.toml");
    std::fs::write(&file, &session).unwrap();
    // A file `run --ethercat --scenario` takes: parsed as one, its events in order.
    let replay = drive_emu::scenario::load(&file)
        .unwrap_or_else(|e| panic!("the saved session is not a scenario: {e}\n{session}"));
    assert_eq!(replay.events.len(), 3, "{session}");
    assert!(
        matches!(replay.events[0].action, Action::Set { value, .. } if value == 0.042),
        "{session}"
    );
    assert!(
        matches!(
            replay.events[1].action,
            Action::Ethercat {
                fault: EcatFault::Corrupt { frames: 5, .. },
                ..
            }
        ),
        "{session}"
    );
    assert!(
        matches!(
            replay.events[2].action,
            Action::Ethercat {
                fault: EcatFault::OutOfOp { al_code: 0x001A },
                ..
            }
        ),
        "{session}"
    );
    drive_emu::scenario::live::check_bus(&replay, "ethercat").expect("its faults are EtherCAT's");

    let (stats, _) = emu.stop();
    assert!(stats["cycles"].as_u64().unwrap() > 0, "{stats}");
    assert_eq!(stats["faults"]["corrupted"], 5, "{stats}");
    let _ = std::fs::remove_dir_all(&dir);
}
