//! Step 1 of reading an EDS: the text split into sections of `key=value` entries, and what a
//! section name is; the reading context every later step works on.

use std::collections::HashMap;

use super::value::{clip, parse_plain_uint};
use super::{EdsError, EdsWarning, MAX_SECTIONS, MAX_VALUE_BYTES};

pub(super) struct Entry<'a> {
    pub(super) key: &'a str,
    pub(super) value: &'a str,
    pub(super) line: usize,
}

pub(super) struct Section<'a> {
    pub(super) name: &'a str,
    pub(super) line: usize,
    pub(super) entries: Vec<Entry<'a>>,
    pub(super) keys: HashMap<String, usize>,
}

impl<'a> Section<'a> {
    pub(super) fn get(&self, key: &str) -> Option<&Entry<'a>> {
        let i = *self.keys.get(&key.to_ascii_lowercase())?;
        Some(&self.entries[i])
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Kind {
    FileInfo,
    DeviceInfo,
    DummyUsage,
    Comments,
    Commissioning,
    List(u8),
    Object(u16),
    Sub(u16, u8),
    Names(u16),
    Values(u16),
    Links(u16),
    Other,
}

pub(super) fn hex4(s: &str) -> Option<u16> {
    if s.len() == 4 && s.bytes().all(|b| b.is_ascii_hexdigit()) {
        u16::from_str_radix(s, 16).ok()
    } else {
        None
    }
}

pub(super) fn kind_counts_object(k: Kind) -> bool {
    matches!(k, Kind::Object(_))
}

/// What a section name (lowercase) is; `Err` for a sub-index out of range.
pub(super) fn classify(lc: &str) -> Result<Kind, String> {
    Ok(match lc {
        "fileinfo" => Kind::FileInfo,
        "deviceinfo" => Kind::DeviceInfo,
        "dummyusage" => Kind::DummyUsage,
        "comments" => Kind::Comments,
        "devicecomissioning" | "devicecommissioning" => Kind::Commissioning,
        "mandatoryobjects" => Kind::List(0),
        "optionalobjects" => Kind::List(1),
        "manufacturerobjects" => Kind::List(2),
        _ => {
            if let Some(i) = hex4(lc) {
                return Ok(Kind::Object(i));
            }
            if lc.len() < 4 || !lc.is_char_boundary(4) {
                return Ok(Kind::Other);
            }
            let Some(index) = hex4(&lc[..4]) else {
                return Ok(Kind::Other);
            };
            let rest = &lc[4..];
            if let Some(s) = rest.strip_prefix("sub") {
                if !s.is_empty() && s.bytes().all(|b| b.is_ascii_hexdigit()) {
                    let v = u32::from_str_radix(s.trim_start_matches('0'), 16).unwrap_or(
                        if s.trim_start_matches('0').is_empty() {
                            0
                        } else {
                            u32::MAX
                        },
                    );
                    if v > 0xFE {
                        return Err(format!(
                            "sub-index 0x{} is out of range (0..=0xFE; 0xFF is reserved for the structure, CiA 301)",
                            s.to_ascii_uppercase()
                        ));
                    }
                    return Ok(Kind::Sub(index, v as u8));
                }
                return Ok(Kind::Other);
            }
            match rest {
                "name" => Kind::Names(index),
                "value" => Kind::Values(index),
                "objectlinks" => Kind::Links(index),
                _ => Kind::Other,
            }
        }
    })
}

pub(super) struct Ctx<'a> {
    pub(super) sections: Vec<Section<'a>>,
    pub(super) by_kind: HashMap<Kind, usize>,
    pub(super) warnings: Vec<EdsWarning>,
}

pub(super) fn err(
    line: usize,
    section: Option<&str>,
    key: Option<&str>,
    reason: impl Into<String>,
) -> EdsError {
    EdsError {
        line,
        section: section.map(str::to_string),
        key: key.map(str::to_string),
        reason: reason.into(),
    }
}

impl<'a> Ctx<'a> {
    pub(super) fn warn(
        &mut self,
        line: usize,
        section: Option<&str>,
        key: Option<&str>,
        reason: impl Into<String>,
    ) {
        self.warnings.push(EdsWarning {
            line,
            section: section.map(str::to_string),
            key: key.map(str::to_string),
            reason: reason.into(),
        });
    }

