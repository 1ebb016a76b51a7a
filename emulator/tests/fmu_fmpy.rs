//! The axis FMU under FMPy (tests/python/fmu_fmpy.py, `fmpy` pinned in tests/requirements.txt):
//! validation clean, the limit cycle's frequency equal to `sim`'s for the same input within
//! 2 % over a k_v sweep, none on a healthy axis. Needs python3 with fmpy (CI installs it);
//! missing, the test fails and says so.

mod scratch;

use std::path::PathBuf;
use std::process::Command;

/// The FMU's shared library as cargo built it beside the test's binaries.
fn library() -> PathBuf {
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_drive-emu"));
    let dir = bin.parent().unwrap();
    drive_fmu::package::library_in(dir).unwrap_or_else(|| {
        panic!(
            "libdrive_fmu.so not in {}: cargo build -p drive-fmu",
            dir.display()
        )
    })
}

#[test]
fn fmpy_validates_the_fmu_and_its_limit_cycle_equals_sims() {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/python/fmu_fmpy.py");
    let work = scratch::path("fmu");
    let out = Command::new("python3")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_drive-emu"))
        .arg(library())
        .arg(&work)
        .output()
        .expect("python3");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{text}");
    assert!(out.status.success(), "fmu_fmpy.py failed:\n{text}");
    assert!(text.contains("fmu_fmpy: all checks passed"), "{text}");
}

#[test]
fn fmu_without_its_library_says_how_to_build_it() {
    let out = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(["fmu", "--library", "/nonexistent/libdrive_fmu.so", "-o"])
        .arg(scratch::path("x.fmu"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--library /nonexistent/libdrive_fmu.so"),
        "{err}"
    );
    let out = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(["fmu", "--set", "backlsh_mm=0.1", "-o"])
        .arg(scratch::path("y.fmu"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("did you mean `backlash_mm`"), "{err}");
}
