//! The shape of the workspace's Rust code (issue 29: files a newcomer can read), measured from
//! the source text:
//!
//! - no function longer than [`MAX_FN_LINES`] lines (from its `fn` line to its closing brace),
//!   beyond at most [`MAX_LONG_FNS`] that carry a `long-fn: <reason>` comment right above them
//!   (among their doc comments and attributes);
//! - no file circles: among the sibling files of one folder (`a.rs`, `b.rs`; not `mod.rs`, not
//!   sub-folders), no file uses a sibling that uses it back, directly or round a longer loop.
//!
//! The scan blanks comments, strings and character literals first, so a `{` in a string or a
//! path in a doc comment does not count. Uses are the paths the code names: `crate::a::b`,
//! `super::b`, `self::b` and their `{...}` groups, resolved against the file's module path
//! (inline `mod x { ... }` blocks included). A use through a re-export of the parent module
//! (`use super::Item` where the parent's `mod.rs` re-exports it) is a use of the parent, not
//! of the sibling that defines the item.
//!
//! Run with `--nocapture` to see the full list of long functions.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A function longer than this many lines is long.
const MAX_FN_LINES: usize = 120;
/// At most this many long functions, each with its reason in a `long-fn:` comment.
const MAX_LONG_FNS: usize = 3;

/// The crates' source folders, from the workspace root.
const SOURCE_DIRS: &[&str] = &[
    "protocol/src",
    "physics/src",
    "analysis/src",
    "fmu/src",
    "ethercat/src",
    "runtime/src",
    "emulator/src",
    "python/drive-emu/src",
];

/// Long functions not split yet, as (file, function): the measured state when this test was
/// written (issue 29), shrinking as they are split. A ratchet: an entry that is no longer long
/// (or gone) fails the test until it is removed here; a new long function is not added here
/// but split, or given its `long-fn:` reason (at most [`MAX_LONG_FNS`]).
const PENDING: &[(&str, &str)] = &[];

/// File circles not broken yet, as the test prints them. A ratchet like [`PENDING`].
const PENDING_CIRCLES: &[&str] = &[];

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn rs_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rs_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

fn is_ident_char(c: u8) -> bool {
    c.is_ascii_alphanumeric() || c == b'_'
}

/// `src` with comments, string literals (plain, byte, raw) and character literals replaced by
/// spaces; newlines kept, so line numbers hold. Lifetimes (`'a`) are kept.
fn blank(src: &str) -> String {
    let b = src.as_bytes();
    let mut out = b.to_vec();
    let n = b.len();
    let mut i = 0;
    let wipe = |out: &mut Vec<u8>, from: usize, to: usize| {
        for c in &mut out[from..to.min(n)] {
            if *c != b'\n' {
                *c = b' ';
            }
        }
    };
    while i < n {
        let c = b[i];
        if c == b'/' && i + 1 < n && b[i + 1] == b'/' {
            let end = src[i..].find('\n').map_or(n, |k| i + k);
            wipe(&mut out, i, end);
            i = end;
        } else if c == b'/' && i + 1 < n && b[i + 1] == b'*' {
            let mut depth = 1;
            let mut j = i + 2;
            while j < n && depth > 0 {
                if b[j] == b'/' && j + 1 < n && b[j + 1] == b'*' {
                    depth += 1;
                    j += 2;
                } else if b[j] == b'*' && j + 1 < n && b[j + 1] == b'/' {
                    depth -= 1;
                    j += 2;
                } else {
                    j += 1;
                }
            }
            wipe(&mut out, i, j);
            i = j;
        } else if (c == b'r' || (c == b'b' && i + 1 < n && b[i + 1] == b'r'))
            && (i == 0 || !is_ident_char(b[i - 1]))
            && {
                let k = if c == b'b' { i + 2 } else { i + 1 };
                let mut h = k;
                while h < n && b[h] == b'#' {
                    h += 1;
                }
                h < n && b[h] == b'"'
            }
        {
            // Raw string: r"..", r#".."#, br#".."#.
            let k = if c == b'b' { i + 2 } else { i + 1 };
            let mut h = k;
            while b[h] == b'#' {
                h += 1;
            }
            let hashes = h - k;
            let close: String = std::iter::once('"')
                .chain(std::iter::repeat_n('#', hashes))
                .collect();
            let end = src[h + 1..]
                .find(&close)
                .map_or(n, |e| h + 1 + e + close.len());
            wipe(&mut out, i, end);
            i = end;
        } else if c == b'"' {
            let mut j = i + 1;
            while j < n && b[j] != b'"' {
                j += if b[j] == b'\\' { 2 } else { 1 };
            }
            wipe(&mut out, i, j + 1);
            i = j + 1;
        } else if c == b'\'' {
            // A character literal ('x', '\n', '\u{..}', '"') or a lifetime ('a).
            if i + 2 < n && b[i + 1] == b'\\' {
                let end = src[i + 2..].find('\'').map_or(n, |e| i + 2 + e + 1);
                wipe(&mut out, i, end);
                i = end;
            } else {
                let ch_len = src[i + 1..].chars().next().map_or(1, char::len_utf8);
                if i + 1 + ch_len < n && b[i + 1 + ch_len] == b'\'' {
                    wipe(&mut out, i, i + 2 + ch_len);
                    i += 2 + ch_len;
                } else {
                    i += 1;
                }
            }
        } else {
            i += 1;
        }
    }
    // Only ASCII bytes were written over whole characters' spans, so this stays UTF-8 unless a
    // non-ASCII character sat inside a wiped span; replace those leftovers.
    String::from_utf8_lossy(&out).into_owned()
}