    pub(super) fn section(&self, kind: Kind) -> Option<&Section<'a>> {
        self.by_kind.get(&kind).map(|&i| &self.sections[i])
    }
}

pub(super) fn key_err(s: &Section, e: &Entry, reason: impl Into<String>) -> EdsError {
    err(e.line, Some(s.name), Some(e.key), reason)
}

/// A warning of the lexer (no [`Ctx`] yet).
pub(super) fn lex_warn(
    out: &mut Vec<EdsWarning>,
    line: usize,
    section: Option<&str>,
    key: Option<&str>,
    reason: String,
) {
    out.push(EdsWarning {
        line,
        section: section.map(str::to_string),
        key: key.map(str::to_string),
        reason,
    });
}

/// Put `entry` into `sec`: a key given twice is read as the last one gives it (Lely's
/// reading; python canopen's strict parser refuses the file), with a warning.
pub(super) fn add_entry<'a>(
    sec: &mut Section<'a>,
    written_in: &str,
    entry: Entry<'a>,
    warnings: &mut Vec<EdsWarning>,
) {
    let lc = entry.key.to_ascii_lowercase();
    if let Some(&first) = sec.keys.get(&lc) {
        let old = &sec.entries[first];
        let reason = if old.value == entry.value {
            format!(
                "key given twice in this section (first at line {}), same value; read once",
                old.line
            )
        } else {
            format!(
                "key given twice in this section (first at line {}, '{}'): the last one, '{}', is read (as Lely reads it; python canopen refuses the file)",
                old.line,
                clip(old.value),
                clip(entry.value)
            )
        };
        lex_warn(
            warnings,
            entry.line,
            Some(written_in),
            Some(entry.key),
            reason,
        );
        sec.entries[first] = entry;
        return;
    }
    sec.keys.insert(lc, sec.entries.len());
    sec.entries.push(entry);
}

/// Split the text into sections (step 1: lines only). A section given twice is one section
/// (its keys read into the first, as Lely reads it), with a warning.
pub(super) fn lex(text: &str) -> Result<(Vec<Section<'_>>, Vec<EdsWarning>), EdsError> {
    let text = text.strip_prefix('\u{FEFF}').unwrap_or(text);
    let mut lx = Lexer {
        sections: Vec::new(),
        warnings: Vec::new(),
        seen: HashMap::new(),
        current: None,
    };
    for (n, raw) in text.split('\n').enumerate() {
        let line_no = n + 1;
        let line = raw.strip_suffix('\r').unwrap_or(raw).trim();
        if line.is_empty() || line.starts_with(';') || line.starts_with('#') {
            continue;
        }
        if let Some(rest) = line.strip_prefix('[') {
            lx.header(line_no, line, rest)?;
        } else {
            lx.key_value(line_no, line)?;
        }
    }
    Ok((lx.sections, lx.warnings))
}

/// The lexer's state: the sections so far, by lowercase name, and the one keys go into.
struct Lexer<'a> {
    sections: Vec<Section<'a>>,
    warnings: Vec<EdsWarning>,
    seen: HashMap<String, usize>,
    current: Option<usize>,
}

impl<'a> Lexer<'a> {
    /// A `[section]` header line (`rest` follows the `[`): a new section, or the first one of
    /// that name again.
    fn header(&mut self, line_no: usize, line: &'a str, rest: &'a str) -> Result<(), EdsError> {
        let Some(close) = rest.find(']') else {
            return Err(err(
                line_no,
                None,
                None,
                format!("section header '{line}' has no closing ]"),
            ));
        };
        let name = rest[..close].trim();
        let tail = rest[close + 1..].trim();
        if !(tail.is_empty() || tail.starts_with(';') || tail.starts_with('#')) {
            return Err(err(
                line_no,
                Some(name),
                None,
                format!("text '{tail}' after the section header"),
            ));
        }
        if name.is_empty() {
            return Err(err(line_no, None, None, "empty section name []"));
        }
        if name.len() > 256 {
            return Err(err(
                line_no,
                None,
                None,
                "section name longer than 256 bytes",
            ));
        }
        let lc = name.to_ascii_lowercase();
        if let Some(&first) = self.seen.get(&lc) {
            lex_warn(
                &mut self.warnings,
                line_no,
                Some(name),
                None,
                format!(
                    "section given twice (first at line {}): its keys are read as part of the first (as Lely reads it; python canopen refuses the file)",
                    self.sections[first].line
                ),
            );
            self.current = Some(first);
            return Ok(());
        }
        if self.sections.len() >= MAX_SECTIONS {
            return Err(err(
                line_no,
                Some(name),
                None,
                format!("more than {MAX_SECTIONS} sections"),
            ));
        }
        self.seen.insert(lc, self.sections.len());
        self.current = Some(self.sections.len());
        self.sections.push(Section {
            name,
            line: line_no,
            entries: Vec::new(),
            keys: HashMap::new(),
        });
        Ok(())
    }

