//! Scenario input is bounded like every other input (issue 23): the file's size and the
//! counts of events, expectations and motion steps have stated caps, each refused with
//! file, line, key, the cap and the count; and the nonsense an outside audit found accepted
//! (an event after the end, a velocity beyond the axis, a load profile above what the tick
//! can show, a CAN delay of days) is refused with file, line, key and reason.

mod scratch;

use drive_emu::presets::{AxisConfig, AxisKind};
use drive_emu::scenario::{
    self, ScenarioError, MAX_EVENTS, MAX_EXPECTATIONS, MAX_FILE_BYTES, MAX_PROGRAM_STEPS,
};
use proptest::prelude::*;
use std::path::{Path, PathBuf};

/// A valid file: enable, then a 2 s cruise.
const HEAD: &str = r#"name = "t"
[machine]
preset = "cnc1"

[[motion]]
step = "enable"
mode = "csp"

[[motion]]
step = "cruise"
velocity_mm_min = 600.0
accel_mm_s2 = 500.0
duration = "2 s"
"#;

fn parse(src: &str) -> Result<scenario::Scenario, ScenarioError> {
    scenario::parse(src, Path::new("bounds.toml"))
}

fn refused(src: &str) -> ScenarioError {
    match parse(src) {
        Ok(_) => panic!("accepted:\n{}", &src[..src.len().min(2000)]),
        Err(e) => e,
    }
}

/// 1-based line of the `n`-th (0-based) line equal to `text`.
fn nth_line(src: &str, text: &str, n: usize) -> usize {
    src.lines()
        .enumerate()
        .filter(|(_, l)| *l == text)
        .nth(n)
        .map(|(i, _)| i + 1)
        .unwrap()
}

/// The message names the file, the line, the key and says `reason`.
fn says(e: &ScenarioError, key: &str, reasons: &[&str]) {
    let msg = e.to_string();
    assert!(e.line > 0, "{msg}");
    assert!(
        msg.starts_with(&format!("bounds.toml:{}:", e.line)),
        "{msg}"
    );
    assert!(msg.contains(&format!("key `{key}`")), "key `{key}`: {msg}");
    for r in reasons {
        assert!(msg.contains(r), "`{r}` missing: {msg}");
    }
}

fn temp(name: &str) -> PathBuf {
    scratch::path(name)
}

#[test]
fn events_beyond_the_cap_are_refused_with_the_cap_and_the_count() {
    let event = "[[event]]\nat = \"1 s\"\ncan = \"restore\"\n";
    let at_cap = format!("{HEAD}{}", event.repeat(MAX_EVENTS));
    assert_eq!(parse(&at_cap).unwrap().events.len(), MAX_EVENTS);
    let over = format!("{at_cap}{event}{event}");
    let e = refused(&over);
    says(
        &e,
        "event",
        &[
            &format!("{} events", MAX_EVENTS + 2),
            &format!("cap of {MAX_EVENTS}"),
            &format!("number {}", MAX_EVENTS + 1),
        ],
    );
    // at the first event beyond the cap (its table's first line)
    let header = nth_line(&over, "[[event]]", MAX_EVENTS);
    assert!(
        (header..=header + 1).contains(&e.line),
        "line {} for a header at {header}",
        e.line
    );
}

#[test]
fn expectations_beyond_the_cap_are_refused_with_the_cap_and_the_count() {
    let expect = "[[expect]]\nno_emcy = true\n";
    let at_cap = format!("{HEAD}{}", expect.repeat(MAX_EXPECTATIONS));
    assert_eq!(parse(&at_cap).unwrap().expectations.len(), MAX_EXPECTATIONS);
    let e = refused(&format!("{at_cap}{expect}"));
    says(
        &e,
        "expect",
        &[
            &format!("{} expectations", MAX_EXPECTATIONS + 1),
            &format!("cap of {MAX_EXPECTATIONS}"),
        ],
    );
}

