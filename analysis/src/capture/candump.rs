//! The log reader: one line of `candump -L` or `candump -ta` (and can-utils `log2long`) into a
//! frame with its timestamp; remote, error, extended-ID and CAN FD frames are recognised and
//! told apart; any other malformed line is an error with its reason.

use drive_protocol::CanFrame;
// ------------------------------------------------------------------------------------------
// Line parser

/// What a log line holds, besides a standard data frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameKind {
    /// A standard-ID (11-bit) data frame: the CANopen traffic we decode.
    Data(CanFrame),
    /// A remote (RTR) frame.
    Remote { id: u32 },
    /// An error frame (CAN_ERR_FLAG set in the ID).
    Error,
    /// A 29-bit identifier.
    Extended { id: u32 },
    /// A CAN FD frame.
    Fd { id: u32 },
}

/// One frame of the log, timestamp in microseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LogFrame {
    pub t_us: i64,
    pub kind: FrameKind,
}

/// True when the first line that is neither empty nor a `#` comment starts with `(`: a candump
/// log with timestamps rather than a CSV trace.
pub fn looks_like_candump(text: &str) -> bool {
    text.lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .is_some_and(|l| l.starts_with('('))
}

/// Parse one line of `candump -L` or `candump -ta` output. `Ok(None)` for an empty line or a
/// `#` comment; the error is the reason, without file and line.
pub fn parse_line(line: &str) -> Result<Option<LogFrame>, String> {
    let s = line.trim();
    if s.is_empty() || s.starts_with('#') {
        return Ok(None);
    }
    let rest = s
        .strip_prefix('(')
        .ok_or("expected `(timestamp)` at the start of the line (candump -L or -ta)")?;
    let (ts, rest) = rest
        .split_once(')')
        .ok_or("timestamp without closing `)`")?;
    let t_us = parse_timestamp(ts)?;
    let mut tokens = rest.split_whitespace();
    let _iface = tokens
        .next()
        .ok_or("no interface name after the timestamp")?;
    let frame = tokens
        .next()
        .ok_or("no CAN frame after the interface name")?;
    let kind = match frame.split_once('#') {
        Some((id, data)) => {
            // candump -L; newer can-utils may append a direction flag.
            match (tokens.next(), tokens.next()) {
                (None, _) | (Some("T" | "R"), None) => {}
                (Some(t), _) => return Err(format!("unexpected `{t}` after the frame")),
            }
            parse_compact(id, data)?
        }
        None => parse_columns(frame, &mut tokens)?,
    };
    Ok(Some(LogFrame { t_us, kind }))
}

/// `1700000000.123456` -> microseconds. More than 6 decimals are truncated.
fn parse_timestamp(ts: &str) -> Result<i64, String> {
    let bad = || format!("bad timestamp `({ts})`: seconds.microseconds expected (candump -t a)");
    let (secs, frac) = ts.split_once('.').ok_or_else(bad)?;
    let digits = |s: &str, max: usize| {
        !s.is_empty() && s.len() <= max && s.bytes().all(|b| b.is_ascii_digit())
    };
    if !digits(secs, 12) || !digits(frac, 9) {
        return Err(bad());
    }
    let secs: i64 = secs.parse().map_err(|_| bad())?;
    let mut us: i64 = 0;
    for k in 0..6 {
        let d = frac.as_bytes().get(k).map_or(0, |b| i64::from(b - b'0'));
        us = us * 10 + d;
    }
    secs.checked_mul(1_000_000)
        .and_then(|s| s.checked_add(us))
        .ok_or_else(bad)
}

fn is_hex(s: &str) -> bool {
    !s.is_empty() && s.bytes().all(|b| b.is_ascii_hexdigit())
}

enum IdKind {
    Standard(u32),
    Extended(u32),
    Error,
}

/// 3 hex digits: standard; 8: extended, or an error frame when CAN_ERR_FLAG is set.
fn parse_id(s: &str) -> Result<IdKind, String> {
    let bad = || format!("bad CAN ID `{s}`: 3 hex digits (11-bit) or 8 (29-bit) expected");
    if !is_hex(s) {
        return Err(bad());
    }
    let v = u32::from_str_radix(s, 16).map_err(|_| bad())?;
    match s.len() {
        3 if v <= 0x7FF => Ok(IdKind::Standard(v)),
        3 => Err(format!("CAN ID `{s}` above 0x7FF")),
        8 if v & 0x2000_0000 != 0 => Ok(IdKind::Error),
        8 if v <= 0x1FFF_FFFF => Ok(IdKind::Extended(v)),
        _ => Err(bad()),
    }
}

