//! What the EtherCAT host tests share: a veth pair of the test's own (deleted when dropped,
//! also when the test fails), `drive-emu run --ethercat` on its slave end (stopped and
//! reaped when dropped), and a python master on its master end.
//!
//! Needs root (a veth pair, a raw socket) and pysoem (tests/requirements.txt). As root, or in
//! CI (`CI` set), a veth pair that cannot be made fails the test; as a user outside CI the
//! test says why and does nothing.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, ChildStdout, Command, Stdio};

pub struct Veth {
    pub master: String,
    pub slave: String,
}

impl Veth {
    /// A veth pair named from this process and `test` (one letter per test of the binary):
    /// at most 15 characters.
    pub fn create(test: char) -> Result<Veth, String> {
        let tag = std::process::id() % 100_000;
        let (master, slave) = (format!("ecm{tag}{test}"), format!("ecs{tag}{test}"));
        let ip = |args: &[&str]| {
            let out = Command::new("ip")
                .args(args)
                .output()
                .map_err(|e| format!("ip {}: {e}", args.join(" ")))?;
            if out.status.success() {
                Ok(())
            } else {
                Err(format!(
                    "ip {}: {}",
                    args.join(" "),
                    String::from_utf8_lossy(&out.stderr)
                ))
            }
        };
        ip(&[
            "link", "add", &master, "type", "veth", "peer", "name", &slave,
        ])?;
        let v = Veth { master, slave };
        ip(&["link", "set", &v.master, "up"])?;
        ip(&["link", "set", &v.slave, "up"])?;
        Ok(v)
    }
}

impl Drop for Veth {
    fn drop(&mut self) {
        // deleting one end deletes the pair
        let _ = Command::new("ip")
            .args(["link", "del", &self.master])
            .status();
    }
}

/// Whether the test can make a veth pair: root, or CI (where it must, and fails if not).
pub fn may_run(name: &str) -> bool {
    // SAFETY: geteuid has no preconditions.
    let root = unsafe { libc::geteuid() } == 0;
    let ci = std::env::var_os("CI").is_some();
    if !root && !ci {
        eprintln!("{name}: not root and not in CI: a veth pair needs root; not run");
        return false;
    }
    true
}

/// The emulator process, stopped (SIGINT) and reaped when dropped.
pub struct Emulator {
    pub child: Child,
    pub stdout: BufReader<ChildStdout>,
    pub ready: serde_json::Value,
}

impl Emulator {
    /// `drive-emu run --ethercat IFACE --ready --json` with `args`; waits for the ready line.
    pub fn start(iface: &str, args: &[&str]) -> Emulator {
        let mut child = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
            .args(["run", "--ethercat", iface])
            .args(args)
            .args(["--ready", "--json", "--rt-priority", "0", "--no-mlock"])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("drive-emu runs");
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        stdout.read_line(&mut line).unwrap();
        let ready: serde_json::Value =
            serde_json::from_str(&line).unwrap_or_else(|e| panic!("ready line {line:?}: {e}"));
        assert_eq!(ready["event"], "ready");
        Emulator {
            child,
            stdout,
            ready,
        }
    }

    /// Stop it (SIGINT) and read the statistics line --json prints at exit, and what came
    /// before it.
    pub fn stop(&mut self) -> (serde_json::Value, Vec<String>) {
        // SAFETY: a signal to our own child, by its pid.
        unsafe {
            libc::kill(self.child.id() as libc::pid_t, libc::SIGINT);
        }
        let mut rest = String::new();
        std::io::Read::read_to_string(&mut self.stdout, &mut rest).unwrap();
        let lines: Vec<String> = rest.lines().map(str::to_string).collect();
        let last = lines.last().cloned().unwrap_or_default();
        let stats: serde_json::Value = serde_json::from_str(last.trim())
            .unwrap_or_else(|e| panic!("statistics {rest:?}: {e}"));
        (stats, lines)
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        // SAFETY: a signal to our own child, by its pid.
        unsafe {
            libc::kill(self.child.id() as libc::pid_t, libc::SIGINT);
        }
        let _ = self.child.wait();
    }
}

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Run tests/python/`script` with `args` (at most `timeout_s`); its last stdout line is a
/// JSON report. Panics with its output when it fails.
pub fn python(script: &str, args: &[&str], timeout_s: u32) -> serde_json::Value {
    let out = Command::new("timeout")
        .arg(timeout_s.to_string())
        .arg("python3")
        .arg(repo().join("tests/python").join(script))
        .args(args)
        .output()
        .expect("python3 runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{script} failed ({}):\n{}\n{}\n(pysoem missing? pip install -r tests/requirements.txt)",
        out.status,
        text,
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(text.lines().last().unwrap_or(""))
        .unwrap_or_else(|e| panic!("{script}'s report {text:?}: {e}"))
}
