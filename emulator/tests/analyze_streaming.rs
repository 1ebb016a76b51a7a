//! `analyze` reads a CSV trace line by line and keeps only the columns its analysis uses
//! (issue 32, finding 5: a 249 MiB CSV peaked at 2.2 GB when the file was read whole, then
//! split into every column). Two files with the same samples, one with 40 extra columns of
//! long numbers (five times the bytes): the heap's peak while analysing the wide one exceeds
//! the narrow one's by far less than the extra bytes, and the verdicts are the same. A reader
//! that held the file's text, or every column, would pay at least the extra bytes.
//!
//! A candump log is streamed the same way: two logs with the same frames of the drive, one
//! with ten times as many frames of other nodes besides, cost the same heap; and a short log
//! gets a clear "too few" where it said "slope of NaN" (issue 32, finding 8).

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use drive_emu::cli::analyze::{analyze_input, AnalyzeArgs, AnalyzeInput};
use drive_emu::samples::Sample;

struct Counting;

static NOW: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(by: usize) {
    let now = NOW.fetch_add(by, Ordering::SeqCst) + by;
    PEAK.fetch_max(now, Ordering::SeqCst);
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        NOW.fetch_sub(layout.size(), Ordering::SeqCst);
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // Counted as the new block before the old one goes (a move may need both).
        grew(new_size);
        NOW.fetch_sub(layout.size(), Ordering::SeqCst);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// One test at a time measures the heap (`cargo test` runs them on threads of one process).
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner())
}

const ROWS: usize = 60_000;
const EXTRA: usize = 40;

/// A drive's sample log of a move at constant speed with a small limit cycle; `extra`
/// columns of long numbers after the sample's own.
fn write_log(path: &Path, extra: usize) -> u64 {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut header = Sample::CSV_HEADER.to_string();
    for i in 0..extra {
        header.push_str(&format!(",extra_{i}"));
    }
    writeln!(f, "{header}").unwrap();
    let v = 20_000.0; // uu/s
    let mut row = Vec::new();
    for k in 0..ROWS {
        let t_us = (k as u64 + 1) * 1000;
        let t = t_us as f64 * 1e-6;
        let cycle = 4.0 * (2.0 * std::f64::consts::PI * 1.5 * t).sin();
        let s = Sample {
            t_s: Sample::t_s_of_us(t_us),
            statusword: 0x1237,
            mode_display: 8,
            target_uu: (v * t).round(),
            setpoint_velocity_uu_s: v,
            position_uu: (v * t + cycle).round() as i32,
            direct_position_uu: (v * t + 2.0 * cycle).round() as i32,
            velocity_uu_s: (v + 30.0 * cycle) as i32,
            torque_permille: 40,
            current_permille: (100.0 + 10.0 * cycle) as i16,
            following_error_uu: cycle.round() as i32,
        };
        row.clear();
        s.write_csv_row(&mut row).unwrap();
        if extra > 0 {
            row.pop(); // the newline
            for i in 0..extra {
                write!(row, ",{:.12}", (k * (i + 7)) as f64 / 3.0).unwrap();
            }
            row.push(b'\n');
        }
        f.write_all(&row).unwrap();
    }
    f.flush().unwrap();
    std::fs::metadata(path).unwrap().len()
}

/// Heap peak (bytes above what was allocated before) of analysing `path`, and the verdict.
fn analyse(path: &Path) -> (usize, String) {
    let args = AnalyzeArgs {
        trace: path.to_path_buf(),
        kv: Some(3.4),
        ..AnalyzeArgs::default()
    };
    let base = NOW.load(Ordering::SeqCst);
    PEAK.store(base, Ordering::SeqCst);
    let a = analyze_input(&args, AnalyzeInput::File).unwrap();
    let peak = PEAK.load(Ordering::SeqCst) - base;
    let verdict = format!(
        "{:?} {:?}",
        a.output.report.verdict, a.output.report.reasons
    );
    (peak, verdict)
}

struct Scratch(PathBuf);
impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn a_wide_csv_costs_no_more_heap_than_the_columns_the_analysis_reads() {
    let _one = one_at_a_time();
    let dir = Scratch(std::env::temp_dir().join(format!(
        "drive-emu-analyze-streaming-{}",
        std::process::id()
    )));
    std::fs::create_dir_all(&dir.0).unwrap();
    let narrow = dir.0.join("narrow.csv");
    let wide = dir.0.join("wide.csv");
    let narrow_bytes = write_log(&narrow, 0);
    let wide_bytes = write_log(&wide, EXTRA);
    let extra_bytes = (wide_bytes - narrow_bytes) as usize;
    assert!(
        extra_bytes > 4 * narrow_bytes as usize,
        "{narrow_bytes} {wide_bytes}"
    );

    let (peak_narrow, verdict_narrow) = analyse(&narrow);
    let (peak_wide, verdict_wide) = analyse(&wide);
    assert_eq!(verdict_narrow, verdict_wide);
    // The text of the file alone (held whole) would add `extra_bytes`, its columns 8 bytes per
    // value; streaming adds a line buffer and the names of the columns dropped.
    assert!(
        peak_wide < peak_narrow + extra_bytes / 10,
        "heap peak {peak_wide} B for {wide_bytes} B against {peak_narrow} B for {narrow_bytes} B: \
         the extra {extra_bytes} B of columns the analysis does not read were kept"
    );
    // And the narrow file's peak is the columns the analysis needs, not the text as well
    // (8 columns of 8 bytes a row kept, the trace's 7, twice for growth; the text is ~60 B a
    // row): well under three times the file plus the trace.
    assert!(
        peak_narrow < 3 * narrow_bytes as usize + 2 * 7 * 8 * ROWS,
        "heap peak {peak_narrow} B for a {narrow_bytes} B file"
    );
}

