//! Scenario files: every shipped file parses; every kind of bad input is reported with file,
//! line, key and reason.

use drive_emu::scenario::{self, ProgramStep, ScenarioError};
use std::path::{Path, PathBuf};

fn scenarios_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios")
}

const GOOD: &str = r#"
name = "t"
[machine]
preset = "cnc1"
backlash_mm = 0.02

[[motion]]
step = "enable"
mode = "csp"

[[motion]]
step = "cruise"
velocity_mm_min = 1000.0
accel_mm_s2 = 500.0
duration = "2 s"

[[event]]
id = "w"
at = "1 s"
ramp = "backlash_mm"
to = 0.05
over = "10 min"

[[expect]]
emcy = "0x7300"
after = "w"
within = "50 ms"
"#;

/// Parse `GOOD` with `from` replaced by `to` and return the error.
fn bad(from: &str, to: &str) -> ScenarioError {
    assert!(GOOD.contains(from), "test bug: `{from}` not in GOOD");
    let src = GOOD.replacen(from, to, 1);
    match scenario::parse(&src, Path::new("bad.toml")) {
        Ok(_) => panic!("accepted:\n{src}"),
        Err(e) => e,
    }
}

fn line_of(src: &str, needle: &str) -> usize {
    src.lines().position(|l| l.contains(needle)).unwrap() + 1
}

/// The message names the file, the line, the key and the reason.
fn check(e: &ScenarioError, key: &str, reason: &str) {
    let msg = e.to_string();
    assert!(
        msg.starts_with(&format!("bad.toml:{}:", e.line)) && e.line > 0,
        "{msg}"
    );
    assert!(
        e.key.ends_with(key),
        "key `{}` should end with `{key}`: {msg}",
        e.key
    );
    assert!(msg.contains(&format!("key `{}`", e.key)), "{msg}");
    assert!(msg.contains(reason), "reason `{reason}` missing: {msg}");
}

#[test]
fn the_good_example_parses() {
    let s = scenario::parse(GOOD, Path::new("good.toml")).unwrap();
    assert_eq!(s.name, "t");
    assert_eq!(s.program.len(), 2);
    assert_eq!(s.events.len(), 1);
    assert_eq!(s.expectations.len(), 1);
    assert_eq!(s.machine.configs.len(), 1);
    assert_eq!(s.machine.rotary_units, Some(false));
}

#[test]
fn every_shipped_scenario_parses() {
    let mut n = 0;
    for entry in std::fs::read_dir(scenarios_dir()).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "toml") {
            let s = scenario::load(&p).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(
                p.file_stem().unwrap().to_str().unwrap(),
                s.name,
                "file name and scenario name differ"
            );
            assert!(!s.expectations.is_empty(), "{} expects nothing", s.name);
            n += 1;
        }
    }
    assert!(n >= 7, "{n} scenarios");
}

#[test]
fn wear_ramp_idles_are_fast_forwarded() {
    let s = scenario::load(&scenarios_dir().join("cnc1-wear-ramp.toml")).unwrap();
    let idles = s
        .program
        .iter()
        .filter(|p| matches!(p, ProgramStep::Idle { .. }))
        .count();
    assert_eq!(idles, 13);
    let (steps, skip) = s.master_program(0.1);
    assert_eq!(steps.len(), s.program.len());
    let skipped: u64 = skip.iter().sum();
    assert_eq!(skipped, 13 * (300_000_000 - 100_000));
}

#[test]
fn unknown_key_is_rejected_with_its_line() {
    let e = bad("accel_mm_s2 = 500.0", "acel_mm_s2 = 500.0");
    assert_eq!(e.line, line_of(GOOD, "accel_mm_s2"));
    check(&e, "acel_mm_s2", "unknown field `acel_mm_s2`");
    // Top level and in [machine] too.
    let e = bad("name = \"t\"", "name = \"t\"\ncolour = 1");
    assert_eq!((e.line, e.key.as_str()), (3, "colour"), "{e}");
    let e = bad("backlash_mm = 0.02", "backlash_mmm = 0.02");
    assert_eq!(e.line, line_of(GOOD, "backlash_mm = 0.02"));
    check(&e, "backlash_mmm", "unknown machine key `backlash_mmm`");
}

