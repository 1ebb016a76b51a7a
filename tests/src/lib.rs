//! Helpers for the end-to-end tests on a real (virtual) CAN bus.
//!
//! The tests need vcan interfaces. Where the kernel lacks CAN they run inside user-mode
//! Linux: `./vcan-setup.sh --ifaces 2 -- cargo nextest run -p e2e` (see docs/vcan.md).
//! A test must never skip when the bus is missing: the helpers here panic with a message
//! naming `./vcan-setup.sh`.
//!
//! Environment:
//! * `DRIVE_EMU_VCAN`  interface of bus 0 (default `vcan0`);
//!   `DRIVE_EMU_VCAN1`, `DRIVE_EMU_VCAN2`, ... for further buses (default `vcan1`, ...).
//! * `DRIVE_EMU_PYTHON` python interpreter with python-can/canopen (default `python3`).

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

pub use socketcan;
use socketcan::{CanFrame, CanSocket, EmbeddedFrame, Socket, StandardId};

/// How to get a bus, for failure messages.
pub const HOWTO: &str = "run the e2e tests with a CAN bus: ./vcan-setup.sh --ifaces 2 -- cargo nextest run -p e2e \
     (or ./test-all.sh); on a kernel with CAN, `sudo ./vcan-setup.sh --ifaces 2` once is enough. See docs/vcan.md";

/// Interface name of bus `n` (0 = `$DRIVE_EMU_VCAN` or `vcan0`).
pub fn iface(n: usize) -> String {
    let var = if n == 0 {
        "DRIVE_EMU_VCAN".to_string()
    } else {
        format!("DRIVE_EMU_VCAN{n}")
    };
    std::env::var(&var).unwrap_or_else(|_| format!("vcan{n}"))
}

/// Open a raw CAN socket on `ifname`, or panic explaining how to get one.
pub fn open_bus(ifname: &str) -> CanSocket {
    match CanSocket::open(ifname) {
        Ok(s) => s,
        Err(e) => {
            let why = match e.raw_os_error() {
                Some(97) => "this kernel has no CAN support (EAFNOSUPPORT)".to_string(),
                Some(19) if !kernel_has_can() => {
                    "this kernel has no CAN support (socket(AF_CAN) fails)".to_string()
                }
                Some(19) => format!("there is no interface {ifname} (ENODEV)"),
                _ => format!("{e}"),
            };
            panic!("cannot open CAN interface {ifname}: {why}.\n  {HOWTO}");
        }
    }
}

/// Whether this kernel can open a raw CAN socket at all.
pub fn kernel_has_can() -> bool {
    // SAFETY: plain socket(2)/close(2) calls on an fd we own.
    unsafe {
        let fd = libc::socket(libc::AF_CAN, libc::SOCK_RAW, libc::CAN_RAW);
        if fd < 0 {
            return false;
        }
        libc::close(fd);
    }
    true
}

/// A standard (11-bit) data frame.
pub fn frame(id: u16, data: &[u8]) -> CanFrame {
    let id = StandardId::new(id).expect("11-bit CAN id");
    CanFrame::new(id, data).expect("at most 8 data bytes")
}

/// Wait up to `timeout` for a frame matching `pred`, discarding others.
/// Uses a short socket read timeout in a loop (socketcan's `read_frame_timeout`
/// rounds down to whole milliseconds, see DOMAIN.md section 6).
pub fn recv_matching(
    sock: &CanSocket,
    timeout: Duration,
    mut pred: impl FnMut(&CanFrame) -> bool,
) -> Option<CanFrame> {
    let deadline = Instant::now() + timeout;
    sock.set_read_timeout(Duration::from_millis(20))
        .expect("SO_RCVTIMEO");
    while Instant::now() < deadline {
        match sock.read_frame() {
            Ok(f) if pred(&f) => return Some(f),
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock
                        | std::io::ErrorKind::TimedOut
                        | std::io::ErrorKind::Interrupted
                ) => {}
            Err(e) => panic!("reading CAN frame: {e}"),
        }
    }
    None
}

/// Frame id and data as `(id, bytes)` (standard ids only).
pub fn id_data(f: &CanFrame) -> (u32, Vec<u8>) {
    let id = match f.id() {
        socketcan::Id::Standard(s) => u32::from(s.as_raw()),
        socketcan::Id::Extended(e) => e.as_raw(),
    };
    (id, f.data().to_vec())
}

/// Repository root (the workspace directory).
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// Python interpreter for python-can/canopen peers.
pub fn python() -> String {
    std::env::var("DRIVE_EMU_PYTHON").unwrap_or_else(|_| "python3".to_string())
}

/// A child process whose stdout lines arrive on a channel; killed on drop.
pub struct Peer {
    pub name: String,
    child: Child,
    lines: mpsc::Receiver<String>,
    seen: Vec<String>,
}

impl Peer {
    /// Spawn `cmd` with stdout piped (stderr inherited so failures show in the test log).
    pub fn spawn(name: &str, mut cmd: Command) -> Peer {
        cmd.stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        let mut child = cmd
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {name} ({cmd:?}): {e}. Is it installed? (can-utils, python3 + pip install -r tests/requirements.txt)"));
        let out = child.stdout.take().expect("piped stdout");
        let (tx, rx) = mpsc::channel();
        thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Peer {
            name: name.to_string(),
            child,
            lines: rx,
            seen: Vec::new(),
        }
    }

    /// Wait up to `timeout` for an output line containing `needle`; returns it.
    pub fn wait_line(&mut self, needle: &str, timeout: Duration) -> Option<String> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return None;
            }
            match self.lines.recv_timeout(left.min(Duration::from_millis(50))) {
                Ok(l) => {
                    self.seen.push(l.clone());
                    if l.contains(needle) {
                        return Some(l);
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    // Process ended: no more lines will come.
                    return None;
                }
            }
        }
    }

    /// All lines seen so far (for failure messages).
    pub fn output(&self) -> String {
        self.seen.join("\n")
    }

    /// Wait for the process to exit (up to `timeout`), killing it after that.
    pub fn finish(mut self, timeout: Duration) -> std::process::ExitStatus {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(st) = self.child.try_wait().expect("try_wait") {
                return st;
            }
            if Instant::now() >= deadline {
                let _ = self.child.kill();
                return self.child.wait().expect("wait");
            }
            thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Generous timeouts: inside user-mode Linux everything is slower and noisy (no timing
/// assertions in e2e tests; these are only upper bounds to avoid hanging).
pub const PEER_TIMEOUT: Duration = Duration::from_secs(60);

/// Path of the `drive-emu` binary for tests that start the emulator as a process:
/// `$DRIVE_EMU_BIN` (test-all.sh sets it when the binary has been built), else
/// `$CARGO_TARGET_DIR/debug/drive-emu` (default `target/`).
pub fn drive_emu_bin() -> PathBuf {
    if let Ok(p) = std::env::var("DRIVE_EMU_BIN") {
        return PathBuf::from(p);
    }
    let target = std::env::var("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|_| repo_root().join("target"));
    let p = target.join("debug").join("drive-emu");
    assert!(
        p.exists(),
        "drive-emu binary not found at {}: build it (cargo build -p drive-emu) or set DRIVE_EMU_BIN",
        p.display()
    );
    p
}
