//! Issue 29: the Python module's wheel links only what it uses. Its crate (`drive-emu-python`)
//! depends on the runtime crate (`drive-runtime`, decision 0019), not on the binary's
//! (`drive-emu`: the command line and the live panel), and without SocketCAN
//! (`default-features = false`), so no HTTP server (axum, tokio, hyper), no argument parser
//! (clap) and no SocketCAN is in its dependency tree; and it calls the typed API
//! (`drive_runtime::api`), never the command line (no clap, no argv).
//!
//! `cargo tree --locked --offline`: the lock file as committed, nothing fetched (CI has built
//! the workspace before the tests run, so every package is in cargo's cache).

use std::path::Path;
use std::process::Command;

/// The crates of the panel's HTTP server, of SocketCAN, of the command line, and the binary's
/// crate itself.
const NOT_IN_THE_WHEEL: &[&str] = &[
    "axum",
    "tokio",
    "hyper",
    "hyper-util",
    "socketcan",
    "clap",
    "drive-emu",
];

fn workspace() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap()
}

/// The names of the packages in `package`'s normal dependency tree (build and dev
/// dependencies left out: they are not linked into the wheel), with the features `args` give.
fn normal_tree(package: &str, args: &[&str]) -> Vec<String> {
    let cargo = option_env!("CARGO").unwrap_or("cargo");
    let out = Command::new(cargo)
        .current_dir(workspace())
        .args([
            "tree",
            "--locked",
            "--offline",
            "-e",
            "normal",
            "--prefix",
            "none",
        ])
        .args(["--format", "{p}", "-p", package])
        .args(args)
        .output()
        .expect("cargo runs");
    assert!(
        out.status.success(),
        "cargo tree -p {package}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .collect()
}

#[test]
fn the_python_module_links_no_panel_server_and_no_socketcan() {
    let wheel = normal_tree("drive-emu-python", &[]);
    // the tree is the module's: the runtime crate and PyO3 are in it
    for needed in ["drive-runtime", "pyo3", "numpy", "drive-protocol"] {
        assert!(
            wheel.iter().any(|p| p == needed),
            "{needed} missing: {wheel:?}"
        );
    }
    for name in NOT_IN_THE_WHEEL {
        assert!(
            !wheel.iter().any(|p| p == name),
            "{name} is in the Python module's dependency tree"
        );
    }
    // The same query sees them where they are: the binary's crate with its default features.
    let full = normal_tree("drive-emu", &[]);
    for name in NOT_IN_THE_WHEEL {
        assert!(
            full.iter().any(|p| p == name),
            "{name} not found in drive-emu's own tree: the query would miss it"
        );
    }
}

/// The module's source builds requests of the typed API and parses no command line (nor names
/// the binary's crate, `drive_emu::`); its manifest names no clap and no drive-emu.
fn python_source_is_free_of_the_cli() -> bool {
    let dir = workspace().join("python/drive-emu");
    let src = std::fs::read_to_string(dir.join("src/lib.rs")).unwrap();
    for cli in ["drive_emu::", "clap::", "argv", "try_get_matches"] {
        assert!(
            !src.contains(cli),
            "python/drive-emu/src/lib.rs uses `{cli}`"
        );
    }
    assert!(
        src.contains("drive_runtime::api"),
        "the module calls the typed API"
    );
    let manifest = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
    assert!(
        !manifest.lines().any(|l| l.trim_start().starts_with("clap")),
        "python/drive-emu/Cargo.toml depends on clap"
    );
    assert!(
        !manifest
            .lines()
            .any(|l| l.trim_start().starts_with("drive-emu ")
                || l.trim_start().starts_with("drive-emu=")),
        "python/drive-emu/Cargo.toml depends on the binary's crate"
    );
    true
}

#[test]
fn the_python_module_calls_the_typed_api_not_the_command_line() {
    assert!(python_source_is_free_of_the_cli());
}
