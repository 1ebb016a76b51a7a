//! Recordings started and stopped from the panel: per axis a CSV of every tick in the columns
//! of `run --trace` (written by the collector from the fan-out), and, on a CAN interface, a
//! capture of the bus in `candump -L` format read by a socket of its own (what candump would
//! see; the loop is not involved). Both are what `drive-emu analyze` reads. Files go to the
//! panel's directory as `rec-N-node5.csv` and `rec-N.log`, downloadable while the run lasts.
//!
//! The directory is private ([`RecordDir`]): by default a new one under the system's temporary
//! directory with a random name, created once with mode 0700 (refused if the name exists, so
//! nobody can prepare it); one the user names must be a directory of this user that nobody
//! else may write (created 0700 if absent). Files are created `O_EXCL|O_NOFOLLOW` (a planted
//! name or symlink is refused, never followed), served only after `fstat` on the opened
//! descriptor says regular file, and streamed. A run makes at most
//! [`RecordLimits::max_recordings`] recordings of at most [`RecordLimits::max_bytes`] each:
//! one that reaches its cap stops writing and says so.

use crate::bus::CanBus;
use crate::runtime::trace::CsvSink;
use crate::samples::Sample;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::os::unix::fs::{DirBuilderExt, MetadataExt, OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

/// How many recordings a run makes and how large one grows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecordLimits {
    /// Recordings per run; one more is refused (409).
    pub max_recordings: u32,
    /// Bytes of one recording, all its files together; past it nothing more is written.
    pub max_bytes: u64,
}

impl Default for RecordLimits {
    fn default() -> Self {
        // 1 GiB: about 80 minutes of one axis at 1 kHz with its capture.
        RecordLimits {
            max_recordings: 100,
            max_bytes: 1 << 30,
        }
    }
}

/// The panel's recording directory.
#[derive(Debug)]
pub struct RecordDir {
    pub path: PathBuf,
    /// This run made it (removed at the end when it is empty).
    pub created: bool,
}

fn io_err(kind: std::io::ErrorKind, msg: String) -> std::io::Error {
    std::io::Error::new(kind, msg)
}

/// 16 random hex digits from the kernel.
fn random_hex() -> std::io::Result<String> {
    let mut b = [0u8; 8];
    // SAFETY: the buffer is valid for its length.
    let n = unsafe { libc::getrandom(b.as_mut_ptr().cast(), b.len(), 0) };
    if n != b.len() as isize {
        return Err(std::io::Error::last_os_error());
    }
    Ok(format!("{:016x}", u64::from_ne_bytes(b)))
}

impl RecordDir {
    /// A new private directory under `parent` (the system's temporary directory by default):
    /// `drive-emu-panel-<16 random hex digits>`, mode 0700, made with `mkdir` (a name that
    /// exists is never used).
    pub fn private_in(parent: &Path) -> std::io::Result<RecordDir> {
        let mut last = None;
        for _ in 0..8 {
            let path = parent.join(format!("drive-emu-panel-{}", random_hex()?));
            match std::fs::DirBuilder::new().mode(0o700).create(&path) {
                Ok(()) => {
                    return Ok(RecordDir {
                        path,
                        created: true,
                    })
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
                Err(e) => {
                    return Err(io_err(
                        e.kind(),
                        format!(
                            "cannot create the recording directory {}: {e}",
                            path.display()
                        ),
                    ))
                }
            }
        }
        Err(last.unwrap_or_else(|| io_err(std::io::ErrorKind::AlreadyExists, "exists".into())))
    }

    /// The directory the user named (`--panel-dir`): made with mode 0700 when it does not
    /// exist; else it must be a real directory (not a symlink) of this user that no one else
    /// may write.
    pub fn named(path: &Path) -> std::io::Result<RecordDir> {
        match std::fs::symlink_metadata(path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                std::fs::DirBuilder::new()
                    .mode(0o700)
                    .create(path)
                    .map_err(|e| {
                        io_err(
                            e.kind(),
                            format!("--panel-dir {}: cannot create: {e}", path.display()),
                        )
                    })?;
                Ok(RecordDir {
                    path: path.to_path_buf(),
                    created: true,
                })
            }
            Err(e) => Err(io_err(
                e.kind(),
                format!("--panel-dir {}: {e}", path.display()),
            )),
            Ok(m) => {
                // SAFETY: geteuid has no preconditions.
                let me = unsafe { libc::geteuid() };
                check_dir_meta(&m, me).map_err(|why| {
                    io_err(
                        std::io::ErrorKind::PermissionDenied,
                        format!("--panel-dir {}: {why}", path.display()),
                    )
                })?;
                Ok(RecordDir {
                    path: path.to_path_buf(),
                    created: false,
                })
            }
        }
    }

