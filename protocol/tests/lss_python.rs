//! python canopen's `LssMaster` (pinned in tests/requirements.txt) against our nodes on the
//! host, without a CAN kernel: tests/python/lss_fastscan.py speaks CAN frames as lines on
//! its stdin / stdout (a python-can bus of its own), and this harness runs three
//! non-configured nodes with different LSS addresses on that "bus", in wall-clock time.
//! python canopen's real `fast_scan()` must find each once, in address order, and give it its
//! node-ID; each boots (boot-up after the 200 ms boot delay) and answers SDO; selective
//! switch and inquire work; configured nodes ignore fastscan. Missing python / canopen FAILS.
//!
//! On a real bus, identical frames sent at once by several nodes (the 0x4F answers of
//! fastscan) arbitrate as one frame: the harness sends them once.
mod common;
use common::*;
use drive_protocol::{CanFrame, Node};
use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const SCRIPT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../tests/python/lss_fastscan.py"
);

/// Nodes built as `Node::new(serial)` take `serial` as 0x1018:4, then power on
/// non-configured.
const SERIALS: [u8; 3] = [4, 1, 2];
const FIRST_NODE: u8 = 20;

fn frame_line(f: &CanFrame) -> String {
    let hex: String = f.payload().iter().map(|b| format!("{b:02x}")).collect();
    format!("F {:X} {hex}\n", f.id)
}

fn parse_frame(line: &str) -> Option<CanFrame> {
    let mut it = line.split_whitespace();
    if it.next()? != "F" {
        return None;
    }
    let id = u32::from_str_radix(it.next()?, 16).ok()?;
    let hex = it.next().unwrap_or("");
    let data: Vec<u8> = (0..hex.len() / 2)
        .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16))
        .collect::<Result<_, _>>()
        .ok()?;
    Some(CanFrame::new(id, &data))
}

#[test]
fn python_lss_master_finds_and_configures_three_non_configured_nodes() {
    let mut nodes: Vec<Node> = SERIALS
        .iter()
        .map(|&s| Node::new(lss_config(255, s as u32, 200_000, 0, false)).unwrap())
        .collect();
    let mut drives: Vec<SimDrive> = SERIALS.iter().map(|_| SimDrive::default()).collect();
    let identities: Vec<String> = SERIALS
        .iter()
        .map(|s| format!("0,0x402,0x10000,{s}"))
        .collect();

    let mut child = Command::new("python3")
        .arg(SCRIPT)
        .arg("--pipe")
        .arg(FIRST_NODE.to_string())
        .args(&identities)
        .env("PYTHONUNBUFFERED", "1")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| {
            panic!("python3 not runnable ({e}); install python3 and `pip install -r tests/requirements.txt`")
        });
    let mut to_py = child.stdin.take().unwrap();
    let (tx, rx) = mpsc::channel::<String>();
    let out = child.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let err = child.stderr.take().unwrap();
    let stderr = std::thread::spawn(move || {
        let mut s = String::new();
        for line in BufReader::new(err).lines().map_while(Result::ok) {
            s.push_str(&line);
            s.push('\n');
        }
        s
    });

    let start = Instant::now();
    let now_us = || start.elapsed().as_micros() as u64;
    for n in &mut nodes {
        n.boot(now_us());
    }
    let mut report = Vec::new();
    let mut last_poll = 0u64;
    let mut frames_in = 0usize;
    let deadline = Duration::from_secs(300);
    let verdict = loop {
        assert!(
            start.elapsed() < deadline,
            "no verdict within {deadline:?}; report so far:\n{}",
            report.join("\n")
        );
        let mut sent: Vec<CanFrame> = Vec::new();
        match rx.recv_timeout(Duration::from_millis(1)) {
            Ok(line) => {
                if let Some(f) = parse_frame(&line) {
                    frames_in += 1;
                    let now = now_us();
                    for (n, d) in nodes.iter_mut().zip(&mut drives) {
                        n.handle(&f, now, d);
                    }
                } else if line.starts_with("PASS") || line.starts_with("FAIL") {
                    report.push(line.clone());
                    break line;
                } else {
                    report.push(line);
                }
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => break "EXITED".to_string(),
        }
        let now = now_us();
        if now >= last_poll + 1000 {
            last_poll = now;
            for (n, d) in nodes.iter_mut().zip(&mut drives) {
                n.poll(now, d);
            }
        }
        for n in &mut nodes {
            while let Some(f) = n.pop_tx() {
                // identical frames sent at once are one frame on the bus
                if !sent.contains(&f) {
                    sent.push(f);
                }
            }
        }
        for f in &sent {
            if to_py.write_all(frame_line(f).as_bytes()).is_err() {
                break;
            }
        }
        let _ = to_py.flush();
    };
    drop(to_py);
    let status = child.wait().unwrap();
    let stderr = stderr.join().unwrap();
    let report = report.join("\n");
    eprintln!("lss_fastscan.py ({frames_in} frames):\n{report}\nstderr:\n{stderr}");
    assert!(
        !stderr.contains("No module named"),
        "python canopen missing: run `pip install -r tests/requirements.txt` (canopen==2.4.1)\n{stderr}"
    );
    assert!(
        verdict.starts_with("PASS") && status.success(),
        "lss_fastscan.py: {verdict} ({status})\n{report}\n{stderr}"
    );
    // found in address order (serials 1, 2, 4), node-IDs 20, 21, 22
    let found: Vec<&str> = report
        .lines()
        .filter(|l| l.starts_with("STEP fast_scan found"))
        .collect();
    assert_eq!(found.len(), 3, "{report}");
    for (line, serial) in found.iter().zip(["0x1", "0x2", "0x4"]) {
        let want = format!("['0x0', '0x402', '0x10000', '{serial}']");
        assert!(line.contains(&want), "{line}: expected {want}");
    }
    for (k, serial) in [1u8, 2, 4].into_iter().enumerate() {
        let node = nodes
            .iter()
            .find(|n| n.object_raw(0x1018, 4) == Some(u32::from(serial)))
            .unwrap();
        assert_eq!(node.node_id(), FIRST_NODE + k as u8, "serial {serial}");
        assert_eq!(node.nmt_state(), drive_protocol::NmtState::PreOperational);
    }
}
