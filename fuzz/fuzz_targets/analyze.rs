//! Any bytes as a trace file given to `drive-emu analyze` (a candump log, a CSV trace of
//! either layout, gzip-compressed or plain), read as the command reads a file: never a panic;
//! an error is one clean line (file content quoted, bounded) whose `fuzz.csv:N:` line, when
//! it gives one, is in the input; a result has an exit code `analyze` uses, reasons and
//! notes that are clean lines, and serialises to JSON (`--json`).
//!
//! The first byte picks the options (k_v given or from the preset, linear or rotary), the
//! rest is the file. Run: cargo fuzz run --sanitizer none --debug-assertions analyze. Seed
//! corpus: `tests/corpus/*` and `emulator/tests` traces (candump logs and CSV).
//!
//! Each input is a file of at most [`MAX_LINES`] lines, so that an input costs a bounded time
//! (10^6 inputs in minutes): a plain file is cut after its `MAX_LINES`th line (the checks are
//! made on the file cut); a gzip file is given whole when what it holds is at most
//! `MAX_LINES` lines and [`MAX_GZ_BYTES`] bytes (read as `analyze` reads it, up to a
//! decoding error), and skipped otherwise (a few bytes of gzip can hold megabytes).
#![no_main]

use drive_emu::cli::analyze::{analyze_input, AnalyzeArgs, AnalyzeInput};
use drive_protocol_fuzz::{assert_clean_message, lines};
use libfuzzer_sys::fuzz_target;
use std::io::Read;

/// Most lines of a trace one input gives `analyze` (the seeds have 62 and 80).
const MAX_LINES: usize = 256;

/// Most bytes a gzip input may decompress to.
const MAX_GZ_BYTES: u64 = 64 << 10;

/// The first `MAX_LINES` lines of a plain file (with their newlines); a gzip file whole if it
/// holds no more than the caps allow, else `None`.
fn capped(file: &[u8]) -> Option<&[u8]> {
    if file.starts_with(&[0x1f, 0x8b]) {
        let mut plain = Vec::new();
        // A decoding error ends the text here as it ends `analyze`'s reading.
        let _ = flate2::read::MultiGzDecoder::new(file)
            .take(MAX_GZ_BYTES + 1)
            .read_to_end(&mut plain);
        let n = plain.iter().filter(|&&b| b == b'\n').count();
        return (plain.len() as u64 <= MAX_GZ_BYTES && n < MAX_LINES).then_some(file);
    }
    match file
        .iter()
        .enumerate()
        .filter(|(_, &b)| b == b'\n')
        .nth(MAX_LINES - 1)
    {
        Some((i, _)) => Some(&file[..=i]),
        None => Some(file),
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&opts, file)) = data.split_first() else {
        return;
    };
    let Some(file) = capped(file) else {
        return;
    };
    let args = AnalyzeArgs {
        trace: "fuzz.csv".into(),
        kv: (opts & 1 == 1).then_some(3.4),
        preset: (opts & 1 == 0).then(|| "cnc1".to_string()),
        rotary: opts & 2 == 2,
        ..AnalyzeArgs::default()
    };
    match analyze_input(&args, AnalyzeInput::Bytes(file)) {
        Err(e) => {
            let msg = format!("{e:#}");
            assert_clean_message("analyze", &msg);
            if let Some(rest) = msg.strip_prefix("fuzz.csv:") {
                let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
                if let Ok(n) = digits.parse::<usize>() {
                    // Plain text only: a gzip file's lines are those of what it holds.
                    if !file.starts_with(&[0x1f, 0x8b]) {
                        let total = lines(&String::from_utf8_lossy(file));
                        assert!(n >= 1 && n <= total, "line {n} of {total}: {msg}");
                    }
                }
            }
        }
        Ok(a) => {
            let o = &a.output;
            assert!(matches!(o.exit_code, 0 | 3), "exit code {}", o.exit_code);
            for n in &o.notes {
                assert_clean_message("analyze note", n);
            }
            for r in &o.report.reasons {
                assert_clean_message("analyze reason", r);
            }
            serde_json::to_string(o).expect("the output serialises to JSON");
        }
    }
});
