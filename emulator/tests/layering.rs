//! The emulator's module layering (docs/decisions/0006-emulator-layers.md, 0019): every
//! top-level module of `runtime/src` (crate drive-runtime) has a place in [`RUNTIME_LAYERS`],
//! every one of `emulator/src` (crate drive-emu, the binary) in [`LAYERS`], bottom first, and
//! imports only modules below it. Imports are read from the source text: `crate::X` anywhere (code, tests, doc
//! links), `crate::{X, ...}` groups, and `super::` chains that climb to the crate root. A module
//! that imports one above it (or itself from below: a cycle) fails this test, and so does a new
//! top-level module that is not placed in the order.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The runtime crate's layer order (runtime/src, with what its lib.rs re-exports), bottom
/// first. A module may import only modules before it in this list. Written once here and in
/// docs/decisions/0006-emulator-layers.md.
const RUNTIME_LAYERS: &[&str] = &[
    // crate drive-analysis, re-exported (lib.rs `pub use drive_analysis::{...}`):
    "quote",  // file content rendered in messages: control characters escaped, capped
    "infile", // the bounded reader of every input file: regular files only, size cap
    "time",   // clocks: monotonic wall clock, virtual clock
    // crate drive-analysis, re-exported:
    "samples", // trace sample types and trace-file reading
    "bus",     // CAN bus abstraction: SocketCAN, in-process, fault injector
    // crate drive-physics, re-exported (lib.rs `pub use drive_physics::{...}`):
    "axis",     // physics: two-mass axis with backlash, friction, encoders
    "control",  // servo cascade on the axis
    "presets",  // axis configurations (preset files, overrides)
    "runtime",  // the fixed-rate loop wiring bus, nodes and simulated drives
    "drive",    // the Drive adapter on the simulated axis, machine file
    "observe",  // the tick's observation fan-out: per-axis snapshots in a seqlock ring
    "master",   // reference CiA 402 master (sans-IO) and its bus loop
    "analysis", // re-exports drive-analysis' detector and decoding; experiments, ballbar
    "monitor",  // the detector on a running drive's own samples (run --detect)
    "report",   // report files and plots (crate drive-analysis, re-exported)
    "session",  // runtime + master on one bus: offline runs
    "scenario", // scenario files, timelines, expectations, runner
    "study",    // parameter studies and figures
    "api",      // the typed requests under the command line and the Python module
];

/// The binary crate's own modules (emulator/src), above all of [`RUNTIME_LAYERS`], which its
/// lib.rs re-exports (`pub use drive_runtime::{...}`) under the names they always had.
const BINARY_LAYERS: &[&str] = &[
    "panel", // the live panel of `run --panel`: server, stream, injections, recording
    "cli",   // the command line
];

/// The binary crate's layer order, bottom first: [`RUNTIME_LAYERS`], then [`BINARY_LAYERS`].
const LAYERS: &[&str] = &concat_layers();

const fn concat_layers() -> [&'static str; RUNTIME_LAYERS.len() + BINARY_LAYERS.len()] {
    let mut out = [""; RUNTIME_LAYERS.len() + BINARY_LAYERS.len()];
    let mut i = 0;
    while i < out.len() {
        out[i] = if i < RUNTIME_LAYERS.len() {
            RUNTIME_LAYERS[i]
        } else {
            BINARY_LAYERS[i - RUNTIME_LAYERS.len()]
        };
        i += 1;
    }
    out
}

/// What the runtime crate must never name: the binary crate, its command line or panel, the
/// argument parser, the panel's HTTP stack (the Python module's wheel links the runtime).
const RUNTIME_FORBIDDEN: &[&str] = &[
    "drive_emu::",
    "crate::cli",
    "crate::panel",
    "super::cli",
    "super::panel",
    "clap::",
    "axum",
    "tokio",
    "hyper::",
    "hyper_util",
];

