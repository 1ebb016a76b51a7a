//! The parameter registry (`drive_physics::params`) walked through every place a running
//! axis' parameter is named: scenario files, the panel's controls, the drive's 0x2000..
//! objects. One spelling per parameter and kind of axis everywhere; a typo gets the name
//! that was meant. (Preset files and `--set`: physics/tests/registry.rs.)

use std::collections::BTreeSet;

use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::drive::node::{node, NodeOptions};
use drive_emu::drive::objects::DEFAULT_BASE;
use drive_emu::panel::control::Controls;
use drive_emu::panel::{PanelAxis, PanelSetup};
use drive_emu::presets::{preset_names, AxisConfig, AxisKind};
use drive_emu::scenario::units::ParamName;
use drive_physics::params::PARAMS;

/// The registry's live spellings for a kind of axis.
fn live_keys(rotary: bool) -> BTreeSet<&'static str> {
    PARAMS
        .iter()
        .filter(|p| p.live.is_some())
        .map(|p| p.form(rotary).key)
        .collect()
}

#[derive(serde::Deserialize)]
struct Event {
    #[allow(dead_code)]
    set: ParamName,
}

fn parse_key(key: &str) -> Result<ParamName, String> {
    toml::from_str::<Event>(&format!("set = \"{key}\""))
        .map(|e| e.set)
        .map_err(|e| e.to_string())
}

#[test]
fn scenario_files_take_every_live_parameter_by_its_registry_name() {
    for rotary in [false, true] {
        for key in live_keys(rotary) {
            let p = parse_key(key).unwrap_or_else(|e| panic!("{key}: {e}"));
            assert_eq!(p.0.key, key);
            let (spec, form) = drive_physics::params::find(key).unwrap();
            assert_eq!(Some(p.0.param), spec.live, "{key}");
            assert_eq!(p.0.scale, form.si_per_unit, "{key}");
        }
    }
}

#[test]
fn scenario_typos_and_moved_names_say_what_was_meant() {
    let e = parse_key("backlsh_mm").unwrap_err();
    assert!(e.contains("did you mean `backlash_mm`"), "{e}");
    let e = parse_key("external_load_N").unwrap_err();
    assert!(e.contains("now `load_force_n`"), "{e}");
    let e = parse_key("colour").unwrap_err();
    assert!(!e.contains("did you mean"), "{e}");
}

#[test]
fn the_drive_objects_carry_the_registry_names_on_either_kind_of_axis() {
    for name in preset_names() {
        let cfg = AxisConfig::from_preset(name).unwrap();
        let rotary = cfg.kind == AxisKind::Rotary;
        let mut drive = AxisDrive::from_config(&cfg).unwrap();
        let n = node(&mut drive, 5).unwrap();
        for p in PARAMS {
            let Some(off) = p.object_offset else { continue };
            let (_, entry) = n
                .od()
                .get(DEFAULT_BASE + off, 0)
                .unwrap_or_else(|| panic!("{name}: no object 0x{:04X}", DEFAULT_BASE + off));
            assert_eq!(
                entry.name,
                p.form(rotary).key,
                "{name}: 0x{:04X}",
                DEFAULT_BASE + off
            );
        }
    }
    // Built through the options as `run` builds it, too.
    let _ = NodeOptions::new(5);
}

#[test]
fn the_panel_offers_every_live_parameter_under_its_registry_name_and_unit() {
    for name in preset_names() {
        let cfg = AxisConfig::from_preset(name).unwrap();
        let rotary = cfg.kind == AxisKind::Rotary;
        let setup = PanelSetup {
            bus: drive_emu::panel::PanelBus::Can,
            axes: vec![PanelAxis {
                node_id: 5,
                preset: name.to_string(),
                config: cfg,
                overrides: vec![],
            }],
            iface: None,
            tick_hz: 1000,
            lockstep: false,
            master_id: 1,
            json_stdout: false,
        };
        let controls = Controls::new(&setup).unwrap();
        let offered: BTreeSet<&str> = controls.params.iter().map(|c| c.key).collect();
        assert_eq!(offered, live_keys(rotary), "{name}");
        for c in &controls.params {
            let (_, form) = drive_physics::params::find(c.key).unwrap();
            assert_eq!(c.unit, form.unit, "{name}: {}", c.key);
            assert!(c.min <= c.initial && c.initial <= c.max, "{name}: {c:?}");
        }
    }
}

