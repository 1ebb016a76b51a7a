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
