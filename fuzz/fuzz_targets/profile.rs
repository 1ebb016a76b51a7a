//! Any bytes as a drive behaviour profile file (`--profile FILE`): never a panic; an error
//! is one clean line (file content quoted) whose line, when it has one, is in the file.
//!
//! Run: cargo fuzz run --sanitizer none --debug-assertions profile. Seed corpus:
//! `profiles/*.toml`.
#![no_main]

use drive_emu::drive::quirk_profile::ProfileFile;
use drive_protocol_fuzz::{assert_clean_message, lines};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Err(e) = ProfileFile::parse(text, "fuzz.toml", "fuzz", None) {
        let msg = e.to_string();
        assert_clean_message("profile", &msg);
        if let Some(line) = e.line {
            assert!(
                line >= 1 && line <= lines(text),
                "line {line} of a {}-line file: {msg}",
                lines(text)
            );
        }
    }
});