/// The physics crate's modules (physics/src), bottom first: the same rule inside it.
const PHYSICS_LAYERS: &[&str] = &["params", "axis", "control", "presets"];

/// The analysis crate's modules (analysis/src), bottom first: the same rule inside it.
const ANALYSIS_LAYERS: &[&str] = &[
    "quote",      // file content rendered in messages
    "infile",     // the bounded reader of every input file
    "samples",    // trace sample types and trace-file reading
    "spectrum",   // amplitude spectra, fundamentals
    "windows",    // constant-velocity windows of a trace
    "axis_trace", // the trace the detector reads
    "verdict",    // what the detector finds per window
    "gap",        // how large the gap is where a window is flagged
    "detector",   // the backlash detector
    "capture",    // a CAN capture decoded into the detector's trace
    "ballbar",    // the ballbar's trace, figures and capture decoding
    "report",     // report files and plots
];

/// The emulator's modules that are the analysis crate's, re-exported (runtime's lib.rs or
/// `analysis/mod.rs`), as paths under runtime/src (and emulator/src) that must not exist (no
/// copies).
const ANALYSIS_REEXPORTED: &[&str] = &[
    "quote.rs",
    "infile.rs",
    "samples",
    "report",
    "analysis/spectrum.rs",
    "analysis/windows.rs",
    "analysis/detector.rs",
    "analysis/gap.rs",
    "analysis/ballbar/metrics.rs",
    "analysis/capture/candump.rs",
];

/// The workspace's crates and the workspace crates each may depend on (its `[dependencies]`
/// on a `path`): the compiler keeps these layers, this test keeps the list. Bottom first.
const CRATES: &[(&str, &[&str])] = &[
    ("protocol", &[]),
    ("physics", &[]),
    ("analysis", &["protocol", "physics"]),
    ("fmu", &["physics"]),
    ("ethercat", &["protocol"]),
    ("runtime", &["protocol", "physics", "analysis", "ethercat"]),
    (
        "emulator",
        &[
            "protocol", "physics", "analysis", "fmu", "ethercat", "runtime",
        ],
    ),
];

/// What the physics crate must never name: a fieldbus, a thread, a clock, a socket.
const PHYSICS_FORBIDDEN: &[&str] = &[
    "drive_protocol",
    "drive_emu",
    "std::thread",
    "Instant",
    "SystemTime",
    "std::net",
    "std::sync",
];

/// What the analysis crate must never name: the emulator, a thread, a lock, a clock, a
/// socket (it reads traces and files and computes; the emulator runs the drives).
const ANALYSIS_FORBIDDEN: &[&str] = &[
    "drive_emu",
    "std::thread",
    "Instant",
    "SystemTime",
    "std::net",
    "Mutex",
    "RwLock",
    "mpsc",
    "Atomic",
    "tokio",
    "socketcan::",
];

/// Files directly in `src/` that are not modules of the layering (crate root, binary).
const ROOT_FILES: &[&str] = &["lib.rs", "main.rs"];

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

fn is_ident_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// The identifier at the start of `s`.
fn ident(s: &str) -> &str {
    let end = s.find(|c| !is_ident_char(c)).unwrap_or(s.len());
    &s[..end]
}