    /// At the end of the run: remove the directory if this run made it and it is empty.
    pub fn remove_if_empty(&self) {
        if self.created {
            let _ = std::fs::remove_dir(&self.path);
        }
    }
}

/// Why an existing directory is not private to user `me`, if it is not.
pub fn check_dir_meta(m: &std::fs::Metadata, me: u32) -> Result<(), String> {
    let t = m.file_type();
    if t.is_symlink() {
        return Err("is a symbolic link: name the directory itself".into());
    }
    if !t.is_dir() {
        return Err("is not a directory".into());
    }
    if m.uid() != me {
        return Err(format!(
            "belongs to user {}, not to this user ({me}): another user could read or replace \
             the recordings",
            m.uid()
        ));
    }
    let mode = m.permissions().mode() & 0o7777;
    if mode & 0o022 != 0 {
        return Err(format!(
            "mode {mode:04o}: others may write in it (chmod go-w, or name a new directory)"
        ));
    }
    Ok(())
}

/// A recording's files and their shared byte count against the cap.
struct Budget {
    used: AtomicU64,
    cap: u64,
    /// The cap was reached: nothing more is written.
    full: AtomicBool,
}

impl Budget {
    /// Take `n` bytes: false (and full from now on) when they do not fit.
    fn take(&self, n: usize) -> bool {
        if self.full.load(Ordering::Relaxed) {
            return false;
        }
        let before = self.used.fetch_add(n as u64, Ordering::Relaxed);
        if before + n as u64 > self.cap {
            self.used.fetch_sub(n as u64, Ordering::Relaxed);
            self.full.store(true, Ordering::Relaxed);
            return false;
        }
        true
    }
}

/// A recording in progress.
pub struct Recording {
    pub number: u32,
    pub started_us: u64,
    /// The same writer and layout as `run --trace`'s files.
    csv: Vec<CsvSink<File>>,
    pub csv_names: Vec<String>,
    pub samples: u64,
    /// Ticks missed because the collector fell behind the fan-out.
    pub lost: u64,
    capture: Option<Capture>,
    pub capture_name: Option<String>,
    /// Why there is no capture, when there is none.
    pub capture_note: Option<String>,
    budget: Arc<Budget>,
}

struct Capture {
    stop: Arc<AtomicBool>,
    frames: Arc<AtomicU64>,
    thread: JoinHandle<std::io::Result<()>>,
}

/// What the panel's recordings are (for the stream and the API).
#[derive(Default)]
pub struct RecordState {
    pub active: Option<Recording>,
    /// Files finished, by name (newest last).
    pub files: Vec<String>,
    pub next_number: u32,
}

/// A file name the panel wrote (only such names are served).
pub fn is_served_name(name: &str) -> bool {
    name.starts_with("rec-")
        && (name.ends_with(".csv") || name.ends_with(".log"))
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '.')
}

/// Create `dir/name`: a new file (`O_EXCL`: a name that exists, a planted symlink included,
/// is refused), mode 0600, `O_NOFOLLOW`.
pub fn create_new(path: &Path) -> std::io::Result<File> {
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC)
        .open(path)
        .map_err(|e| {
            let why = if e.kind() == std::io::ErrorKind::AlreadyExists {
                "it exists already (refused: a recording never writes over or through a file)"
                    .to_string()
            } else {
                e.to_string()
            };
            io_err(e.kind(), format!("cannot create {}: {why}", path.display()))
        })
}

fn create(dir: &Path, name: &str) -> std::io::Result<BufWriter<File>> {
    create_new(&dir.join(name)).map(BufWriter::new)
}

