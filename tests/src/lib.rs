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

use drive_protocol::wire::{cob, Initiate, Mux, SdoRequest, SdoResponse};
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
/// rounds down to whole milliseconds).
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

    /// The process ID.
    pub fn pid(&self) -> u32 {
        self.child.id()
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

// ---------------------------------------------------------------------------------------
// The emulator as a child process, and a minimal CANopen master for the emulator tests.

use std::sync::{Arc, Mutex};

/// `drive-emu run ...` as a child process. Its stderr is collected (and echoed to ours, so
/// it shows in the test log); [`Emu::stop`] sends SIGTERM and returns exit status and
/// output. Killed on drop if still running.
pub struct Emu {
    child: Option<Child>,
    stderr: Arc<Mutex<Vec<String>>>,
    stdout: Arc<Mutex<Vec<String>>>,
    readers: Vec<thread::JoinHandle<()>>,
}

fn collect(
    name: &'static str,
    r: impl std::io::Read + Send + 'static,
    into: Arc<Mutex<Vec<String>>>,
) -> thread::JoinHandle<()> {
    thread::spawn(move || {
        for line in BufReader::new(r).lines().map_while(Result::ok) {
            eprintln!("[drive-emu {name}] {line}");
            into.lock().unwrap().push(line);
        }
    })
}

/// What a stopped emulator left behind.
#[derive(Debug)]
pub struct EmuExit {
    pub status: std::process::ExitStatus,
    pub stderr: String,
    pub stdout: String,
}

impl EmuExit {
    /// The loop's tick count from the statistics line printed on exit (`ticks N at ...`).
    pub fn ticks(&self) -> u64 {
        self.stderr
            .split("ticks ")
            .nth(1)
            .and_then(|s| s.split_whitespace().next())
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("no tick count in:\n{}", self.stderr))
    }
}

impl Emu {
    /// Start `drive-emu run --rt-priority 0 --no-mlock ARGS...` (no real-time scheduling,
    /// no mlock: the tests run unprivileged and in UML).
    pub fn spawn(args: &[&str]) -> Emu {
        let bin = drive_emu_bin();
        let mut cmd = Command::new(&bin);
        cmd.args(["run", "--rt-priority", "0", "--no-mlock"])
            .args(args)
            .env("RUST_BACKTRACE", "1")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let mut child = cmd
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {} ({cmd:?}): {e}", bin.display()));
        let stderr = Arc::new(Mutex::new(Vec::new()));
        let stdout = Arc::new(Mutex::new(Vec::new()));
        let readers = vec![
            collect("stderr", child.stderr.take().unwrap(), Arc::clone(&stderr)),
            collect("stdout", child.stdout.take().unwrap(), Arc::clone(&stdout)),
        ];
        Emu {
            child: Some(child),
            stderr,
            stdout,
            readers,
        }
    }

    /// The process ID (for signals such as SIGSTOP / SIGCONT).
    pub fn pid(&self) -> libc::pid_t {
        self.child.as_ref().expect("running").id() as libc::pid_t
    }

    /// True while the process runs.
    pub fn alive(&mut self) -> bool {
        matches!(self.child.as_mut().map(|c| c.try_wait()), Some(Ok(None)))
    }

    /// stderr so far.
    pub fn stderr_now(&self) -> String {
        self.stderr.lock().unwrap().join("\n")
    }

    /// Wait for a line of stdout containing `needle` (the `--ready` line, say); the line, or
    /// `None` after `timeout` or when the process has exited.
    pub fn wait_stdout(&mut self, needle: &str, timeout: Duration) -> Option<String> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(l) = self
                .stdout
                .lock()
                .unwrap()
                .iter()
                .find(|l| l.contains(needle))
            {
                return Some(l.clone());
            }
            if Instant::now() >= deadline || !self.alive() {
                return None;
            }
            thread::sleep(Duration::from_millis(20));
        }
    }

    /// SIGTERM, wait (up to 30 s, then SIGKILL), collect the output.
    pub fn stop(mut self) -> EmuExit {
        let mut child = self.child.take().expect("running");
        // SAFETY: kill(2) on our own child's pid.
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
        let deadline = Instant::now() + Duration::from_secs(30);
        let status = loop {
            if let Some(st) = child.try_wait().expect("try_wait") {
                break st;
            }
            if Instant::now() >= deadline {
                eprintln!("drive-emu did not stop within 30 s of SIGTERM: killing it");
                let _ = child.kill();
                break child.wait().expect("wait");
            }
            thread::sleep(Duration::from_millis(20));
        };
        for r in self.readers.drain(..) {
            let _ = r.join();
        }
        EmuExit {
            status,
            stderr: self.stderr.lock().unwrap().join("\n"),
            stdout: self.stdout.lock().unwrap().join("\n"),
        }
    }

    /// [`Emu::stop`], asserting a clean exit (status 0, no panic); returns the exit record.
    pub fn stop_clean(self) -> EmuExit {
        let exit = self.stop();
        assert!(
            !exit.stderr.contains("panicked"),
            "drive-emu panicked; stderr:\n{}",
            exit.stderr
        );
        assert!(
            exit.status.success(),
            "drive-emu exited with {} after SIGTERM; stderr:\n{}",
            exit.status,
            exit.stderr
        );
        assert!(
            exit.stderr.contains("drive-emu: stopped."),
            "drive-emu printed no statistics on SIGTERM; stderr:\n{}",
            exit.stderr
        );
        exit
    }
}

