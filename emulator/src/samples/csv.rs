//! Reading trace files: plain or gzip text, bounded in size and line length, and CSV text
//! into named columns.

use anyhow::{bail, Context};
use std::path::Path;

/// Largest trace read, bytes (a 1 kHz candump log grows by about 0.2 MB/s: over 20 minutes).
pub const MAX_TRACE_BYTES: u64 = 256 << 20;
/// Longest line accepted, bytes: anything longer is not a candump log or a CSV trace.
pub const MAX_LINE_BYTES: usize = 64 << 10;

/// Read a trace file as text: gzip-compressed or plain, at most [`MAX_TRACE_BYTES`] and lines
/// of at most [`MAX_LINE_BYTES`], streamed so that `/dev/zero` or a binary file is refused
/// early with a clear error instead of filling memory.
pub fn read_trace_text(path: &Path) -> anyhow::Result<String> {
    use std::io::Read;
    let mut f = crate::infile::open(path, "")?.file;
    let mut magic = [0u8; 2];
    let n = f
        .read(&mut magic)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let head = std::io::Cursor::new(magic[..n].to_vec());
    let gz = n == 2 && magic == [0x1f, 0x8b];
    let raw = head.chain(f);
    let mut src: Box<dyn Read> = if gz {
        Box::new(flate2::read::MultiGzDecoder::new(raw))
    } else {
        Box::new(raw)
    };
    let mut out = Vec::new();
    let mut buf = vec![0u8; 64 << 10];
    let mut line_len = 0usize;
    let mut line_no = 1usize;
    loop {
        let k = src.read(&mut buf).with_context(|| {
            format!(
                "{}: cannot read{}",
                path.display(),
                if gz { " (gzip)" } else { "" }
            )
        })?;
        if k == 0 {
            break;
        }
        for &b in &buf[..k] {
            if b == b'\n' {
                line_len = 0;
                line_no += 1;
            } else {
                line_len += 1;
                if line_len > MAX_LINE_BYTES {
                    bail!(
                        "{}:{line_no}: line longer than {} KiB: not a candump log or CSV trace",
                        path.display(),
                        MAX_LINE_BYTES >> 10
                    );
                }
            }
        }
        out.extend_from_slice(&buf[..k]);
        if out.len() as u64 > MAX_TRACE_BYTES {
            bail!(
                "{}: more than {} MiB{}: cut it to the part to analyse (e.g. with head or split)",
                path.display(),
                MAX_TRACE_BYTES >> 20,
                if gz { " uncompressed" } else { "" }
            );
        }
    }
    String::from_utf8(out).map_err(|e| {
        anyhow::anyhow!(
            "{}: not text (invalid UTF-8 at byte {}): not a candump log or CSV trace",
            path.display(),
            e.utf8_error().valid_up_to()
        )
    })
}

/// Named columns of a CSV trace.
pub type Columns = Vec<(String, Vec<f64>)>;

/// Read a CSV into named columns.
pub fn read_csv(path: &Path) -> anyhow::Result<Columns> {
    let text = read_trace_text(path)?;
    Ok(parse_csv(path, &text)?.0)
}

/// Parse CSV text (read from `path`) into named columns, and notes: a last line cut short (no
/// newline at the end: the writer was killed mid-line) is skipped and reported.
pub fn parse_csv(path: &Path, text: &str) -> anyhow::Result<(Columns, Vec<String>)> {
    let all: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.starts_with('#'))
        .collect();
    let cut_at_end = !text.ends_with('\n');
    let mut notes = Vec::new();
    let mut lines = all.iter().copied();
    let (_, header) = lines.next().context("empty trace")?;
    let mut cols: Vec<(String, Vec<f64>)> = header
        .split(',')
        .map(|h| (h.trim().to_string(), Vec::new()))
        .collect();
    let last_no = all.last().map(|(i, _)| *i);
    for (i, line) in lines {
        let fields: Vec<&str> = line.split(',').collect();
        let parsed: Result<Vec<f64>, String> = if cut_at_end && Some(i) == last_no {
            // No newline at the end: the writer stopped mid-line; even a line that parses
            // may have lost digits.
            Err("no newline at the end".to_string())
        } else if fields.len() != cols.len() {
            Err(format!(
                "{} fields, header has {}",
                fields.len(),
                cols.len()
            ))
        } else {
            fields
                .iter()
                .zip(&cols)
                .map(|(f, c)| {
                    f.trim()
                        .parse::<f64>()
                        .map_err(|_| format!("column {}: `{f}` is not a number", c.0))
                })
                .collect()
        };
        match parsed {
            Ok(v) => {
                for (c, x) in cols.iter_mut().zip(v) {
                    c.1.push(x);
                }
            }
            Err(e) if cut_at_end && Some(i) == last_no => notes.push(format!(
                "{}:{}: last line cut short ({e}: the writer was stopped mid-line): skipped",
                path.display(),
                i + 1
            )),
            Err(e) => bail!("{}:{}: {e}", path.display(), i + 1),
        }
    }
    Ok((cols, notes))
}
