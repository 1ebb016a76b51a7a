//! Live runs on vcan: `drive-emu run --trace` flushing its trace on SIGTERM, and
//! `drive-emu scenario FILE --iface` injecting a scenario's timeline into a drive that an
//! external controller (this test, a minimal CANopen master) runs in lock-step.
//! Node IDs: 32 (trace), 33 (scenario), 34 (SYNC loss in lock-step), 36 (unfinished scenario).

use e2e::*;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Send one SYNC and wait for the drive's answer to it (its last synchronous TPDO, 0x480+n):
/// the pace of a master, with no timing assumed.
fn sync_and_wait(sock: &socketcan::CanSocket, node: u8, i: usize) {
    send(sock, 0x080, &[]);
    recv_matching(sock, PEER_TIMEOUT, |f| {
        id_data(f).0 == 0x480 + u32::from(node)
    })
    .unwrap_or_else(|| panic!("no TPDO4 after SYNC {i}"));
}

/// Read a CSV into a header and rows of numbers.
fn read_csv(path: &std::path::Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("header")
        .split(',')
        .map(String::from)
        .collect();
    let rows = lines
        .map(|l| {
            l.split(',')
                .map(|x| x.parse().unwrap_or_else(|e| panic!("`{x}` in `{l}`: {e}")))
                .collect()
        })
        .collect();
    (header, rows)
}

#[test]
fn run_trace_is_complete_after_sigterm() {
    const NODE: u8 = 32;
    const SYNCS: usize = 600;
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let trace = temp_file("run-trace.csv", "");
    std::fs::remove_file(&trace).unwrap();
    let emu = Emu::spawn(&[
        "--iface",
        &ifname,
        "--node",
        "32",
        "--lockstep",
        "--trace",
        trace.to_str().unwrap(),
    ]);
    assert!(
        wait_bootup(&sock, NODE, PEER_TIMEOUT),
        "no boot-up; {}",
        emu.stderr_now()
    );
    // Operational, then a move in profile velocity mode so the trace has motion in it.
    nmt(&sock, 0x01, NODE);
    sdo_download(&sock, NODE, 0x6060, 0, &[3]).expect("mode PV");
    sdo_download(&sock, NODE, 0x60FF, 0, &20_000i32.to_le_bytes()).expect("target velocity");
    for cw in [0x06u16, 0x07, 0x0F] {
        sdo_download(&sock, NODE, 0x6040, 0, &cw.to_le_bytes()).expect("controlword");
        sync_and_wait(&sock, NODE, 0);
    }
    for i in 0..SYNCS {
        sync_and_wait(&sock, NODE, i);
    }
    let exit = emu.stop_clean();
    assert!(
        exit.stderr.contains("drive-emu: trace: "),
        "{}",
        exit.stderr
    );

    let (header, rows) = read_csv(&trace);
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no {name}"))
    };
    // Lock-step: one row per SYNC, the last one included (flushed on SIGTERM).
    assert_eq!(rows.len(), SYNCS + 3, "rows in the trace");
    let (t, sw, v) = (col("t_s"), col("statusword"), col("velocity_uu_s"));
    for w in rows.windows(2) {
        assert!(
            (w[1][t] - w[0][t] - 1e-3).abs() < 1e-9,
            "1 ms apart: {:?}",
            w
        );
    }
    let last = rows.last().unwrap();
    assert_eq!(last[sw] as u16 & 0x6F, 0x27, "operation enabled at the end");
    // 20 mm/s reached within the 0.6 s (CNC1 accelerates in a few tens of ms).
    assert!((last[v] - 20_000.0).abs() < 1_000.0, "velocity {}", last[v]);
}

