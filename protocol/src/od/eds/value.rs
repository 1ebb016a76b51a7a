//! EDS values: numbers, `$NODEID` expressions, octet strings, and [`ValueExpr`] turned into wire bytes.

use super::{DataType, MAX_VALUE_BYTES};

/// A value as the file writes it, before it is turned into wire bytes for a type and a node
/// ID by [`ValueExpr::resolve`].
#[derive(Clone, Debug, PartialEq)]
pub enum ValueExpr {
    /// A decimal or octal integer, or a negative hex one: the number it says.
    Integer(i128),
    /// A hexadecimal integer without sign (`0x1F`): the number for an integer type (for a
    /// signed type, a pattern above the type's maximum is its two's complement), the IEEE 754
    /// bits for REAL32 and REAL64 (Lely's notation).
    Hex(u128),
    /// `$NODEID` plus this offset (negative for `$NODEID-1`).
    NodeIdPlus(i128),
    /// A decimal with a point or an exponent (`30.0`, `1e-3`): REAL32 / REAL64 (python
    /// canopen's notation).
    Decimal(f64),
    /// The text of a VISIBLE_STRING or UNICODE_STRING.
    Text(String),
    /// The bytes of an OCTET_STRING or DOMAIN, written as hex digit pairs.
    Octets(Vec<u8>),
}

impl ValueExpr {
    /// Read the text of a value of type `dtype` (`Ok(None)` for an empty value). The error
    /// says why the text is not a value of that type; range is checked by
    /// [`ValueExpr::resolve`].
    pub fn parse(text: &str, dtype: DataType) -> Result<Option<ValueExpr>, String> {
        let t = text.trim();
        if t.is_empty() {
            return Ok(None);
        }
        if t.len() > MAX_VALUE_BYTES {
            return Err(format!(
                "value of {} bytes, more than the {MAX_VALUE_BYTES} allowed",
                t.len()
            ));
        }
        match dtype {
            DataType::VisibleString | DataType::UnicodeString => {
                Ok(Some(ValueExpr::Text(t.to_string())))
            }
            DataType::OctetString | DataType::Domain => match hex_prefixed_digits(t) {
                Some(digits) => Ok(Some(octets_of_prefixed(digits))),
                None => parse_octets(t).map(Some),
            },
            _ => parse_number(strip_hash_comment(t)).map(Some),
        }
    }

    /// What a reader of the file should hear about a value of type `dtype` written as `text`
    /// (already read as `self`), or `None`: an OCTET_STRING or DOMAIN written as a number with
    /// a `0x` prefix (SEVCON's DVT and Ingenia's tools write `0x0`, `0x0000`,
    /// `0x000400000000002c00002401`), and a VISIBLE_STRING that looks like one (read as its
    /// text, as CiA 306 and python canopen read it).
    pub(super) fn prefix_note(&self, text: &str, dtype: DataType) -> Option<String> {
        let t = text.trim();
        hex_prefixed_digits(t)?;
        match (self, dtype) {
            (ValueExpr::Octets(b), DataType::OctetString | DataType::Domain) => Some(format!(
                "{} value '{}' is written as a number with 0x: read as {} (its hex digits as \
                 pairs in the order written{}; python canopen 2.4.1 drops such a value, Lely's \
                 dcfchk does not check it); CiA 306 writes octet strings as hex digit pairs \
                 without 0x",
                dtype.name(),
                clip(t),
                bytes_text(b),
                if (t.len() - 2) % 2 == 1 {
                    ", an odd count with a 0 before the first digit as in a number"
                } else {
                    ""
                }
            )),
            (ValueExpr::Text(s), DataType::VisibleString) => Some(format!(
                "VISIBLE_STRING value '{}' looks like a number with 0x: read as the text of {} \
                 characters, as CiA 306 and python canopen read a string (the device serves \
                 those characters)",
                clip(t),
                s.chars().count()
            )),
            _ => None,
        }
    }

    /// Whether the value depends on the node ID (`$NODEID`).
    pub fn uses_node_id(&self) -> bool {
        matches!(self, ValueExpr::NodeIdPlus(_))
    }

