//! `drive-emu run --socketcand 127.0.0.1:0`: no kernel CAN. A lock-step drive with two axes
//! and two plain TCP clients; python canopen as the master over python-can's `socketcand`
//! interface (tests/python/socketcand_master.py).
//! The drive boots (boot-up seen), takes NMT, moves in PP and in CSP with the master's SYNC,
//! answers 0x2100; it stops cleanly on SIGTERM and says what its clients did. Needs python3
//! with python-can 4.6.1 and canopen 2.4.1 (tests/requirements.txt; `DRIVE_EMU_PYTHON`
//! names another interpreter).

mod scratch;
mod socketcand_drive;

use socketcand_drive::Drive;

use std::io::Read;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_drive-emu");

fn python() -> String {
    std::env::var("DRIVE_EMU_PYTHON").unwrap_or_else(|_| "python3".into())
}

fn write_eds(node: u8) -> std::path::PathBuf {
    let out = Command::new(BIN)
        .args(["eds", "--preset", "cnc1", "--node", &node.to_string()])
        .args(["--real32", "decimal"])
        .output()
        .expect("drive-emu eds");
    assert!(out.status.success(), "{out:?}");
    let path = scratch::path(&format!("node{node}.eds"));
    std::fs::write(&path, out.stdout).unwrap();
    path
}

#[test]
fn python_canopen_over_socketcand_boots_moves_pp_and_csp_and_reads_the_statistics() {
    let eds = write_eds(5);
    let drive = Drive::start(&["--node", "5"]);
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/python/socketcand_master.py"
    );
    let out = Command::new(python())
        .arg(script)
        .args(["--port", &drive.port.to_string(), "--node", "5"])
        .arg("--eds")
        .arg(&eds)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", python()));
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    if !out.status.success() {
        let (_, _, drive_err) = drive.stop();
        panic!("the master failed:\n{stdout}\n{stderr}\ndrive:\n{drive_err}");
    }
    let seen: serde_json::Value =
        serde_json::from_str(stdout.lines().last().unwrap_or_default()).expect("its JSON line");
    assert_eq!(seen["bootup"], true, "{seen}");
    assert_eq!(seen["nmt_after_bootup"], "PRE-OPERATIONAL", "{seen}");
    assert_eq!(seen["nmt_operational"], "OPERATIONAL", "{seen}");
    assert_eq!(seen["nmt_end"], "PRE-OPERATIONAL", "{seen}");
    assert!(seen["stats_ticks"].as_u64().unwrap() > 0, "{seen}");
    for mode in ["pp", "csp"] {
        assert_eq!(seen[format!("{mode}_state")], "OPERATION ENABLED", "{seen}");
    }
    let um = |k: &str| seen[k].as_i64().unwrap_or_else(|| panic!("{k} in {seen}"));
    // Moved, and to the set-point (within the backlash and the position window).
    assert!(um("pp_target_um") != 0, "{seen}");
    assert!(
        (um("pp_reached_um") - um("pp_target_um")).abs() <= 100,
        "{seen}"
    );
    assert!(um("csp_target_um") - um("pp_reached_um") >= 900, "{seen}");
    assert!(
        (um("csp_actual_um") - um("csp_target_um")).abs() <= 100,
        "{seen}"
    );
    assert!(
        (um("csp_tpdo_um") - um("csp_target_um")).abs() <= 100,
        "{seen}"
    );

    let (code, stats, err) = drive.stop();
    assert_eq!(code, Some(0), "{err}");
    // The master's SYNCs reached the drive: 150 in the ramp, one for the last TPDO.
    assert_eq!(stats["stats"]["syncs"], 151, "{stats}");
    assert_eq!(stats["stats"]["rx_overflows"], 0, "{stats}");
    assert!(
        err.contains("socketcand: 1 clients served (0 refused)") && err.contains("0 bad messages"),
        "{err}"
    );
}

/// The pytest fixture's own tests (python/tests/test_fixture.py) and its socketcand tests
/// (test_socketcand.py) on this host, the fixture serving the bus over socketcand: the python
/// package from this tree (PYTHONPATH), this build's drive-emu.
#[test]
fn the_pytest_fixture_and_its_tests_run_over_socketcand() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let out = Command::new(python())
        .current_dir(root)
        .args([
            "-m",
            "pytest",
            "-p",
            "drive_emu_testing.plugin",
            "-p",
            "no:cacheprovider",
        ])
        .args([
            "-q",
            "python/tests/test_fixture.py",
            "python/tests/test_socketcand.py",
        ])
        .args(["--drive-emu-bin", BIN])
        // the package as in this tree, whether or not one is installed
        .env("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")
        .env("PYTHONPATH", format!("{root}/python"))
        .env("DRIVE_EMU_SOCKETCAND", "127.0.0.1:0")
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", python()));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "pytest failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // All ran, none skipped (pytest's summary line: "N passed in ...").
    let summary = stdout.lines().last().unwrap_or_default();
    assert!(
        summary.contains(" passed") && !summary.contains("skipped") && !summary.contains("failed"),
        "{stdout}"
    );
    let passed: u32 = summary
        .split_whitespace()
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(passed >= 9, "{stdout}");
}

