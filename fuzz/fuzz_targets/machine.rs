//! Any bytes as a machine file (`drive-emu run --config FILE`): never a panic; an error is
//! one clean line (file content quoted) whose `line N`, when it gives one, is in the file.
//! Profile names are resolved as from a file in the current directory.
//!
//! Run: cargo fuzz run --sanitizer none --debug-assertions machine. Seed corpus: the machine
//! files of `docs/` and `tests/`.
#![no_main]

use drive_emu::drive::machine;
use drive_protocol_fuzz::{assert_clean_message, assert_line_within};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Err(e) = machine::parse(text, "fuzz.toml") {
        let msg = format!("{e:#}");
        assert_clean_message("machine file", &msg);
        assert_line_within("machine file", &msg, "fuzz.toml", text);
    }
});