    /// The wire bytes of this value as type `dtype` (little-endian; exactly `dtype.size()`
    /// bytes for the fixed-size types; the text's bytes for VISIBLE_STRING (UTF-8), UTF-16LE
    /// code units for UNICODE_STRING, the bytes for OCTET_STRING and DOMAIN), with `$NODEID`
    /// replaced by `node_id`. Errors: a value outside the type's range, `$NODEID` without a
    /// node ID, a value of the wrong kind for the type.
    pub fn resolve(&self, dtype: DataType, node_id: Option<u8>) -> Result<Vec<u8>, String> {
        match dtype {
            DataType::VisibleString => match self {
                ValueExpr::Text(s) => Ok(s.as_bytes().to_vec()),
                other => Err(format!("{} is not a VISIBLE_STRING value", other.kind())),
            },
            DataType::UnicodeString => match self {
                ValueExpr::Text(s) => Ok(s.encode_utf16().flat_map(|u| u.to_le_bytes()).collect()),
                other => Err(format!("{} is not a UNICODE_STRING value", other.kind())),
            },
            DataType::OctetString | DataType::Domain => match self {
                ValueExpr::Octets(b) => Ok(b.clone()),
                other => Err(format!("{} is not a {} value", other.kind(), dtype.name())),
            },
            DataType::Real32 => {
                let bits = match self {
                    ValueExpr::Hex(u) => u32::try_from(*u)
                        .map_err(|_| format!("0x{u:X} is more than the 32 bits of a REAL32"))?,
                    ValueExpr::Decimal(f) => real32_from_f64(*f)?,
                    ValueExpr::Integer(i) => real32_from_f64(*i as f64)?,
                    other => return Err(format!("{} is not a REAL32 value", other.kind())),
                };
                Ok(bits.to_le_bytes().to_vec())
            }
            DataType::Real64 => {
                let bits = match self {
                    ValueExpr::Hex(u) => u64::try_from(*u)
                        .map_err(|_| format!("0x{u:X} is more than the 64 bits of a REAL64"))?,
                    ValueExpr::Decimal(f) if f.is_finite() => f.to_bits(),
                    ValueExpr::Decimal(f) => return Err(format!("{f} is not a finite REAL64")),
                    ValueExpr::Integer(i) => (*i as f64).to_bits(),
                    other => return Err(format!("{} is not a REAL64 value", other.kind())),
                };
                Ok(bits.to_le_bytes().to_vec())
            }
            DataType::TimeOfDay | DataType::TimeDifference => {
                let v: i128 = match self {
                    ValueExpr::Integer(i) => *i,
                    ValueExpr::Hex(u) => i128::try_from(*u).unwrap_or(i128::MAX),
                    other => {
                        return Err(format!("{} is not a {} value", other.kind(), dtype.name()))
                    }
                };
                if !(0..(1i128 << 48)).contains(&v) {
                    return Err(format!("{v} is outside the 48 bits of a {}", dtype.name()));
                }
                Ok(v.to_le_bytes()[..6].to_vec())
            }
            _ => {
                // BOOLEAN and the integers
                let (lo, hi) = dtype.range().unwrap_or((0, 0));
                let v: i128 = match self {
                    ValueExpr::Integer(i) => *i,
                    ValueExpr::Hex(u) => {
                        let u = i128::try_from(*u).unwrap_or(i128::MAX);
                        let bits = (dtype.size() * 8) as u32;
                        if dtype.signed() && u > hi && u < (1i128 << bits) {
                            // two's complement pattern of the type's width
                            u - (1i128 << bits)
                        } else {
                            u
                        }
                    }
                    ValueExpr::NodeIdPlus(off) => match node_id {
                        Some(n) => *off + n as i128,
                        None => return Err("$NODEID in a value, but no node ID to put in".into()),
                    },
                    other => {
                        return Err(format!("{} is not a {} value", other.kind(), dtype.name()))
                    }
                };
                if v < lo || v > hi {
                    return Err(format!(
                        "{v} is outside the range of {} ({lo}..={hi})",
                        dtype.name()
                    ));
                }
                Ok(v.to_le_bytes()[..dtype.size()].to_vec())
            }
        }
    }

    pub(super) fn kind(&self) -> String {
        match self {
            ValueExpr::Integer(i) => format!("the integer {i}"),
            ValueExpr::Hex(u) => format!("0x{u:X}"),
            ValueExpr::NodeIdPlus(o) => format!("$NODEID{o:+}"),
            ValueExpr::Decimal(f) => format!("the decimal {f}"),
            ValueExpr::Text(_) => "a text".into(),
            ValueExpr::Octets(_) => "a byte string".into(),
        }
    }
}