impl Drop for Emu {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Write `text` to a fresh file under the temp directory; returns its path.
/// A scratch directory per test thread, removed when the test's thread ends.
struct Scratch(PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

thread_local! {
    static SCRATCH: Scratch = Scratch(std::env::temp_dir().join(
        format!("drive-emu-e2e-{}-{:?}", std::process::id(), std::thread::current().id())
            .replace(['(', ')'], ""),
    ));
}

fn scratch_dir() -> PathBuf {
    SCRATCH.with(|d| {
        std::fs::create_dir_all(&d.0).expect("scratch dir");
        d.0.clone()
    })
}

/// The directory goes when the calling test's thread ends.
pub fn temp_file(name: &str, text: &str) -> PathBuf {
    let p = scratch_dir().join(name);
    std::fs::write(&p, text).expect("write temp file");
    p
}

/// Send one frame, panicking on error (with the frame in the message).
pub fn send(sock: &CanSocket, id: u16, data: &[u8]) {
    sock.write_frame(&frame(id, data))
        .unwrap_or_else(|e| panic!("sending {id:03X}#{data:02X?}: {e}"));
}

/// NMT command `cs` to `node` (0 = all).
pub fn nmt(sock: &CanSocket, cs: u8, node: u8) {
    send(sock, 0x000, &[cs, node]);
}

/// Wait for the boot-up message (0x700+node, one byte 0x00).
pub fn wait_bootup(sock: &CanSocket, node: u8, timeout: Duration) -> bool {
    recv_matching(sock, timeout, |f| {
        id_data(f) == (0x700 + u32::from(node), vec![0x00])
    })
    .is_some()
}

/// An SDO transfer that did not succeed: an abort (code) or no answer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SdoError {
    Abort(u32),
    Timeout,
    Unexpected(Vec<u8>),
}

/// SDO answer timeout in the tests (an upper bound only).
pub const SDO_TIMEOUT: Duration = Duration::from_secs(5);

fn sdo_request(sock: &CanSocket, node: u8, req: SdoRequest) -> Result<SdoResponse, SdoError> {
    sdo_request_within(sock, node, req, SDO_TIMEOUT)
}

fn sdo_request_within(
    sock: &CanSocket,
    node: u8,
    req: SdoRequest,
    timeout: Duration,
) -> Result<SdoResponse, SdoError> {
    let tx = cob::SDO_RX as u16 + u16::from(node);
    let rx = cob::SDO_TX + u32::from(node);
    send(sock, tx, &req.emit());
    let ans = recv_matching(sock, timeout, |f| {
        let (id, d) = id_data(f);
        let Ok(d) = <[u8; 8]>::try_from(d.as_slice()) else {
            return false;
        };
        // An answer to this request: same multiplexer, or a segment answer (no mux).
        id == rx && (req.mux().is_none() || req.mux() == Some(Mux::of(&d)))
    })
    .ok_or(SdoError::Timeout)?;
    let d = id_data(&ans).1;
    let frame: [u8; 8] = d.as_slice().try_into().expect("8 bytes checked above");
    match SdoResponse::parse(&frame) {
        Ok(SdoResponse::Abort { code, .. }) => Err(SdoError::Abort(code)),
        Ok(r) => Ok(r),
        Err(_) => Err(SdoError::Unexpected(d)),
    }
}

/// SDO upload (expedited or segmented) of `index:sub` from `node`.
pub fn sdo_upload(sock: &CanSocket, node: u8, index: u16, sub: u8) -> Result<Vec<u8>, SdoError> {
    sdo_upload_within(sock, node, index, sub, SDO_TIMEOUT)
}

/// [`sdo_upload`] that waits up to `first` for the answer to its first request: a drive still
/// working through a backlog (a flood it was sent, on a busy host) answers in bus order.
pub fn sdo_upload_within(
    sock: &CanSocket,
    node: u8,
    index: u16,
    sub: u8,
    first: Duration,
) -> Result<Vec<u8>, SdoError> {
    let mux = Mux::new(index, sub);
    let total = match sdo_request_within(sock, node, SdoRequest::InitiateUpload { mux }, first)? {
        SdoResponse::InitiateUpload {
            data: data @ Initiate::Expedited { .. },
            ..
        } => return Ok(data.bytes().to_vec()),
        SdoResponse::InitiateUpload {
            data: Initiate::Segmented { size },
            ..
        } => size.map(|s| s as usize),
        other => return Err(SdoError::Unexpected(other.emit().to_vec())),
    };
    let mut out = Vec::new();
    let mut toggle = false;
    loop {
        let s = match sdo_request(sock, node, SdoRequest::UploadSegment { toggle })? {
            SdoResponse::UploadSegment(s) if s.toggle == toggle => s,
            other => return Err(SdoError::Unexpected(other.emit().to_vec())),
        };
        out.extend_from_slice(s.bytes());
        if s.last {
            break;
        }
        toggle = !toggle;
    }
    if let Some(t) = total {
        if t != out.len() {
            return Err(SdoError::Unexpected(out));
        }
    }
    Ok(out)
}

/// Expedited SDO download (1..=4 bytes) of `data` to `index:sub` of `node`.
pub fn sdo_download(
    sock: &CanSocket,
    node: u8,
    index: u16,
    sub: u8,
    data: &[u8],
) -> Result<(), SdoError> {
    assert!((1..=4).contains(&data.len()), "expedited: 1..=4 bytes");
    let req = SdoRequest::InitiateDownload {
        mux: Mux::new(index, sub),
        data: Initiate::expedited(data),
    };
    match sdo_request(sock, node, req)? {
        SdoResponse::InitiateDownload { .. } => Ok(()),
        other => Err(SdoError::Unexpected(other.emit().to_vec())),
    }
}

/// Wait (bounded by [`PEER_TIMEOUT`], retrying the request) until `node` answers an SDO upload
/// of 0x1000 sent now. A drive handles its received frames in arrival order, so once it has
/// answered, every frame sent before the request has been handled too, however far behind a
/// loaded host made it. Panics with the reason if no answer comes.
pub fn sdo_barrier(sock: &CanSocket, node: u8) {
    let deadline = Instant::now() + PEER_TIMEOUT;
    loop {
        match sdo_upload(sock, node, 0x1000, 0) {
            Ok(_) => return,
            Err(SdoError::Timeout) if Instant::now() < deadline => continue,
            Err(e) => panic!("node {node} did not answer an SDO upload of 0x1000: {e:?}"),
        }
    }
}

/// Upload of a U32 (or shorter unsigned) object as u32.
pub fn sdo_u32(sock: &CanSocket, node: u8, index: u16, sub: u8) -> u32 {
    let d = sdo_upload(sock, node, index, sub)
        .unwrap_or_else(|e| panic!("SDO upload {index:04X}:{sub} from node {node}: {e:?}"));
    let mut b = [0u8; 4];
    b[..d.len().min(4)].copy_from_slice(&d[..d.len().min(4)]);
    u32::from_le_bytes(b)
}

/// A python master script of tests/python/ against the drive as `run` serves node `node`
/// with the `cnc1` preset, in lock-step with a 10 ms SYNC period: the script gets the bus, the
/// node and the drive's own EDS (`drive-emu eds`), prints READY when it listens (the drive
/// starts then, so that the script sees its boot-up), `STEP ...` lines and PASS. Every one
/// of `steps` must be among its lines.
pub fn python_master_passes(script: &str, node: u8, steps: &[&str]) {
    let ifname = iface(0);
    let id = node.to_string();
    let eds = Command::new(drive_emu_bin())
        .args(["eds", "--preset", "cnc1", "--node", &id])
        .output()
        .expect("run drive-emu eds");
    assert!(
        eds.status.success(),
        "drive-emu eds failed: {}",
        String::from_utf8_lossy(&eds.stderr)
    );
    let eds_path = temp_file(
        &format!("node{node}.eds"),
        &String::from_utf8_lossy(&eds.stdout),
    );
    let mut cmd = Command::new(python());
    cmd.arg(repo_root().join("tests/python").join(script))
        .args([&ifname, &id])
        .arg(&eds_path)
        .env("PYTHONUNBUFFERED", "1");
    let mut peer = Peer::spawn(script, cmd);
    peer.wait_line("READY", PEER_TIMEOUT).unwrap_or_else(|| {
        panic!(
            "{script} did not start (pip install -r tests/requirements.txt?):\n{}",
            peer.output()
        )
    });
    let emu = Emu::spawn(&[
        "--iface",
        &ifname,
        "--node",
        &id,
        "--preset",
        "cnc1",
        "--lockstep",
        "--sync-period-us",
        "10000",
    ]);
    let verdict = peer.wait_line("PASS", 4 * PEER_TIMEOUT);
    let out = peer.output();
    let status = peer.finish(PEER_TIMEOUT);
    let exit = emu.stop_clean();
    eprintln!("{script} output:\n{out}");
    assert!(
        verdict.is_some() && status.success(),
        "{script} failed ({status}); its output:\n{out}\n\ndrive-emu stderr:\n{}",
        exit.stderr
    );
    for step in steps {
        assert!(out.contains(step), "no `{step}` in the output:\n{out}");
    }
}