/// The identifier starting at byte `i` of `s`.
fn ident_at(s: &[u8], i: usize) -> &str {
    let mut j = i;
    while j < s.len() && is_ident_char(s[j]) {
        j += 1;
    }
    std::str::from_utf8(&s[i..j]).unwrap_or("")
}

fn skip_ws(s: &[u8], mut i: usize) -> usize {
    while i < s.len() && s[i].is_ascii_whitespace() {
        i += 1;
    }
    i
}

/// A function and its length.
#[derive(Debug)]
struct Fun {
    file: String,
    name: String,
    line: usize,
    lines: usize,
    /// The `long-fn:` reason in the comments right above it, if any.
    reason: Option<String>,
}

fn line_of(text: &[u8], i: usize) -> usize {
    1 + text[..i].iter().filter(|&&c| c == b'\n').count()
}

/// The index of the brace closing the one at `open` (in blanked text).
fn matching_brace(s: &[u8], open: usize) -> usize {
    let mut depth = 0usize;
    for (k, &c) in s.iter().enumerate().skip(open) {
        match c {
            b'{' => depth += 1,
            b'}' => {
                depth -= 1;
                if depth == 0 {
                    return k;
                }
            }
            _ => {}
        }
    }
    s.len() - 1
}

/// The `long-fn: reason` in the run of comment and attribute lines right above line `line`.
fn reason_above(raw_lines: &[&str], line: usize) -> Option<String> {
    let mut k = line - 1; // 0-based index of the `fn` line
    while k > 0 {
        k -= 1;
        let t = raw_lines[k].trim();
        if let Some(i) = t.find("long-fn:") {
            let why = t[i + "long-fn:".len()..].trim();
            return (!why.is_empty()).then(|| why.to_string());
        }
        if !(t.starts_with("//") || t.starts_with("#[") || t.starts_with(')')) {
            return None;
        }
    }
    None
}