#[test]
fn bad_time_or_unit_is_rejected() {
    let e = bad("duration = \"2 s\"", "duration = \"2 sec\"");
    assert_eq!(e.line, line_of(GOOD, "duration = \"2 s\""));
    check(&e, "duration", "unknown unit `sec`");
    let e = bad("duration = \"2 s\"", "duration = 2");
    check(&e, "duration", "has no unit");
    let e = bad("over = \"10 min\"", "over = \"-10 min\"");
    assert_eq!(e.line, line_of(GOOD, "over = "));
    check(&e, "over", "negative");
    let e = bad("duration = \"2 s\"", "duration = \"0 s\"");
    check(&e, "duration", "longer than 0");
    // Units family: a rotary key in a linear program.
    let e = bad("velocity_mm_min = 1000.0", "velocity_deg_s = 10.0");
    assert_eq!(e.line, line_of(GOOD, "accel_mm_s2"));
    check(
        &e,
        "accel_mm_s2",
        &format!(
            "mixes linear (mm) units with the rotary (deg) units used at line {}",
            line_of(GOOD, "velocity_mm_min")
        ),
    );
    // A value the preset rejects.
    let e = bad("backlash_mm = 0.02", "backlash_mm = -0.02");
    assert_eq!(e.line, line_of(GOOD, "backlash_mm = 0.02"));
    check(&e, "backlash_mm", "must be >= 0");
}

#[test]
fn unknown_parameter_is_rejected() {
    let e = bad("ramp = \"backlash_mm\"", "ramp = \"backlash_inch\"");
    assert_eq!(e.line, line_of(GOOD, "ramp = "));
    check(&e, "ramp", "unknown parameter `backlash_inch`");
    let e = bad("preset = \"cnc1\"", "preset = \"cnc9\"");
    assert_eq!(e.line, line_of(GOOD, "preset = "));
    check(&e, "preset", "unknown preset `cnc9`");
    let e = bad("to = 0.05", "to = -0.05");
    check(&e, "to", "at least 0");
}

#[test]
fn bad_event_is_rejected() {
    // No action.
    let e = bad("ramp = \"backlash_mm\"\n", "");
    assert_eq!(e.line, line_of(GOOD, "[[event]]"), "{e}");
    check(&e, "set", "an event needs one of: set, ramp");
    // Two triggers.
    let e = bad("at = \"1 s\"", "at = \"1 s\"\non_state = \"fault\"");
    check(&e, "on_state", "takes only one of: at, on_state");
    // A key that does not belong to the action.
    let e = bad("over = \"10 min\"", "over = \"10 min\"\namplitude = 3.0");
    assert_eq!(e.line, line_of(GOOD, "over = ") + 1);
    check(&e, "amplitude", "does not apply to a `ramp` event");
    // Missing required key.
    let e = bad("to = 0.05\n", "");
    check(&e, "to", "needs `to`");
    // Unknown state, bad EMCY code, unknown expectation reference.
    let e = bad("at = \"1 s\"", "on_state = \"running\"");
    check(&e, "on_state", "unknown CiA 402 state `running`");
    let e = bad("emcy = \"0x7300\"", "emcy = \"0x17300\"");
    check(&e, "emcy", "not a 16-bit EMCY code");
    let e = bad("after = \"w\"", "after = \"nope\"");
    check(&e, "after", "no event has id `nope`");
    // Unknown step kind and a key foreign to the step.
    let e = bad("step = \"cruise\"", "step = \"cruse\"");
    check(&e, "step", "unknown variant `cruse`");
    let e = bad("mode = \"csp\"", "mode = \"csp\"\nduration = \"1 s\"");
    check(&e, "duration", "does not apply to a `enable` step");
}

#[test]
fn syntax_errors_and_unreadable_files_are_reported() {
    let e = bad("mode = \"csp\"", "mode = \"csp");
    assert_eq!(e.line, line_of(GOOD, "mode = "));
    let e = scenario::load(Path::new("/nonexistent/x.toml")).unwrap_err();
    assert!(e.to_string().contains("cannot read"), "{e}");
}

#[test]
fn until_before_from_is_rejected() {
    let src = format!("{GOOD}\n[[expect]]\nno_emcy = true\nfrom = \"10 s\"\nuntil = \"5 s\"\n");
    let e = scenario::parse(&src, Path::new("bad.toml")).unwrap_err();
    assert_eq!(e.line, line_of(&src, "until = "));
    check(&e, "until", "`until` (5 s) is before `from` (10 s)");
}

