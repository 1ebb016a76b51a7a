//! The README and the book (docs/, built by mdBook from docs/SUMMARY.md) link only to what
//! exists: every relative link and image in README.md and every .md under docs/ names a file
//! that exists, and its `#anchor`, where it points into a Markdown file, is the id of a heading
//! there (GitHub's and mdBook's rule: lower case, whitespace to '-', everything but letters,
//! digits, '-' and '_' dropped; a repeated heading gets -1, -2, ...). A link from a book page
//! stays inside docs/ (the rendered book has nothing else; name a source file as `code`), and
//! every book page is listed in docs/SUMMARY.md (mdBook renders only those).
//!
//! Markdown read here: fenced code blocks (``` and ~~~), indented code blocks and inline code
//! spans hold no links or headings; links are inline (`[text](target "title")`, `![alt](..)`,
//! across lines too), reference definitions (`[label]: target`) and HTML `href=` / `src=`.
//! External targets (`scheme://...`, `mailto:`) are not fetched.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};

/// One broken link: file, line, target, reason.
#[derive(Debug, PartialEq)]
struct Broken {
    file: PathBuf,
    line: usize,
    target: String,
    reason: String,
}

impl std::fmt::Display for Broken {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}:{}: ({}) {}",
            self.file.display(),
            self.line,
            self.target,
            self.reason
        )
    }
}

/// The text with code blanked out (fenced and indented code blocks, inline code spans), line
/// breaks kept so that byte offsets still give line numbers.
fn without_code(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut fence: Option<(char, usize)> = None;
    let mut prev_blank = true;
    let mut in_list = false;
    let mut in_indented = false;
    for line in text.split_inclusive('\n') {
        let body = line.trim_end_matches(['\n', '\r']);
        let indent = body.len() - body.trim_start_matches(' ').len();
        let trimmed = body.trim_start();
        let blank = trimmed.is_empty();
        // fenced code: a run of 3+ ` or ~ opens; the same char, at least as many, closes
        let run = |c: char| trimmed.chars().take_while(|&x| x == c).count();
        if let Some((c, n)) = fence {
            if indent < 4 && run(c) >= n && trimmed.trim_start_matches(c).trim().is_empty() {
                fence = None;
            }
            out.push_str(&blank_out(line));
            continue;
        }
        if indent < 4 {
            if let Some(c) = ['`', '~'].into_iter().find(|&c| run(c) >= 3) {
                fence = Some((c, run(c)));
                out.push_str(&blank_out(line));
                prev_blank = false;
                in_indented = false;
                continue;
            }
        }
        // indented code: 4+ spaces after a blank line, outside a list (list items continue
        // with indented lines)
        if !blank {
            if in_indented && indent >= 4 {
                out.push_str(&blank_out(line));
                continue;
            }
            in_indented = false;
            if indent >= 4 && prev_blank && !in_list {
                in_indented = true;
                out.push_str(&blank_out(line));
                prev_blank = false;
                continue;
            }
            if indent == 0 {
                in_list = is_list_item(trimmed);
            } else if is_list_item(trimmed) {
                in_list = true;
            }
        }
        prev_blank = blank;
        out.push_str(line);
    }
    without_code_spans(&out)
}

fn is_list_item(s: &str) -> bool {
    let digits = s.chars().take_while(|c| c.is_ascii_digit()).count();
    s.starts_with("- ")
        || s.starts_with("* ")
        || s.starts_with("+ ")
        || (digits > 0 && (s[digits..].starts_with(". ") || s[digits..].starts_with(") ")))
}

fn blank_out(s: &str) -> String {
    s.chars()
        .map(|c| if c == '\n' { '\n' } else { ' ' })
        .collect()
}

/// Inline code spans blanked: a run of n backticks up to the next run of exactly n.
fn without_code_spans(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = b.to_vec();
    let mut i = 0;
    while i < b.len() {
        if b[i] != b'`' {
            i += 1;
            continue;
        }
        let n = b[i..].iter().take_while(|&&c| c == b'`').count();
        let mut j = i + n;
        let mut close = None;
        while j < b.len() {
            if b[j] == b'`' {
                let m = b[j..].iter().take_while(|&&c| c == b'`').count();
                if m == n {
                    close = Some(j);
                    break;
                }
                j += m;
            } else {
                j += 1;
            }
        }
        match close {
            Some(j) => {
                for c in &mut out[i..j + n] {
                    if *c != b'\n' {
                        *c = b' ';
                    }
                }
                i = j + n;
            }
            None => i += n,
        }
    }
    // only ASCII bytes were replaced by ASCII spaces, inside or around whole code spans
    String::from_utf8(out).unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into())
}