/// A REAL32 expedited SDO download of `value` to `index` sub 0: `Ok` or the abort code.
fn sdo_write_real32(
    n: &mut drive_protocol::Node,
    drive: &mut AxisDrive,
    index: u16,
    value: f32,
) -> Result<(), u32> {
    use drive_protocol::CanFrame;
    let [lo, hi] = index.to_le_bytes();
    let [a, b, c, d] = value.to_le_bytes();
    n.handle(
        &CanFrame::new(0x605, &[0x23, lo, hi, 0, a, b, c, d]),
        0,
        drive,
    );
    let mut answer = None;
    while let Some(f) = n.pop_tx() {
        if f.id == 0x585 {
            answer = Some(f.data);
        }
    }
    let data = answer.expect("an SDO answer");
    match data[0] {
        0x60 => Ok(()),
        0x80 => Err(u32::from_le_bytes(data[4..8].try_into().unwrap())),
        c => panic!("SDO answer 0x{c:02X}"),
    }
}

/// A one-event scenario on `preset`: `set key = value` at 0 s, then a short CSP cruise.
fn one_set_scenario(preset: &str, key: &str, value: f64) -> String {
    format!(
        "name = \"range\"\n[machine]\npreset = \"{preset}\"\n\n\
         [[motion]]\nstep = \"enable\"\nmode = \"csp\"\n\n\
         [[motion]]\nstep = \"dwell\"\nduration = \"0.2 s\"\n\n\
         [[event]]\nat = \"0 s\"\nset = \"{key}\"\nvalue = {value:e}\n"
    )
}

/// `v` as `--set KEY=` and the preset files write it: a boolean for the one key whose file
/// form is one (`position_from_direct`: 0 or 1 on the drive's object, false or true in a file).
fn set_text(key: &str, v: f64) -> String {
    match (key, v) {
        ("position_from_direct", 0.0) => "false".into(),
        ("position_from_direct", 1.0) => "true".into(),
        _ => format!("{v:e}"),
    }
}

/// A value just outside `bound` on the side away from the range (`above`: past a maximum).
fn just_outside(bound: f64, above: bool) -> f64 {
    let d = (bound.abs() * 1e-3).max(1e-6);
    if above {
        bound + d
    } else {
        bound - d
    }
}

