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
    let f = crate::infile::open(path, "")?.file;
    read_trace_text_from(path, f)
}

/// [`read_trace_text`] of what `f` gives (a file opened, bytes in memory), named `path` in
/// errors.
pub fn read_trace_text_from(path: &Path, mut f: impl std::io::Read) -> anyhow::Result<String> {
    use std::io::Read;
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

/// A trace file's lines, streamed (the file is never held whole): gzip-compressed or plain,
/// at most [`MAX_TRACE_BYTES`] (uncompressed) and lines of at most [`MAX_LINE_BYTES`], each
/// UTF-8; errors name the file and the line.
pub struct TraceLines<'a> {
    src: Box<dyn std::io::BufRead + 'a>,
    path: std::path::PathBuf,
    gz: bool,
    total: u64,
    line_no: usize,
    /// The last line read ended with a newline (false before any line, and at a cut end).
    newline: bool,
}

impl<'a> TraceLines<'a> {
    /// Open the file `path` (through the bounded input reader: a FIFO or device is refused).
    pub fn open(path: &Path) -> anyhow::Result<TraceLines<'static>> {
        let f = crate::infile::open(path, "")?.file;
        TraceLines::from_reader(path, f)
    }

    /// The lines of what `f` gives (a file opened, bytes in memory), named `path` in errors.
    pub fn from_reader(path: &Path, mut f: impl std::io::Read + 'a) -> anyhow::Result<Self> {
        use std::io::{BufReader, Read};
        let mut magic = [0u8; 2];
        let mut n = 0;
        while n < 2 {
            let k = f
                .read(&mut magic[n..])
                .with_context(|| format!("cannot read {}", path.display()))?;
            if k == 0 {
                break;
            }
            n += k;
        }
        let head = std::io::Cursor::new(magic[..n].to_vec());
        let gz = n == 2 && magic == [0x1f, 0x8b];
        let raw = head.chain(f);
        let src: Box<dyn std::io::BufRead + 'a> = if gz {
            Box::new(BufReader::with_capacity(
                64 << 10,
                flate2::read::MultiGzDecoder::new(raw),
            ))
        } else {
            Box::new(BufReader::with_capacity(64 << 10, raw))
        };
        Ok(TraceLines {
            src,
            path: path.to_path_buf(),
            gz,
            total: 0,
            line_no: 0,
            newline: false,
        })
    }

    /// The number (from 1) of the line last returned.
    pub fn line_no(&self) -> usize {
        self.line_no
    }

    /// Whether the last line returned ended with a newline (a line cut at the end of the
    /// file did not).
    pub fn ended_with_newline(&self) -> bool {
        self.newline
    }

    /// The next line, without its newline (nor a `\r` before it); `None` at the end.
    pub fn next_line<'b>(&mut self, buf: &'b mut Vec<u8>) -> anyhow::Result<Option<&'b str>> {
        buf.clear();
        let mut got_any = false;
        self.newline = false;
        loop {
            let chunk = self.src.fill_buf().with_context(|| {
                format!(
                    "{}: cannot read{}",
                    self.path.display(),
                    if self.gz { " (gzip)" } else { "" }
                )
            })?;
            if chunk.is_empty() {
                break;
            }
            got_any = true;
            let (take, done) = match chunk.iter().position(|&b| b == b'\n') {
                Some(i) => (i + 1, true),
                None => (chunk.len(), false),
            };
            let body = if done { take - 1 } else { take };
            if buf.len() + body > MAX_LINE_BYTES {
                bail!(
                    "{}:{}: line longer than {} KiB: not a candump log or CSV trace",
                    self.path.display(),
                    self.line_no + 1,
                    MAX_LINE_BYTES >> 10
                );
            }
            buf.extend_from_slice(&chunk[..body]);
            self.src.consume(take);
            self.total += take as u64;
            if self.total > MAX_TRACE_BYTES {
                bail!(
                    "{}: more than {} MiB{}: cut it to the part to analyse (e.g. with head or \
                     split)",
                    self.path.display(),
                    MAX_TRACE_BYTES >> 20,
                    if self.gz { " uncompressed" } else { "" }
                );
            }
            if done {
                self.newline = true;
                break;
            }
        }
        if !got_any {
            return Ok(None);
        }
        self.line_no += 1;
        if buf.last() == Some(&b'\r') {
            buf.pop();
        }
        match std::str::from_utf8(buf) {
            Ok(s) => Ok(Some(s)),
            Err(e) => bail!(
                "{}:{}: not text (invalid UTF-8 at byte {} of the line): not a candump log or \
                 CSV trace",
                self.path.display(),
                self.line_no,
                e.valid_up_to() + 1
            ),
        }
    }
}

