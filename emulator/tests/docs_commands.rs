//! Every `drive-emu` command the README and the book show is one the program takes: each
//! command line in a fenced code block (shell lines, `\` continuations joined, `$ ` prompts,
//! `./target/release/drive-emu` and `cargo run ... -p drive-emu --` forms) and each inline
//! code span that starts with `drive-emu SUBCOMMAND` is parsed by the program's own command
//! line (`drive_emu::cli::Cli`), so a renamed or removed flag, a value that no longer parses
//! or a subcommand that is gone fails here with file and line. A synopsis with placeholders
//! (`[--set K=V ...]`, `<iface>`) is not a command and is skipped; prose may name a command
//! or a flag without its values (`drive-emu sim`, `--out`), but not one that does not exist.
//! The test says how many it checked and skipped, and needs a floor of them checked.

use clap::Parser;
use drive_emu::cli::Cli;
use std::path::{Path, PathBuf};

const SUBCOMMANDS: [&str; 13] = [
    "demo", "run", "sim", "ballbar", "contour", "sweep", "figures", "scenario", "analyze", "eds",
    "fmu", "presets", "profiles",
];

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn pages() -> Vec<PathBuf> {
    let mut v = vec![repo().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(repo().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    docs.sort();
    v.extend(docs);
    v
}

/// Shell words of `s` (single and double quotes, backslash escapes), or None where the
/// quoting is not closed.
fn words(s: &str) -> Option<Vec<String>> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut have = false;
    let mut chars = s.chars();
    while let Some(c) = chars.next() {
        match c {
            '\'' => {
                have = true;
                loop {
                    match chars.next()? {
                        '\'' => break,
                        c => cur.push(c),
                    }
                }
            }
            '"' => {
                have = true;
                loop {
                    match chars.next()? {
                        '"' => break,
                        '\\' => cur.push(chars.next()?),
                        c => cur.push(c),
                    }
                }
            }
            '\\' => {
                have = true;
                cur.push(chars.next()?);
            }
            c if c.is_whitespace() => {
                if have {
                    out.push(std::mem::take(&mut cur));
                    have = false;
                }
            }
            c => {
                have = true;
                cur.push(c);
            }
        }
    }
    if have {
        out.push(cur);
    }
    Some(out)
}

/// The arguments after `drive-emu` in one shell command line, if it runs drive-emu.
fn command_args(line: &str) -> Option<String> {
    let line = line.trim().trim_start_matches("$ ");
    // a command sent to the background ends at its `&`
    let line = line.strip_suffix(" &").unwrap_or(line);
    // the command ends at a pipe, a redirection, a list or a comment
    let end = [
        " | ", " > ", " 2>", " >>", " && ", " ; ", " # ", " & ", " || ",
    ]
    .iter()
    .filter_map(|op| line.find(op))
    .min()
    .unwrap_or(line.len());
    let line = &line[..end];
    let rest = if let Some(i) = line.find("-p drive-emu ") {
        let after = &line[i + "-p drive-emu ".len()..];
        let j = after.find("-- ")?;
        &after[j + 3..]
    } else {
        let i = line
            .match_indices("drive-emu ")
            .map(|(i, _)| i)
            .find(|&i| i == 0 || line[..i].ends_with([' ', '/', '(', '`']))?;
        &line[i + "drive-emu ".len()..]
    };
    let sub = rest.split_whitespace().next()?;
    SUBCOMMANDS.contains(&sub).then(|| rest.to_string())
}

/// Where a command was found: a code block runs it whole; prose may name a command or a flag
/// without its values (`drive-emu sim`, `--out`), or wrap a span over two lines.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Found {
    Block,
    Prose,
}

/// (line, command arguments, where) of every drive-emu command in a page.
fn commands(text: &str) -> Vec<(usize, String, Found)> {
    let mut out = Vec::new();
    let mut fence: Option<String> = None;
    let mut pending: Option<(usize, String)> = None;
    for (i, raw) in text.lines().enumerate() {
        let t = raw.trim_start();
        if t.starts_with("```") || t.starts_with("~~~") {
            fence = match fence {
                None => Some(t[3..].trim().to_string()),
                Some(_) => None,
            };
            pending = None;
            continue;
        }
        // a line of a shell block: fenced, or an indented code block (four spaces or a tab)
        // whose line starts a command or continues one with `\`: checked whole
        let in_block = match &fence {
            Some(lang) => matches!(lang.as_str(), "" | "sh" | "bash" | "console" | "shell"),
            None => is_indented_command(raw) || pending.is_some(),
        };
        match &fence {
            _ if in_block => {
                let (start, mut joined) = pending.take().unwrap_or((i + 1, String::new()));
                joined.push_str(raw.trim_end().trim_end_matches('\\'));
                joined.push(' ');
                if raw.trim_end().ends_with('\\') {
                    pending = Some((start, joined));
                } else if let Some(args) = command_args(&joined) {
                    out.push((start, args, Found::Block));
                }
            }
            Some(_) => {}
            None => {
                // inline code spans: `drive-emu SUBCOMMAND ...`
                for (k, span) in raw.split('`').enumerate() {
                    if k % 2 == 1 && span.starts_with("drive-emu ") {
                        if let Some(args) = command_args(span) {
                            out.push((i + 1, args, Found::Prose));
                        }
                    }
                }
            }
        }
    }
    out
}