#[test]
fn scenario_timeline_live_on_vcan_against_an_external_controller() {
    const NODE: u8 = 33;
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let file = repo_root().join("scenarios/encoder-loss.toml");
    let trace = temp_file("scenario-live.csv", "");
    let mut child = Command::new(drive_emu_bin())
        .args([
            "scenario",
            file.to_str().unwrap(),
            "--iface",
            &ifname,
            "--node",
            "33",
            // The scenario's end (without it: once its event has run its course).
            "--duration",
            "3",
        ])
        .args(["--lockstep", "--trace", trace.to_str().unwrap()])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start drive-emu scenario");
    assert!(
        wait_bootup(&sock, NODE, PEER_TIMEOUT),
        "no boot-up from the scenario's drive"
    );

    // The external controller: start, profile velocity at 10 mm/s, enable, then SYNC after
    // SYNC until the scenario ends (lock-step: its clock is our SYNCs).
    nmt(&sock, 0x01, NODE);
    sdo_download(&sock, NODE, 0x6060, 0, &[3]).expect("mode PV");
    sdo_download(&sock, NODE, 0x60FF, 0, &10_000i32.to_le_bytes()).expect("target velocity");
    for cw in [0x06u16, 0x07, 0x0F] {
        sdo_download(&sock, NODE, 0x6040, 0, &cw.to_le_bytes()).expect("controlword");
        sync_and_wait(&sock, NODE, 0);
    }
    let deadline = Instant::now() + Duration::from_secs(600);
    let mut i = 0usize;
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        assert!(Instant::now() < deadline, "the scenario never ended");
        send(&sock, 0x080, &[]);
        // Pace on the answer, but the drive stops answering when the scenario ends.
        let _ = recv_matching(&sock, Duration::from_secs(2), |f| {
            id_data(f).0 == 0x480 + u32::from(NODE)
        });
        i += 1;
    };
    assert!(i + 3 >= 3000, "{i} SYNCs for a 3 s scenario");
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        status.success(),
        "scenario --iface: {status}\nstdout:\n{stdout}\nstderr:\n{stderr}"
    );
    eprintln!("{stdout}");
    assert!(stdout.contains("encoder-loss (live on"), "{stdout}");
    assert!(stdout.contains("EMCY 0x7300"), "{stdout}");
    assert!(!stdout.contains("[FAIL"), "{stdout}");

    // The trace shows the same story: operation enabled, then FAULT to the end.
    let (header, rows) = read_csv(&trace);
    let sw = header.iter().position(|h| h == "statusword").unwrap();
    let state = |r: &Vec<f64>| r[sw] as u16;
    let enabled = rows
        .iter()
        .position(|r| state(r) & 0x6F == 0x27)
        .expect("enabled");
    let fault = rows
        .iter()
        .position(|r| state(r) & 0x4F == 0x08)
        .expect("fault");
    assert!(
        enabled < fault,
        "enabled at row {enabled}, fault at row {fault}"
    );
    // The loss came at least 1 s (1000 SYNCs) after enabling, as the scenario says (later by
    // however long the scenario thread took to notice: its clock is the wall's, the drive's
    // is our SYNCs), and the fault followed the event the scenario reports within 10 ms.
    assert!(
        fault - enabled >= 1000,
        "fault {} rows after enabling",
        fault - enabled
    );
    let t = header.iter().position(|h| h == "t_s").unwrap();
    let fired_s: f64 = stdout
        .lines()
        .find(|l| l.contains("event: sensor"))
        .and_then(|l| {
            l.trim()
                .strip_prefix("t=")?
                .split_whitespace()
                .next()?
                .parse()
                .ok()
        })
        .unwrap_or_else(|| panic!("no event line in:\n{stdout}"));
    let dt_ms = (rows[fault][t] - fired_s) * 1e3;
    assert!(
        (0.0..=10.0).contains(&dt_ms),
        "fault {dt_ms} ms after the event"
    );
    assert!(
        rows[fault..].iter().all(|r| state(r) & 0x4F == 0x08),
        "stays in FAULT"
    );
}

