//! Any bytes as an EDS/DCF file: the parser must never panic; an error points at a line of the
//! file; a file it accepts resolves every value (at node ID 5) to its type's size.
//!
//! Each input is cut to its first [`MAX_INPUT_BYTES`] (32 KiB) before it is parsed, so that an
//! input costs a bounded time (10^6 inputs in minutes): the vendor seeds (up to 145 KiB) are
//! fuzzed as their first 32 KiB, the checks made on the text that is parsed.
//!
//! Run (nightly): cargo +nightly fuzz run eds -- -max_total_time=600
//! Seed corpus: the vendor files, `mkdir -p fuzz/corpus/eds && cp tests/eds/vendors/* fuzz/corpus/eds/`
//! Compile check (stable): cargo check --manifest-path fuzz/Cargo.toml --bins
#![no_main]

use drive_protocol::od::eds_parse::{decode_text, parse};
use libfuzzer_sys::fuzz_target;

/// Most bytes of an input that are parsed.
const MAX_INPUT_BYTES: usize = 32 << 10;

fuzz_target!(|data: &[u8]| {
    let data = &data[..data.len().min(MAX_INPUT_BYTES)];
    let text = decode_text(data);
    let lines = text.split('\n').count().max(1);
    match parse(&text) {
        Err(e) => assert!(
            e.line >= 1 && e.line <= lines,
            "line {} of {lines}: {e}",
            e.line
        ),
        Ok(f) => {
            for w in &f.warnings {
                assert!(
                    w.line >= 1 && w.line <= lines,
                    "warning line {}: {w}",
                    w.line
                );
            }
            for o in &f.objects {
                for s in &o.subs {
                    for v in [&s.default, &s.parameter_value, &s.low, &s.high]
                        .into_iter()
                        .flatten()
                    {
                        let b = v
                            .resolve(s.data_type, Some(5))
                            .unwrap_or_else(|e| panic!("0x{:04X}sub{:X}: {e}", o.index, s.sub));
                        assert!(s.data_type.variable() || b.len() == s.data_type.size());
                    }
                }
            }
        }
    }
});
