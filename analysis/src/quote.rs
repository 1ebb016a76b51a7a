//! File content in messages: one function renders any text a file (or a bus peer, or a
//! request) supplied before it goes into an error message, so that an escape sequence, a
//! lone carriage return or a megabyte-long line cannot reach the terminal or hide the
//! message's position (`line N`).
//!
//! The rendering itself is the protocol crate's ([`drive_protocol::quote`]), so that the EDS
//! reader's messages and the emulator's are rendered by one function:
//!
//! - [`text`]: control characters (C0, DEL, C1) and the Unicode bidirectional controls escaped
//!   as `\n`, `\r`, `\t`, `\u{1b}`; at most [`MAX_CHARS`] characters, then `...(N more
//!   characters)`;
//! - [`bytes`]: the same for bytes that may not be UTF-8 (each invalid byte as `\xNN`);
//! - [`number`]: a float as people read it: `1e300`, not 300 digits; `NaN` and `inf` named.

pub use drive_protocol::quote::{bytes, number, text, text_max, MAX_CHARS};

/// Longest parser message in [`toml_error`], characters.
pub const MAX_MESSAGE_CHARS: usize = 400;

/// A TOML reader's error on `src` as one line: `line N, column C: message: `the line``. The
/// toml crate's own text quotes the offending line raw over several lines; here the
/// message and the line are rendered by [`text`] (control characters escaped, capped).
pub fn toml_error(e: &toml::de::Error, src: &str) -> String {
    let msg = e.message().trim();
    let msg = text_max(msg, MAX_MESSAGE_CHARS);
    match e.span() {
        Some(span) => {
            let (line, col) = line_col(src.as_bytes(), span.start);
            let start = src[..span.start.min(src.len())]
                .rfind('\n')
                .map_or(0, |i| i + 1);
            let end = src[start..].find('\n').map_or(src.len(), |i| start + i);
            let at = &src[start..end];
            if at.trim().is_empty() {
                format!("line {line}, column {col}: {msg}")
            } else {
                format!("line {line}, column {col}: {msg}: `{}`", text(at))
            }
        }
        None => msg,
    }
}

/// (line, column) of byte `offset` in `b`, both from 1; the column counts bytes.
pub fn line_col(b: &[u8], offset: usize) -> (usize, usize) {
    let before = &b[..offset.min(b.len())];
    let line = before.iter().filter(|&&c| c == b'\n').count() + 1;
    let col = before.iter().rev().take_while(|&&c| c != b'\n').count() + 1;
    (line, col)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_count_lines_and_bytes_from_one() {
        assert_eq!(line_col(b"ab\ncd\xff", 5), (2, 3));
        assert_eq!(line_col(b"\xff", 0), (1, 1));
    }
}
