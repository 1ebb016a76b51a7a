//! Recordings started and stopped from the panel: per axis a CSV of every tick in the columns
//! of `run --trace` (written by the collector from the fan-out), and, on a CAN interface, a
//! capture of the bus in `candump -L` format read by a socket of its own (what candump would
//! see; the loop is not involved). Both are what `drive-emu analyze` reads. Files go to the
//! panel's directory as `rec-N-node5.csv` and `rec-N.log`, downloadable while the run lasts.

use super::server::Shared;
use crate::bus::CanBus;
use crate::samples::Sample;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

/// A recording in progress.
pub struct Recording {
    pub number: u32,
    pub started_us: u64,
    csv: Vec<BufWriter<File>>,
    pub csv_names: Vec<String>,
    pub samples: u64,
    /// Ticks missed because the collector fell behind the fan-out.
    pub lost: u64,
    capture: Option<Capture>,
    pub capture_name: Option<String>,
    /// Why there is no capture, when there is none.
    pub capture_note: Option<String>,
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

fn create(dir: &Path, name: &str) -> std::io::Result<BufWriter<File>> {
    let p = dir.join(name);
    File::create(&p)
        .map(BufWriter::new)
        .map_err(|e| std::io::Error::new(e.kind(), format!("cannot create {}: {e}", p.display())))
}

/// Start a recording: the files created (an error here starts nothing), the capture thread on
/// `iface` if there is one.
pub fn start(
    dir: &Path,
    number: u32,
    node_ids: &[u8],
    iface: Option<&str>,
    now_us: u64,
) -> std::io::Result<Recording> {
    std::fs::create_dir_all(dir).map_err(|e| {
        std::io::Error::new(e.kind(), format!("cannot create {}: {e}", dir.display()))
    })?;
    let mut csv = Vec::new();
    let mut csv_names = Vec::new();
    for n in node_ids {
        let name = format!("rec-{number}-node{n}.csv");
        let mut w = create(dir, &name)?;
        writeln!(w, "{}", Sample::CSV_HEADER)?;
        csv.push(w);
        csv_names.push(name);
    }
    let (capture, capture_name, capture_note) = match iface {
        Some(iface) => {
            let name = format!("rec-{number}.log");
            let file = create(dir, &name)?;
            match open_capture_bus(iface) {
                Ok(bus) => (
                    Some(spawn_capture(bus, iface.to_string(), file)?),
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
                        write_candump_line(&mut out, t_ns, &iface, &f)?;
                        frames.fetch_add(1, Ordering::Relaxed);
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
    /// One tick of axis `axis` (collector thread).
    pub fn write(&mut self, axis: usize, s: &Sample) {
        if let Some(w) = self.csv.get_mut(axis) {
            if s.write_csv_row(w).is_ok() {
                self.samples += 1;
            }
        }
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

/// Finish a recording still running when the panel stops.
pub fn finish_active(shared: &Shared) {
    let active = shared.record.lock().ok().and_then(|mut r| r.active.take());
    if let Some(r) = active {
        let (names, _) = r.finish();
        for n in names {
            eprintln!(
                "drive-emu: panel: recording written: {}",
                shared.record_dir.join(n).display()
            );
        }
    }
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

    #[test]
    fn a_recording_without_a_can_interface_says_why_it_has_no_capture() {
        let dir = std::env::temp_dir().join(format!("drive-emu-rec-test-{}", std::process::id()));
        let r = start(&dir, 7, &[5, 6], Some("nocan9"), 1_000).unwrap();
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
        // A directory that cannot be made: an error, nothing started.
        let e = start(Path::new("/proc/no/such/dir"), 1, &[5], None, 0)
            .err()
            .expect("refused");
        assert!(e.to_string().contains("/proc/no/such/dir"), "{e}");
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
