//! What a drive reports, as a sample log: [`node_sample`] (a node's actual values, as the
//! observation bus publishes them every tick), the one CSV writer of every recording
//! ([`CsvSink`]) and the file names of a traced run ([`trace_paths`]). The recorder thread of
//! `run --trace` reads the observation bus (observe/trace.rs).

use crate::samples::Sample;
use drive_protocol::DriveCore;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// What `node` reports at `now_us`: the values a master reads from its TPDOs (statusword,
/// mode, positions, velocity, torque, current, following error) plus the drive's own
/// set-points (0x6062 position demand, 0x606B velocity demand).
pub fn node_sample(node: &DriveCore, now_us: u64) -> Sample {
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

/// One CSV sample log being written: the header, then one row per [`Sample`], in the master's
/// sample-log layout ([`Sample::CSV_HEADER`]) that `drive-emu analyze` reads. The one writer
/// of every recording (`run --trace`, the panel's recordings); `admit` lets a recording with a
/// byte cap refuse a row (whole rows only).
pub struct CsvSink<W: Write> {
    w: BufWriter<W>,
    row: Vec<u8>,
    /// Rows written.
    pub samples: u64,
}

impl<W: Write> CsvSink<W> {
    /// Start the log on `w`: the header, when `admit` takes its length in bytes.
    pub fn new(w: W, admit: impl FnOnce(usize) -> bool) -> std::io::Result<Self> {
        let mut w = BufWriter::new(w);
        let header = Sample::CSV_HEADER;
        if admit(header.len() + 1) {
            writeln!(w, "{header}")?;
        }
        Ok(Self {
            w,
            row: Vec::with_capacity(256),
            samples: 0,
        })
    }

    /// One row, when `admit` takes its length in bytes; whether it was written.
    pub fn write(
        &mut self,
        s: &Sample,
        admit: impl FnOnce(usize) -> bool,
    ) -> std::io::Result<bool> {
        self.row.clear();
        s.write_csv_row(&mut self.row)?;
        if !admit(self.row.len()) {
            return Ok(false);
        }
        self.w.write_all(&self.row)?;
        self.samples += 1;
        Ok(true)
    }

    pub fn flush(&mut self) -> std::io::Result<()> {
        self.w.flush()
    }
}

/// Create the file `p` for a trace, its error naming the path.
pub fn create_trace_file(p: &Path) -> std::io::Result<CsvSink<std::fs::File>> {
    let f = std::fs::File::create(p).map_err(|e| {
        std::io::Error::new(e.kind(), format!("cannot create {}: {e}", p.display()))
    })?;
    CsvSink::new(f, |_| true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unwritable_trace_path_is_an_error_before_the_run() {
        let err = create_trace_file(Path::new("/nonexistent-dir/trace.csv"))
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
