//! Tracing a live run: what each drive reports, one sample per tick, written to CSV by a
//! recorder thread, so a `drive-emu run` stopped with Ctrl-C or SIGTERM leaves a complete
//! trace behind.
//!
//! - The loop thread calls [`TraceTap::on_tick`] after every tick: it reads each node's actual
//!   values (as a master would see them in its TPDOs) into a [`Sample`] and pushes it into a
//!   preallocated lock-free queue. No allocation, lock or I/O: a full queue is a counted loss.
//! - The [`Recorder`] thread drains the queues every few milliseconds into one CSV per axis,
//!   in the master's sample-log layout ([`Sample::CSV_HEADER`]), which `drive-emu analyze`
//!   reads. [`Recorder::finish`] drains what is left and flushes the files.

use super::{AxisSlot, Runtime, SimulatedDrive};
use crate::bus::CanBus;
use crate::samples::Sample;
use crossbeam::queue::ArrayQueue;
use drive_protocol::Node;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// Samples a queue holds: 65 s at 1 kHz, far more than the recorder ever lags.
const QUEUE_SAMPLES: usize = 1 << 16;

/// What `node` reports at `now_us`: the values a master reads from its TPDOs (statusword,
/// mode, positions, velocity, torque, current, following error) plus the drive's own
/// set-points (0x6062 position demand, 0x606B velocity demand).
pub fn node_sample(node: &Node, now_us: u64) -> Sample {
    let raw = |i: u16, s: u8| node.object_raw(i, s).unwrap_or(0);
    Sample {
        t_s: Sample::t_s_of_us(now_us),
        statusword: node.statusword(),
        mode_display: node.mode(),
        target_uu: f64::from(raw(0x6062, 0) as i32),
        setpoint_velocity_uu_s: f64::from(raw(0x606B, 0) as i32),
        position_uu: node.position_actual(),
        direct_position_uu: raw(0x60E4, 1) as i32,
        velocity_uu_s: raw(0x606C, 0) as i32,
        torque_permille: raw(0x6077, 0) as u16 as i16,
        current_permille: raw(0x6078, 0) as u16 as i16,
        following_error_uu: raw(0x60F4, 0) as i32,
    }
}

/// The loop thread's half: one queue per axis, sized once.
pub struct TraceTap {
    queues: Vec<ArrayQueue<Sample>>,
    lost: AtomicU64,
}

impl TraceTap {
    pub fn new(axes: usize) -> Self {
        Self {
            queues: (0..axes).map(|_| ArrayQueue::new(QUEUE_SAMPLES)).collect(),
            lost: AtomicU64::new(0),
        }
    }

    /// After every tick: one sample per axis. Real-time safe.
    pub fn on_tick<B: CanBus, D: SimulatedDrive>(&self, rt: &Runtime<B, D>) {
        self.push_all(&rt.axes, rt.sim_time_us);
    }

    fn push_all<D>(&self, axes: &[AxisSlot<D>], now_us: u64) {
        self.push_nodes(axes.iter().map(|a| &a.node), now_us);
    }

