//! Bad preset values are rejected with the key and the reason.

use drive_emu::presets::{AxisConfig, ConfigError};

fn err(key: &str, value: &str) -> ConfigError {
    AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override(key, value)
        .expect_err("must be rejected")
}

#[test]
fn all_presets_load() {
    for name in drive_emu::presets::preset_names() {
        let c = AxisConfig::from_preset(name).unwrap();
        assert_eq!(c.name, name);
    }
}

#[test]
fn negative_mass_is_rejected() {
    let e = err("carriage_mass_kg", "-5");
    assert_eq!(e.key, "carriage_mass_kg");
    // the registry's range for the key, with its unit
    assert!(
        e.reason.contains("must be within 0.1 ..= 1000000 kg"),
        "{e}"
    );
}

#[test]
fn zero_pitch_is_rejected() {
    let e = err("pitch_mm", "0");
    assert_eq!(e.key, "pitch_mm");
    assert!(e.reason.contains("must be within 0.1 ..= 1000 mm"), "{e}");
}

#[test]
fn step_too_coarse_for_stiffness_is_rejected() {
    // 20000 N/um on the CNC1 masses: omega_n ~ 6000 rad/s, so 62.5 us gives omega h ~ 0.37
    // (accepted) and 125 us gives 0.75 (too coarse: the limit is omega h <= 0.5).
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("stiffness_n_per_um", "20000")
        .unwrap();
    let e = cfg
        .with_override("physics_step_us", "125")
        .expect_err("too coarse");
    assert_eq!(e.key, "physics_step_us");
    assert!(e.reason.contains("too coarse"), "{e}");
    // Stiffer still, at the default step.
    let e = err("stiffness_n_per_um", "1e6");
    assert_eq!(e.key, "physics_step_us");
}

#[test]
fn unknown_key_is_rejected() {
    let e = err("backlash_inch", "0.001");
    assert_eq!(e.key, "backlash_inch");
    assert_eq!(e.reason, "unknown key (did you mean `backlash_mm`?)");
    let text = AxisConfig::from_preset("cnc2").unwrap();
    let mut t = toml::to_string(&text).unwrap();
    t.push_str("\nfoo_bar = 3\n");
    let e = AxisConfig::from_toml(&t).unwrap_err();
    assert_eq!(e.key, "foo_bar");
}

#[test]
fn wrong_type_names_the_key() {
    let e = err("kv_per_s", "\"fast\"");
    assert_eq!(e.key, "kv_per_s");
}

#[test]
fn wrong_type_quoting_the_value_still_names_the_key() {
    // serde's message quotes the value first: "invalid type: floating point `1.5`, expected u64"
    let e = err("motor_encoder_counts_per_rev", "1.5");
    assert_eq!(e.key, "motor_encoder_counts_per_rev");
    assert!(e.reason.contains("1.5") && e.reason.contains("u64"), "{e}");
    let e = err("vertical", "0.5");
    assert_eq!(e.key, "vertical");
}

#[test]
fn key_for_the_other_axis_kind_is_rejected() {
    let e = err("backlash_deg", "0.01");
    assert_eq!(e.key, "backlash_deg");
    assert!(e.reason.contains("linear"), "{e}");
}

#[test]
fn other_bad_values() {
    assert_eq!(err("kv_per_s", "0").key, "kv_per_s");
    assert_eq!(err("backlash_mm", "-0.01").key, "backlash_mm");
    assert_eq!(err("damping_ratio", "nan").key, "damping_ratio");
    assert_eq!(err("max_current_a", "1").key, "max_current_a");
    assert_eq!(err("speed_cycle_us", "100").key, "speed_cycle_us");
    assert_eq!(err("position_cycle_us", "1100").key, "position_cycle_us");
    let e = AxisConfig::from_preset("cnc9").unwrap_err();
    assert_eq!(e.key, "preset");
}