/// A `candump -L` log of node 5 at 1 kHz SYNC, moving at constant speed with a small limit
/// cycle, in the drive's default mapping (TPDO1 statusword + mode, TPDO2-4 statusword +
/// position / velocity / direct position; RPDO2 controlword + target); `others` frames of
/// other nodes after each SYNC. `syncs` SYNCs.
fn write_candump(path: &Path, syncs: usize, others: usize) -> u64 {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut line = |t_us: u64, id: u32, data: &[u8]| {
        let hex: String = data.iter().map(|b| format!("{b:02X}")).collect();
        writeln!(
            f,
            "({}.{:06}) vcan0 {id:03X}#{hex}",
            1_700_000_000 + t_us / 1_000_000,
            t_us % 1_000_000
        )
        .unwrap();
    };
    line(0, 0x000, &[0x82, 5]);
    line(1000, 0x705, &[0x00]);
    line(2000, 0x000, &[0x01, 5]);
    let v = 20_000.0; // uu/s
    for k in 0..syncs {
        let t_us = 3000 + 1000 * k as u64;
        let t = k as f64 * 1e-3;
        let cycle = 4.0 * (2.0 * std::f64::consts::PI * 1.5 * t).sin();
        let target = ((v * t).round() as i32).to_le_bytes();
        line(
            t_us,
            0x305,
            &[0x0F, 0x00, target[0], target[1], target[2], target[3]],
        );
        line(t_us + 1, 0x080, &[]);
        let with_sw = |x: i32| {
            let b = x.to_le_bytes();
            [0x37, 0x12, b[0], b[1], b[2], b[3]]
        };
        line(t_us + 500, 0x185, &[0x37, 0x12, 8]);
        line(t_us + 501, 0x285, &with_sw((v * t + cycle).round() as i32));
        line(t_us + 502, 0x385, &with_sw((v + 30.0 * cycle) as i32));
        line(
            t_us + 503,
            0x485,
            &with_sw((v * t + 2.0 * cycle).round() as i32),
        );
        for j in 0..others {
            let id = 0x181 + (j as u32 % 3);
            line(
                t_us + 600 + j as u64,
                id,
                &[k as u8, j as u8, 0xAA, 0x55, 1, 2, 3, 4],
            );
        }
    }
    f.flush().unwrap();
    drop(f);
    std::fs::metadata(path).unwrap().len()
}

#[test]
fn a_candump_log_is_streamed_not_held_whole() {
    let _one = one_at_a_time();
    let dir = Scratch(
        std::env::temp_dir().join(format!("drive-emu-analyze-candump-{}", std::process::id())),
    );
    std::fs::create_dir_all(&dir.0).unwrap();
    let plain = dir.0.join("plain.log");
    let busy = dir.0.join("busy.log");
    let syncs = 20_000;
    let plain_bytes = write_candump(&plain, syncs, 0);
    let busy_bytes = write_candump(&busy, syncs, 10);
    let extra_bytes = (busy_bytes - plain_bytes) as usize;
    assert!(
        extra_bytes > plain_bytes as usize,
        "{plain_bytes} {busy_bytes}"
    );
    let (peak_plain, verdict_plain) = analyse(&plain);
    let (peak_busy, verdict_busy) = analyse(&busy);
    assert_eq!(verdict_plain, verdict_busy);
    // Held whole, the busy log's text alone would add `extra_bytes`.
    assert!(
        peak_busy < peak_plain + extra_bytes / 10,
        "heap peak {peak_busy} B for {busy_bytes} B against {peak_plain} B for {plain_bytes} B: \
         the log's text was kept"
    );
}

/// Issue 32, finding 8: a log too short to fit the clocks' slopes said "slope of NaN"; it
/// says there are too few samples.
#[test]
fn a_short_candump_log_never_says_nan() {
    let _one = one_at_a_time();
    let dir = Scratch(
        std::env::temp_dir().join(format!("drive-emu-analyze-short-{}", std::process::id())),
    );
    std::fs::create_dir_all(&dir.0).unwrap();
    let short = dir.0.join("short.log");
    write_candump(&short, 12, 0);
    let args = AnalyzeArgs {
        trace: short.clone(),
        kv: Some(3.4),
        ..AnalyzeArgs::default()
    };
    let text = match analyze_input(&args, AnalyzeInput::File) {
        Ok(a) => {
            let mut all = a.output.notes.join("\n");
            all.push('\n');
            all.push_str(&a.output.report.reasons.join("\n"));
            all.push('\n');
            all.push_str(&serde_json::to_string(&a.output).unwrap());
            all
        }
        Err(e) => format!("{e:#}"),
    };
    assert!(
        !text.contains("NaN") && !text.to_lowercase().contains("slope of nan"),
        "{text}"
    );
    assert!(
        text.contains("too few") || text.contains("too short"),
        "{text}"
    );
}
