//! Any bytes as an LSS store file (`run --lss-store FILE`): never a panic; an error is one
//! clean line whose `line N`, when it gives one, is in the file; a file it accepts holds a
//! node ID in 1..=127 (or none) and a CiA 301 bit timing.
//!
//! Run: cargo fuzz run --sanitizer none --debug-assertions lss_store.
#![no_main]

use drive_emu::cli::lss_store;
use drive_protocol::wire::lss::bit_rate_kbit_per_s;
use drive_protocol_fuzz::{assert_clean_message, assert_line_within};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match lss_store::parse(text, "fuzz.toml") {
        Err(e) => {
            let msg = format!("{e:#}");
            assert_clean_message("lss store", &msg);
            assert_line_within("lss store", &msg, "fuzz.toml", text);
        }
        Ok(s) => {
            assert!(s.node_id.is_none_or(|n| (1..=127).contains(&n)), "{s:?}");
            assert!(bit_rate_kbit_per_s(s.bit_timing_index).is_some(), "{s:?}");
        }
    }
});
