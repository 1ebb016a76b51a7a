//! `run --trace`: a reader of the observation bus that writes every tick of every axis to one
//! CSV per axis ([`crate::runtime::trace::CsvSink`], the sample log `drive-emu analyze`
//! reads), so a run stopped with Ctrl-C or SIGTERM leaves a complete trace behind.
//!
//! The [`Recorder`] thread follows each axis's ring with a cursor of its own every few
//! milliseconds; [`Recorder::finish`] (after the loop has stopped) reads what is left and
//! flushes the files. The loop does nothing for it beyond publishing; a recorder that falls
//! more than the ring behind (a stalled disk) loses the oldest ticks and says how many.

use super::ring::Cursor;
use super::Observation;
use crate::runtime::trace::{create_trace_file, CsvSink};
use std::fs::File;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// The recorder thread and what it writes.
pub struct Recorder {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<std::io::Result<(u64, u64)>>,
    pub paths: Vec<PathBuf>,
}

/// What a finished recording holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TraceSummary {
    pub paths: Vec<PathBuf>,
    /// Samples written, over all files.
    pub samples: u64,
    /// Ticks lost because the recorder fell more than the ring behind.
    pub lost: u64,
}

impl Recorder {
    /// Create the files, one per axis of `obs` (an error here, before the loop starts, loses
    /// nothing), and start following the bus from its next record.
    pub fn start(obs: Arc<Observation>, paths: Vec<PathBuf>) -> std::io::Result<Self> {
        assert_eq!(obs.rings.len(), paths.len(), "one file per axis");
        let mut files = Vec::with_capacity(paths.len());
        for p in &paths {
            files.push(create_trace_file(p)?);
        }
        let cursors = obs.cursors_at_end();
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = Arc::clone(&stop);
            std::thread::Builder::new()
                .name("drive-emu-trace".into())
                .spawn(move || follow(&obs, cursors, files, &stop))?
        };
        Ok(Self {
            stop,
            thread,
            paths,
        })
    }

    /// Call after the loop has stopped: read the rest, flush, close.
    pub fn finish(self) -> std::io::Result<TraceSummary> {
        self.stop.store(true, Ordering::Release);
        let (samples, lost) = self
            .thread
            .join()
            .map_err(|_| std::io::Error::other("the trace recorder thread panicked"))??;
        Ok(TraceSummary {
            paths: self.paths,
            samples,
            lost,
        })
    }
}

/// The recorder thread: every 20 ms, every axis's new ticks into its file. Returns (rows
/// written, ticks lost).
fn follow(
    obs: &Observation,
    mut cursors: Vec<Cursor>,
    mut files: Vec<CsvSink<File>>,
    stop: &AtomicBool,
) -> std::io::Result<(u64, u64)> {
    loop {
        // Read the flag before reading the rings: nothing published before `finish` is
        // left behind.
        let last = stop.load(Ordering::Acquire);
        for (k, (c, w)) in cursors.iter_mut().zip(files.iter_mut()).enumerate() {
            while let Some(s) = obs.next(k, c) {
                w.write(&s.sample, |_| true)?;
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
    Ok((
        files.iter().map(|w| w.samples).sum(),
        cursors.iter().map(|c| c.lost).sum(),
    ))
}
