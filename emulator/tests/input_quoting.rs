//! File content in error messages is rendered, never echoed raw (issue 32, finding 8): a
//! machine file, a profile, an LSS store file and a scenario with an escape sequence, a lone
//! carriage return, a bidirectional control or a megabyte-long line in the wrong place each
//! give one readable line that says where (`line N`, or `FILE:N:` for the scenario and the
//! profile), with the content's control characters escaped and its length capped.

use drive_emu::cli::lss_store;
use drive_emu::drive::machine;
use drive_emu::drive::quirk_profile::ProfileFile;
use drive_emu::scenario;
use std::path::Path;

/// Bad content, each at line 3 (after two lines every kind of file takes).
fn bad_third_lines() -> Vec<(&'static str, String)> {
    vec![
        (
            "an escape sequence in a key",
            "bad\u{1b}[2J\u{1b}[31m = 1\n".to_string(),
        ),
        (
            "a lone carriage return",
            "x = 1\rfake = \"line 1\"\n".to_string(),
        ),
        (
            "a bidi override in a value",
            "x = \u{202e}1 esrever\n".to_string(),
        ),
        ("a megabyte line", format!("x = {}q\n", "9".repeat(1 << 20))),
    ]
}

fn assert_readable(what: &str, msg: &str) {
    let raw = msg.chars().find(|&c| {
        c.is_control()
            || matches!(c, '\u{200E}' | '\u{200F}' | '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}')
    });
    assert!(raw.is_none(), "{what}: raw {raw:?} in {msg:?}");
    assert!(
        msg.len() < 1500,
        "{what}: {} bytes: {}...",
        msg.len(),
        &msg[..200]
    );
}

#[test]
fn machine_and_lss_store_files_say_the_line_and_quote_the_content() {
    for (what, third) in bad_third_lines() {
        let text = format!("# a file\n\n{third}");
        let e = machine::parse(&text, "m.toml").unwrap_err();
        let msg = format!("{e:#}");
        assert_readable(what, &msg);
        assert!(msg.starts_with("m.toml: line 3, column "), "{what}: {msg}");

        let text = format!("node_id = 5\nbit_timing_index = 4\n{third}");
        let e = lss_store::parse(&text, "s.toml").unwrap_err();
        let msg = format!("{e:#}");
        assert_readable(what, &msg);
        assert!(msg.starts_with("s.toml: line 3, column "), "{what}: {msg}");
    }
}

#[test]
fn profiles_and_scenarios_say_the_line_and_quote_the_content() {
    for (what, third) in bad_third_lines() {
        let text = format!("# a profile\n\n{third}");
        let e = ProfileFile::parse(&text, "p.toml", "p", None).unwrap_err();
        let msg = e.to_string();
        assert_readable(what, &msg);
        assert_eq!(e.line, Some(3), "{what}: {msg}");
        assert!(msg.starts_with("p.toml:3: "), "{what}: {msg}");

        let text = format!("# a scenario\n\n{third}");
        let e = scenario::parse(&text, Path::new("s.toml")).unwrap_err();
        let msg = e.to_string();
        assert_readable(what, &msg);
        assert_eq!(e.line, 3, "{what}: {msg}");
        assert!(msg.starts_with("s.toml:3:"), "{what}: {msg}");
    }
}

#[test]
fn an_unknown_key_with_control_characters_is_named_escaped() {
    // serde's message repeats the key (a TOML escape makes it an ESC): it must arrive escaped.
    let e = lss_store::parse(
        "node_id = 5\nbit_timing_index = 4\n\"k\\u001b]0;x\\u0007\" = 1\n",
        "s",
    )
    .unwrap_err();
    let msg = format!("{e:#}");
    assert_readable("unknown key", &msg);
    assert!(msg.contains("\\u{1b}"), "{msg}");
    let e = ProfileFile::parse("\"k\\u001b[1m\" = 1\n", "p.toml", "p", None).unwrap_err();
    let msg = e.to_string();
    assert_readable("unknown profile key", &msg);
    assert!(msg.contains("\\u{1b}"), "{msg}");
}