/// The top-level modules that `text` refers to: `crate::X`, each first name in a
/// `crate::{X, Y::Z, ...}` group, and `super::` chains of `root_depth` steps (`super::` from
/// `src/X.rs` or `src/X/mod.rs` reaches the crate root, one more per folder level).
fn referenced_modules(text: &str, root_depth: usize) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    let climb = "super::".repeat(root_depth);
    for (pat, grouped_ok) in [("crate::", true), (climb.as_str(), true)] {
        let mut rest = text;
        while let Some(i) = rest.find(pat) {
            let before = rest[..i].chars().next_back();
            let after = &rest[i + pat.len()..];
            rest = after;
            // `foo_crate::x` or `super::super::x` seen from its second `super::` is not ours.
            if before.is_some_and(|c| is_ident_char(c) || c == ':') {
                continue;
            }
            if grouped_ok && after.starts_with('{') {
                let mut depth = 0usize;
                let mut start = true;
                for (k, c) in after.char_indices() {
                    match c {
                        '{' => {
                            depth += 1;
                            start = depth == 1;
                        }
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                break;
                            }
                        }
                        ',' if depth == 1 => start = true,
                        c if c.is_whitespace() => {}
                        _ => {
                            if start && depth == 1 {
                                let name = ident(&after[k..]);
                                if !name.is_empty() {
                                    found.insert(name.to_string());
                                }
                            }
                            start = false;
                        }
                    }
                }
            } else {
                let name = ident(after);
                if !name.is_empty() {
                    found.insert(name.to_string());
                }
            }
        }
    }
    found
}

/// `super::` steps from `file` (inside `src/`) up to the crate root.
fn root_depth(src: &Path, file: &Path) -> usize {
    let rel = file.strip_prefix(src).unwrap();
    let folders = rel.components().count() - 1;
    let is_mod = rel
        .file_name()
        .is_some_and(|n| n == "mod.rs" || n == "lib.rs" || n == "main.rs");
    if is_mod {
        folders.max(1)
    } else {
        folders + 1
    }
}

/// Every import that goes up (or sideways into a module not below), as messages.
fn violations(src: &Path) -> Vec<String> {
    violations_in(src, LAYERS)
}

/// [`violations`] of a crate whose modules are `layers`, bottom first.
fn violations_in(src: &Path, layers: &[&str]) -> Vec<String> {
    let layer = |m: &str| layers.iter().position(|l| *l == m);
    let mut out = Vec::new();
    let mut files = Vec::new();
    rs_files(src, &mut files);
    files.sort();
    for f in files {
        let rel = f.strip_prefix(src).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        if rel.components().count() == 1 && ROOT_FILES.contains(&first.as_ref()) {
            continue;
        }
        let module = first.trim_end_matches(".rs").to_string();
        let Some(own) = layer(&module) else {
            out.push(format!(
                "{}: module `{module}` has no place in LAYERS (tests/layering.rs and \
                 docs/decisions/0006-emulator-layers.md)",
                rel.display()
            ));
            continue;
        };
        let text = std::fs::read_to_string(&f).unwrap();
        for m in referenced_modules(&text, root_depth(src, &f)) {
            if m == module {
                continue;
            }
            match layer(&m) {
                Some(l) if l < own => {}
                Some(_) => out.push(format!(
                    "{}: `{module}` imports `{m}`, which is not below it in LAYERS",
                    rel.display()
                )),
                // Not a top-level module (an item of lib.rs, a macro): no layer to break.
                None => {}
            }
        }
    }
    out
}

#[test]
fn every_emulator_module_imports_only_modules_below_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let bad = violations(&src);
    assert!(bad.is_empty(), "layering broken:\n{}", bad.join("\n"));
}

#[test]
fn every_runtime_module_imports_only_modules_below_it() {
    let src = workspace().join("runtime/src");
    let bad = violations_in(&src, RUNTIME_LAYERS);
    assert!(
        bad.is_empty(),
        "runtime layering broken:\n{}",
        bad.join("\n")
    );
}