fn hex_byte(s: &str) -> Result<u8, String> {
    if s.len() != 2 || !is_hex(s) {
        return Err(format!("bad data byte `{s}`: two hex digits expected"));
    }
    u8::from_str_radix(s, 16).map_err(|_| format!("bad data byte `{s}`"))
}

/// `ID#DATA` (candump -L).
fn parse_compact(id: &str, data: &str) -> Result<FrameKind, String> {
    let id = parse_id(id)?;
    if let Some(fd) = data.strip_prefix('#') {
        // CAN FD: a flags nibble, then up to 64 bytes.
        let body = fd.get(1..).unwrap_or("");
        let flags_ok = fd.get(..1).is_some_and(is_hex);
        if !flags_ok
            || !body.len().is_multiple_of(2)
            || body.len() > 128
            || !body.bytes().all(|b| b.is_ascii_hexdigit())
        {
            return Err(format!("bad CAN FD frame data `##{fd}`"));
        }
        return Ok(match id {
            IdKind::Standard(i) | IdKind::Extended(i) => FrameKind::Fd { id: i },
            IdKind::Error => FrameKind::Error,
        });
    }
    if let Some(r) = data.strip_prefix(['R', 'r']) {
        if !(r.is_empty() || (r.len() == 1 && r.bytes().all(|b| (b'0'..=b'8').contains(&b)))) {
            return Err(format!(
                "bad remote frame `#{data}`: `R` or `R0`..`R8` expected"
            ));
        }
        return Ok(match id {
            IdKind::Standard(i) | IdKind::Extended(i) => FrameKind::Remote { id: i },
            IdKind::Error => FrameKind::Error,
        });
    }
    // Optional `_X`: the raw DLC 9..F of an 8-byte classic frame (len8_dlc).
    let (hex, raw_dlc) = match data.split_once('_') {
        Some((h, d)) => (h, Some(d)),
        None => (data, None),
    };
    let hex: String = hex.chars().filter(|&c| c != '.').collect();
    if !hex.len().is_multiple_of(2) {
        return Err(format!("odd number of hex digits in data `{data}`"));
    }
    if hex.len() > 16 {
        return Err(format!(
            "{} data bytes in `{data}`: a classic CAN frame has at most 8",
            hex.len() / 2
        ));
    }
    let mut bytes = [0u8; 8];
    for (k, b) in bytes.iter_mut().enumerate().take(hex.len() / 2) {
        *b = hex_byte(hex.get(2 * k..2 * k + 2).unwrap_or(""))?;
    }
    let len = hex.len() / 2;
    if let Some(d) = raw_dlc {
        let ok = d.len() == 1
            && u8::from_str_radix(d, 16).is_ok_and(|v| (9..=15).contains(&v))
            && len == 8;
        if !ok {
            return Err(format!("bad raw DLC suffix `_{d}` in `{data}`"));
        }
    }
    let payload = bytes.get(..len).unwrap_or(&[]);
    Ok(match id {
        IdKind::Standard(i) => FrameKind::Data(CanFrame::new(i, payload)),
        IdKind::Extended(i) => FrameKind::Extended { id: i },
        IdKind::Error => FrameKind::Error,
    })
}