pub(super) fn real32_from_f64(f: f64) -> Result<u32, String> {
    if !f.is_finite() || f.abs() > f32::MAX as f64 {
        return Err(format!("{f} is outside the range of REAL32"));
    }
    Ok((f as f32).to_bits())
}

/// Text from the bytes of a file: UTF-8 if the bytes are UTF-8, else Latin-1 (ISO 8859-1,
/// each byte the character of the same code), which every byte string is. EDS tools write
/// Latin-1 (Windows-1252 in practice) in names and comments; reading those as Latin-1 keeps
/// every byte and needs no guess.
pub fn decode_text(bytes: &[u8]) -> String {
    match std::str::from_utf8(bytes) {
        Ok(s) => s.to_string(),
        Err(_) => bytes.iter().map(|&b| b as char).collect(),
    }
}

// ---------------------------------------------------------------------------------------
// numbers

/// A `#` after whitespace ends a number (dcf-tools' inline comment), and so does a `;`
/// anywhere (a comment written without the space before it; the reader warns).
pub(super) fn strip_hash_comment(t: &str) -> &str {
    let b = t.as_bytes();
    for i in 1..b.len() {
        if (b[i] == b'#' && b[i - 1].is_ascii_whitespace()) || b[i] == b';' {
            return t[..i].trim_end();
        }
    }
    t
}

/// The hex digits after a `0x` / `0X` prefix, where there is at least one and nothing else.
fn hex_prefixed_digits(t: &str) -> Option<&str> {
    let d = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X"))?;
    (!d.is_empty() && d.bytes().all(|b| b.is_ascii_hexdigit())).then_some(d)
}

/// The bytes of an octet string written as a number with `0x`: its digits as pairs in the
/// order written (SEVCON's DCFs dump a domain upload so: `0x4681` is the bytes 46 81, the
/// fault code 0x4681 as the device sends it), an odd count read with a 0 before the first
/// digit, as a number would be (`0x0` is one byte 00).
fn octets_of_prefixed(digits: &str) -> ValueExpr {
    let d = digits.as_bytes();
    let mut out = Vec::with_capacity(d.len() / 2 + 1);
    let (first, rest) = if d.len() % 2 == 1 {
        (Some(d[0]), &d[1..])
    } else {
        (None, d)
    };
    let v = |c: u8| (c as char).to_digit(16).unwrap_or(0) as u8;
    if let Some(c) = first {
        out.push(v(c));
    }
    for p in rest.chunks_exact(2) {
        out.push(v(p[0]) << 4 | v(p[1]));
    }
    ValueExpr::Octets(out)
}

/// `the 2 bytes 00 00`, the first 8 bytes and `..` beyond.
fn bytes_text(b: &[u8]) -> String {
    let mut s = format!(
        "the {} byte{}",
        b.len(),
        if b.len() == 1 { "" } else { "s" }
    );
    for x in b.iter().take(8) {
        s.push_str(&format!(" {x:02x}"));
    }
    if b.len() > 8 {
        s.push_str(" ..");
    }
    s
}

pub(super) fn parse_octets(t: &str) -> Result<ValueExpr, String> {
    let mut out = Vec::with_capacity(t.len() / 2);
    let mut hi: Option<u8> = None;
    for c in t.chars() {
        if c.is_whitespace() {
            if hi.is_some() {
                return Err(format!(
                    "'{t}' is not hex digit pairs (an odd digit before a space)"
                ));
            }
            continue;
        }
        let d = c.to_digit(16).ok_or_else(|| {
            format!("'{t}' is not hex digit pairs ('{c}' is not a hex digit; no 0x prefix)")
        })? as u8;
        match hi.take() {
            None => hi = Some(d),
            Some(h) => out.push(h << 4 | d),
        }
    }
    if hi.is_some() {
        return Err(format!("'{t}' has an odd number of hex digits"));
    }
    Ok(ValueExpr::Octets(out))
}