/// Issue 32: the registry's live parameters walked through every place a value enters, on
/// every preset (linear, rotary, twin pinion). The range is the drive's own (what 0x2000..
/// accepts, `param_bounds`, with the registry's lower bound): a value just outside it is
/// refused with a clear message at the drive's SDO object, the panel's control, a scenario
/// file (before the run starts, not when the event fires) and `--set` / the preset and
/// machine files (`AxisConfig::with_override`, what `sim`, `run`, `sweep` and Python's
/// `sim`/`sweep` take); a value at either end is taken everywhere.
#[test]
fn a_value_just_outside_a_live_parameters_range_is_refused_at_every_entry() {
    use drive_emu::scenario::inject::{check_ranges, param_bounds};
    use drive_emu::scenario::units::param_key;
    use std::path::Path;
    let mut checked = 0;
    let mut fails: Vec<String> = vec![];
    for name in preset_names() {
        let cfg = AxisConfig::from_preset(name).unwrap();
        let rotary = cfg.kind == AxisKind::Rotary;
        let setup = PanelSetup {
            bus: drive_emu::panel::PanelBus::Can,
            axes: vec![PanelAxis {
                node_id: 5,
                preset: name.to_string(),
                config: cfg.clone(),
                overrides: vec![],
            }],
            iface: None,
            tick_hz: 1000,
            lockstep: false,
            master_id: 1,
            json_stdout: false,
        };
        let controls = Controls::new(&setup).unwrap();
        for p in PARAMS.iter().filter(|p| p.live.is_some()) {
            let form = p.form(rotary);
            let key = param_key(form.key).unwrap();
            let mut drive = AxisDrive::from_config(&cfg).unwrap();
            let (lo, hi) = param_bounds(&mut drive, key)
                .unwrap_or_else(|| panic!("{name}: {}: no range", form.key));
            let mut n = node(&mut drive, 5).unwrap();
            n.boot(0);
            while n.pop_tx().is_some() {}
            let index = DEFAULT_BASE + p.object_offset.unwrap();
            let mut outside = vec![];
            if lo.is_finite() {
                outside.push(just_outside(lo, false));
            }
            // An upper bound past anything a REAL32 or a file holds is no bound to test.
            if hi < 1e30 {
                outside.push(just_outside(hi, true));
            }
            let ends: Vec<f64> = [lo, hi].into_iter().filter(|v| v.abs() < 1e30).collect();
            let what = |v: f64| format!("{name}: {} = {v:e} (range {lo:e} .. {hi:e})", form.key);
            let scenario = |v: f64| {
                drive_emu::scenario::parse(
                    &one_set_scenario(name, form.key, v),
                    Path::new("range.toml"),
                )
                .map_err(|e| e.to_string())
                .and_then(|s| check_ranges(&s, &cfg).map_err(|e| e.to_string()))
            };
            for &v in &outside {
                checked += 1;
                // The drive's object.
                match sdo_write_real32(&mut n, &mut drive, index, v as f32) {
                    Ok(()) => fails.push(format!("{}: SDO took it", what(v))),
                    Err(e) if !(0x0609_0030..=0x0609_0032).contains(&e) => {
                        fails.push(format!("{}: SDO abort 0x{e:08X}", what(v)))
                    }
                    Err(_) => {}
                }
                // The panel's control.
                match controls.check(&serde_json::json!({"set": form.key, "value": v})) {
                    Ok(_) => fails.push(format!("{}: the panel took it", what(v))),
                    Err(r) if !r.reason.contains(form.key) => {
                        fails.push(format!("{}: panel: {r:?}", what(v)))
                    }
                    Err(_) => {}
                }
                // A scenario file: refused before the run, at the event's line.
                match scenario(v) {
                    Ok(()) => fails.push(format!("{}: the scenario took it", what(v))),
                    Err(m) if !(m.starts_with("range.toml:") && m.contains(form.key)) => {
                        fails.push(format!("{}: scenario: {m}", what(v)))
                    }
                    Err(_) => {}
                }
                // --set, the preset and machine files.
                if p.preset {
                    match cfg.with_override(form.key, &set_text(form.key, v)) {
                        Ok(_) => fails.push(format!("{}: --set took it", what(v))),
                        Err(e) if e.key != form.key => {
                            fails.push(format!("{}: --set: {e}", what(v)))
                        }
                        Err(_) => {}
                    }
                }
            }
            for &v in &ends {
                // A REAL32 may round an end outwards: the nearest REAL32 inside.
                let mut w = v as f32;
                if f64::from(w) < lo || f64::from(w) > hi {
                    w = if v == lo { w.next_up() } else { w.next_down() };
                }
                if let Err(e) = sdo_write_real32(&mut n, &mut drive, index, w) {
                    fails.push(format!("{}: SDO abort 0x{e:08X} at the end", what(v)));
                }
                if let Err(e) = controls.check(&serde_json::json!({"set": form.key, "value": v})) {
                    fails.push(format!("{}: panel refused the end: {e:?}", what(v)));
                }
                if let Err(e) = scenario(v) {
                    fails.push(format!("{}: scenario refused the end: {e}", what(v)));
                }
                if p.preset {
                    if let Err(e) = cfg.with_override(form.key, &set_text(form.key, v)) {
                        fails.push(format!("{}: --set refused the end: {e}", what(v)));
                    }
                }
            }
        }
    }
    assert!(
        fails.is_empty(),
        "{} of {checked}:\n{}",
        fails.len(),
        fails.join("\n")
    );
    assert!(checked > 100, "{checked} values checked");
}