/// Start a recording: the files created (an error here starts nothing and leaves no file),
/// the capture thread on `iface` if there is one.
pub fn start(
    dir: &Path,
    number: u32,
    node_ids: &[u8],
    iface: Option<&str>,
    now_us: u64,
    max_bytes: u64,
) -> std::io::Result<Recording> {
    let budget = Arc::new(Budget {
        used: AtomicU64::new(0),
        cap: max_bytes,
        full: AtomicBool::new(false),
    });
    let mut csv = Vec::new();
    let mut csv_names: Vec<String> = Vec::new();
    let undo = |names: &[String]| {
        for n in names {
            let _ = std::fs::remove_file(dir.join(n));
        }
    };
    for n in node_ids {
        let name = format!("rec-{number}-node{n}.csv");
        let made = create_new(&dir.join(&name)).and_then(|f| CsvSink::new(f, |n| budget.take(n)));
        match made {
            Ok(w) => {
                csv.push(w);
                csv_names.push(name);
            }
            Err(e) => {
                drop(csv);
                undo(&csv_names);
                return Err(e);
            }
        }
    }
    let (capture, capture_name, capture_note) = match iface {
        Some(iface) => {
            let name = format!("rec-{number}.log");
            let file = match create(dir, &name) {
                Ok(f) => f,
                Err(e) => {
                    drop(csv);
                    undo(&csv_names);
                    return Err(e);
                }
            };
            match open_capture_bus(iface) {
                Ok(bus) => (
                    Some(spawn_capture(
                        bus,
                        iface.to_string(),
                        file,
                        Arc::clone(&budget),
                    )?),
                    Some(name),
                    None,
                ),
                Err(e) => {
                    let _ = std::fs::remove_file(dir.join(&name));
                    (None, None, Some(format!("no capture: {e}")))
                }
            }
        }
        None => (
            None,
            None,
            Some("no capture: the drive is not on a CAN interface".into()),
        ),
    };
    Ok(Recording {
        number,
        started_us: now_us,
        csv,
        csv_names,
        samples: 0,
        lost: 0,
        capture,
        capture_name,
        capture_note,
        budget,
    })
}

/// A socket of its own on `iface`, to capture what the bus carries.
#[cfg(feature = "socketcan")]
fn open_capture_bus(iface: &str) -> anyhow::Result<crate::bus::socketcan::SocketCanBus> {
    Ok(crate::bus::socketcan::SocketCanBus::open(iface)?)
}

/// Without SocketCAN there is no interface to capture.
#[cfg(not(feature = "socketcan"))]
fn open_capture_bus(iface: &str) -> anyhow::Result<crate::bus::inproc::InProcEndpoint> {
    anyhow::bail!("{iface}: this drive-emu was built without SocketCAN")
}