/// An unsigned integer literal: `0x` hex, leading-0 octal, decimal. Returns the value and
/// whether it was hex (and whether octal, for the warning).
pub(super) fn parse_uint(t: &str) -> Result<(u128, Radix), String> {
    let (digits, radix) = if let Some(h) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        (h, Radix::Hex)
    } else if t.len() > 1 && t.starts_with('0') {
        (&t[1..], Radix::Octal)
    } else {
        (t, Radix::Decimal)
    };
    let base = match radix {
        Radix::Hex => 16,
        Radix::Octal => 8,
        Radix::Decimal => 10,
    };
    if digits.is_empty() {
        return Err(format!("'{t}' is not a number"));
    }
    let mut v: u128 = 0;
    for c in digits.chars() {
        let d = match c.to_digit(base) {
            Some(d) => d,
            // '08', '09': not octal; the decimal reading is the only one (python canopen and
            // Lely stop; the value_key warning says so)
            None if radix == Radix::Octal && digits.bytes().all(|b| b.is_ascii_digit()) => {
                return parse_uint(digits.trim_start_matches('0'))
                    .map(|(v, _)| (v, Radix::Decimal));
            }
            None => return Err(format!("'{t}' is not a number")),
        };
        v = v
            .checked_mul(base as u128)
            .and_then(|v| v.checked_add(d as u128))
            .ok_or_else(|| format!("'{t}' is too large a number"))?;
    }
    Ok((v, radix))
}

#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Radix {
    Decimal,
    Hex,
    Octal,
}

pub(super) fn is_decimal_float(t: &str) -> bool {
    let body = t.strip_prefix(['-', '+']).unwrap_or(t);
    if body.starts_with("0x") || body.starts_with("0X") {
        return false;
    }
    let has_mark = body.contains(['.', 'e', 'E']);
    has_mark
        && body
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_digit() || c == '.')
        && body
            .chars()
            .all(|c| c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '-' | '+'))
}

/// A number or a `$NODEID` expression.
pub(super) fn parse_number(t: &str) -> Result<ValueExpr, String> {
    if t.to_ascii_uppercase().contains("$NODEID") {
        return parse_nodeid_expr(t);
    }
    if is_decimal_float(t) {
        return t
            .parse::<f64>()
            .ok()
            .filter(|f| f.is_finite())
            .map(ValueExpr::Decimal)
            .ok_or_else(|| format!("'{t}' is not a number"));
    }
    let (neg, body) = match t.as_bytes()[0] {
        b'-' => (true, t[1..].trim_start()),
        b'+' => (false, t[1..].trim_start()),
        _ => (false, t),
    };
    let (v, radix) = parse_uint(body)?;
    if radix == Radix::Hex && !neg {
        return Ok(ValueExpr::Hex(v));
    }
    let v = i128::try_from(v).map_err(|_| format!("'{t}' is too large a number"))?;
    Ok(ValueExpr::Integer(if neg { -v } else { v }))
}

/// `$NODEID`, `$NODEID+N`, `$NODEID-N`, `N+$NODEID`, with any spaces and case.
pub(super) fn parse_nodeid_expr(t: &str) -> Result<ValueExpr, String> {
    let bad = |why: &str| format!("'{t}' is not a $NODEID expression: {why}");
    let upper = t.to_ascii_uppercase();
    let pos = upper.find("$NODEID").unwrap_or(0);
    if upper[pos + 7..].contains("$NODEID") {
        return Err(bad("$NODEID twice"));
    }
    let before = t[..pos].trim();
    let after = t[pos + 7..].trim();
    let offset = match (before.is_empty(), after.is_empty()) {
        (true, true) => 0,
        (true, false) => {
            // $NODEID +/- N
            let (neg, rest) = match after.as_bytes()[0] {
                b'+' => (false, after[1..].trim_start()),
                b'-' => (true, after[1..].trim_start()),
                _ => return Err(bad("expected + or - after $NODEID")),
            };
            let v = signed_literal(rest).map_err(|e| bad(&e))?;
            if neg {
                -v
            } else {
                v
            }
        }
        (false, true) => {
            // N + $NODEID
            let Some(n) = before.strip_suffix('+') else {
                return Err(bad("expected + before $NODEID"));
            };
            signed_literal(n.trim_end()).map_err(|e| bad(&e))?
        }
        (false, false) => return Err(bad("text on both sides of $NODEID")),
    };
    Ok(ValueExpr::NodeIdPlus(offset))
}

pub(super) fn signed_literal(t: &str) -> Result<i128, String> {
    let (neg, body) = match t.as_bytes().first() {
        Some(b'-') => (true, t[1..].trim_start()),
        Some(b'+') => (false, t[1..].trim_start()),
        Some(_) => (false, t),
        None => return Err("a number is missing".into()),
    };
    let (v, _) = parse_uint(body)?;
    let v = i128::try_from(v).map_err(|_| format!("'{t}' is too large a number"))?;
    Ok(if neg { -v } else { v })
}

