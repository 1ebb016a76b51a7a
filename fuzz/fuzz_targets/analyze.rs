//! Any bytes as a trace file given to `drive-emu analyze` (a candump log, a CSV trace of
//! either layout, gzip-compressed or plain), read as the command reads a file: never a panic;
//! an error is one clean line (file content quoted, bounded) whose `fuzz.csv:N:` line, when
//! it gives one, is in the input; a result has an exit code `analyze` uses, reasons and
//! notes that are clean lines, and serialises to JSON (`--json`).
//!
//! The first byte picks the options (k_v given or from the preset, linear or rotary), the
//! rest is the file. Run: cargo fuzz run --sanitizer none --debug-assertions analyze. Seed
//! corpus: `tests/corpus/*` and `emulator/tests` traces (candump logs and CSV).
#![no_main]

use drive_emu::cli::analyze::{analyze_input, AnalyzeArgs, AnalyzeInput};
use drive_protocol_fuzz::{assert_clean_message, lines};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&opts, file)) = data.split_first() else {
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