/// A socketcand client speaking the protocol by hand: (id, data) of each frame.
struct Client {
    s: std::net::TcpStream,
    buf: Vec<u8>,
}

impl Client {
    fn raw(port: u16) -> Client {
        let s = std::net::TcpStream::connect(("127.0.0.1", port)).expect("connect");
        s.set_read_timeout(Some(std::time::Duration::from_secs(60)))
            .unwrap();
        let mut c = Client { s, buf: Vec::new() };
        assert_eq!(c.next(), "< hi >");
        c.say("< open can0 >");
        assert_eq!(c.next(), "< ok >");
        c.say("< rawmode >");
        assert_eq!(c.next(), "< ok >");
        c
    }

    fn say(&mut self, text: &str) {
        use std::io::Write;
        self.s.write_all(text.as_bytes()).expect("write");
    }

    fn next(&mut self) -> String {
        loop {
            if let Some(end) = self.buf.iter().position(|&b| b == b'>') {
                let msg: Vec<u8> = self.buf.drain(..=end).collect();
                return String::from_utf8(msg).unwrap().trim_start().to_string();
            }
            let mut chunk = [0u8; 4096];
            let n = self
                .s
                .read(&mut chunk)
                .expect("the drive said nothing in time");
            assert!(n > 0, "the server closed the connection");
            self.buf.extend_from_slice(&chunk[..n]);
        }
    }

    /// The next frame with identifier `id` (hex, as sent), its data; others skipped.
    fn frame(&mut self, id: &str) -> String {
        loop {
            let msg = self.next();
            let parts: Vec<&str> = msg.split(' ').collect();
            if parts.len() == 6 && parts[1] == "frame" && parts[2] == id {
                return parts[4].to_string();
            }
        }
    }
}

fn machine_file() -> std::path::PathBuf {
    let p = scratch::path("two-axes.toml");
    std::fs::write(
        &p,
        "tick_hz = 1000\n[[axis]]\nnode_id = 5\npreset = \"cnc1\"\n\
         [[axis]]\nnode_id = 6\npreset = \"cnc3\"\n",
    )
    .unwrap();
    p
}

/// Lock-step, two axes, two clients: both axes boot on an NMT reset, answer SDO, and the
/// drive's time moves by exactly the SYNCs the clients sent (one tick each); the other client
/// hears every one of them.
#[test]
fn a_lockstep_drive_with_two_axes_serves_two_clients() {
    let cfg = machine_file();
    let drive = Drive::start(&[
        "--config",
        cfg.to_str().unwrap(),
        "--lockstep",
        "--sync-period-us",
        "1000",
    ]);
    let mut a = Client::raw(drive.port);
    let mut b = Client::raw(drive.port);
    a.say("< send 000 2 81 0 >"); // NMT reset node, all nodes
                                  // B heard A's NMT command; both hear both boot-ups.
    assert_eq!(b.frame("000"), "8100");
    for c in [&mut a, &mut b] {
        let mut booted = std::collections::BTreeSet::new();
        while booted.len() < 2 {
            let msg = c.next();
            for id in ["705", "706"] {
                if msg.starts_with(&format!("< frame {id} ")) {
                    assert!(msg.ends_with(" 00 >"), "{msg}");
                    booted.insert(id);
                }
            }
        }
    }
    // SDO upload of 0x1000 (device type) from each axis.
    for (node, req, resp) in [(5, "605", "585"), (6, "606", "586")] {
        a.say(&format!("< send {req} 8 40 0 10 0 0 0 0 0 >"));
        assert_eq!(a.frame(resp), "4300100092010200", "node {node}");
    }
    const SYNCS: usize = 300;
    for k in 0..SYNCS {
        let who = if k % 2 == 0 { &mut a } else { &mut b };
        who.say("< send 080 0 >");
    }
    // Each client hears the other's SYNCs: half of them.
    for _ in 0..SYNCS / 2 {
        assert_eq!(a.frame("080"), "");
        assert_eq!(b.frame("080"), "");
    }
    // The SDO answer comes after the SYNCs before it were handled.
    a.say("< send 605 8 40 0 10 0 0 0 0 0 >");
    a.frame("585");
    let (code, stats, err) = drive.stop();
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(stats["stats"]["syncs"], SYNCS, "{stats}");
    assert_eq!(stats["stats"]["ticks"], SYNCS, "{stats}");
    assert!(err.contains("2 clients served (0 refused)"), "{err}");
    assert!(err.contains("0 dropped to slow clients"), "{err}");
}