/// Every function with a body in `raw` (the file `file`).
fn functions(file: &str, raw: &str) -> Vec<Fun> {
    let text = blank(raw);
    let s = text.as_bytes();
    let raw_lines: Vec<&str> = raw.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(k) = text[i..].find("fn") {
        let at = i + k;
        i = at + 2;
        if (at > 0 && is_ident_char(s[at - 1]))
            || at + 2 >= s.len()
            || !s[at + 2].is_ascii_whitespace()
        {
            continue;
        }
        let name_at = skip_ws(s, at + 2);
        let name = ident_at(s, name_at);
        if name.is_empty() {
            continue;
        }
        // The body's `{`, or a `;` (a declaration without body), outside (), [] and <>.
        let mut depth = 0i32;
        let mut j = name_at + name.len();
        let mut body = None;
        while j < s.len() {
            match s[j] {
                b'(' | b'[' => depth += 1,
                b')' | b']' => depth -= 1,
                b'{' if depth == 0 => {
                    body = Some(j);
                    break;
                }
                b';' if depth == 0 => break,
                _ => {}
            }
            j += 1;
        }
        let Some(open) = body else { continue };
        let close = matching_brace(s, open);
        let line = line_of(s, at);
        out.push(Fun {
            file: file.to_string(),
            name: name.to_string(),
            line,
            lines: line_of(s, close) - line + 1,
            reason: reason_above(&raw_lines, line),
        });
    }
    out
}

fn all_functions() -> Vec<Fun> {
    let ws = workspace();
    let mut out = Vec::new();
    for d in SOURCE_DIRS {
        let mut files = Vec::new();
        rs_files(&ws.join(d), &mut files);
        files.sort();
        for f in files {
            let rel = f.strip_prefix(&ws).unwrap().display().to_string();
            out.extend(functions(&rel, &std::fs::read_to_string(&f).unwrap()));
        }
    }
    out
}