/// (line, target) of every link in the text.
fn links(text: &str) -> Vec<(usize, String)> {
    let text = without_code(text);
    let line_of = |at: usize| text[..at].matches('\n').count() + 1;
    let mut found = Vec::new();
    // inline links and images: `](target)` or `](<target> "title")`
    let mut from = 0;
    while let Some(k) = text[from..].find("](") {
        let start = from + k + 2;
        let rest = &text[start..];
        let (target, _) = if let Some(r) = rest.strip_prefix('<') {
            r.split_once('>').unwrap_or((r, ""))
        } else {
            // up to the closing parenthesis (balanced) or the first whitespace (a title follows)
            let mut depth = 0;
            let end = rest
                .char_indices()
                .find(|&(_, c)| match c {
                    '(' => {
                        depth += 1;
                        false
                    }
                    ')' if depth == 0 => true,
                    ')' => {
                        depth -= 1;
                        false
                    }
                    c => c.is_whitespace(),
                })
                .map_or(rest.len(), |(i, _)| i);
            (&rest[..end], "")
        };
        found.push((line_of(start), target.to_string()));
        from = start;
    }
    // reference definitions: `[label]: target` at the start of a line
    let mut at = 0;
    for line in text.split_inclusive('\n') {
        let t = line.trim_start();
        if t.starts_with('[') && !t.starts_with("[^") {
            if let Some(k) = t.find("]:") {
                if let Some(target) = t[k + 2..].split_whitespace().next() {
                    found.push((line_of(at), target.trim_matches(['<', '>']).to_string()));
                }
            }
        }
        at += line.len();
    }
    // HTML attributes
    for attr in ["href=\"", "src=\""] {
        let mut from = 0;
        while let Some(k) = text[from..].find(attr) {
            let start = from + k + attr.len();
            let end = text[start..].find('"').map_or(text.len(), |e| start + e);
            found.push((line_of(start), text[start..end].to_string()));
            from = end;
        }
    }
    found.sort();
    found
}

/// The id mdBook and GitHub give a heading's text.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| {
            if c.is_alphanumeric() || c == '_' || c == '-' {
                Some(c)
            } else if c.is_whitespace() {
                Some('-')
            } else {
                None
            }
        })
        .collect()
}

/// The heading's text as rendered: links and images by their text, code spans by their content,
/// HTML tags dropped, a closing `#` sequence dropped.
fn heading_text(raw: &str) -> String {
    // a closing sequence of '#' goes only when a space precedes it (`# C#` keeps its '#')
    let mut raw = raw.trim();
    let open = raw.trim_end_matches('#');
    if open.len() < raw.len() && (open.is_empty() || open.ends_with(' ')) {
        raw = open.trim_end();
    }
    let mut out = String::new();
    let mut chars = raw.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            ']' if chars.peek() == Some(&'(') => {
                // skip the link target
                let mut depth = 0;
                for d in chars.by_ref() {
                    match d {
                        '(' => depth += 1,
                        ')' => {
                            depth -= 1;
                            if depth == 0 {
                                break;
                            }
                        }
                        _ => {}
                    }
                }
            }
            '<' => {
                // an HTML tag: dropped up to '>'
                for d in chars.by_ref() {
                    if d == '>' {
                        break;
                    }
                }
            }
            c => out.push(c),
        }
    }
    out
}

/// The ids of the headings of a Markdown text, repeats numbered as mdBook and GitHub do.
fn anchors(text: &str) -> BTreeSet<String> {
    let mut ids = BTreeSet::new();
    for line in without_code_keep_headings(text).lines() {
        let indent = line.len() - line.trim_start_matches(' ').len();
        let t = line.trim_start();
        let hashes = t.chars().take_while(|&c| c == '#').count();
        if indent > 3 || !(1..=6).contains(&hashes) {
            continue;
        }
        let rest = &t[hashes..];
        if !(rest.is_empty() || rest.starts_with(' ') || rest.starts_with('\t')) {
            continue;
        }
        let id = slug(&heading_text(rest));
        let mut unique = id.clone();
        let mut n = 0;
        while !ids.insert(unique.clone()) {
            n += 1;
            unique = format!("{id}-{n}");
        }
    }
    ids
}