/// A plain unsigned integer key (SubNumber, NrOfRXPDO...): decimal, hex or octal.
pub(super) fn parse_plain_uint(t: &str) -> Result<u128, String> {
    let t = strip_hash_comment(t.trim());
    let body = t.strip_prefix('+').unwrap_or(t);
    parse_uint(body).map(|(v, _)| v)
}

/// A value quoted in a message: its first 40 characters.
pub(super) fn clip(s: &str) -> String {
    if s.chars().count() > 40 {
        let mut c: String = s.chars().take(40).collect();
        c.push('…');
        c
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers() {
        let p = |t: &str| parse_number(t).unwrap();
        assert_eq!(p("10"), ValueExpr::Integer(10));
        assert_eq!(p("010"), ValueExpr::Integer(8));
        assert_eq!(p("0"), ValueExpr::Integer(0));
        assert_eq!(p("0x1F"), ValueExpr::Hex(0x1F));
        assert_eq!(p("-0x10"), ValueExpr::Integer(-16));
        assert_eq!(p("-5"), ValueExpr::Integer(-5));
        assert_eq!(p("$NODEID"), ValueExpr::NodeIdPlus(0));
        assert_eq!(p("$NODEID+0x180"), ValueExpr::NodeIdPlus(0x180));
        assert_eq!(p("$NodeID + 0x80"), ValueExpr::NodeIdPlus(0x80));
        assert_eq!(p("0x200+$nodeid"), ValueExpr::NodeIdPlus(0x200));
        assert_eq!(p("$NODEID-1"), ValueExpr::NodeIdPlus(-1));
        assert_eq!(p("30.0"), ValueExpr::Decimal(30.0));
        assert_eq!(p("-1e-3"), ValueExpr::Decimal(-1e-3));
        assert_eq!(p(strip_hash_comment("12 # twelve")), ValueExpr::Integer(12));
        assert_eq!(p("08"), ValueExpr::Integer(8)); // not octal: the decimal (warned)
        for bad in [
            "0x",
            "12a",
            "$NODEID+$NODEID",
            "-$NODEID",
            "1.2.3",
            "0b101",
            "$NODEID*2",
        ] {
            assert!(parse_number(strip_hash_comment(bad)).is_err(), "{bad}");
        }
    }

    #[test]
    fn octets_written_with_0x() {
        let p = |t: &str| ValueExpr::parse(t, DataType::Domain).unwrap().unwrap();
        assert_eq!(p("0x0"), ValueExpr::Octets(vec![0]));
        assert_eq!(p("0x0000"), ValueExpr::Octets(vec![0, 0]));
        assert_eq!(p("0X123"), ValueExpr::Octets(vec![0x01, 0x23]));
        assert_eq!(
            p("0x000400000000002c00002401"),
            ValueExpr::Octets(vec![0, 4, 0, 0, 0, 0, 0, 0x2c, 0, 0, 0x24, 1])
        );
        for bad in ["0x", "0x0g", "0x 00"] {
            assert!(
                ValueExpr::parse(bad, DataType::OctetString).is_err(),
                "{bad}"
            );
        }
        let v = p("0x0000");
        let note = v.prefix_note("0x0000", DataType::Domain).unwrap();
        assert!(note.contains("read as the 2 bytes 00 00 ("), "{note}");
        // written as CiA 306 says: no note
        assert_eq!(p("0000").prefix_note("0000", DataType::Domain), None);
        let long = p("0x000102030405060708");
        let note = long
            .prefix_note("0x000102030405060708", DataType::Domain)
            .unwrap();
        assert!(
            note.contains("the 9 bytes 00 01 02 03 04 05 06 07 .."),
            "{note}"
        );
        let s = ValueExpr::parse("0x0000", DataType::VisibleString)
            .unwrap()
            .unwrap();
        assert_eq!(s, ValueExpr::Text("0x0000".into()));
        assert!(s
            .prefix_note("0x0000", DataType::VisibleString)
            .unwrap()
            .contains("the text of 6 characters"));
        assert_eq!(
            ValueExpr::Text("drive".into()).prefix_note("drive", DataType::VisibleString),
            None
        );
    }
}