/// The runtime crate is everything below the command line and the panel: it has no `cli` or
/// `panel` module, names none (nor the binary crate, clap or the panel's HTTP stack), and its
/// dependency tree holds no clap, axum, tokio, hyper or drive-emu.
#[test]
fn the_runtime_crate_names_no_cli_or_panel_and_links_no_clap_or_http_server() {
    let src = workspace().join("runtime/src");
    for m in BINARY_LAYERS {
        for p in [src.join(m), src.join(format!("{m}.rs"))] {
            assert!(!p.exists(), "{} exists", p.display());
        }
    }
    let lib = std::fs::read_to_string(src.join("lib.rs")).unwrap();
    let declared = declared_modules(&lib);
    for m in BINARY_LAYERS {
        assert!(!declared.contains(m), "runtime/src/lib.rs declares `{m}`");
    }
    let named = naming(&src, RUNTIME_FORBIDDEN);
    assert!(named.is_empty(), "{}", named.join("\n"));
    // The check sees a use of the command line from below.
    let dir = scratch(
        "runtime-forbidden",
        &[("study/mod.rs", "use crate::cli::sweep::SweepArgs;\n")],
    );
    assert_eq!(naming(&dir, RUNTIME_FORBIDDEN).len(), 1);
    std::fs::remove_dir_all(&dir).ok();

    let tree = normal_tree("drive-runtime");
    assert!(
        tree.contains("drive-runtime") && tree.contains("drive-protocol"),
        "{tree:?}"
    );
    for name in ["clap", "axum", "tokio", "hyper", "hyper-util", "drive-emu"] {
        assert!(!tree.contains(name), "drive-runtime links {name}");
    }
    // The same query finds clap where it is: under the binary.
    assert!(normal_tree("drive-emu").contains("clap"));
}

#[test]
fn every_physics_module_imports_only_modules_below_it_and_nothing_of_a_bus_or_a_clock() {
    let src = workspace().join("physics/src");
    let bad = violations_in(&src, PHYSICS_LAYERS);
    assert!(
        bad.is_empty(),
        "physics layering broken:\n{}",
        bad.join("\n")
    );
    let mut files = Vec::new();
    rs_files(&src, &mut files);
    let mut named = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        for w in PHYSICS_FORBIDDEN {
            if text.contains(w) {
                named.push(format!("{} names `{w}`", f.display()));
            }
        }
    }
    assert!(named.is_empty(), "{}", named.join("\n"));
}

/// The files under `src` that name one of `forbidden`, as messages.
fn naming(src: &Path, forbidden: &[&str]) -> Vec<String> {
    let mut files = Vec::new();
    rs_files(src, &mut files);
    let mut named = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        for w in forbidden {
            if text.contains(w) {
                named.push(format!("{} names `{w}`", f.display()));
            }
        }
    }
    named
}

#[test]
fn every_analysis_module_imports_only_modules_below_it_and_nothing_that_runs() {
    let src = workspace().join("analysis/src");
    let bad = violations_in(&src, ANALYSIS_LAYERS);
    assert!(
        bad.is_empty(),
        "analysis layering broken:\n{}",
        bad.join("\n")
    );
    // Every module of the crate is placed, and every place is a module.
    let lib = std::fs::read_to_string(src.join("lib.rs")).unwrap();
    let declared: Vec<&str> = lib
        .lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .map(|l| l.trim_end_matches(';'))
        .collect();
    assert_eq!(
        declared, ANALYSIS_LAYERS,
        "analysis/src/lib.rs in layer order"
    );
    let named = naming(&src, ANALYSIS_FORBIDDEN);
    assert!(named.is_empty(), "{}", named.join("\n"));
    // The check sees a forbidden word.
    let dir = scratch(
        "analysis-forbidden",
        &[("spectrum.rs", "use std::sync::Mutex;\n")],
    );
    assert_eq!(naming(&dir, ANALYSIS_FORBIDDEN).len(), 1);
    std::fs::remove_dir_all(&dir).ok();
}

/// The workspace root.
fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The workspace crates (folders) that `manifest` depends on by path, in `[dependencies]`
/// (dev-dependencies may reach further: tests drive a crate from outside).
fn path_dependencies(manifest: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut in_deps = false;
    for line in manifest.lines() {
        let l = line.trim();
        if l.starts_with('[') {
            in_deps = l == "[dependencies]";
            continue;
        }
        if !in_deps {
            continue;
        }
        if let Some(i) = l.find("path = \"../") {
            let rest = &l[i + "path = \"../".len()..];
            let name = rest.split('"').next().unwrap_or("");
            out.insert(name.trim_end_matches('/').to_string());
        }
    }
    out
}