/// A CSV trace read by [`read_csv_stream`]: the columns kept, the names of the others with
/// whether all their values were whole, finite numbers, and the reader's notes.
#[derive(Debug, Default)]
pub struct StreamedCsv {
    pub columns: Columns,
    /// Columns read but not kept: (name, every value a finite whole number).
    pub whole: Vec<(String, bool)>,
    pub notes: Vec<String>,
}

/// What [`read_csv_stream`] found.
pub enum Streamed {
    /// The first line that is neither empty nor a `#` comment starts with `(`: a candump log.
    Candump,
    Csv(StreamedCsv),
}

/// Read a CSV trace line by line, keeping the columns `keep` names (the others are checked
/// as numbers and dropped): the same rules as [`parse_csv`] (empty and `#` lines skipped; a
/// last line cut short is skipped and noted), without ever holding the file's text.
pub fn read_csv_stream(
    mut lines: TraceLines<'_>,
    keep: impl Fn(&str) -> bool,
) -> anyhow::Result<Streamed> {
    let path = lines.path.clone();
    let mut buf = Vec::new();
    let header = loop {
        match lines.next_line(&mut buf)? {
            None => bail!("empty trace"),
            Some(l) if l.trim().is_empty() || l.starts_with('#') => continue,
            Some(l) => break l.to_string(),
        }
    };
    if header.trim_start().starts_with('(') {
        return Ok(Streamed::Candump);
    }
    let names: Vec<String> = header.split(',').map(|h| h.trim().to_string()).collect();
    // Where each field goes: Some(index into kept columns) or None (dropped, index into whole).
    let mut slots = Vec::with_capacity(names.len());
    let mut out = StreamedCsv::default();
    for n in &names {
        if keep(n) {
            slots.push(Ok(out.columns.len()));
            out.columns.push((n.clone(), Vec::new()));
        } else {
            slots.push(Err(out.whole.len()));
            out.whole.push((n.clone(), true));
        }
    }
    // The last data line is checked once the next one (or the end) is known: a file that does
    // not end with a newline was cut mid-line, and its last data line is skipped.
    let mut pending: Option<(usize, Result<Vec<f64>, String>)> = None;
    let mut row = Vec::with_capacity(names.len());
    let mut ends_with_newline = true;
    while let Some(line) = lines.next_line(&mut buf)? {
        ends_with_newline = lines.ended_with_newline();
        if line.trim().is_empty() || line.starts_with('#') {
            continue;
        }
        if let Some(p) = pending.take() {
            commit(&path, p, &slots, &mut out, false)?;
        }
        row.clear();
        let mut count = 0usize;
        let mut bad = None;
        for f in line.split(',') {
            count += 1;
            if count > names.len() || bad.is_some() {
                continue;
            }
            match f.trim().parse::<f64>() {
                Ok(x) => row.push(x),
                Err(_) => {
                    bad = Some(format!(
                        "column {}: `{}` is not a number",
                        crate::quote::text(&names[count - 1]),
                        crate::quote::text(f)
                    ))
                }
            }
        }
        let parsed = if count != names.len() {
            Err(format!("{count} fields, header has {}", names.len()))
        } else if let Some(b) = bad {
            Err(b)
        } else {
            Ok(row.clone())
        };
        pending = Some((lines.line_no(), parsed));
    }
    if let Some(p) = pending.take() {
        commit(&path, p, &slots, &mut out, !ends_with_newline)?;
    }
    Ok(Streamed::Csv(out))
}

fn commit(
    path: &Path,
    (line, parsed): (usize, Result<Vec<f64>, String>),
    slots: &[Result<usize, usize>],
    out: &mut StreamedCsv,
    cut: bool,
) -> anyhow::Result<()> {
    // No newline at the end: the writer stopped mid-line; even a line that parses may have
    // lost digits.
    let parsed = if cut {
        Err("no newline at the end".to_string())
    } else {
        parsed
    };
    match parsed {
        Ok(v) => {
            for (slot, x) in slots.iter().zip(v) {
                match *slot {
                    Ok(c) => out.columns[c].1.push(x),
                    Err(w) => {
                        let whole = &mut out.whole[w].1;
                        *whole = *whole && x.is_finite() && x.fract() == 0.0;
                    }
                }
            }
            Ok(())
        }
        Err(e) if cut => {
            out.notes.push(format!(
                "{}:{line}: last line cut short ({e}: the writer was stopped mid-line): skipped",
                path.display()
            ));
            Ok(())
        }
        Err(e) => bail!("{}:{line}: {e}", path.display()),
    }
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
                    f.trim().parse::<f64>().map_err(|_| {
                        format!(
                            "column {}: `{}` is not a number",
                            crate::quote::text(&c.0),
                            crate::quote::text(f)
                        )
                    })
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
