//! What every fuzz target checks of a message the emulator prints about input it was given:
//! one line, no control character or bidirectional control from the input (a terminal
//! shows the message as written), and bounded in length (a megabyte line is not echoed).

/// Longest message the emulator prints about a refused input, characters.
pub const MAX_MESSAGE_CHARS: usize = 4000;

/// Whether `c` must not reach a terminal as is (`drive_emu::quote` escapes these).
pub fn raw_control(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{200E}' | '\u{200F}' | '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}')
}

/// Panic unless `msg` is one clean, bounded line.
pub fn assert_clean_message(what: &str, msg: &str) {
    if let Some(c) = msg.chars().find(|&c| raw_control(c)) {
        panic!("{what}: raw {c:?} in the message: {msg:?}");
    }
    let n = msg.chars().count();
    assert!(
        n <= MAX_MESSAGE_CHARS,
        "{what}: message of {n} characters: {:?}...",
        msg.chars().take(200).collect::<String>()
    );
}

/// The `N` of a message that begins `{origin}: line N` (the position the emulator's TOML
/// readers give), if it begins so.
pub fn line_of_message(msg: &str, origin: &str) -> Option<usize> {
    let rest = msg.strip_prefix(origin)?.strip_prefix(": line ")?;
    let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
    digits.parse().ok()
}

/// Number of lines of `text` (a position may point just past a final newline).
pub fn lines(text: &str) -> usize {
    text.split('\n').count().max(1)
}

/// Panic unless a position `{origin}: line N` that `msg` begins with is within `text`.
pub fn assert_line_within(what: &str, msg: &str, origin: &str, text: &str) {
    if let Some(n) = line_of_message(msg, origin) {
        let total = lines(text);
        assert!(
            n >= 1 && n <= total,
            "{what}: line {n} of a {total}-line input: {msg}"
        );
    }
}
