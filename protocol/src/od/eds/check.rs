//! Checks across the file once every object is read: the object lists and unknown keys.

use std::collections::{HashMap, HashSet};

use super::lex::{num_key, Ctx, Entry, Kind};
use super::value::parse_plain_uint;
use super::EdsError;

/// Keys CiA 306 (and the tools) define for an object or sub-index section.
pub(super) const OBJECT_KEYS: &[&str] = &[
    "subnumber",
    "parametername",
    "objecttype",
    "datatype",
    "accesstype",
    "lowlimit",
    "highlimit",
    "defaultvalue",
    "pdomapping",
    "objflags",
    "compactsubobj",
    "parametervalue",
    "uploadfile",
    "downloadfile",
    "denotation",
    "paramrefd",
    "storagelocation",
];

/// What a list's missing entries are said as: once, however many.
fn missing_entries(n: usize, missing: usize, first: usize) -> Option<String> {
    match missing {
        0 => None,
        1 => Some(format!(
            "SupportedObjects={n} but entry {first} is missing; the entries present are read"
        )),
        _ => Some(format!(
            "SupportedObjects={n} but {missing} entries are missing (the first: {first}); the entries present are read"
        )),
    }
}

/// The object lists against the object sections. Python canopen reads every object section
/// and ignores the lists, so a list that does not match the sections is read past with a
/// warning: an entry without its section, a missing entry number, a missing count.
pub(super) fn check_lists(cx: &mut Ctx, objects: &[(u16, usize)]) -> Result<(), EdsError> {
    let mut listed: HashMap<u16, (usize, usize)> = HashMap::new(); // index -> (list section, line)
    for list in 0..3u8 {
        let Some(&si) = cx.by_kind.get(&Kind::List(list)) else {
            continue;
        };
        let s = &cx.sections[si];
        let name = s.name;
        let mut notes: Vec<(usize, Option<&str>, String)> = Vec::new();
        let counted = num_key(&mut cx.warnings, Some(s), "SupportedObjects", 65_535);
        let numbered = |e: &&Entry| e.key.parse::<usize>().is_ok_and(|i| i > 0);
        let n = match counted {
            Some(n) => n as usize,
            None => {
                let n = s
                    .entries
                    .iter()
                    .filter(numbered)
                    .filter_map(|e| e.key.parse::<usize>().ok())
                    .max()
                    .unwrap_or(0)
                    // as SupportedObjects at most: an entry numbered beyond is ignored, said
                    // below (a number like 699185165023 once made this loop run for ever)
                    .min(65_535);
                notes.push((
                    s.line,
                    Some("SupportedObjects"),
                    format!("SupportedObjects is missing or unreadable: the {n} numbered entries are read"),
                ));
                n
            }
        };
        let mut dups = Vec::new();
        // missing entries are said once (how many, the first), not one note each: a count of
        // 65535 with no entries would otherwise be 65535 warnings
        let (mut missing, mut first_missing) = (0usize, 0usize);
        for i in 1..=n {
            let Some(e) = s.get(&i.to_string()) else {
                missing += 1;
                if first_missing == 0 {
                    first_missing = i;
                }
                continue;
            };
            let index = match parse_plain_uint(e.value) {
                Ok(v) => match u16::try_from(v).ok().filter(|&x| x != 0) {
                    Some(x) => x,
                    None => {
                        notes.push((
                            e.line,
                            Some(e.key),
                            format!("0x{v:X} is not an object index; entry ignored"),
                        ));
                        continue;
                    }
                },
                Err(r) => {
                    notes.push((e.line, Some(e.key), format!("{r}; entry ignored")));
                    continue;
                }
            };
            if !cx.by_kind.contains_key(&Kind::Object(index)) {
                notes.push((
                    e.line,
                    Some(e.key),
                    format!("object 0x{index:04X} is listed but has no section [{index:04X}]; entry ignored (python canopen reads the sections, not the lists)"),
                ));
                continue;
            }
            if let Some(&(first_si, first_line)) = listed.get(&index) {
                dups.push((e.line, e.key, index, cx.sections[first_si].name, first_line));
            } else {
                listed.insert(index, (si, e.line));
            }
        }
        if let Some(why) = missing_entries(n, missing, first_missing) {
            notes.push((s.line, None, why));
        }
        for e in s.entries.iter().filter(|e| {
            !e.key.eq_ignore_ascii_case("SupportedObjects")
                && e.key.parse::<usize>().map_or(true, |i| i == 0 || i > n)
        }) {
            notes.push((
                e.line,
                Some(e.key),
                format!("entry beyond SupportedObjects={n}; ignored"),
            ));
        }
        for (line, key, index, first, first_line) in dups {
            notes.push((
                line,
                Some(key),
                format!(
                    "object 0x{index:04X} listed twice (also in [{first}] at line {first_line})"
                ),
            ));
        }
        for (line, key, why) in notes {
            cx.warn(line, Some(name), key, why);
        }
    }
    let mut unlisted = Vec::new();
    for &(index, si) in objects {
        if !listed.contains_key(&index) {
            unlisted.push((cx.sections[si].line, cx.sections[si].name));
        }
    }
    for (line, name) in unlisted {
        cx.warn(line, Some(name), None, "object not named in [MandatoryObjects], [OptionalObjects] or [ManufacturerObjects]; kept");
    }
    Ok(())
}

/// One warning per unknown key name in object and sub-index sections.
pub(super) fn warn_unknown_keys(cx: &mut Ctx) {
    let mut seen: HashSet<String> = HashSet::new();
    let mut out = Vec::new();
    let mut kinds: Vec<(usize, Kind)> = cx.by_kind.iter().map(|(k, &i)| (i, *k)).collect();
    kinds.sort_unstable_by_key(|(i, _)| *i);
    for (si, kind) in kinds {
        if !matches!(kind, Kind::Object(_) | Kind::Sub(..)) {
            continue;
        }
        let s = &cx.sections[si];
        for e in &s.entries {
            let lc = e.key.to_ascii_lowercase();
            if !OBJECT_KEYS.contains(&lc.as_str()) && seen.insert(lc) {
                out.push((e.line, s.name, e.key));
            }
        }
    }
    for (line, name, key) in out {
        cx.warn(
            line,
            Some(name),
            Some(key),
            "key not defined by CiA 306; ignored (first of its kind)",
        );
    }
}
