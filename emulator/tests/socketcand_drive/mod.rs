//! `drive-emu run --socketcand 127.0.0.1:0` as a child process for the tests that talk to it
//! over socketcand (socketcand_run.rs, vendor_files_python.rs): started, its ready line read
//! and checked, stopped by SIGTERM or killed when dropped.

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, ChildStdout, Command, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_drive-emu");

/// A running `drive-emu run --socketcand 127.0.0.1:0`, killed if the test fails.
pub struct Drive {
    pub child: Child,
    pub stdout: BufReader<ChildStdout>,
    #[allow(dead_code)] // not every test file talks to the port
    pub port: u16,
    /// The ready line.
    #[allow(dead_code)] // not every test file reads it
    pub ready: serde_json::Value,
}

impl Drive {
    /// Start it with `extra` arguments and read its ready line.
    pub fn start(extra: &[&str]) -> Drive {
        let mut child = Command::new(BIN)
            .args(["run", "--socketcand", "127.0.0.1:0", "--ready", "--json"])
            .args(["--rt-priority", "0", "--no-mlock"])
            .args(extra)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start drive-emu");
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        // The ready line comes once the drive has booted; EOF means it exited.
        stdout.read_line(&mut line).expect("read the ready line");
        let ready: serde_json::Value = serde_json::from_str(&line).unwrap_or_else(|_| {
            let mut err = String::new();
            let _ = child.stderr.take().unwrap().read_to_string(&mut err);
            panic!("{extra:?}: no ready line: {line:?}; stderr:\n{err}")
        });
        assert_eq!(ready["event"], "ready");
        assert_eq!(ready["iface"], serde_json::Value::Null, "{ready}");
        let sc = &ready["socketcand"];
        assert_eq!(sc["host"], "127.0.0.1", "{ready}");
        assert_eq!(sc["channel"], "can0", "{ready}");
        let port = sc["port"].as_u64().expect("the port it got") as u16;
        assert_ne!(port, 0);
        Drive {
            child,
            stdout,
            port,
            ready,
        }
    }

    /// SIGTERM; the exit code, the JSON statistics on stdout and stderr.
    #[allow(dead_code)] // not every test file stops it by SIGTERM
    pub fn stop(mut self) -> (Option<i32>, serde_json::Value, String) {
        // SAFETY: kill(2) on our own child's pid.
        unsafe { libc::kill(self.child.id() as i32, libc::SIGTERM) };
        let mut out = String::new();
        self.stdout.read_to_string(&mut out).unwrap();
        let mut err = String::new();
        self.child
            .stderr
            .take()
            .unwrap()
            .read_to_string(&mut err)
            .unwrap();
        let status = self.child.wait().unwrap();
        let stats = serde_json::from_str(&out)
            .unwrap_or_else(|e| panic!("exit statistics {out:?}: {e}; stderr:\n{err}"));
        (status.code(), stats, err)
    }
}

impl Drop for Drive {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