#[test]
fn every_crate_depends_only_on_the_crates_below_it() {
    let root = workspace();
    let mut bad = Vec::new();
    for (i, (krate, allowed)) in CRATES.iter().enumerate() {
        let manifest = std::fs::read_to_string(root.join(krate).join("Cargo.toml")).unwrap();
        for dep in path_dependencies(&manifest) {
            let below = CRATES[..i].iter().any(|(c, _)| *c == dep);
            if !below || !allowed.contains(&dep.as_str()) {
                bad.push(format!("{krate} depends on {dep}"));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "crate layering broken: {bad:?} (CRATES in tests/layering.rs)"
    );
    // Every member of the workspace with a library is placed.
    let ws = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    for m in [
        "protocol", "physics", "analysis", "fmu", "ethercat", "runtime", "emulator",
    ] {
        assert!(
            ws.contains(&format!("\"{m}\"")),
            "{m} not a workspace member"
        );
    }
    assert_eq!(
        path_dependencies("[dependencies]\na = { path = \"../physics\" }\n[dev-dependencies]\nb = { path = \"../x\" }\n"),
        BTreeSet::from(["physics".to_string()])
    );
}

/// The modules a lib.rs declares (`pub mod x;`, `mod x;`).
fn declared_modules(lib: &str) -> BTreeSet<&str> {
    lib.lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .chain(lib.lines().filter_map(|l| l.trim().strip_prefix("mod ")))
        .map(|l| l.trim_end_matches(';'))
        .collect()
}

#[test]
fn every_module_of_lib_rs_has_a_layer_and_every_layer_is_a_module() {
    let root = workspace();
    // drive-runtime: its own modules and the physics' and analysis' re-exported.
    let lib = std::fs::read_to_string(root.join("runtime/src/lib.rs")).unwrap();
    let declared: BTreeSet<&str> = declared_modules(&lib)
        .into_iter()
        .chain(reexported(&lib, "drive_physics"))
        .chain(reexported(&lib, "drive_analysis"))
        .collect();
    let layers: BTreeSet<&str> = RUNTIME_LAYERS.iter().copied().collect();
    assert_eq!(declared, layers, "runtime/src/lib.rs");
    // drive-emu: its own modules (panel, cli) and every one of the runtime's re-exported under
    // its old name, so every `drive_emu::` path still names the same item.
    let lib = std::fs::read_to_string(root.join("emulator/src/lib.rs")).unwrap();
    let own = declared_modules(&lib);
    assert_eq!(
        own,
        BINARY_LAYERS.iter().copied().collect::<BTreeSet<_>>(),
        "emulator/src/lib.rs declares"
    );
    let via_runtime: BTreeSet<&str> = reexported(&lib, "drive_runtime").into_iter().collect();
    assert_eq!(via_runtime, layers, "emulator/src/lib.rs re-exports");
    // The runtime's modules are re-exported by the binary, not copied; the physics' and the
    // analysis' are theirs, in neither.
    let physics = PHYSICS_LAYERS.iter().filter(|m| **m != "params");
    let runtime_modules = RUNTIME_LAYERS.iter();
    for krate in ["runtime", "emulator"] {
        let src = root.join(krate).join("src");
        for m in physics.clone() {
            assert!(
                !src.join(m).exists(),
                "{krate}/src/{m} exists beside the physics crate's"
            );
        }
        for p in ANALYSIS_REEXPORTED {
            assert!(
                !src.join(p).exists(),
                "{krate}/src/{p} exists beside the analysis crate's"
            );
        }
    }
    let src = root.join("emulator/src");
    for m in runtime_modules {
        for p in [src.join(m), src.join(format!("{m}.rs"))] {
            assert!(
                !p.exists(),
                "{} exists beside the runtime crate's",
                p.display()
            );
        }
    }
}

/// The names of a `pub use CRATE::{a, b, c};` line of `lib`.
fn reexported<'a>(lib: &'a str, krate: &str) -> Vec<&'a str> {
    let head = format!("pub use {krate}::{{");
    lib.lines()
        .filter_map(|l| l.trim().strip_prefix(head.as_str()))
        .flat_map(|l| l.trim_end_matches("};").split(','))
        .map(str::trim)
        .filter(|n| !n.is_empty())
        .collect()
}