/// A line of an indented code block that starts a drive-emu command (prose in a list item
/// is indented too, but does not start with the program's name or a prompt).
fn is_indented_command(raw: &str) -> bool {
    let t = raw.trim_start();
    (raw.starts_with("    ") || raw.starts_with('\t'))
        && ["drive-emu ", "$ ", "./target/", "cargo run "]
            .iter()
            .any(|f| t.starts_with(f))
}

/// A synopsis, not a command: placeholders the program cannot take.
fn is_synopsis(args: &str) -> bool {
    args.contains('[') || args.contains('<') || args.contains("...") || args.contains('{')
}

#[test]
fn every_command_in_the_readme_and_the_book_parses() {
    let mut checked = 0;
    let mut skipped = Vec::new();
    let mut failures = Vec::new();
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        let name = page
            .strip_prefix(repo())
            .unwrap_or(&page)
            .display()
            .to_string();
        for (line, args, found) in commands(&text) {
            if is_synopsis(&args) {
                skipped.push(format!("{name}:{line}: drive-emu {args}"));
                continue;
            }
            let Some(w) = words(&args) else {
                failures.push(format!(
                    "{name}:{line}: unclosed quote in `drive-emu {args}`"
                ));
                continue;
            };
            checked += 1;
            let argv = std::iter::once("drive-emu".to_string()).chain(w);
            match Cli::try_parse_from(argv) {
                Ok(_) => {}
                Err(e)
                    if matches!(
                        e.kind(),
                        clap::error::ErrorKind::DisplayHelp
                            | clap::error::ErrorKind::DisplayVersion
                    ) => {}
                // prose naming a command or a flag without all its values: what it names
                // exists (an unknown flag or subcommand is still an error)
                Err(e)
                    if found == Found::Prose
                        && (e.kind() == clap::error::ErrorKind::MissingRequiredArgument
                            || e.to_string().contains("none was supplied")) => {}
                Err(e) => failures.push(format!(
                    "{name}:{line}: `drive-emu {args}`: {}",
                    e.to_string().lines().next().unwrap_or_default()
                )),
            }
        }
    }
    println!(
        "{checked} commands checked, {} synopses skipped:\n{}",
        skipped.len(),
        skipped.join("\n")
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(
        checked >= 60,
        "only {checked} commands found in the README and the book"
    );
}

#[test]
fn the_extractor_finds_commands_in_their_forms_and_skips_prose() {
    let page = "\
Run `drive-emu sim --preset cnc1 --velocity 10` or read on; `drive-emu` alone is prose.

```sh
$ drive-emu run --iface vcan0 \\
    --preset cnc2 | tee log
./target/release/drive-emu eds --node 5 > drive.eds
cargo run --release -p drive-emu -- demo --velocity 5
echo drive-emu-not-this
```

```toml
preset = \"drive-emu run\"
```

    drive-emu ballbar --preset cnc1 \\
        --radius-mm 50
- a list item whose next line is indented prose:
    drive-emu is named here, not run
";
    let found = commands(page);
    let args: Vec<&str> = found.iter().map(|(_, a, _)| a.trim()).collect();
    assert_eq!(
        args,
        [
            "sim --preset cnc1 --velocity 10",
            "run --iface vcan0      --preset cnc2",
            "eds --node 5",
            "demo --velocity 5",
            "ballbar --preset cnc1          --radius-mm 50"
        ]
    );
    assert_eq!(found[1].0, 4);
    assert_eq!(found[0].2, Found::Prose);
    assert_eq!(found[1].2, Found::Block);
    assert_eq!(
        words("a 'b c' \"d\\\"e\" f\\ g").unwrap(),
        ["a", "b c", "d\"e", "f g"]
    );
    // a flag that does not exist is refused by the program's command line
    assert!(Cli::try_parse_from(["drive-emu", "sim", "--velocity", "1", "--nope"]).is_err());
}