/// Issue 32: a live preset parameter at either end of its range gives a short `sim` run (what
/// `sim --set` and Python's `sim` run) that ends with finite samples: no accepted value gives
/// NaN or a run without end. A linear axis and a rotary twin-pinion table.
#[test]
fn a_live_parameter_at_either_end_of_its_range_gives_a_finite_short_sim() {
    use clap::Parser;
    use drive_emu::cli::sim::{simulate, SimArgs};
    use drive_emu::scenario::inject::param_bounds;
    use drive_emu::scenario::units::param_key;
    #[derive(Parser)]
    struct Wrap {
        #[command(flatten)]
        sim: SimArgs,
    }
    let stop = std::sync::atomic::AtomicBool::new(false);
    let mut runs = 0;
    for name in ["cnc1", "cnc3"] {
        let cfg = AxisConfig::from_preset(name).unwrap();
        let rotary = cfg.kind == AxisKind::Rotary;
        for p in PARAMS.iter().filter(|p| p.live.is_some() && p.preset) {
            let form = p.form(rotary);
            let mut drive = AxisDrive::from_config(&cfg).unwrap();
            let (lo, hi) = param_bounds(&mut drive, param_key(form.key).unwrap()).unwrap();
            for v in [lo, hi].into_iter().filter(|v| v.abs() < 1e30) {
                let set = format!("{}={}", form.key, set_text(form.key, v));
                let args =
                    Wrap::parse_from(["sim", "--velocity", "5", "--preset", name, "--set", &set])
                        .sim;
                let args = SimArgs {
                    duration: 0.3,
                    ..args
                };
                let r = simulate(&args, false, &stop)
                    .unwrap_or_else(|e| panic!("{name}: sim --set {set}: {e:#}"));
                assert!(
                    r.trace.motor_velocity_rpm.iter().all(|x| x.is_finite()),
                    "{name}: sim --set {set}: a non-finite sample"
                );
                runs += 1;
            }
        }
    }
    assert!(runs >= 30, "{runs} runs");
}

/// `v` as a preset file and `--set` write it: an integer for the integer-typed keys.
fn preset_text(key: &str, v: f64) -> String {
    let integer = matches!(
        key,
        "motor_encoder_counts_per_rev" | "direct_encoder_counts_per_rev" | "noise_seed"
    );
    if integer {
        format!("{}", v.round() as i128)
    } else {
        format!("{v:e}")
    }
}

/// An integer key's value just outside an integer bound is the next integer.
fn preset_just_outside(key: &str, bound: f64, above: bool) -> f64 {
    match (preset_text(key, 1.5).as_str(), above) {
        ("2", true) => bound + 1.0,
        ("2", false) => bound - 1.0,
        _ => just_outside(bound, above),
    }
}

/// The axes whose kinds and transmissions between them spell every preset key: a lead
/// screw (cnc1), a rotary gear-wheel table (cnc3), a rack and pinion (cnc4); and, for the
/// keys no preset sets (Stribeck friction: a static friction above Coulomb's needs its
/// velocity), cnc1 and cnc3 with it set, walked for those keys only.
const KINDS: [(&str, &[&str]); 5] = [
    ("cnc1", &[]),
    ("cnc3", &[]),
    ("cnc4", &[]),
    (
        "cnc1",
        &[
            "stribeck_velocity_mm_per_s=5",
            "load_static_friction_ratio=1.5",
        ],
    ),
    (
        "cnc3",
        &[
            "stribeck_velocity_deg_per_s=0.5",
            "load_static_friction_ratio=1.5",
        ],
    ),
];

