//! Every input file goes through one bounded reader, and no accepted value gives a NaN or a
//! run without end (issue 32, findings 5, 6 and 8): a FIFO, a device or a huge file given to
//! --eds, --config, --profile, `extends =`, `eds =` in a machine file, --lss-store, a scenario
//! or `analyze` is refused by name, at once (a FIFO with no writer does not hang the open);
//! `sim` with a value the model cannot resolve errors instead of printing "fundamental none";
//! physics_step_us has a lower bound; `analyze --kv` takes the drive's range only.

use std::path::PathBuf;
use std::process::Command;

/// (success, stderr) of `drive-emu ARGS`.
fn drive_emu(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(args)
        .env_remove("DRIVE_EMU_PANEL_TOKEN")
        .output()
        .expect("run drive-emu");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn refused(args: &[&str], needles: &[&str]) {
    let (ok, err) = drive_emu(args);
    assert!(!ok, "{args:?} was accepted: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: `{n}` missing in:\n{err}");
    }
    assert!(!err.contains("panicked"), "{err}");
}

/// A scratch directory with a FIFO (no writer ever) and a few files.
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Scratch {
        let d =
            std::env::temp_dir().join(format!("drive-emu-bounds-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let c = std::ffi::CString::new(d.join("pipe").to_str().unwrap()).unwrap();
        // SAFETY: a valid C string.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        Scratch(d)
    }
    fn path(&self, name: &str) -> String {
        self.0.join(name).to_str().unwrap().to_string()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn fifos_and_devices_are_refused_by_name_for_every_input_file() {
    let s = Scratch::new("kinds");
    let pipe = s.path("pipe");
    for (bad, kind) in [
        (pipe.as_str(), "a FIFO"),
        ("/dev/zero", "a character device"),
    ] {
        refused(
            &["run", "--iface", "no-such-can9", "--eds", bad],
            &[bad, kind, "not a regular file"],
        );
        refused(
            &["run", "--iface", "no-such-can9", "--config", bad],
            &[bad, kind],
        );
        refused(&["eds", "--from", bad], &[bad, kind]);
        refused(&["scenario", bad], &[kind]);
        refused(&["analyze", bad, "--kv", "30"], &[kind]);
        refused(
            &["run", "--iface", "no-such-can9", "--lss-store", bad],
            &[bad, kind],
        );
    }
    // A profile, its `extends =`, and `eds =` in a machine file, pointing at the FIFO.
    std::os::unix::fs::symlink("/dev/zero", s.0.join("zero.toml")).unwrap();
    let zero = s.path("zero.toml");
    refused(
        &["eds", "--profile", &zero],
        &["zero.toml", "a character device"],
    );
    std::fs::write(
        s.0.join("child.toml"),
        "schema = 1\nname = \"child\"\ndescription = \"x\"\nextends = \"zero.toml\"\n",
    )
    .unwrap();
    refused(
        &["eds", "--profile", &s.path("child.toml")],
        &["a character device"],
    );
    std::fs::write(
        s.0.join("machine.toml"),
        "[[axis]]\nnode_id = 5\npreset = \"cnc1\"\neds = \"pipe\"\n",
    )
    .unwrap();
    refused(
        &[
            "run",
            "--iface",
            "no-such-can9",
            "--config",
            &s.path("machine.toml"),
        ],
        &["pipe", "a FIFO"],
    );
}

#[test]
fn a_huge_configuration_file_is_refused_before_it_is_read() {
    let s = Scratch::new("huge");
    let big = s.0.join("big.toml");
    let f = std::fs::File::create(&big).unwrap();
    // Sparse: 64 MiB on paper, nothing on disk.
    f.set_len(64 << 20).unwrap();
    refused(
        &[
            "run",
            "--iface",
            "no-such-can9",
            "--config",
            big.to_str().unwrap(),
        ],
        &["67108864 bytes, above the cap of 8388608 bytes (8 MiB)"],
    );
    refused(
        &["eds", "--profile", big.to_str().unwrap()],
        &["above the cap"],
    );
}

#[test]
fn a_machine_file_that_is_not_utf8_says_where() {
    let s = Scratch::new("utf8");
    std::fs::write(
        s.0.join("m.toml"),
        b"tick_hz = 1000\n[[axis]]\nnode_id = 5\npreset = \"cnc\xff\"\n",
    )
    .unwrap();
    refused(
        &[
            "run",
            "--iface",
            "no-such-can9",
            "--config",
            &s.path("m.toml"),
        ],
        &["line 4, column 14: not UTF-8"],
    );
}

#[test]
fn a_parameter_the_model_cannot_resolve_is_an_error_not_a_nan() {
    let (ok, err) = drive_emu(&[
        "sim",
        "--preset",
        "cnc1",
        "--velocity",
        "10",
        "--duration",
        "1",
        "--set",
        "motor_inertia_kgm2=1e300",
    ]);
    if ok {
        panic!("sim with motor_inertia_kgm2=1e300 succeeded: {err}");
    }
    assert!(
        err.contains("motor_inertia_kgm2") && !err.contains("panicked"),
        "{err}"
    );
    refused(
        &[
            "sim",
            "--velocity",
            "10",
            "--set",
            "physics_step_us=1e-12",
            "--duration",
            "0.1",
        ],
        &["physics_step_us", "must be within 1 ..= 10000 us"],
    );
}

#[test]
fn analyze_takes_only_the_drives_k_v_range() {
    let s = Scratch::new("kv");
    let csv = s.0.join("t.csv");
    std::fs::write(&csv, "t_s,x\n0,1\n").unwrap();
    for kv in ["3.4e38", "0", "1e-12", "1001"] {
        refused(
            &["analyze", csv.to_str().unwrap(), "--kv", kv],
            &["--kv", "the drive's range 1e-9 .. 1000"],
        );
    }
}
