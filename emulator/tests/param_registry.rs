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
