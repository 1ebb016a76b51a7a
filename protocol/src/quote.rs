//! File content in messages: one function renders any text a file (or a bus peer, or a
//! request) supplied before it goes into an error message, so that an escape sequence, a
//! lone carriage return or a megabyte-long line cannot reach the terminal or hide the
//! message's position (`line N`). The EDS reader's errors and warnings
//! ([`crate::od::eds`]) are rendered through it, and so is every message of the
//! emulator about its input files (its `quote` module re-uses these functions).
//!
//! - [`text`]: control characters (C0, DEL, C1) and the Unicode bidirectional controls escaped
//!   as `\n`, `\r`, `\t`, `\u{1b}`; at most [`MAX_CHARS`] characters, then `...(N more
//!   characters)`;
//! - [`text_max`]: the same with another cap (a parser's own message);
//! - [`bytes`]: the same for bytes that may not be UTF-8 (each invalid byte as `\xNN`);
//! - [`number`]: a float as people read it: `1e300`, not 300 digits; `NaN` and `inf` named.

use std::fmt::Write;

/// Longest quotation, characters (a message stays one readable line).
pub const MAX_CHARS: usize = 80;

/// Whether `c` must not reach a terminal as is (what [`text`] escapes).
pub fn escaped(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{200E}' | '\u{200F}' | '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}')
}

fn push_char(out: &mut String, c: char) {
    match c {
        '\n' => out.push_str("\\n"),
        '\r' => out.push_str("\\r"),
        '\t' => out.push_str("\\t"),
        c if escaped(c) => {
            let _ = write!(out, "\\u{{{:x}}}", c as u32);
        }
        c => out.push(c),
    }
}

/// `s` for a message: control characters escaped, at most [`MAX_CHARS`] characters.
pub fn text(s: &str) -> String {
    text_max(s, MAX_CHARS)
}

/// Bytes for a message: valid UTF-8 as [`text`], every invalid byte as `\xNN`; at most
/// [`MAX_CHARS`] characters.
pub fn bytes(b: &[u8]) -> String {
    let mut out = String::new();
    let mut shown = 0usize;
    let mut used = 0usize;
    'chunks: for chunk in b.utf8_chunks() {
        for c in chunk.valid().chars() {
            if shown == MAX_CHARS {
                break 'chunks;
            }
            push_char(&mut out, c);
            shown += 1;
            used += c.len_utf8();
        }
        for &x in chunk.invalid() {
            if shown == MAX_CHARS {
                break 'chunks;
            }
            let _ = write!(out, "\\x{x:02X}");
            shown += 1;
            used += 1;
        }
    }
    if used < b.len() {
        let _ = write!(out, "...({} more bytes)", b.len() - used);
    }
    out
}

/// A number for a message: up to 6 significant digits, in exponent form outside
/// 1e-4..1e6 (`1e300`, `3.4e38`, `2.5e-9`), `NaN`, `inf`, `-inf`.
pub fn number(x: f64) -> String {
    if x.is_nan() {
        return "NaN".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "inf".into() } else { "-inf".into() };
    }
    let a = x.abs();
    if a == 0.0 || (1e-4..1e6).contains(&a) {
        // Shortest form that round-trips, unless it is long: then 6 significant digits.
        let s = format!("{x}");
        if s.len() <= 12 {
            return s;
        }
        let digits = (5 - a.log10().floor() as i32).clamp(0, 10) as usize;
        let s = format!("{x:.digits$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
        return s;
    }
    let s = format!("{x:.5e}");
    // 1.00000e300 -> 1e300; 3.40282e38 stays.
    match s.split_once('e') {
        Some((m, e)) => {
            let m = if m.contains('.') {
                m.trim_end_matches('0').trim_end_matches('.')
            } else {
                m
            };
            format!("{m}e{e}")
        }
        None => s,
    }
}

/// `s` for a message as [`text`], at most `max` characters (a parser's own message, which
/// may repeat file content, gets more room than a quotation).
pub fn text_max(s: &str, max: usize) -> String {
    let mut out = String::with_capacity(s.len().min(4 * max));
    let mut chars = s.chars();
    for c in chars.by_ref().take(max) {
        push_char(&mut out, c);
    }
    let more = chars.count();
    if more > 0 {
        let _ = write!(out, "...({more} more characters)");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_characters_are_escaped_and_nothing_raw_remains() {
        let s = text("a\u{1b}[2Jb\rc\nd\te\u{7f}f\u{9b}g\u{202e}h");
        assert_eq!(
            s, "a\\u{1b}[2Jb\\rc\\nd\\te\\u{7f}f\\u{9b}g\\u{202e}h",
            "{s}"
        );
        assert!(!s.chars().any(escaped));
        assert_eq!(text("plain = 1"), "plain = 1");
        assert_eq!(text("motor ü"), "motor ü");
    }

    #[test]
    fn long_text_is_capped_and_says_how_much_is_left() {
        let s = text(&"x".repeat(1000));
        assert_eq!(s, format!("{}...(920 more characters)", "x".repeat(80)));
        let b = bytes(&[b'y'; 500]);
        assert_eq!(b, format!("{}...(420 more bytes)", "y".repeat(80)));
    }

    #[test]
    fn invalid_bytes_are_shown_as_hex() {
        assert_eq!(bytes(b"ab\xff\xfecd\x1b"), "ab\\xFF\\xFEcd\\u{1b}");
        assert_eq!(bytes("é".as_bytes()), "é");
        assert_eq!(bytes(b"\xe2\x82"), "\\xE2\\x82");
        assert_eq!(bytes(b""), "");
    }

    #[test]
    fn numbers_are_compact() {
        assert_eq!(number(1e300), "1e300");
        assert_eq!(number(3.4e38), "3.4e38");
        assert_eq!(number(f32::MAX as f64), "3.40282e38");
        assert_eq!(number(2.5e-9), "2.5e-9");
        assert_eq!(number(30.0), "30");
        assert_eq!(number(0.1), "0.1");
        assert_eq!(number(1.0 / 3.0), "0.333333");
        assert_eq!(number(123456.789), "123456.789");
        assert_eq!(number(98765.43210987), "98765.4");
        assert_eq!(number(f64::NAN), "NaN");
        assert_eq!(number(f64::NEG_INFINITY), "-inf");
        assert_eq!(number(0.0), "0");
        assert!(number(-1e300).len() < 10);
    }
}