    /// One sample per node at `now_us`, in axis order: for a loop other than the CAN
    /// [`Runtime`] (the EtherCAT front end's). Real-time safe.
    pub fn push_nodes<'a>(&self, nodes: impl IntoIterator<Item = &'a Node>, now_us: u64) {
        for (q, node) in self.queues.iter().zip(nodes) {
            if q.push(node_sample(node, now_us)).is_err() {
                self.lost.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// The oldest sample of axis `k` not taken yet (for a reader other than the recorder).
    pub fn pop(&self, k: usize) -> Option<Sample> {
        self.queues.get(k)?.pop()
    }

    /// Samples dropped because the recorder fell behind.
    pub fn lost(&self) -> u64 {
        self.lost.load(Ordering::Relaxed)
    }
}

/// The files of a traced run: `path` itself for one axis; for several, the node ID goes
/// before the extension (`trace.csv` -> `trace-node5.csv`, `trace-node6.csv`).
pub fn trace_paths(path: &Path, node_ids: &[u8]) -> Vec<PathBuf> {
    if node_ids.len() == 1 {
        return vec![path.to_path_buf()];
    }
    let stem = path
        .file_stem()
        .map_or_else(|| "trace".into(), |s| s.to_string_lossy().into_owned());
    let ext = path
        .extension()
        .map_or_else(|| "csv".into(), |s| s.to_string_lossy().into_owned());
    node_ids
        .iter()
        .map(|n| path.with_file_name(format!("{stem}-node{n}.{ext}")))
        .collect()
}

/// The recorder thread and what it wrote.
pub struct Recorder {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<std::io::Result<u64>>,
    pub paths: Vec<PathBuf>,
}

/// What a finished recording holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TraceSummary {
    pub paths: Vec<PathBuf>,
    /// Samples written, over all files.
    pub samples: u64,
    /// Samples lost because the recorder fell behind.
    pub lost: u64,
}

impl Recorder {
    /// Create the files (an error here, before the loop starts, loses nothing) and start
    /// draining `tap` into them.
    pub fn start(tap: Arc<TraceTap>, paths: Vec<PathBuf>) -> std::io::Result<Self> {
        assert_eq!(tap.queues.len(), paths.len(), "one file per axis");
        let mut files = Vec::with_capacity(paths.len());
        for p in &paths {
            let f = std::fs::File::create(p).map_err(|e| {
                std::io::Error::new(e.kind(), format!("cannot create {}: {e}", p.display()))
            })?;
            let mut w = BufWriter::new(f);
            writeln!(w, "{}", Sample::CSV_HEADER)?;
            files.push(w);
        }
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = Arc::clone(&stop);
            std::thread::Builder::new()
                .name("drive-emu-trace".into())
                .spawn(move || {
                    let mut written = 0u64;
                    loop {
                        // Read the flag before draining: nothing pushed before `finish` is
                        // left behind.
                        let last = stop.load(Ordering::Acquire);
                        for (q, w) in tap.queues.iter().zip(files.iter_mut()) {
                            while let Some(s) = q.pop() {
                                s.write_csv_row(w)?;
                                written += 1;
                            }
                        }
                        if last {
                            break;
                        }
                        std::thread::sleep(Duration::from_millis(20));
                    }
                    for w in &mut files {
                        w.flush()?;
                    }
                    Ok(written)
                })?
        };
        Ok(Self {
            stop,
            thread,
            paths,
        })
    }

    /// Call after the loop has stopped: drain the rest, flush, close.
    pub fn finish(self, tap: &TraceTap) -> std::io::Result<TraceSummary> {
        self.stop.store(true, Ordering::Release);
        let samples = self
            .thread
            .join()
            .map_err(|_| std::io::Error::other("the trace recorder thread panicked"))??;
        Ok(TraceSummary {
            paths: self.paths,
            samples,
            lost: tap.lost(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unwritable_trace_path_is_an_error_before_the_run() {
        let tap = Arc::new(TraceTap::new(1));
        let err = Recorder::start(tap, vec![PathBuf::from("/nonexistent-dir/trace.csv")])
            .err()
            .expect("cannot create");
        assert!(
            err.to_string().contains("/nonexistent-dir/trace.csv"),
            "{err}"
        );
    }

    #[test]
    fn several_axes_get_one_file_each_named_by_node() {
        let p = Path::new("/tmp/run/trace.csv");
        assert_eq!(trace_paths(p, &[5]), vec![p.to_path_buf()]);
        assert_eq!(
            trace_paths(p, &[5, 6]),
            vec![
                PathBuf::from("/tmp/run/trace-node5.csv"),
                PathBuf::from("/tmp/run/trace-node6.csv")
            ]
        );
    }
}