/// Code blocks blanked but code spans kept (a heading's `code` is part of its id).
fn without_code_keep_headings(text: &str) -> String {
    // blank code blocks line by line by comparing with the fully stripped text: a line that
    // is entirely blank there but not in the source was inside a block, unless it only held
    // code spans; headings never consist of code spans alone without '#', so keep any line
    // whose source starts with '#'
    let stripped = without_code(text);
    text.lines()
        .zip(stripped.lines())
        .map(|(src, s)| {
            let is_heading_src = src.trim_start().starts_with('#');
            let heading_survives = s.trim_start().starts_with('#');
            if is_heading_src && heading_survives {
                src
            } else {
                ""
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Lexically normalised path (`a/./b/../c` -> `a/c`); None if it climbs above the start.
fn normalize(p: &Path) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    return None;
                }
            }
            Component::Normal(x) => out.push(x),
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    Some(out)
}

fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let hex = |c: u8| (c as char).to_digit(16);
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Checks the links of `pages` (paths relative to the repository root -> text). `exists` says
/// whether a repository-relative path is a file or directory; the texts of linked Markdown
/// files come from `pages` or `read`.
fn check(
    pages: &BTreeMap<PathBuf, String>,
    exists: &dyn Fn(&Path) -> bool,
    read: &dyn Fn(&Path) -> Option<String>,
) -> Vec<Broken> {
    let mut broken = Vec::new();
    let book = Path::new("docs");
    for (file, text) in pages {
        let dir = file.parent().unwrap_or(Path::new(""));
        for (line, target) in links(text) {
            let mut bad = |reason: String| {
                broken.push(Broken {
                    file: file.clone(),
                    line,
                    target: target.clone(),
                    reason,
                })
            };
            if target.is_empty() {
                bad("empty link target".into());
                continue;
            }
            let scheme = target.split_once(':').is_some_and(|(s, _)| {
                !s.is_empty()
                    && s.chars()
                        .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
            });
            if scheme {
                continue; // http:, https:, mailto:, ...
            }
            let (path, anchor) = match target.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (target.as_str(), None),
            };
            let path = percent_decode(path.split('?').next().unwrap_or(""));
            let resolved = if path.is_empty() {
                Some(file.clone())
            } else if path.starts_with('/') {
                None
            } else {
                normalize(&dir.join(&path))
            };
            let Some(resolved) = resolved else {
                bad("absolute or outside the repository".into());
                continue;
            };
            if !exists(&resolved) {
                bad(format!("{} does not exist", resolved.display()));
                continue;
            }
            if file.starts_with(book) && !resolved.starts_with(book) {
                bad(format!(
                    "{} is outside docs/: the rendered book has no such page (write the path as `code`)",
                    resolved.display()
                ));
                continue;
            }
            let Some(anchor) = anchor else { continue };
            if resolved.extension().is_none_or(|e| e != "md") {
                continue; // an anchor into a non-Markdown file is not checked
            }
            let Some(target_text) = pages.get(&resolved).cloned().or_else(|| read(&resolved))
            else {
                bad(format!("{} cannot be read", resolved.display()));
                continue;
            };
            let ids = anchors(&target_text);
            if !ids.contains(&percent_decode(anchor)) {
                let near: Vec<_> = ids
                    .iter()
                    .filter(|id| {
                        let a = anchor.split('-').next().unwrap_or("");
                        !a.is_empty() && id.contains(a)
                    })
                    .take(5)
                    .collect();
                bad(format!(
                    "no heading of {} has the id `{anchor}`{}",
                    resolved.display(),
                    if near.is_empty() {
                        String::new()
                    } else {
                        format!(" (ids there: {near:?})")
                    }
                ));
            }
        }
    }
    broken
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("emulator/ has a parent")
        .to_path_buf()
}

/// README.md and every .md under docs/, repository-relative.
fn pages() -> BTreeMap<PathBuf, String> {
    fn walk(root: &Path, rel: &Path, out: &mut BTreeMap<PathBuf, String>) {
        let mut entries: Vec<_> = std::fs::read_dir(root.join(rel))
            .unwrap_or_else(|e| panic!("reading {}: {e}", rel.display()))
            .map(|e| e.expect("a directory entry").file_name())
            .collect();
        entries.sort();
        for name in entries {
            let rel = rel.join(&name);
            let full = root.join(&rel);
            if full.is_dir() {
                walk(root, &rel, out);
            } else if rel.extension().is_some_and(|e| e == "md") {
                let text = std::fs::read_to_string(&full)
                    .unwrap_or_else(|e| panic!("reading {}: {e}", rel.display()));
                out.insert(rel, text);
            }
        }
    }
    let root = repo();
    let mut out = BTreeMap::new();
    out.insert(
        PathBuf::from("README.md"),
        std::fs::read_to_string(root.join("README.md")).expect("README.md"),
    );
    walk(&root, Path::new("docs"), &mut out);
    out
}