/// A scratch `src/` tree with the given files.
fn scratch(name: &str, files: &[(&str, &str)]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("layering-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    for (p, text) in files {
        let p = dir.join(p);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
    dir
}

#[test]
fn the_check_catches_an_upward_import_a_cycle_and_an_unplaced_module() {
    // runtime -> master is upward (master -> runtime would be fine): a cycle as soon as master
    // uses the runtime too.
    let dir = scratch(
        "up",
        &[
            ("lib.rs", "pub mod runtime;\npub mod master;\n"),
            ("runtime/mod.rs", "use crate::bus::CanBus;\n"),
            ("runtime/offline.rs", "use crate::master::Master;\n"),
            ("master/mod.rs", "use crate::runtime::Runtime;\n"),
        ],
    );
    let bad = violations(&dir);
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert!(bad[0].contains("runtime/offline.rs") && bad[0].contains("`master`"));
    std::fs::remove_dir_all(&dir).ok();

    // The same, written as a group, and as a `super::` climb to the root.
    let dir = scratch(
        "forms",
        &[
            (
                "runtime/trace.rs",
                "use crate::{bus::CanBus, cli::analyze};\n",
            ),
            ("runtime/mod.rs", "use super::scenario::Scenario;\n"),
            (
                "runtime/pll.rs",
                "use super::Runtime; use super::super::report;\n",
            ),
            ("time.rs", "//! [`crate::bus::CanBus`] is above the clock\n"),
            ("widgets/mod.rs", "\n"),
        ],
    );
    let bad = violations(&dir);
    let has = |file: &str, what: &str| bad.iter().any(|b| b.contains(file) && b.contains(what));
    assert!(has("runtime/trace.rs", "`cli`"), "{bad:?}");
    assert!(has("runtime/mod.rs", "`scenario`"), "{bad:?}");
    assert!(has("runtime/pll.rs", "`report`"), "{bad:?}");
    assert!(has("time.rs", "`bus`"), "{bad:?}");
    assert!(has("widgets/mod.rs", "no place in LAYERS"), "{bad:?}");
    assert_eq!(bad.len(), 5, "{bad:?}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The package names in `package`'s normal and build dependency tree (itself included).
fn normal_tree(package: &str) -> BTreeSet<String> {
    let out = std::process::Command::new(env!("CARGO"))
        .args([
            "tree",
            "-p",
            package,
            "-e",
            "normal,build",
            "--prefix",
            "none",
            "--offline",
        ])
        .current_dir(workspace())
        .output()
        .expect("run cargo tree");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.split(' ').next())
        .map(str::to_string)
        .collect()
}

/// `cargo install --path emulator` builds the binary and what it needs, nothing of the Python
/// module (pyo3, maturin) or of the benchmarks (criterion, divan): those live in their own
/// crate (python/drive-emu) or in dev-dependencies.
#[test]
fn installing_the_binary_builds_no_python_or_benchmark_crates() {
    let crates = normal_tree("drive-emu");
    assert!(
        crates.contains("clap") && crates.contains("drive-protocol"),
        "{crates:?}"
    );
    for name in ["pyo3", "maturin", "criterion", "divan", "proptest"] {
        assert!(!crates.contains(name), "`cargo install` would build {name}");
    }
}