/// `ID [n] B0 B1 ...` (candump default columns, with -ta).
fn parse_columns<'a>(
    id: &str,
    tokens: &mut impl Iterator<Item = &'a str>,
) -> Result<FrameKind, String> {
    let id = parse_id(id)?;
    let dlc_tok = tokens.next().ok_or("no `[len]` after the CAN ID")?;
    let dlc_str = dlc_tok
        .strip_prefix('[')
        .and_then(|d| d.strip_suffix(']'))
        .filter(|d| !d.is_empty() && d.len() <= 2 && d.bytes().all(|b| b.is_ascii_digit()))
        .ok_or_else(|| format!("bad length `{dlc_tok}`: `[0]`..`[8]` expected"))?;
    let dlc: usize = dlc_str
        .parse()
        .map_err(|_| format!("bad length `{dlc_tok}`"))?;
    if dlc_str.len() == 2 {
        // candump prints a CAN FD frame's length with two digits (`[02]`, `[64]`).
        if dlc > 64 {
            return Err(format!("CAN FD length {dlc} > 64"));
        }
        for _ in 0..dlc {
            hex_byte(
                tokens
                    .next()
                    .ok_or("CAN FD frame shorter than its length")?,
            )?;
        }
        return Ok(match id {
            IdKind::Standard(i) | IdKind::Extended(i) => FrameKind::Fd { id: i },
            IdKind::Error => FrameKind::Error,
        });
    }
    if dlc > 8 {
        return Err(format!(
            "length {dlc} > 8: a classic CAN frame has at most 8 bytes"
        ));
    }
    let mut bytes = [0u8; 8];
    let mut rest: Vec<&str> = Vec::new();
    let mut n = 0;
    for t in tokens.by_ref() {
        if n < dlc && t != "remote" {
            bytes[n] = hex_byte(t)?;
            n += 1;
        } else {
            rest.push(t);
            break;
        }
    }
    let remote = rest.first() == Some(&"remote");
    if remote {
        if tokens.next() != Some("request") {
            return Err("`remote` without `request`".into());
        }
    } else if n < dlc {
        return Err(format!("{n} data bytes, length says {dlc}"));
    }
    // What may follow: the -a ASCII column, or ERRORFRAME.
    let tail = if remote {
        tokens.next()
    } else {
        rest.first().copied()
    };
    let error_word = tail == Some("ERRORFRAME");
    if let Some(t) = tail {
        if !(t.starts_with('\'') || error_word) {
            return Err(format!("unexpected `{t}` after {dlc} data bytes"));
        }
    }
    Ok(match id {
        IdKind::Error => FrameKind::Error,
        IdKind::Standard(i) | IdKind::Extended(i) if remote => FrameKind::Remote { id: i },
        IdKind::Standard(_) if error_word => FrameKind::Error,
        IdKind::Standard(i) => FrameKind::Data(CanFrame::new(i, bytes.get(..dlc).unwrap_or(&[]))),
        IdKind::Extended(i) => FrameKind::Extended { id: i },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(line: &str) -> CanFrame {
        match parse_line(line).unwrap().unwrap().kind {
            FrameKind::Data(f) => f,
            k => panic!("{k:?}"),
        }
    }

    #[test]
    fn reads_the_log_format() {
        let f = parse_line("(1700000000.123456) vcan0 185#0102030405060708")
            .unwrap()
            .unwrap();
        assert_eq!(f.t_us, 1_700_000_000_123_456);
        assert_eq!(
            f.kind,
            FrameKind::Data(CanFrame::new(0x185, &[1, 2, 3, 4, 5, 6, 7, 8]))
        );
        assert_eq!(data("(0.5) can0 080#").len, 0);
        assert_eq!(
            parse_line("(0.5) can0 080#").unwrap().unwrap().t_us,
            500_000
        );
        assert_eq!(data("(1.000001) can0 7ff#aB").payload(), &[0xAB]);
        assert_eq!(data("(1.0) can0 123#11.22 T").payload(), &[0x11, 0x22]);
        assert_eq!(
            data("(1.0) can0 123#1122334455667788_C").payload(),
            &[0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88]
        );
    }

    #[test]
    fn reads_the_column_format() {
        let f = parse_line(" (1700000000.123456)  vcan0  185   [8]  01 02 03 04 05 06 07 08")
            .unwrap()
            .unwrap();
        assert_eq!(f.t_us, 1_700_000_000_123_456);
        assert_eq!(
            f.kind,
            FrameKind::Data(CanFrame::new(0x185, &[1, 2, 3, 4, 5, 6, 7, 8]))
        );
        assert_eq!(data(" (1.0)  vcan0  080   [0] ").len, 0);
        assert_eq!(
            data(" (1.0)  vcan0  285   [2]  0A FF   '..'").payload(),
            &[0x0A, 0xFF]
        );
    }

    #[test]
    fn reads_what_can_utils_log2long_prints() {
        // `log2long` (can-utils) output for a -L log: the same columns as `candump -ta`.
        let kinds: Vec<FrameKind> = [
            "(1700000000.123456)  vcan0       185   [8]  01 02 03 04 05 06 07 08   '........'",
            "(1700000000.123460)  vcan0       080   [0]                            ''",
            "(1700000000.123470)  vcan0       705   [0]  remote request",
            "(1700000000.123480)  vcan0  12345678   [2]  01 02                     '..'",
            "(1700000000.123490)  vcan0  20000004   [8]  00 04 00 00 00 00 00 00   ERRORFRAME",
            "(1700000000.123500)  vcan0       123  [02]  AA BB                     '..'",
        ]
        .iter()
        .map(|l| parse_line(l).unwrap().unwrap().kind)
        .collect();
        assert_eq!(
            kinds,
            [
                FrameKind::Data(CanFrame::new(0x185, &[1, 2, 3, 4, 5, 6, 7, 8])),
                FrameKind::Data(CanFrame::new(0x080, &[])),
                FrameKind::Remote { id: 0x705 },
                FrameKind::Extended { id: 0x1234_5678 },
                FrameKind::Error,
                FrameKind::Fd { id: 0x123 },
            ]
        );
    }

    #[test]
    fn skips_remote_error_extended_and_fd_frames() {
        let kind = |l: &str| parse_line(l).unwrap().unwrap().kind;
        assert_eq!(kind("(1.0) can0 705#R"), FrameKind::Remote { id: 0x705 });
        assert_eq!(kind("(1.0) can0 705#R1"), FrameKind::Remote { id: 0x705 });
        assert_eq!(
            kind(" (1.0)  can0  705   [1]  remote request"),
            FrameKind::Remote { id: 0x705 }
        );
        assert_eq!(
            kind("(1.0) can0 20000004#0004000000000000"),
            FrameKind::Error
        );
        assert_eq!(
            kind(" (1.0)  can0  20000004   [8]  00 04 00 00 00 00 00 00   ERRORFRAME"),
            FrameKind::Error
        );
        assert_eq!(
            kind("(1.0) can0 12345678#00"),
            FrameKind::Extended { id: 0x1234_5678 }
        );
        assert_eq!(
            kind(" (1.0)  can0  12345678   [1]  00"),
            FrameKind::Extended { id: 0x1234_5678 }
        );
        assert_eq!(kind("(1.0) can0 123##1AABB"), FrameKind::Fd { id: 0x123 });
        assert_eq!(parse_line("   ").unwrap(), None);
        assert_eq!(parse_line("# comment").unwrap(), None);
    }

    #[test]
    fn rejects_malformed_lines_with_a_reason() {
        let err = |l: &str| parse_line(l).unwrap_err();
        assert!(
            err("(1.0) can0 185#0G").contains("0G"),
            "{}",
            err("(1.0) can0 185#0G")
        );
        assert!(err("(1.0) can0 185#012").contains("odd"));
        assert!(err("(1.0) can0 185#010203040506070809").contains("at most 8"));
        assert!(err(" (1.0)  can0  185   [9]  01 02 03 04 05 06 07 08 09").contains("> 8"));
        assert!(err(" (1.0)  can0  185  [65]  01").contains("> 64"));
        assert!(err(" (1.0)  can0  185  [12]  01 02").contains("shorter"));
        assert!(err(" (1.0)  can0  185   [2]  01 XY").contains("XY"));
        assert!(err(" (1.0)  can0  185   [3]  01 02").contains("length says 3"));
        assert!(err(" (1.0)  can0  185   [1]  01 02").contains("unexpected `02`"));
        assert!(err("(1.0) can0 1G5#00").contains("CAN ID"));
        assert!(err("(1.0) can0 85#00").contains("CAN ID"));
        assert!(err("(1.0) can0 885#00").contains("above 0x7FF"));
        assert!(err("(1.0) can0 185#R9").contains("remote"));
        assert!(err("(x.0) can0 185#00").contains("timestamp"));
        assert!(err("(2023-11-14 22:13:20.123456) can0 185#00").contains("timestamp"));
        assert!(err("(1.0 can0 185#00").contains("`)`"));
        assert!(err("185#00").contains("timestamp"));
        assert!(err("(1.0) can0").contains("no CAN frame"));
        assert!(err("(1.0) can0 185#00 extra").contains("extra"));
        // Never panics on odd input.
        for l in [
            "(",
            "()",
            "(.)",
            "(1.)",
            "(1.0) c 1#",
            "(1.0) c ###",
            "(1.0) c 123#_",
            "(1.0) c 123 [",
            "(1.0) c 123 []",
            "(1.0) c 123 [1] é",
        ] {
            assert!(parse_line(l).is_err(), "{l}");
        }
    }

    #[test]
    fn sniffs_the_format_by_content() {
        assert!(looks_like_candump("\n# x\n (1.0)  can0  080   [0]\n"));
        assert!(!looks_like_candump("t_s,velocity_uu_s\n0,1\n"));
        assert!(!looks_like_candump(""));
    }
}