#[test]
fn readme_and_book_links_resolve() {
    let root = repo();
    let pages = pages();
    assert!(
        pages.len() > 10 && pages.contains_key(Path::new("docs/SUMMARY.md")),
        "found only {:?}",
        pages.keys().collect::<Vec<_>>()
    );
    let broken = check(&pages, &|p| root.join(p).exists(), &|p| {
        std::fs::read_to_string(root.join(p)).ok()
    });
    let total: usize = pages.values().map(|t| links(t).len()).sum();
    assert!(
        total > 100,
        "only {total} links found: is the link reader broken?"
    );
    assert!(
        broken.is_empty(),
        "{} broken link(s) of {total}:\n{}",
        broken.len(),
        broken
            .iter()
            .map(|b| b.to_string())
            .collect::<Vec<_>>()
            .join("\n")
    );
}

#[test]
fn every_book_page_is_in_the_summary() {
    let pages = pages();
    let summary = &pages[Path::new("docs/SUMMARY.md")];
    let listed: BTreeSet<PathBuf> = links(summary)
        .into_iter()
        .filter_map(|(_, t)| normalize(&Path::new("docs").join(t.split('#').next().unwrap_or(""))))
        .collect();
    let missing: Vec<_> = pages
        .keys()
        .filter(|p| p.starts_with("docs") && p.as_path() != Path::new("docs/SUMMARY.md"))
        .filter(|p| !listed.contains(*p))
        .collect();
    assert!(
        missing.is_empty(),
        "not in docs/SUMMARY.md, so mdBook does not render them: {missing:?}"
    );
}

/// The checker itself finds what it must: a missing file, a missing anchor, a link out of the
/// book; and accepts code, repeated headings and external links.
#[test]
fn the_checker_reports_broken_links_and_accepts_good_ones() {
    let mut pages = BTreeMap::new();
    pages.insert(
        PathBuf::from("README.md"),
        "# Top\n\nSee [the guide](docs/guide.md#set-up-vcan0), [gone](docs/gone.md),\n\
         [bad anchor](docs/guide.md#nowhere) and ![a\npicture](docs/img/a.png).\n\
         [site](https://example.org/x#y) `[not a link](nowhere.md)`\n\n    [indented code](nowhere.md)\n\n\
         ```\n[fenced](nowhere.md)\n# not a heading\n```\n[self](#top)\n"
            .to_string(),
    );
    pages.insert(
        PathBuf::from("docs/guide.md"),
        "# Guide\n\n## Set up `vcan0`!\n\n## Notes\n\n## Notes\n\n[back](../README.md) \
         [notes 2](#notes-1) [source](../emulator/src/lib.rs)\n[ref]: missing.md\n"
            .to_string(),
    );
    let files: BTreeSet<PathBuf> = [
        "README.md",
        "docs/guide.md",
        "docs/img/a.png",
        "emulator/src/lib.rs",
    ]
    .into_iter()
    .map(PathBuf::from)
    .collect();
    let broken = check(&pages, &|p| files.contains(p), &|_| None);
    let got: Vec<(&str, usize, &str)> = broken
        .iter()
        .map(|b| (b.file.to_str().unwrap(), b.line, b.target.as_str()))
        .collect();
    assert_eq!(
        got,
        vec![
            ("README.md", 3, "docs/gone.md"),
            ("README.md", 4, "docs/guide.md#nowhere"),
            ("docs/guide.md", 9, "../README.md"),
            ("docs/guide.md", 9, "../emulator/src/lib.rs"),
            ("docs/guide.md", 10, "missing.md"),
        ],
        "{broken:#?}"
    );
    assert!(broken[2].reason.contains("outside docs/"), "{}", broken[2]);
    assert!(broken[1].reason.contains("no heading"), "{}", broken[1]);
    assert_eq!(slug(&heading_text(" Set up `vcan0`!")), "set-up-vcan0");
    assert_eq!(
        slug(&heading_text(
            " 3.1 `enable_requires_mode`: no OPERATION ENABLED (Nanotec PD4-C)"
        )),
        "31-enable_requires_mode-no-operation-enabled-nanotec-pd4-c"
    );
    assert_eq!(
        slug(&heading_text(" The [panel](panel.md) stream ##")),
        "the-panel-stream"
    );
}