#[test]
fn a_program_beyond_the_step_cap_is_refused_even_in_several_repeats() {
    // Each repeat alone is under the cap; together they are not.
    let times = MAX_PROGRAM_STEPS * 3 / 5;
    let repeat = format!(
        "[[motion]]\nstep = \"repeat\"\ntimes = {times}\nbody = [{{ step = \"dwell\", duration = \"1 ms\" }}]\n"
    );
    parse(&format!("{HEAD}{repeat}")).unwrap();
    let src = format!("{HEAD}{repeat}{repeat}");
    let e = refused(&src);
    says(
        &e,
        "motion[3].times",
        &[
            &format!("{} steps", 2 + 2 * times),
            &format!("cap of {MAX_PROGRAM_STEPS}"),
        ],
    );
}

#[test]
fn a_file_beyond_the_size_cap_is_refused_before_it_is_read() {
    // A sparse file of the cap plus one byte: refused from its size, nothing parsed.
    let p = temp("huge.toml");
    let f = std::fs::File::create(&p).unwrap();
    f.set_len(MAX_FILE_BYTES + 1).unwrap();
    drop(f);
    let e = scenario::load(&p).unwrap_err();
    let msg = e.to_string();
    assert!(msg.starts_with(&p.display().to_string()), "{msg}");
    for needle in [
        &format!("{} bytes", MAX_FILE_BYTES + 1),
        &format!(
            "cap of {MAX_FILE_BYTES} bytes ({} MiB)",
            MAX_FILE_BYTES >> 20
        ),
        &format!("{MAX_EVENTS} events"),
    ] {
        assert!(msg.contains(needle.as_str()), "`{needle}` missing: {msg}");
    }
    std::fs::remove_file(&p).unwrap();
    // An endless input: a device, refused before a byte is read (the bounded reader takes
    // regular files only).
    let e = scenario::load(Path::new("/dev/zero")).unwrap_err();
    assert!(
        e.to_string()
            .contains("character device, not a regular file"),
        "{e}"
    );
    // A file at the cap is read (and then parsed: here, not TOML).
    let p = temp("at-cap.toml");
    let mut text = HEAD.to_string();
    text.push('#');
    text.push_str(&"x".repeat(MAX_FILE_BYTES as usize - text.len() - 1));
    text.push('\n');
    assert_eq!(text.len() as u64, MAX_FILE_BYTES);
    std::fs::write(&p, &text).unwrap();
    scenario::load(&p).unwrap();
    std::fs::remove_file(&p).unwrap();
}

#[test]
fn an_event_at_or_after_the_end_is_refused() {
    let src = format!(
        "duration = \"2 s\"\n{HEAD}\n[[event]]\nat = \"5 s\"\nset = \"backlash_mm\"\nvalue = 0.01\n"
    );
    let e = refused(&src);
    says(
        &e,
        "event[0].at",
        &[
            "5 s is at or after the scenario's end",
            "duration = 2 s",
            "never fire",
        ],
    );
    assert_eq!(e.line, nth_line(&src, "at = \"5 s\"", 0));
    // at the end itself: the run stops there, before firing it
    refused(&src.replace("at = \"5 s\"", "at = \"2 s\""));
    parse(&src.replace("at = \"5 s\"", "at = \"1999 ms\"")).unwrap();
    // a condition delayed beyond the end
    let src = format!(
        "duration = \"2 s\"\n{HEAD}\n[[event]]\non_state = \"operation_enabled\"\nafter = \"3 s\"\ncan = \"sync_loss\"\n"
    );
    says(&refused(&src), "event[0].after", &["a delay of 3 s"]);
}

/// The axis's top speed in mm/min (linear) or deg/min (rotary), from the preset's motor
/// speed and transmission: what a motion program may ask for.
fn top_speed_per_min(preset: &str) -> f64 {
    let c = AxisConfig::from_preset(preset).unwrap();
    let load_rev_per_min = c.max_speed_rpm / c.gear_ratio;
    match c.kind {
        AxisKind::Rotary => load_rev_per_min * 360.0,
        AxisKind::Linear => match (c.pitch_mm, c.pinion_diameter_mm) {
            (Some(pitch), _) => load_rev_per_min * pitch,
            (None, Some(d)) => load_rev_per_min * std::f64::consts::PI * d,
            _ => unreachable!("a linear axis has a screw or a pinion"),
        },
    }
}