#[test]
fn overlapping_ramps_of_one_parameter_are_rejected() {
    // The GOOD file ramps backlash from 1 s over 10 min; a second ramp at 5 min overlaps.
    let second =
        "\n[[event]]\nat = \"5 min\"\nramp = \"backlash_mm\"\nto = 0.01\nover = \"1 min\"\n";
    let src = format!("{GOOD}{second}");
    let e = scenario::parse(&src, Path::new("bad.toml")).unwrap_err();
    check(&e, "ramp", "overlaps the ramp at line");
    // After the first one ends, it is fine; another parameter may ramp at the same time.
    let later = second.replace("5 min", "11 min");
    scenario::parse(&format!("{GOOD}{later}"), Path::new("ok.toml")).unwrap();
    let other = second
        .replace("backlash_mm", "kv_per_s")
        .replace("0.01", "25.0");
    scenario::parse(&format!("{GOOD}{other}"), Path::new("ok.toml")).unwrap();
}

#[test]
fn absurd_times_are_out_of_range_not_unknown_units() {
    let e = bad("duration = \"2 s\"", "duration = \"1e30 h\"");
    check(&e, "duration", "out of range");
}

#[test]
fn nonsense_preset_overrides_are_rejected_with_key_and_limit() {
    use drive_emu::presets::AxisConfig;
    let cnc1 = AxisConfig::from_preset("cnc1").unwrap();
    for (key, value, reason) in [
        ("backlash_mm", "1e9", "must be <= 10"),
        ("kv_per_s", "1e308", "must be <= 1000"),
        ("kv_per_s", "nan", "finite"),
        ("speed_ti_ms", "0", "must be > 0"),
        ("speed_kp_nms_per_rad", "1e6", "stable discrete speed loop"),
        ("stiffness_n_per_um", "1e-30", "must be >="),
        (
            "carriage_mass_kg",
            "-1",
            "must be within 0.1 ..= 1000000 kg",
        ),
    ] {
        let e = cnc1.with_override(key, value).unwrap_err();
        assert_eq!(e.key, key, "{key}={value}: {e:?}");
        assert!(e.reason.contains(reason), "{key}={value}: {}", e.reason);
    }
}

/// Errors in files that use multi-line values (arrays, multi-line strings, nested tables)
/// point at the line and column of the offending value, name its key, and say why: what
/// `drive-emu scenario` prints as `file:line:column: key `...`: reason`.
#[test]
fn multi_line_files_report_line_column_key_and_reason() {
    let cases = [
        (
            "name = \"a\"\n[machine]\npreset = \"cnc1\"\nbacklash_mm = [\n  0.01,\n  0.02,\n]\n",
            "a.toml",
            (4, 15),
            "machine.backlash_mm",
            "invalid type: sequence",
        ),
        (
            "name = \"b\"\n[machine]\npreset = \"cnc1\"\n[[event]]\nat = \"1 s\"\nset = \"backlash_mm\"\nvalue = \"\"\"\n0.03\n\"\"\"\n",
            "b.toml",
            (7, 9),
            "event[0].value",
            "expected f64",
        ),
        (
            "name = \"f\"\ndescription = \"\"\"\nline one\nline two\n\"\"\"\n[machine]\npreset = \"cnc1\"\nkv_per_s = 1e308\n",
            "f.toml",
            (8, 12),
            "machine.kv_per_s",
            "must be <=",
        ),
        (
            "name = \"g\"\n[machine]\npreset = \"cnc1\"\n[[motion]]\nstep = \"repeat\"\ntimes = 2\nbody = [\n  { step = \"cruise\", velocity_mm_s = 10, duration = \"1 s\" },\n  { step = \"cruise\", velocity_mm_s = 10, duration = \"1 lightyear\" },\n]\n",
            "g.toml",
            (9, 53),
            "duration",
            "unknown unit `lightyear`",
        ),
        (
            "name = \"h\"\n[machine]\npresets = [\n  \"cnc1\",\n  \"cnc9\",\n]\n",
            "h.toml",
            (5, 3),
            "machine.presets",
            "unknown preset `cnc9`",
        ),
    ];
    for (src, file, (line, column), key, why) in cases {
        let e = scenario::parse(src, Path::new(file)).expect_err(file);
        let text = e.to_string();
        assert_eq!((e.line, e.column), (line, column), "{text}");
        assert!(
            text.starts_with(&format!("{file}:{line}:{column}: key `")),
            "{text}"
        );
        assert!(e.key.contains(key) && e.reason.contains(why), "{text}");
    }
}