/// `run --scenario sync-loss.toml --lockstep --json` with this test as the controller: the
/// scenario cuts the SYNCs on their way into the drive, so its lock-step clock would stand
/// still and the run would never end. A second after the last SYNC the drive's own clock
/// takes over: it reports the SYNC loss (EMCY 0x8100) after the event, and the run ends by
/// itself. Its stdout is one JSON document with the events, the EMCYs and the expectations.
#[test]
fn sync_loss_in_lockstep_ends_the_live_run_and_json_reports_it() {
    const NODE: u8 = 34;
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let file = repo_root().join("scenarios/sync-loss.toml");
    let mut child = Command::new(drive_emu_bin())
        .args([
            "run",
            "--rt-priority",
            "0",
            "--no-mlock",
            "--iface",
            &ifname,
        ])
        .args(["--node", "34", "--lockstep", "--json", "--scenario"])
        .arg(&file)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start drive-emu run --scenario");
    assert!(wait_bootup(&sock, NODE, PEER_TIMEOUT), "no boot-up");
    // The controller: 1 ms communication cycle (the drive's lock-step period comes from
    // 0x1006), CSP, enable, then SYNC until the run ends.
    sdo_download(&sock, NODE, 0x1006, 0, &1000u32.to_le_bytes()).expect("0x1006");
    nmt(&sock, 0x01, NODE);
    sdo_download(&sock, NODE, 0x6060, 0, &[8]).expect("mode CSP");
    for cw in [0x06u16, 0x07, 0x0F] {
        sdo_download(&sock, NODE, 0x6040, 0, &cw.to_le_bytes()).expect("controlword");
        sync_and_wait(&sock, NODE, 0);
    }
    let deadline = Instant::now() + Duration::from_secs(300);
    let mut syncs = 0usize;
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        assert!(
            Instant::now() < deadline,
            "the run did not end after its SYNCs were cut ({syncs} SYNCs sent)"
        );
        send(&sock, 0x080, &[]);
        syncs += 1;
        // Paced by the drive's answer while it sees SYNC; after the cut there is none.
        let _ = recv_matching(&sock, Duration::from_millis(20), |f| {
            id_data(f).0 == 0x480 + u32::from(NODE)
        });
    };
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    eprintln!("{stderr}");
    assert!(
        status.success(),
        "{status}\nstdout:\n{stdout}\nstderr:\n{stderr}"
    );
    let v: serde_json::Value = serde_json::from_str(&stdout)
        .unwrap_or_else(|e| panic!("stdout is not one JSON document ({e}):\n{stdout}"));
    let sc = &v["scenario"];
    assert_eq!(sc["passed"], true, "{stdout}");
    assert_eq!(v["lockstep_sync_period_us"], 1000, "{stdout}");
    assert!(
        v["free_run_ticks_without_sync"].as_u64().unwrap() > 0,
        "{stdout}"
    );
    let events = sc["events"].as_array().expect("events");
    assert_eq!(events.len(), 1, "{stdout}");
    assert!(
        events[0]["event"].as_str().unwrap().contains("SYNC lost"),
        "{stdout}"
    );
    let t_event = events[0]["t_s"].as_f64().unwrap();
    let emcy = sc["emcys"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["code"] == "0x8100")
        .unwrap_or_else(|| panic!("no EMCY 0x8100 in {stdout}"));
    assert!(emcy["t_s"].as_f64().unwrap() > t_event, "{stdout}");
    let exps = sc["expectations"].as_array().expect("expectations");
    assert!(
        !exps.is_empty() && exps.iter().all(|e| e["passed"] == true),
        "{stdout}"
    );
}

/// `run --scenario FILE --duration 1` where the file's second event comes at 100 s: the run
/// ends at 1 s with that event not fired. The scenario did not finish, so the run fails (exit
/// status not 0) and says so, in its JSON and on stderr, though its one expectation held.
#[test]
fn run_scenario_that_does_not_finish_exits_non_zero_and_says_so() {
    const NODE: u8 = 36;
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let file = temp_file(
        "unfinished.toml",
        r#"
name = "unfinished"
[machine]
preset = "cnc1"
[[motion]]
step = "enable"
mode = "csp"
[[event]]
at = "0.2 s"
set = "backlash_mm"
value = 0.03
[[event]]
at = "100 s"
sensor = "direct_encoder_loss"
[[expect]]
no_emcy = true
"#,
    );
    let mut child = Command::new(drive_emu_bin())
        .args([
            "run",
            "--rt-priority",
            "0",
            "--no-mlock",
            "--iface",
            &ifname,
        ])
        .args(["--node", "36", "--lockstep", "--json", "--duration", "1"])
        .arg("--scenario")
        .arg(&file)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start drive-emu run --scenario");
    assert!(wait_bootup(&sock, NODE, PEER_TIMEOUT), "no boot-up");
    nmt(&sock, 0x01, NODE);
    let deadline = Instant::now() + Duration::from_secs(300);
    let mut i = 0usize;
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        assert!(Instant::now() < deadline, "the run never ended");
        send(&sock, 0x080, &[]);
        let _ = recv_matching(&sock, Duration::from_secs(2), |f| {
            id_data(f).0 == 0x480 + u32::from(NODE)
        });
        i += 1;
    };
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !status.success(),
        "an unfinished scenario exited 0 after {i} SYNCs\nstdout:\n{stdout}\nstderr:\n{stderr}"
    );
    let v: serde_json::Value = serde_json::from_str(&stdout)
        .unwrap_or_else(|e| panic!("stdout is not one JSON document ({e}):\n{stdout}"));
    let sc = &v["scenario"];
    assert_eq!(sc["passed"], false, "{stdout}");
    assert_eq!(sc["finished"], false, "{stdout}");
    assert!(
        sc["failure"]
            .as_str()
            .is_some_and(|f| f.contains("did not finish") && f.contains("line 12")),
        "{stdout}"
    );
    assert_eq!(sc["events_not_fired"].as_array().map(Vec::len), Some(1));
    assert!(
        sc["expectations"]
            .as_array()
            .is_some_and(|e| e.iter().all(|x| x["passed"] == true)),
        "{stdout}"
    );
    assert!(
        stderr.contains("error: the scenario did not finish"),
        "{stderr}"
    );
}
