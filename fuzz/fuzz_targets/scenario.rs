//! Any bytes as a scenario file (`drive-emu scenario FILE`): the parser never panics; an
//! error is one clean line (file content quoted: no raw control character, bounded length)
//! whose line number, when it has one, is within the file.
//!
//! Run: cargo fuzz run --sanitizer none --debug-assertions scenario (stable; ./test-all.sh
//! runs every target for a bounded time). Seed corpus: `scenarios/*.toml`.
#![no_main]

use drive_emu::scenario;
use drive_protocol_fuzz::{assert_clean_message, lines};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    // The loader refuses text that is not UTF-8 before parsing (infile.rs).
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Err(e) = scenario::parse(text, Path::new("fuzz.toml")) {
        let msg = e.to_string();
        assert_clean_message("scenario", &msg);
        assert!(
            e.line <= lines(text),
            "line {} of a {}-line file: {msg}",
            e.line,
            lines(text)
        );
    }
});