    /// A `key=value` line, into the current section.
    fn key_value(&mut self, line_no: usize, line: &'a str) -> Result<(), EdsError> {
        let Some(eq) = line.find('=') else {
            let section = self.current.map(|i| self.sections[i].name);
            return Err(err(
                line_no,
                section,
                None,
                format!(
                    "'{}' is neither a [section], a key=value pair nor a comment",
                    clip(line)
                ),
            ));
        };
        let key = line[..eq].trim();
        let mut value = line[eq + 1..].trim();
        // inline comment: ';' after whitespace (python canopen and dcf-tools)
        if let Some(p) = value
            .as_bytes()
            .windows(2)
            .position(|w| w[0].is_ascii_whitespace() && w[1] == b';')
        {
            value = value[..p].trim_end();
        }
        let Some(sec) = self.current.map(|i| &mut self.sections[i]) else {
            return Err(err(
                line_no,
                None,
                Some(key),
                "key=value before the first [section]",
            ));
        };
        if key.is_empty() {
            return Err(err(
                line_no,
                Some(sec.name),
                None,
                "a key is missing before '='",
            ));
        }
        if value.len() > MAX_VALUE_BYTES {
            return Err(err(
                line_no,
                Some(sec.name),
                Some(key),
                format!(
                    "value of {} bytes, more than the {MAX_VALUE_BYTES} allowed",
                    value.len()
                ),
            ));
        }
        let written_in = sec.name;
        add_entry(
            sec,
            written_in,
            Entry {
                key,
                value,
                line: line_no,
            },
            &mut self.warnings,
        );
        Ok(())
    }
}

pub(super) fn text_of(s: Option<&Section>, key: &str) -> Option<String> {
    s.and_then(|s| s.get(key)).map(|e| e.value.to_string())
}

/// A number key of a fixed section, range-checked; empty is `None`. A value that is not a
/// number, or above `max`, is read as not given, with a warning (these keys describe the
/// file; the objects say what the device does).
pub(super) fn num_key(
    w: &mut Vec<EdsWarning>,
    s: Option<&Section>,
    key: &str,
    max: u128,
) -> Option<u128> {
    let s = s?;
    let e = s.get(key)?;
    if e.value.is_empty() {
        return None;
    }
    let why = match parse_plain_uint(e.value) {
        Ok(v) if v <= max => return Some(v),
        Ok(v) => format!("{v} is more than {max}"),
        Err(r) => r,
    };
    lex_warn(
        w,
        e.line,
        Some(s.name),
        Some(e.key),
        format!("{why}: read as not given"),
    );
    None
}

/// A 0/1 key; `true`/`yes` and `false`/`no` and any non-zero number are read too, with a
/// warning.
pub(super) fn bool_key(w: &mut Vec<EdsWarning>, s: Option<&Section>, key: &str) -> Option<bool> {
    let e = s?.get(key)?;
    let word = match e.value.to_ascii_lowercase().as_str() {
        "true" | "yes" => Some(true),
        "false" | "no" => Some(false),
        _ => None,
    };
    let (v, note) = match word {
        Some(b) => (b, true),
        None => {
            let v = num_key(w, s, key, u128::MAX)?;
            (v != 0, v > 1)
        }
    };
    if note {
        lex_warn(
            w,
            e.line,
            s.map(|s| s.name),
            Some(e.key),
            format!(
                "'{}' where CiA 306 writes 0 or 1: read as {}",
                e.value, v as u8
            ),
        );
    }
    Some(v)
}