/// One walked axis: its preset, the `--set` it starts from, and the `--set` of one value.
type Taken = (&'static str, &'static [&'static str], String);

/// Issue 32: every preset-only parameter (a key of the preset and machine files and `--set`
/// with no running form) has a registry range, and it is checked where the key enters: a value
/// just outside is refused naming the key by `--set` (`AxisConfig::with_override`: `sim`,
/// `run`, `sweep`, Python) and by a preset file (`AxisConfig::from_toml`); each end is taken,
/// or refused by another check that names the key (a cross-check with other keys, e.g. the
/// physics step against the stiffness), never by the range itself. Returns the configurations
/// taken at an end.
fn preset_only_ends_accepted() -> Vec<Taken> {
    let mut fails: Vec<String> = vec![];
    let mut taken = vec![];
    let mut keys = BTreeSet::new();
    for (name, sets) in KINDS {
        let cfg = AxisConfig::from_preset(name)
            .unwrap()
            .with_overrides(sets.iter().copied())
            .unwrap();
        let rotary = cfg.kind == AxisKind::Rotary;
        let table = toml::Table::try_from(&cfg).unwrap();
        for p in PARAMS.iter().filter(|p| p.preset && p.live.is_none()) {
            let form = p.form(rotary);
            let only_sets = !sets.is_empty();
            let in_sets = sets.iter().any(|s| s.split('=').next() == Some(form.key));
            if !form.applies_to(rotary)
                || cfg.preset_only_value(form.key).is_none()
                || (only_sets && !in_sets)
            {
                continue;
            }
            keys.insert(form.key);
            let (lo, hi) = (form.min, form.max);
            let what = |v: f64| format!("{name}: {} = {v:e} (range {lo:e} ..= {hi:e})", form.key);
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                fails.push(format!("{name}: {}: no registry range", form.key));
                continue;
            }
            let file = |text: &str| {
                let mut t = table.clone();
                let v: toml::Value = toml::from_str::<toml::Table>(&format!("v = {text}"))
                    .unwrap()
                    .remove("v")
                    .unwrap();
                t.insert(form.key.to_string(), v);
                AxisConfig::from_toml(&toml::to_string(&t).unwrap())
            };
            // u64::MAX as a float is above every u64: no bound a file can cross.
            let outside = [
                Some(preset_just_outside(form.key, lo, false)),
                (hi < u64::MAX as f64).then(|| preset_just_outside(form.key, hi, true)),
            ];
            for v in outside.into_iter().flatten() {
                let text = preset_text(form.key, v);
                match cfg.with_override(form.key, &text) {
                    Ok(_) => fails.push(format!("{}: --set took it", what(v))),
                    Err(e) if e.key != form.key => fails.push(format!("{}: --set: {e}", what(v))),
                    Err(_) => {}
                }
                match file(&text) {
                    Ok(_) => fails.push(format!("{}: a preset file took it", what(v))),
                    Err(e) if e.key != form.key => fails.push(format!("{}: file: {e}", what(v))),
                    Err(_) => {}
                }
            }
            for v in [lo, hi] {
                let text = preset_text(form.key, v);
                match cfg.with_override(form.key, &text) {
                    Ok(_) => taken.push((name, sets, format!("{}={text}", form.key))),
                    Err(e) if e.key == form.key && e.reason.contains("must be within") => {
                        fails.push(format!("{}: its own range refused the end: {e}", what(v)))
                    }
                    // Refused by a cross-check with the preset's other keys.
                    Err(_) => {}
                }
            }
        }
    }
    // Every preset-only key of the registry was walked on some preset.
    for p in PARAMS.iter().filter(|p| p.preset && p.live.is_none()) {
        for f in p.forms() {
            if !keys.contains(f.key) {
                fails.push(format!("{}: on none of {KINDS:?}", f.key));
            }
        }
    }
    assert!(fails.is_empty(), "{}:\n{}", fails.len(), fails.join("\n"));
    taken
}

/// Issue 32: each preset-only parameter at either end of its registry range, where the preset
/// takes it, gives a short `sim` run that ends with finite samples (no NaN, no divergence, no
/// run without end: the physics step is at least 1 µs).
#[test]
fn a_preset_only_parameter_is_refused_outside_its_range_and_runs_finite_at_either_end() {
    use clap::Parser;
    use drive_emu::cli::sim::{simulate, SimArgs};
    #[derive(Parser)]
    struct Wrap {
        #[command(flatten)]
        sim: SimArgs,
    }
    let taken = preset_only_ends_accepted();
    let stop = std::sync::atomic::AtomicBool::new(false);
    let mut fails = vec![];
    for (name, sets, set) in &taken {
        let mut argv = vec!["sim", "--velocity", "1", "--preset", name];
        for s in sets.iter().copied().chain([set.as_str()]) {
            argv.extend(["--set", s]);
        }
        let args = Wrap::parse_from(argv).sim;
        let args = SimArgs {
            duration: 0.05,
            ..args
        };
        match simulate(&args, false, &stop) {
            Ok(r) => {
                if !r.trace.motor_velocity_rpm.iter().all(|x| x.is_finite()) {
                    fails.push(format!("{name}: sim --set {set}: a non-finite sample"));
                }
            }
            Err(e) => fails.push(format!("{name}: sim --set {set}: {e:#}")),
        }
    }
    assert!(
        fails.is_empty(),
        "{} of {}:\n{}",
        fails.len(),
        taken.len(),
        fails.join("\n")
    );
    assert!(taken.len() >= 40, "{} runs", taken.len());
}

/// Issue 32: demo's flags that set a registry parameter (`--backlash-mm` / `--backlash-deg`,
/// and the moved `--backlash`) are checked against the registry's range of the preset's
/// spelling, on a linear and a rotary preset: a value just outside (and NaN) is a usage error
/// (exit status 2, as `--set` gives) naming the flag the user wrote, the range with its unit
/// and the key; each end is taken; the other kind of axis' flag is refused naming the right one.
#[test]
fn demo_flags_are_checked_against_the_registry_ranges() {
    use clap::Parser;
    use drive_emu::cli::demo::{validate, DemoArgs, REGISTRY_FLAGS};
    use drive_emu::cli::exit::{code_of, USAGE};
    use drive_emu::cli::param_flags::flag_of;
    #[derive(Parser)]
    struct Wrap {
        #[command(flatten)]
        demo: DemoArgs,
    }
    let mut fails = vec![];
    let mut checked = 0;
    for name in ["cnc1", "cnc3"] {
        let rotary = AxisConfig::from_preset(name).unwrap().kind == AxisKind::Rotary;
        for &(param, old, _) in REGISTRY_FLAGS {
            let spec = drive_physics::params::of_live(param);
            let form = spec.form(rotary);
            let (lo, hi) = (form.min, form.max);
            assert!(
                lo.is_finite() && hi.is_finite(),
                "{}: no registry range",
                form.key
            );
            let range = format!("{lo} ..= {hi} {}", form.unit);
            let args = |flag: &str, v: f64| {
                Wrap::try_parse_from(["demo", "--preset", name, flag, &v.to_string()])
                    .unwrap_or_else(|e| panic!("{name}: {flag} {v}: {e}"))
                    .demo
            };
            for flag in [flag_of(form.key), old.to_string()] {
                for v in [just_outside(lo, false), just_outside(hi, true), f64::NAN] {
                    checked += 1;
                    match validate(&args(&flag, v)) {
                        Ok(()) => fails.push(format!("{name}: {flag} {v} taken")),
                        Err(e) => {
                            let m = format!("{e:#}");
                            if !(m.starts_with(&format!("{flag} "))
                                && m.contains(&range)
                                && m.contains(form.key))
                            {
                                fails.push(format!("{name}: {flag} {v}: `{range}` or key: {m}"));
                            }
                            if code_of(&e) != USAGE {
                                fails
                                    .push(format!("{name}: {flag} {v}: exit {}: {m}", code_of(&e)));
                            }
                        }
                    }
                }
                for v in [lo, hi] {
                    let a = args(&flag, v);
                    if let Err(e) = validate(&a) {
                        fails.push(format!("{name}: {flag} {v} (an end) refused: {e:#}"));
                    }
                    assert_eq!(a.worn_backlash(), v, "{name}: {flag}");
                }
            }
            // The other kind of axis' spelling, even in range, names this axis' flag.
            let other = flag_of(spec.form(!rotary).key);
            match validate(&args(&other, 0.01)) {
                Ok(()) => fails.push(format!("{name}: {other} taken on this kind of axis")),
                Err(e) => {
                    let m = format!("{e:#}");
                    if !m.starts_with(&other) || !m.contains(&flag_of(form.key)) {
                        fails.push(format!("{name}: {other}: {m}"));
                    }
                    if code_of(&e) != USAGE {
                        fails.push(format!("{name}: {other}: exit {}", code_of(&e)));
                    }
                }
            }
        }
    }
    assert!(fails.is_empty(), "{}:\n{}", fails.len(), fails.join("\n"));
    assert!(checked >= 12);
}

/// The long flags and their aliases of a parsed command's arguments.
fn flags_of(cmd: &clap::Command) -> Vec<(String, Vec<String>, bool)> {
    cmd.get_arguments()
        .filter_map(|a| {
            let long = a.get_long()?;
            let aliases = a
                .get_all_aliases()
                .unwrap_or_default()
                .into_iter()
                .map(|s| format!("--{s}"))
                .collect();
            Some((format!("--{long}"), aliases, a.is_hide_set()))
        })
        .collect()
}

/// Issue 29: the sweep's grid axes and demo's parameter flags are the registry's keys. For
/// each of their parameters and each spelling of it (`kv_per_s`; `backlash_mm` on a linear,
/// `backlash_deg` on a rotary axis) the flag `--kv-per-s` is shown in the help and
/// `--kv_per_s` is taken too, both giving that axis its value; the flag that moved (`--kv`,
/// `--backlash`) is hidden, still taken, and warns "`--kv` is now `--kv-per-s`"; no other
/// shown flag of the two commands names a registry parameter some other way; a typo gets
/// the flag that was meant.
#[test]
fn sweep_grid_axes_and_demo_flags_are_spelled_as_the_registry() {
    use clap::{CommandFactory, Parser};
    use drive_emu::cli::demo::{DemoArgs, REGISTRY_FLAGS};
    use drive_emu::cli::param_flags::flag_of;
    use drive_emu::cli::sweep::{SweepArgs, GRID_PARAMS};
    #[derive(Parser)]
    struct Sweep {
        #[command(flatten)]
        a: SweepArgs,
    }
    #[derive(Parser)]
    struct Demo {
        #[command(flatten)]
        a: DemoArgs,
    }
    let mut fails: Vec<String> = vec![];
    let mut walked = 0;
    let sweep_flags = flags_of(&Sweep::command());
    let demo_flags = flags_of(&Demo::command());
    let demo_params: Vec<_> = REGISTRY_FLAGS.iter().map(|&(p, old, _)| (p, old)).collect();
    for (what, flags, params) in [
        ("sweep", &sweep_flags, GRID_PARAMS.to_vec()),
        ("demo", &demo_flags, demo_params),
    ] {
        for (param, old) in params {
            let spec = drive_physics::params::of_live(param);
            for rotary in [false, true] {
                let key = spec.form(rotary).key;
                let flag = flag_of(key);
                let dashed = format!("--{key}");
                walked += 1;
                match flags.iter().find(|(l, ..)| *l == flag) {
                    None => fails.push(format!("{what}: no {flag} for `{key}`")),
                    Some((_, aliases, hidden)) => {
                        if *hidden {
                            fails.push(format!("{what}: {flag} hidden"));
                        }
                        if flag != dashed && !aliases.contains(&dashed) {
                            fails.push(format!("{what}: {dashed} not taken for {flag}"));
                        }
                    }
                }
                // Both spellings land on the axis, with no warning; the moved one warns.
                for written in [flag.as_str(), dashed.as_str(), old] {
                    let argv = [what, "--preset", if rotary { "cnc3" } else { "cnc1" }];
                    let value = "0.0123";
                    let (got, warnings) = match what {
                        "sweep" => {
                            let a =
                                Sweep::try_parse_from(argv.iter().copied().chain([written, value]))
                                    .map(|w| w.a);
                            match a {
                                Ok(a) => (
                                    a.grid_text(param, rotary).map(|(_, t)| t.to_string()),
                                    a.moved_flags(),
                                ),
                                Err(e) => (Some(format!("clap: {e}")), vec![]),
                            }
                        }
                        _ => {
                            let a =
                                Demo::try_parse_from(argv.iter().copied().chain([written, value]))
                                    .map(|w| w.a);
                            match a {
                                Ok(a) => (Some(a.worn_backlash().to_string()), a.moved_flags()),
                                Err(e) => (Some(format!("clap: {e}")), vec![]),
                            }
                        }
                    };
                    if got.as_deref() != Some(value) {
                        fails.push(format!("{what} {written} {value}: the axis got {got:?}"));
                    }
                    let warned = warnings
                        .iter()
                        .any(|w| w.contains(&format!("`{old}` is now `")));
                    if (written == old) != warned {
                        fails.push(format!("{what} {written}: warnings {warnings:?}"));
                    }
                }
                // A typo: clap names the registry's flag.
                let typo = format!("--{}{key}", &key[..1]).replace('_', "-");
                let argv = [what, typo.as_str(), "1"];
                let e = match what {
                    "sweep" => Sweep::try_parse_from(argv).err(),
                    _ => Demo::try_parse_from(argv).err(),
                };
                match e {
                    Some(e) if e.to_string().contains(&format!("'{flag}'")) => {}
                    other => fails.push(format!("{what} {typo}: {other:?}")),
                }
            }
            // The moved flag: hidden, still there.
            match flags.iter().find(|(l, ..)| l == old) {
                Some((_, _, true)) => {}
                other => fails.push(format!("{what}: moved {old}: {other:?}")),
            }
        }
        // No shown flag spells a registry parameter but its own key: a flag that is a
        // registry parameter's name without its unit (`--kv`, `--backlash`) is hidden.
        for (l, _, hidden) in flags.iter() {
            let bare = l.trim_start_matches("--").replace('-', "_");
            let prefix_of_key = drive_physics::params::keys()
                .any(|k| k != bare && k.starts_with(&format!("{bare}_")));
            if prefix_of_key && drive_physics::params::find(&bare).is_none() && !hidden {
                fails.push(format!(
                    "{what}: {l} shown, a registry key without its unit"
                ));
            }
        }
    }
    assert!(fails.is_empty(), "{}:\n{}", fails.len(), fails.join("\n"));
    assert!(walked >= 6, "{walked}");
}

/// `drive-emu ARGS`: its exit status and stderr.
fn drive_emu(args: &[&str]) -> (Option<i32>, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Issues 29 and 32 through the binary: a sweep grid value outside its parameter's range is
/// refused before any case runs (exit status 2, nothing written), naming the flag the user
/// wrote, the registry key and its range; a moved flag (`--kv`, `--backlash`) is still taken
/// and says its new name on stderr, one line, first.
#[test]
fn the_binary_refuses_grid_values_out_of_range_and_warns_on_moved_flags() {
    let out = std::env::temp_dir().join(format!("param-registry-sweep-{}", std::process::id()));
    let out_s = out.to_str().unwrap();
    let cases: [(&[&str], &[&str], Option<&str>); 4] = [
        (
            &["sweep", "--preset", "cnc1", "--kv-per-s", "2000"],
            &["--kv-per-s 2000 on cnc1", "kv_per_s", "1000"],
            None,
        ),
        (
            &["sweep", "--preset", "cnc3", "--backlash-deg", "0.01,6"],
            &["--backlash-deg 6 on cnc3", "backlash_deg", "must be <= 5.7"],
            None,
        ),
        (
            &["sweep", "--preset", "cnc1", "--kv", "2000"],
            &["--kv 2000 on cnc1", "kv_per_s"],
            Some("drive-emu: warning: `--kv` is now `--kv-per-s`"),
        ),
        (
            &["demo", "--backlash", "1e9"],
            &[
                "--backlash 1000000000: must be within 0 ..= 10 mm",
                "backlash_mm",
            ],
            Some("drive-emu: warning: `--backlash` is now `--backlash-mm`"),
        ),
    ];
    for (args, needles, warning) in cases {
        let mut argv = args.to_vec();
        if args[0] == "sweep" {
            argv.extend(["--out", out_s]);
        }
        let (code, err) = drive_emu(&argv);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        for n in needles {
            assert!(err.contains(n), "{args:?}: `{n}` missing in: {err}");
        }
        let first = err.lines().next().unwrap_or_default();
        match warning {
            Some(w) => assert!(first.starts_with(w), "{args:?}: first line: {err}"),
            None => assert!(!err.contains("warning"), "{args:?}: {err}"),
        }
        assert!(!out.exists(), "{args:?}: the sweep wrote {out_s}");
    }
}