#[test]
fn a_velocity_beyond_the_axis_top_speed_is_refused_on_every_preset() {
    for preset in ["cnc1", "cnc2", "cnc3", "cnc4", "cnc5"] {
        let top = top_speed_per_min(preset);
        let rotary = AxisConfig::from_preset(preset).unwrap().kind == AxisKind::Rotary;
        let (key, accel) = if rotary {
            ("velocity_deg_min", "accel_deg_s2")
        } else {
            ("velocity_mm_min", "accel_mm_s2")
        };
        let with = |v: f64| {
            HEAD.replace("preset = \"cnc1\"", &format!("preset = \"{preset}\""))
                .replace("velocity_mm_min = 600.0", &format!("{key} = {v:e}"))
                .replace("accel_mm_s2", accel)
        };
        parse(&with(top * 0.999)).unwrap_or_else(|e| panic!("{preset}: {e}"));
        for v in [top * 1.001, -top * 1.001, 1e300] {
            let e = refused(&with(v));
            says(
                &e,
                &format!("motion[1].{key}"),
                &[&format!("top speed of the {preset} axis"), "max_speed_rpm"],
            );
        }
    }
}

#[test]
fn a_load_profile_above_half_the_tick_rate_is_refused() {
    let profile = |f: &str| {
        format!(
            "{HEAD}\n[[event]]\nat = \"0 s\"\nprofile = \"load_force_n\"\namplitude = 100.0\nfrequency_hz = {f}\n"
        )
    };
    for f in ["1e12", "500.0"] {
        says(
            &refused(&profile(f)),
            "event[0].frequency_hz",
            &["once per tick (1000 us, 1000 Hz)", "below 500 Hz"],
        );
    }
    parse(&profile("499.0")).unwrap();
    // a shorter tick raises the limit
    let fine = profile("1999.0").replace("[machine]", "[master]\ntick_us = 250\n[machine]");
    parse(&fine).unwrap();
    says(
        &refused(&fine.replace("1999.0", "2000.0")),
        "event[0].frequency_hz",
        &["below 2000 Hz"],
    );
}

#[test]
fn a_can_delay_beyond_the_cap_is_refused() {
    let delay = |t: u64| {
        format!("{HEAD}\n[[event]]\nat = \"0 s\"\ncan = \"delay\"\nshare = 0.5\nticks = {t}\n")
    };
    parse(&delay(1000)).unwrap();
    for t in [1001, 1_000_000_000] {
        says(
            &refused(&delay(t)),
            "event[0].ticks",
            &["at most 1000 ticks", "use `can = \"drop\"`"],
        );
    }
}

/// A timed ramp on one of two parameters: (parameter, start s, length s).
fn ramp_text((param, start, len): (usize, u32, u32)) -> String {
    let key = ["backlash_mm", "kv_per_s"][param];
    let to = ["0.01", "25.0"][param];
    format!("[[event]]\nat = \"{start} s\"\nramp = \"{key}\"\nto = {to}\nover = \"{len} s\"\n")
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, .. ProptestConfig::default() })]

    /// The ramp-overlap check (O(log n) per ramp) refuses a file exactly when two timed ramps
    /// of one parameter overlap, as checking every pair does.
    #[test]
    fn overlapping_ramps_are_found_as_by_checking_every_pair(
        ramps in proptest::collection::vec((0usize..2, 0u32..40, 0u32..8), 0..12)
    ) {
        let overlap = ramps.iter().enumerate().any(|(i, a)| {
            ramps[..i].iter().any(|b| {
                a.0 == b.0 && b.1 < a.1 + a.2 && a.1 < b.1 + b.2
            })
        });
        let src = format!(
            "{HEAD}\n{}",
            ramps.iter().map(|&r| ramp_text(r)).collect::<String>()
        );
        match parse(&src) {
            Ok(_) => prop_assert!(!overlap, "overlapping ramps accepted:\n{}", src),
            Err(e) => {
                prop_assert!(overlap, "refused: {}", e);
                prop_assert!(e.to_string().contains("overlaps the ramp at line"), "{}", e);
            }
        }
    }
}