fn spawn_capture(
    bus: impl CanBus + Send + 'static,
    iface: String,
    mut out: BufWriter<File>,
    budget: Arc<Budget>,
) -> std::io::Result<Capture> {
    let stop = Arc::new(AtomicBool::new(false));
    let frames = Arc::new(AtomicU64::new(0));
    let thread = {
        let (stop, frames) = (Arc::clone(&stop), Arc::clone(&frames));
        std::thread::Builder::new()
            .name("drive-emu-panel-capture".into())
            .spawn(move || {
                let mut bus = bus;
                let Some(fd) = bus.rx_fd() else {
                    return Ok(());
                };
                let mut line = Vec::with_capacity(64);
                while !stop.load(Ordering::Acquire) {
                    let mut pfd = libc::pollfd {
                        fd,
                        events: libc::POLLIN,
                        revents: 0,
                    };
                    // SAFETY: one valid pollfd, the descriptor is the bus's own.
                    unsafe { libc::poll(&mut pfd, 1, 50) };
                    while let Ok(Some(f)) = bus.recv() {
                        let t_ns = bus.last_rx_stamp_ns().unwrap_or_else(|| {
                            std::time::SystemTime::now()
                                .duration_since(std::time::UNIX_EPOCH)
                                .map_or(0, |d| d.as_nanos() as i128)
                        });
                        line.clear();
                        write_candump_line(&mut line, t_ns, &iface, &f)?;
                        if budget.take(line.len()) {
                            out.write_all(&line)?;
                            frames.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                }
                out.flush()
            })?
    };
    Ok(Capture {
        stop,
        frames,
        thread,
    })
}

/// One frame as `candump -L` writes it: `(1700000000.123456) vcan0 185#0102`, `R` for a
/// remote frame.
pub fn write_candump_line(
    w: &mut impl Write,
    t_ns: i128,
    iface: &str,
    f: &crate::bus::CanFrame,
) -> std::io::Result<()> {
    let us = t_ns.div_euclid(1000);
    write!(
        w,
        "({}.{:06}) {iface} ",
        us.div_euclid(1_000_000),
        us.rem_euclid(1_000_000),
    )?;
    if f.extended {
        write!(w, "{:08X}#", f.id)?;
    } else {
        write!(w, "{:03X}#", f.id)?;
    }
    if f.rtr {
        writeln!(w, "R")
    } else {
        for b in f.payload() {
            write!(w, "{b:02X}")?;
        }
        writeln!(w)
    }
}

impl Recording {
    /// One tick of axis `axis` (collector thread); nothing once the recording is at its cap.
    pub fn write(&mut self, axis: usize, s: &Sample) {
        if let Some(w) = self.csv.get_mut(axis) {
            let budget = &self.budget;
            if let Ok(true) = w.write(s, |n| budget.take(n)) {
                self.samples += 1;
            }
        }
    }

    /// Bytes written so far, all files.
    pub fn bytes(&self) -> u64 {
        self.budget.used.load(Ordering::Relaxed)
    }

    /// The reason the recording stopped growing, once it reached its cap.
    pub fn cap_note(&self) -> Option<String> {
        self.budget.full.load(Ordering::Relaxed).then(|| {
            format!(
                "the recording reached its cap of {} bytes ({} MiB): later ticks and frames \
                 were not written; stop it and start another",
                self.budget.cap,
                self.budget.cap >> 20
            )
        })
    }

    /// Frames captured so far.
    pub fn frames(&self) -> u64 {
        self.capture
            .as_ref()
            .map_or(0, |c| c.frames.load(Ordering::Relaxed))
    }

    /// Stop: flush and close the files; the names written.
    pub fn finish(mut self) -> (Vec<String>, Option<String>) {
        let mut names = Vec::new();
        for (w, n) in self.csv.iter_mut().zip(&self.csv_names) {
            if w.flush().is_ok() {
                names.push(n.clone());
            }
        }
        let mut problem = None;
        if let Some(c) = self.capture.take() {
            c.stop.store(true, Ordering::Release);
            match c.thread.join() {
                Ok(Ok(())) => names.extend(self.capture_name.clone()),
                Ok(Err(e)) => problem = Some(format!("capture: {e}")),
                Err(_) => problem = Some("the capture thread panicked".into()),
            }
        }
        (names, problem)
    }
}

/// The directory's file `name`, if it is one the panel wrote.
pub fn served_path(dir: &Path, state: &RecordState, name: &str) -> Option<PathBuf> {
    (is_served_name(name) && state.files.iter().any(|f| f == name)).then(|| dir.join(name))
}

/// Open a finished recording to serve it: `O_NOFOLLOW` (a symlink put in its place is
/// refused), without blocking (a FIFO put in its place does not hang the server), and only a
/// regular file by `fstat` on the descriptor opened. Returns the file and its size then.
pub fn open_served(path: &Path) -> std::io::Result<(File, u64)> {
    let f = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK | libc::O_CLOEXEC | libc::O_NOCTTY)
        .open(path)?;
    let m = f.metadata()?;
    if !m.file_type().is_file() {
        return Err(io_err(
            std::io::ErrorKind::InvalidData,
            "not a regular file any more (replaced?)".into(),
        ));
    }
    Ok((f, m.len()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::capture::candump::{parse_line, FrameKind};
    use crate::bus::CanFrame;

    #[test]
    fn capture_lines_are_what_the_candump_reader_reads() {
        let mut out = Vec::new();
        let f = CanFrame::new(0x185, &[0x37, 0x06, 0xFF]);
        write_candump_line(&mut out, 1_700_000_000_123_456_789, "vcan0", &f).unwrap();
        write_candump_line(&mut out, 5_000, "vcan0", &CanFrame::remote(0x705, 0)).unwrap();
        let text = String::from_utf8(out).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "(1700000000.123456) vcan0 185#3706FF");
        let p = parse_line(lines[0]).unwrap().unwrap();
        assert_eq!(p.t_us, 1_700_000_000_123_456);
        assert_eq!(p.kind, FrameKind::Data(f));
        let r = parse_line(lines[1]).unwrap().unwrap();
        assert_eq!(r.kind, FrameKind::Remote { id: 0x705 });
    }

    /// A scratch directory of this test (made private, removed by the caller).
    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("drive-emu-rec-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        RecordDir::named(&d).unwrap();
        d
    }

    #[test]
    fn a_recording_without_a_can_interface_says_why_it_has_no_capture() {
        let dir = scratch("nocan");
        let r = start(&dir, 7, &[5, 6], Some("nocan9"), 1_000, 1 << 20).unwrap();
        assert_eq!(r.csv_names, vec!["rec-7-node5.csv", "rec-7-node6.csv"]);
        assert!(r.capture_name.is_none());
        let note = r.capture_note.clone().unwrap();
        assert!(
            note.starts_with("no capture: ") && note.contains("nocan9"),
            "{note}"
        );
        assert!(
            !dir.join("rec-7.log").exists(),
            "no empty capture file is left"
        );
        let (names, problem) = r.finish();
        assert_eq!(names, vec!["rec-7-node5.csv", "rec-7-node6.csv"]);
        assert!(problem.is_none());
        let text = std::fs::read_to_string(dir.join("rec-7-node5.csv")).unwrap();
        assert_eq!(text.trim_end(), Sample::CSV_HEADER);
        let _ = std::fs::remove_dir_all(&dir);
        // A directory that does not exist: an error, nothing started.
        let e = start(Path::new("/proc/no/such/dir"), 1, &[5], None, 0, 1 << 20)
            .err()
            .expect("refused");
        assert!(e.to_string().contains("/proc/no/such/dir"), "{e}");
    }

    #[test]
    fn the_default_directory_is_new_private_and_random() {
        let parent = scratch("parent");
        let a = RecordDir::private_in(&parent).unwrap();
        let b = RecordDir::private_in(&parent).unwrap();
        assert_ne!(a.path, b.path);
        for d in [&a, &b] {
            let name = d.path.file_name().unwrap().to_str().unwrap();
            let hex = name.strip_prefix("drive-emu-panel-").unwrap();
            assert!(
                hex.len() == 16 && hex.chars().all(|c| c.is_ascii_hexdigit()),
                "{name}"
            );
            let m = std::fs::symlink_metadata(&d.path).unwrap();
            assert!(m.is_dir());
            assert_eq!(m.permissions().mode() & 0o777, 0o700);
            assert!(d.created);
        }
        // Removed at the end only when empty.
        std::fs::write(b.path.join("rec-1-node5.csv"), "x").unwrap();
        a.remove_if_empty();
        b.remove_if_empty();
        assert!(!a.path.exists() && b.path.exists());
        std::fs::remove_dir_all(&parent).unwrap();
    }

    #[test]
    fn a_named_directory_another_user_could_prepare_is_refused() {
        let base = scratch("named");
        // World-writable (what another user could have made, or a shared folder).
        let open = base.join("open");
        std::fs::create_dir(&open).unwrap();
        std::fs::set_permissions(&open, std::fs::Permissions::from_mode(0o777)).unwrap();
        let e = RecordDir::named(&open).unwrap_err().to_string();
        assert!(e.contains("mode 0777: others may write"), "{e}");
        // A symlink to a directory, planted where the user said.
        let link = base.join("link");
        std::os::unix::fs::symlink(&open, &link).unwrap();
        let e = RecordDir::named(&link).unwrap_err().to_string();
        assert!(e.contains("symbolic link"), "{e}");
        // A file.
        let file = base.join("file");
        std::fs::write(&file, "").unwrap();
        assert!(RecordDir::named(&file)
            .unwrap_err()
            .to_string()
            .contains("not a directory"));
        // Another user's directory (simulated: this user's directory checked for another uid).
        let mine = base.join("mine");
        let d = RecordDir::named(&mine).unwrap();
        assert!(d.created);
        let m = std::fs::symlink_metadata(&mine).unwrap();
        assert_eq!(m.permissions().mode() & 0o777, 0o700);
        assert!(check_dir_meta(&m, m.uid()).is_ok());
        let e = check_dir_meta(&m, m.uid().wrapping_add(1)).unwrap_err();
        assert!(e.contains(&format!("belongs to user {}", m.uid())), "{e}");
        // An existing private directory of this user is used, and not removed at the end.
        let again = RecordDir::named(&mine).unwrap();
        assert!(!again.created);
        std::fs::remove_dir_all(&base).unwrap();
    }

    #[test]
    fn a_planted_file_or_symlink_is_never_written_through() {
        let dir = scratch("planted");
        let victim = dir.join("victim");
        std::fs::write(&victim, "root-only secret\n").unwrap();
        // The CSV name of the next recording is a symlink to the victim.
        std::os::unix::fs::symlink(&victim, dir.join("rec-1-node6.csv")).unwrap();
        let e = start(&dir, 1, &[5, 6], None, 0, 1 << 20)
            .err()
            .expect("refused")
            .to_string();
        assert!(
            e.contains("rec-1-node6.csv") && e.contains("exists already"),
            "{e}"
        );
        assert_eq!(
            std::fs::read_to_string(&victim).unwrap(),
            "root-only secret\n"
        );
        assert!(
            !dir.join("rec-1-node5.csv").exists(),
            "nothing half-started is left"
        );
        // A dangling symlink (to a file not there yet) is refused too, and nothing is made.
        std::os::unix::fs::symlink(dir.join("made"), dir.join("rec-2-node5.csv")).unwrap();
        assert!(start(&dir, 2, &[5], None, 0, 1 << 20).is_err());
        assert!(!dir.join("made").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_served_file_swapped_for_a_symlink_fifo_or_device_is_refused() {
        let dir = scratch("served");
        let secret = dir.join("secret");
        std::fs::write(&secret, "root-only secret\n").unwrap();
        let f = dir.join("rec-1-node5.csv");
        std::fs::write(&f, "t_s\n").unwrap();
        let (_, size) = open_served(&f).unwrap();
        assert_eq!(size, 4);
        for (target, what) in [
            (secret.as_path(), "secret"),
            (Path::new("/dev/zero"), "zero"),
        ] {
            std::fs::remove_file(&f).unwrap();
            std::os::unix::fs::symlink(target, &f).unwrap();
            let e = open_served(&f)
                .err()
                .unwrap_or_else(|| panic!("{what} served"));
            assert_eq!(e.raw_os_error(), Some(libc::ELOOP), "{what}: {e}");
        }
        std::fs::remove_file(&f).unwrap();
        let c = std::ffi::CString::new(f.to_str().unwrap()).unwrap();
        // SAFETY: a valid C string.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let e = open_served(&f).expect_err("a FIFO is not served");
        assert!(e.to_string().contains("not a regular file"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_recording_stops_growing_at_its_cap_and_says_so() {
        let dir = scratch("cap");
        let cap = 4096;
        let mut r = start(&dir, 1, &[5], None, 0, cap).unwrap();
        let s = Sample::default();
        for _ in 0..1000 {
            r.write(0, &s);
        }
        assert!(r.samples > 0 && r.samples < 1000, "{} rows", r.samples);
        assert!(r.bytes() <= cap);
        let note = r.cap_note().expect("at the cap");
        assert!(note.contains("cap of 4096 bytes"), "{note}");
        r.finish();
        let len = std::fs::metadata(dir.join("rec-1-node5.csv"))
            .unwrap()
            .len();
        assert!(len <= cap && len > cap - 200, "{len}");
        // Whole rows only.
        let text = std::fs::read_to_string(dir.join("rec-1-node5.csv")).unwrap();
        assert!(text.ends_with('\n'));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn only_the_panels_own_file_names_are_served() {
        assert!(is_served_name("rec-1-node5.csv"));
        assert!(is_served_name("rec-12.log"));
        for bad in [
            "../etc/passwd",
            "rec-1/../../x.csv",
            "trace.csv",
            "rec-1.txt",
            "rec-%2e.csv",
        ] {
            assert!(!is_served_name(bad), "{bad}");
        }
        let dir = Path::new("/tmp/x");
        let st = RecordState {
            files: vec!["rec-1-node5.csv".into()],
            ..Default::default()
        };
        assert_eq!(
            served_path(dir, &st, "rec-1-node5.csv"),
            Some(dir.join("rec-1-node5.csv"))
        );
        assert_eq!(served_path(dir, &st, "rec-2-node5.csv"), None);
    }
}