#[test]
fn the_masters_position_loop_is_checked() {
    let with = |table: &str| format!("name = \"t\"\n{table}\n");
    let ok = GOOD.replacen(
        "name = \"t\"",
        &with("[master.position_loop]\nkv_per_s = 30.0\nencoder = \"motor\""),
        1,
    );
    let s = scenario::parse(&ok, Path::new("ok.toml")).unwrap();
    let p = s.run.master.position_loop.unwrap();
    assert_eq!(p.kv_per_s, 30.0);
    assert_eq!(p.encoder, drive_emu::master::outer_loop::LoopEncoder::Motor);
    // A gain that is no gain, an encoder that is none, a key that does not exist.
    let e = bad(
        "name = \"t\"",
        &with("[master.position_loop]\nkv_per_s = -3.0"),
    );
    check(&e, "master.position_loop.kv_per_s", "more than 0");
    let e = bad(
        "name = \"t\"",
        &with("[master.position_loop]\nkv_per_s = 30.0\nencoder = \"scale\""),
    );
    assert!(e.to_string().contains("scale"), "{e}");
    let e = bad(
        "name = \"t\"",
        &with("[master.position_loop]\nkv_per_s = 30.0\ngain = 2"),
    );
    assert!(e.to_string().contains("unknown field `gain`"), "{e}");
}

/// The shipped EtherCAT scenario: its five faults in order, as the live loop gets them; and
/// every bad EtherCAT event is refused with its line, key and reason.
#[test]
fn ethercat_faults_parse_and_bad_ones_are_refused() {
    use drive_emu::bus::ethercat::EcatFault;
    use drive_emu::scenario::timeline::Action;
    let s = scenario::load(&scenarios_dir().join("ethercat-faults.toml")).unwrap();
    let got: Vec<(EcatFault, Option<u64>)> = s
        .events
        .iter()
        .map(|e| match e.action {
            Action::Ethercat { fault, over_us } => (fault, over_us),
            ref a => panic!("not an EtherCAT fault: {a:?}"),
        })
        .collect();
    assert_eq!(
        got,
        [
            (
                EcatFault::Lost {
                    frames: 20,
                    share: 0.0
                },
                None
            ),
            (EcatFault::BadWkc { share: 1.0 }, Some(50_000)),
            (EcatFault::Late { hold_us: 20_000 }, Some(50_000)),
            (EcatFault::LinkDown, Some(50_000)),
            (EcatFault::OutOfOp { al_code: 0x001A }, None),
        ]
    );
    // live on CAN or offline: refused with the event's line and why
    let e = drive_emu::scenario::live::check_bus(&s, "can").unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains(&format!("line {}:", s.events[0].line)) && msg.contains("run --ethercat"),
        "{msg}"
    );
    let ramp = "ramp = \"backlash_mm\"\nto = 0.05\nover = \"10 min\"";
    for (to, key, reason) in [
        ("ethercat = \"lost\"", "ethercat", "either `frames`"),
        (
            "ethercat = \"lost\"\nframes = 3\nshare = 0.5",
            "ethercat",
            "not both",
        ),
        ("ethercat = \"lost\"\nframes = 0", "frames", "0 frames"),
        (
            "ethercat = \"corrupt\"",
            "ethercat",
            "corrupted EtherCAT frames take either",
        ),
        ("ethercat = \"corrupt\"\nframes = 0", "frames", "0 frames"),
        (
            "ethercat = \"corrupt\"\nhold = \"1 s\"",
            "hold",
            "corrupted EtherCAT frames",
        ),
        (
            "ethercat = \"lost\"\nframes = 2\nover = \"1 s\"",
            "over",
            "`over` goes with `share`",
        ),
        ("ethercat = \"late\"", "hold", "needs `hold`"),
        ("ethercat = \"late\"\nhold = \"2 s\"", "hold", "at most 1 s"),
        (
            "ethercat = \"out_of_op\"\nal_code = \"0x0000\"",
            "al_code",
            "means no error",
        ),
        (
            "ethercat = \"link_down\"\nhold = \"1 ms\"",
            "hold",
            "does not apply to an EtherCAT link down",
        ),
        (
            "ethercat = \"unplug\"",
            "ethercat",
            "unknown variant `unplug`",
        ),
        (
            "ethercat = \"restore\"\ncan = \"restore\"",
            "ethercat",
            "takes only one of",
        ),
    ] {
        let e = bad(ramp, to);
        check(&e, key, reason);
    }
}