#[test]
fn at_most_three_functions_over_120_lines_each_with_its_reason() {
    let mut long: Vec<Fun> = all_functions()
        .into_iter()
        .filter(|f| f.lines > MAX_FN_LINES)
        .collect();
    long.sort_by_key(|f| std::cmp::Reverse(f.lines));
    for f in &long {
        println!("{:4} lines  {}:{} {}", f.lines, f.file, f.line, f.name);
    }
    let mut bad = Vec::new();
    for (file, name) in PENDING {
        if !long.iter().any(|f| f.file == *file && f.name == *name) {
            bad.push(format!(
                "{file} {name} is no longer over {MAX_FN_LINES} lines: remove it from PENDING"
            ));
        }
    }
    let own: Vec<&Fun> = long
        .iter()
        .filter(|f| !PENDING.contains(&(f.file.as_str(), f.name.as_str())))
        .collect();
    for f in &own {
        if f.reason.is_none() {
            bad.push(format!(
                "{}:{} {} has {} lines (over {MAX_FN_LINES}): split it into named steps, or \
                 give its reason in a `// long-fn: <reason>` comment right above it",
                f.file, f.line, f.name, f.lines
            ));
        }
    }
    if own.len() > MAX_LONG_FNS {
        bad.push(format!(
            "{} functions over {MAX_FN_LINES} lines, at most {MAX_LONG_FNS} allowed",
            own.len()
        ));
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// A module's path from its crate root (`["od", "eds", "lex"]`) for a file under `src`.
fn module_path(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap();
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    if !matches!(last.as_str(), "mod.rs" | "lib.rs" | "main.rs") {
        parts.push(last.trim_end_matches(".rs").to_string());
    }
    parts
}

/// The paths named at `i` (just past `crate::`, `super::` chains or `self::`) as segment
/// lists, `{...}` groups expanded, appended to `base`.
fn paths_at(s: &[u8], mut i: usize, base: Vec<String>, out: &mut Vec<Vec<String>>) -> usize {
    let mut path = base;
    loop {
        i = skip_ws(s, i);
        if i < s.len() && s[i] == b'{' {
            i += 1;
            loop {
                i = skip_ws(s, i);
                if i >= s.len() || s[i] == b'}' {
                    return i + 1;
                }
                i = paths_at(s, i, path.clone(), out);
                i = skip_ws(s, i);
                // Skip `as x` and anything else up to the item's end.
                while i < s.len() && s[i] != b',' && s[i] != b'}' {
                    i += 1;
                }
                if i < s.len() && s[i] == b',' {
                    i += 1;
                }
            }
        }
        let id = ident_at(s, i);
        if id.is_empty() {
            out.push(path);
            return i;
        }
        i += id.len();
        if id == "super" {
            path.pop();
        } else if id != "self" {
            path.push(id.to_string());
        }
        if s[i..].starts_with(b"::") {
            i += 2;
        } else {
            out.push(path);
            return i;
        }
    }
}

/// The modules each module of the crate at `src` names (absolute paths), by module path; and
/// the file modules (`x.rs`, not `x/mod.rs`).
type Uses = BTreeMap<Vec<String>, BTreeSet<Vec<String>>>;
fn module_uses(src: &Path) -> (Uses, BTreeSet<Vec<String>>) {
    let mut files = Vec::new();
    rs_files(src, &mut files);
    files.sort();
    let mut uses = Uses::new();
    let mut file_modules = BTreeSet::new();
    for f in files {
        let own = module_path(src, &f);
        if !f.ends_with("mod.rs") && !f.ends_with("lib.rs") && !f.ends_with("main.rs") {
            file_modules.insert(own.clone());
        }
        let text = blank(&std::fs::read_to_string(&f).unwrap());
        let s = text.as_bytes();
        // Inline `mod x {` blocks: (module path, depth of the brace closing it).
        let mut stack: Vec<(Vec<String>, usize)> = vec![(own.clone(), 0)];
        let mut depth = 0usize;
        let mut i = 0;
        while i < s.len() {
            let c = s[i];
            if c == b'{' {
                depth += 1;
                i += 1;
                continue;
            }
            if c == b'}' {
                if stack.len() > 1 && stack.last().unwrap().1 == depth {
                    stack.pop();
                }
                depth = depth.saturating_sub(1);
                i += 1;
                continue;
            }
            if !is_ident_char(c) || (i > 0 && (is_ident_char(s[i - 1]) || s[i - 1] == b':')) {
                i += 1;
                continue;
            }
            let id = ident_at(s, i);
            let here = stack.last().unwrap().0.clone();
            let after = i + id.len();
            if id == "mod" {
                let n = skip_ws(s, after);
                let name = ident_at(s, n);
                let b = skip_ws(s, n + name.len());
                if !name.is_empty() && b < s.len() && s[b] == b'{' {
                    let mut p = here.clone();
                    p.push(name.to_string());
                    stack.push((p, depth + 1));
                }
            } else if matches!(id, "crate" | "super" | "self") && s[after..].starts_with(b"::") {
                let base = if id == "crate" {
                    Vec::new()
                } else {
                    here.clone()
                };
                // `paths_at` reads `super`/`self` itself; start at the keyword for those.
                let start = if id == "crate" { after + 2 } else { i };
                let mut found = Vec::new();
                paths_at(s, start, base, &mut found);
                let set = uses.entry(here.clone()).or_default();
                set.extend(found);
            }
            i = after;
        }
    }
    (uses, file_modules)
}

/// The sibling-file edges of one crate: (folder module, from file, to file).
fn sibling_edges(src: &Path) -> BTreeSet<(Vec<String>, String, String)> {
    let (uses, file_modules) = module_uses(src);
    let mut edges = BTreeSet::new();
    for (from, targets) in &uses {
        for to in targets {
            // The longest common prefix is the folder; the next segments are the siblings.
            let common = from.iter().zip(to).take_while(|(a, b)| a == b).count();
            if common < from.len() && common < to.len() {
                edges.insert((
                    from[..common].to_vec(),
                    from[common].clone(),
                    to[common].clone(),
                ));
            }
        }
    }
    // Keep only edges between sibling files (`a.rs`, `b.rs`), not items or folders.
    edges
        .into_iter()
        .filter(|(dir, a, b)| {
            let is_file = |m: &String| {
                let mut p = dir.clone();
                p.push(m.clone());
                file_modules.contains(&p)
            };
            is_file(a) && is_file(b)
        })
        .collect()
}

/// The file circles of the crate at `src`: each strongly connected group of sibling files.
fn circles(src: &Path) -> Vec<String> {
    let edges = sibling_edges(src);
    let mut by_dir: BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for (dir, a, b) in &edges {
        by_dir
            .entry(dir.clone())
            .or_default()
            .entry(a.clone())
            .or_default()
            .insert(b.clone());
    }
    let mut out = Vec::new();
    for (dir, g) in by_dir {
        let reach = |from: &String| {
            let mut seen = BTreeSet::new();
            let mut todo = vec![from.clone()];
            while let Some(m) = todo.pop() {
                for n in g.get(&m).into_iter().flatten() {
                    if seen.insert(n.clone()) {
                        todo.push(n.clone());
                    }
                }
            }
            seen
        };
        let mut done = BTreeSet::new();
        for a in g.keys() {
            if done.contains(a) {
                continue;
            }
            let from_a = reach(a);
            if !from_a.contains(a) {
                continue;
            }
            let group: BTreeSet<String> = from_a
                .iter()
                .filter(|b| reach(b).contains(a))
                .cloned()
                .collect();
            done.extend(group.iter().cloned());
            let prefix = if dir.is_empty() {
                String::new()
            } else {
                format!("{}/", dir.join("/"))
            };
            let names: Vec<String> = group.iter().map(|m| format!("{prefix}{m}")).collect();
            out.push(format!("{{{}}}", names.join(", ")));
        }
    }
    out
}

#[test]
fn no_file_circles() {
    let ws = workspace();
    let mut found = Vec::new();
    for d in SOURCE_DIRS {
        for c in circles(&ws.join(d)) {
            println!("{d}: {c}");
            found.push(format!("{d}: {c}"));
        }
    }
    let mut bad = Vec::new();
    for c in PENDING_CIRCLES {
        if !found.iter().any(|f| f == c) {
            bad.push(format!(
                "{c} is no longer a circle: remove it from PENDING_CIRCLES"
            ));
        }
    }
    for c in found
        .iter()
        .filter(|f| !PENDING_CIRCLES.contains(&f.as_str()))
    {
        bad.push(format!(
            "file circle {c}: the files use each other (move what both need to where \
             both can use it)"
        ));
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// The measuring itself, on known text: a long function, a reason, a circle and no circle.
#[test]
fn the_measure_counts_lines_skips_literals_and_finds_circles() {
    let body = "    let x = 1;\n".repeat(5);
    let src = format!(
        "// long-fn: one reason\n#[inline]\nfn a(v: [u8; 2]) -> u8 {{\n{body}    let s = \"}} {{\";\n    \
         let c = '{{';\n    // }}\n    let r = r#\"}}\"#;\n    0\n}}\nfn b() {{}}\ntrait T {{ fn d(&self); }}\n"
    );
    let f = functions("x.rs", &src);
    let names: Vec<(&str, usize)> = f.iter().map(|f| (f.name.as_str(), f.lines)).collect();
    assert_eq!(names, [("a", 12), ("b", 1)]);
    assert_eq!(f[0].reason.as_deref(), Some("one reason"));
    assert_eq!(f[1].reason, None);

    let dir = std::env::temp_dir().join(format!("code_shape_{}", std::process::id()));
    let write = |p: &str, t: &str| {
        let p = dir.join(p);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, t).unwrap();
    };
    write("lib.rs", "mod m;\nmod q;\n");
    write("m/mod.rs", "mod a;\nmod b;\nmod c;\npub use a::X;\n");
    write("m/a.rs", "use super::{c::Z, b};\npub struct X;\n");
    write("m/b.rs", "use crate::m::X;\n");
    write(
        "m/c.rs",
        "pub struct Z;\nfn f() { let _ = crate::m::a::X; }\n",
    );
    write(
        "q.rs",
        "use crate::m::X;\n#[cfg(test)]\nmod tests { use super::*; }\n",
    );
    let found = circles(&dir);
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0], "{m/a, m/c}");
}
