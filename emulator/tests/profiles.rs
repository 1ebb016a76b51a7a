//! Quirk profiles (vendor behaviour) on the command line (docs/quirks.md section 4): `drive-emu
//! profiles` lists and checks them; `run --profile / --quirk / --no-quirk` refuse a bad one
//! before touching the bus, with file, line, key and reason, and say what is on; with `--eds`
//! the EDS is authoritative for the identity; `eds --profile` writes the defaults the switches
//! change.

use std::path::PathBuf;
use std::process::{Command, Output};

fn drive_emu(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(args)
        .output()
        .expect("run drive-emu")
}

/// Run drive-emu with `args`; it must fail, and its stderr must contain every `needle`.
fn refused(args: &[&str], needles: &[&str]) -> String {
    let out = drive_emu(args);
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(
        !out.status.success(),
        "{args:?} was accepted; stdout:\n{}",
        String::from_utf8_lossy(&out.stdout)
    );
    for n in needles {
        assert!(stderr.contains(n), "{args:?}: `{n}` missing in:\n{stderr}");
    }
    stderr
}

fn vendor_eds(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/eds/vendors")
        .join(name)
        .display()
        .to_string()
}

fn temp(name: &str, text: &str) -> String {
    let dir = std::env::temp_dir().join(format!("drive-emu-profiles-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

/// A run on an interface that does not exist: everything before the bus happens (profile
/// resolved, start-up message), then the bus fails.
const NO_BUS: [&str; 7] = [
    "run",
    "--iface",
    "nonexistent0",
    "--rt-priority",
    "0",
    "--no-mlock",
    "--ready",
];

#[test]
fn profiles_lists_every_profile_and_switch_and_shows_one() {
    let out = drive_emu(&["profiles"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for p in [
        "strict",
        "nanotec-pd4c",
        "engel-hbi",
        "jvl-mis",
        "faulhaber-mc5004",
        "maxon-epos4",
        "copley-accelnet",
        "roboteq-fbl2360",
        "technosoft-ipos",
        "delta-asda-a2",
        "isel-imd20",
    ] {
        assert!(text.contains(p), "{p} missing:\n{text}");
    }
    // every switch and parameter, with its doc, from the one description
    for s in drive_protocol::Quirks::SWITCHES {
        assert!(text.contains(s.name), "{} missing:\n{text}", s.name);
        assert!(
            text.contains(s.doc.trim()),
            "{}'s doc missing:\n{text}",
            s.name
        );
        for p in s.params {
            assert!(
                text.contains(p.doc.trim()),
                "{}.{}'s doc missing",
                s.name,
                p.name
            );
        }
    }
    let out = drive_emu(&["profiles", "technosoft-ipos"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        text.contains("on  controlword_min_hold (hold_us = 1000)")
            && text.contains("off sync_watchdog"),
        "{text}"
    );
}

#[test]
fn a_bad_profile_file_is_refused_with_file_line_key_and_reason() {
    let p = temp(
        "mine.toml",
        "schema = 1\nname = \"mine\"\ndescription = \"my drive\"\nextends = \"strict\"\n\n\
         [quirks.sdo_response_delay]\ndelay_ms = 70000\n",
    );
    refused(
        &["profiles", &p],
        &[&format!(
            "{p}:7: quirks.sdo_response_delay.delay_ms: 70000 out of range 0..=5000 (ms)"
        )],
    );
    let mut args = NO_BUS.to_vec();
    args.extend(["--profile", &p]);
    let err = refused(&args, &["mine.toml:7: quirks.sdo_response_delay.delay_ms"]);
    assert!(
        !err.contains("cannot open CAN interface"),
        "before the bus:\n{err}"
    );
    // an unknown key (a misspelt parameter, a misspelt switch): file, line, key, nearest name
    let p = temp(
        "typo.toml",
        "schema = 1\nname = \"typo\"\ndescription = \"d\"\nextends = \"strict\"\n\n\
         [quirks.sdo_response_delay]\ndelay = 5\n",
    );
    refused(
        &["profiles", &p],
        &[&format!(
            "{p}:7: quirks.sdo_response_delay.delay: unknown parameter of sdo_response_delay \
             `delay` (did you mean `delay_ms`?"
        )],
    );
    let p = temp(
        "typo2.toml",
        "schema = 1\nname = \"typo2\"\ndescription = \"d\"\n\n[quirks.enable_require_mode]\n",
    );
    refused(
        &["profiles", &p],
        &[&format!(
            "{p}:5: quirks.enable_require_mode: unknown switch `enable_require_mode` (did you \
             mean `enable_requires_mode`?"
        )],
    );
    let p = temp(
        "other.toml",
        "schema = 1\nname = \"mine\"\ndescription = \"d\"\n",
    );
    refused(
        &["profiles", &p],
        &["other.toml:2: name: \"mine\" is not the file's stem \"other\""],
    );
}

#[test]
fn run_refuses_bad_switches_and_profiles_before_the_bus() {
    let run = |extra: &[&str], needles: &[&str]| {
        let mut args = NO_BUS.to_vec();
        args.extend(extra);
        let err = refused(&args, needles);
        assert!(
            !err.contains("cannot open CAN interface"),
            "before the bus:\n{err}"
        );
    };
    run(
        &["--quirk", "sdo_response_delay.delay_ms=70000"],
        &["--quirk sdo_response_delay.delay_ms=70000: quirks.sdo_response_delay.delay_ms: 70000 out of range 0..=5000 (ms)"],
    );
    run(
        &["--quirk", "sdo_reponse_delay"],
        &[
            "unknown switch `sdo_reponse_delay`",
            "did you mean `sdo_response_delay`?",
        ],
    );
    run(
        &["--quirk", "homing_method_zero.zero=skip"],
        &["quirks.homing_method_zero.zero: \"skip\" is not one of \"store\", \"ignore\", \"refuse\""],
    );
    run(
        &["--quirk", "unmappable_objects"],
        &["quirks.unmappable_objects: parameter `objects` is required"],
    );
    run(
        &[
            "--no-quirk",
            "enable_requires_mode",
            "--quirk",
            "enable_requires_mode",
        ],
        &["on or off?"],
    );
    run(
        &["--profile", "maxon"],
        &["unknown profile `maxon`", "maxon-epos4"],
    );
    let m = temp("machine.toml", "[[axis]]\nnode_id = 5\npreset = \"cnc1\"\n");
    run(
        &["--config", &m, "--profile", "maxon-epos4"],
        &[
            "--profile / --quirk / --no-quirk with --config",
            "per [[axis]]",
        ],
    );
    let m = temp(
        "machine2.toml",
        "[[axis]]\nnode_id = 5\npreset = \"cnc1\"\nprofile = \"maxon-epos4\"\n\
         quirks = { sdo_response_delay = { late_every = -1 } }\n",
    );
    run(
        &["--config", &m],
        &["machine2.toml axis 1:5: quirks.sdo_response_delay.late_every: -1 out of range"],
    );
}

#[test]
fn with_an_eds_the_identity_must_agree_and_switches_need_their_objects() {
    let technosoft = vendor_eds("technosoft-ipos.eds");
    let mut args = NO_BUS.to_vec();
    args.extend(["--eds", &technosoft, "--profile", "copley-accelnet"]);
    let err = refused(
        &args,
        &[
            "profile copley-accelnet: [identity] vendor_id = 0x000000AB",
            "says 0x1018:1 = 0x000001A3",
            "the EDS is authoritative",
        ],
    );
    assert!(!err.contains("cannot open CAN interface"), "{err}");
    let faulhaber = vendor_eds("faulhaber-mcdc300x-co.eds");
    let mut args = NO_BUS.to_vec();
    args.extend(["--eds", &faulhaber, "--profile", "delta-asda-a2"]);
    refused(
        &args,
        &["switch sync_watchdog needs object 0x60C2 sub 1, which the object dictionary (the EDS) does not have"],
    );
    // the profile's switches with the vendor's EDS: resolved, said, and only the bus is missing
    let mut args = NO_BUS.to_vec();
    args.extend(["--eds", &technosoft, "--profile", "technosoft-ipos"]);
    refused(
        &args,
        &[
            "node 5: profile technosoft-ipos: controlword_min_hold (hold_us = 1000)",
            "cannot open CAN interface nonexistent0",
        ],
    );
}

#[test]
fn run_says_which_profile_and_switches_are_on() {
    let mut args = NO_BUS.to_vec();
    args.extend([
        "--profile",
        "nanotec-pd4c",
        "--quirk",
        "sdo_response_delay.delay_ms=30",
        "--no-quirk",
        "enable_requires_mode",
    ]);
    refused(
        &args,
        &[
            "node 5: profile nanotec-pd4c: bootup_then_heartbeat (first_heartbeat_after_bootup_us = \
             100, heartbeat_ms_default = 100), sdo_response_delay (delay_ms = 30, late_delay_ms = \
             0, late_every = 0)",
            "0 ms after reset communication",
        ],
    );
    let mut args = NO_BUS.to_vec();
    args.extend(["--quirk", "tpdo_rtr_unsupported"]);
    refused(
        &args,
        &["node 5: profile none: tpdo_rtr_unsupported (abort_code = 0x06090030)"],
    );
}

#[test]
fn the_eds_of_a_profile_has_the_defaults_its_switches_change() {
    let section = |eds: &str, name: &str| -> String {
        let start = eds.find(&format!("[{name}]")).expect(name);
        let rest = &eds[start..];
        let end = rest[1..].find("\n[").map_or(rest.len(), |e| e + 1);
        rest[..end].to_string()
    };
    let eds = |args: &[&str]| {
        let out = drive_emu(args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap()
    };
    let roboteq = eds(&["eds", "--node", "5", "--profile", "roboteq-fbl2360"]);
    for k in 1..=4 {
        let s = section(&roboteq, &format!("18{:02X}sub1", k - 1));
        let want = format!("DefaultValue=$NODEID+0x{:08X}", 0x4000_0080 + 0x100 * k);
        assert!(s.contains(&want), "{want} missing:\n{s}");
    }
    let strict = eds(&["eds", "--node", "5"]);
    assert!(section(&strict, "1800sub1").contains("DefaultValue=$NODEID+0x180"));
    let nanotec = eds(&["eds", "--node", "5", "--profile", "nanotec-pd4c"]);
    assert!(
        section(&nanotec, "1017").contains("DefaultValue=0x64"),
        "{}",
        section(&nanotec, "1017")
    );
    let copley = eds(&["eds", "--node", "5", "--profile", "copley-accelnet"]);
    assert!(
        section(&copley, "1018sub1").contains("DefaultValue=0xAB")
            || section(&copley, "1018sub1").contains("DefaultValue=0x000000AB"),
        "{}",
        section(&copley, "1018sub1")
    );
}
