//! `drive-emu sweep`'s grid is counted before any case is built (issue 32): a grid above
//! `MAX_SWEEP_CASES` (the one cap the Python module's `sweep` uses too) is refused with the
//! count and how it is made, under an address-space limit the built grid would need many
//! times over (5 x 1000 x 1000 cases, each with its machine: gigabytes).

use drive_emu::study::MAX_SWEEP_CASES;

#[test]
fn a_sweep_grid_above_the_cap_is_refused_before_it_is_built() {
    let bin = env!("CARGO_BIN_EXE_drive-emu");
    let out_dir = std::env::temp_dir().join(format!("sweep-grid-{}", std::process::id()));
    // 512 MiB of address space: the program starts in far less; the grid needs gigabytes.
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg(r#"ulimit -v 524288 && exec "$0" "$@""#)
        .arg(bin)
        .args(["sweep", "--preset", "all", "--kv-per-s", "1..100:1000"])
        .args([
            "--backlash-mm",
            "0..0.1:1000",
            "--backlash-deg",
            "0..0.1:1000",
            "--out",
        ])
        .arg(&out_dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    // 2: an argument (cli::exit).
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("5000000 cases (5 presets x 1000 k_v x 1000 backlash)")
            && err.contains(&format!("at most {MAX_SWEEP_CASES}")),
        "{err}"
    );
    assert!(!out_dir.exists(), "nothing written");
    assert_eq!(MAX_SWEEP_CASES, 1_000_000);
}
