//! The parameter registry against the preset files: one name per parameter. Every key of
//! every preset is a registry key (or a structural one), every preset parameter of the
//! registry is a preset key, `--set` takes each one under its name and refuses a typo with
//! the name that was meant.

use std::collections::BTreeSet;

use drive_physics::params::{self, PARAMS};
use drive_physics::presets::{preset_keys, preset_names, AxisConfig, AxisKind, STRUCTURAL_KEYS};

fn table(cfg: &AxisConfig) -> toml::Table {
    toml::Table::try_from(cfg).unwrap()
}

#[test]
fn every_preset_key_is_in_the_registry_and_every_registry_preset_key_is_a_field() {
    let mut fields = BTreeSet::new();
    for name in preset_names() {
        let cfg = AxisConfig::from_preset(name).unwrap();
        for k in table(&cfg).keys() {
            assert!(
                preset_keys().any(|p| p == k),
                "preset {name}: `{k}` is not in the registry (drive_physics::params::PARAMS)"
            );
            fields.insert(k.clone());
        }
    }
    // Optional keys serde leaves out of a table when unset: each is a field all the same
    // (a typo'd registry key would be refused by the parser).
    let base = AxisConfig::from_preset("cnc1").unwrap();
    for k in preset_keys() {
        if fields.contains(k) || STRUCTURAL_KEYS.contains(&k) {
            continue;
        }
        let mut t = table(&base);
        t.insert(k.to_string(), toml::Value::Float(1.0));
        let e = t.try_into::<AxisConfig>().err().map(|e| e.to_string());
        assert!(
            !e.as_deref().is_some_and(|e| e.contains("unknown field")),
            "registry key `{k}` is not a preset field: {e:?}"
        );
    }
}

#[test]
fn set_takes_every_live_preset_parameter_by_its_registry_name_on_its_kind_of_axis() {
    for name in preset_names() {
        let cfg = AxisConfig::from_preset(name).unwrap();
        let rotary = cfg.kind == AxisKind::Rotary;
        let t = table(&cfg);
        for p in PARAMS.iter().filter(|p| p.preset && p.live.is_some()) {
            let form = p.form(rotary);
            let v = t
                .get(form.key)
                .unwrap_or_else(|| panic!("{name}: no `{}`", form.key));
            let text = v.to_string();
            let again = cfg
                .with_override(form.key, &text)
                .unwrap_or_else(|e| panic!("{name}: --set {}={text}: {e}", form.key));
            assert_eq!(again, cfg, "{name}: {}", form.key);
            // The other kind's spelling is refused on this axis (a value it would take).
            if let Some(r) = p.rotary {
                let other = if rotary { &p.linear } else { &r };
                assert!(
                    cfg.with_override(other.key, "1").is_err(),
                    "{name}: `{}` taken on a {:?} axis",
                    other.key,
                    cfg.kind
                );
            }
        }
    }
}

#[test]
fn set_with_a_typo_names_the_key_that_was_meant() {
    let cfg = AxisConfig::from_preset("cnc1").unwrap();
    for (typo, meant) in [
        ("backlsh_mm", "backlash_mm"),
        ("kv_pers", "kv_per_s"),
        ("stifness_n_per_um", "stiffness_n_per_um"),
        ("motor_inertia_kg_m2", "motor_inertia_kgm2"),
    ] {
        let e = cfg.with_override(typo, "1").unwrap_err();
        assert_eq!(e.key, typo);
        assert!(
            e.reason.contains(&format!("did you mean `{meant}`")),
            "{typo}: {e}"
        );
    }
    let e = cfg.with_override("colour", "1").unwrap_err();
    assert_eq!(e.reason, "unknown key");
    let e = cfg.with_override("stiffness_N_per_um", "100").unwrap_err();
    assert!(e.reason.contains("now `stiffness_n_per_um`"), "{e}");
}

#[test]
fn registry_keys_and_moved_names_resolve() {
    for k in params::keys() {
        assert!(params::find(k).is_some());
    }
    assert_eq!(params::find("backlash_deg").unwrap().1.unit, "deg");
}
