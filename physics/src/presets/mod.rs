//! Axis presets (TOML data files `emulator/presets/cncN.toml`, embedded in the binary) and the
//! configuration loader: `AxisConfig::from_preset("cnc1")?.with_override("backlash_mm", "0.05")?`.
//!
//! Files carry units in their key names (mm, um, deg, kg, N/um, 1/s, ...); [`AxisConfig::build`]
//! converts to SI. Unknown keys are rejected (serde `deny_unknown_fields`), and a validation
//! pass rejects bad values with the key and the reason ([`ConfigError`]).

use serde::{Deserialize, Serialize};

use crate::axis::AxisParams;
use crate::control::cascade::CascadeParams;

mod build;
pub use build::{
    MAX_ENCODER_NOISE_COUNTS, MAX_KV_PER_S, MAX_OFFSET_GAPS, MAX_SPEED_KP, MIN_SPEED_TI_S,
};

/// The embedded presets, by name.
pub const PRESETS: [(&str, &str); 5] = [
    ("cnc1", include_str!("../../presets/cnc1.toml")),
    ("cnc2", include_str!("../../presets/cnc2.toml")),
    ("cnc3", include_str!("../../presets/cnc3.toml")),
    ("cnc4", include_str!("../../presets/cnc4.toml")),
    ("cnc5", include_str!("../../presets/cnc5.toml")),
];

/// Names of the embedded presets.
pub fn preset_names() -> impl Iterator<Item = &'static str> {
    PRESETS.iter().map(|(n, _)| *n)
}

/// A rejected configuration value: which key, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConfigError {
    pub key: String,
    pub reason: String,
}

impl ConfigError {
    pub fn new(key: &str, reason: impl Into<String>) -> Self {
        ConfigError {
            key: key.to_string(),
            reason: reason.into(),
        }
    }
}

impl std::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "`{}`: {}", self.key, self.reason)
    }
}

impl std::error::Error for ConfigError {}

/// Kind of axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisKind {
    Linear,
    Rotary,
}

/// Mechanism between motor and load.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Transmission {
    /// Ball or hydrostatic screw: `pitch_mm`, `gear_ratio` (motor revs per screw rev).
    LeadScrew,
    /// Rack and (twin) pinion: `pinion_diameter_mm`, `gear_ratio` (motor revs per pinion rev).
    RackPinion,
    /// (Twin) pinion and gear wheel on a table: `gear_ratio` (motor revs per table rev).
    GearWheel,
}

/// One axis as written in a preset file (units in key names). All keys are flat so that
/// `--set key=value` needs no section.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisConfig {
    pub name: String,
    pub description: String,
    pub kind: AxisKind,
    pub transmission: Transmission,
    // ---- kinematics ----
    pub pitch_mm: Option<f64>,
    pub pinion_diameter_mm: Option<f64>,
    pub gear_ratio: f64,
    // ---- load ----
    pub carriage_mass_kg: Option<f64>,
    pub table_inertia_kgm2: Option<f64>,
    #[serde(default)]
    pub vertical: bool,
    #[serde(default)]
    pub counterbalance_fraction: f64,
    // ---- drive train (at the load) ----
    pub backlash_mm: Option<f64>,
    pub backlash_deg: Option<f64>,
    pub stiffness_n_per_um: Option<f64>,
    pub stiffness_nm_per_arcsec: Option<f64>,
    pub damping_ratio: f64,
    /// Two motors and pinions on the one rack or gear wheel, biased against each other by
    /// `preload_pct` (docs/physics.md, "Twin pinion"). The motor keys then describe the pair
    /// as the speed loop sees it (both motors together); each motor is one half.
    #[serde(default)]
    pub twin_pinion: bool,
    /// Electrical preload of a twin pinion: the bias torque per motor in % of each motor's
    /// rated torque (half of `rated_torque_nm`). 0 on a single-contact drive train.
    #[serde(default)]
    pub preload_pct: f64,
    // ---- load friction ----
    pub load_coulomb_friction_n: Option<f64>,
    pub load_coulomb_friction_nm: Option<f64>,
    #[serde(default)]
    pub load_static_friction_ratio: Option<f64>,
    #[serde(default)]
    pub stribeck_velocity_mm_per_s: Option<f64>,
    #[serde(default)]
    pub stribeck_velocity_deg_per_s: Option<f64>,
    pub load_viscous_friction_n_per_m_per_s: Option<f64>,
    pub load_viscous_friction_nm_per_rad_per_s: Option<f64>,
    // ---- motor ----
    pub motor_inertia_kgm2: f64,
    pub torque_constant_nm_per_a: f64,
    pub rated_torque_nm: f64,
    pub rated_current_a: f64,
    pub max_current_a: f64,
    pub max_speed_rpm: f64,
    /// Thermal time constant of the motor's I2t model, s: the winding's heating time
    /// constant that the drive's motor overload monitor uses (continuous current above
    /// `rated_current_a` trips it; see `drive::axis_drive::ERROR_MOTOR_I2T`).
    #[serde(default = "default_motor_thermal_time_constant_s")]
    pub motor_thermal_time_constant_s: f64,
    pub current_bandwidth_hz: f64,
    pub motor_coulomb_friction_nm: f64,
    pub motor_viscous_friction_nm_per_rad_per_s: f64,
    // ---- encoders ----
    pub motor_encoder_counts_per_rev: u64,
    pub direct_encoder_resolution_nm: Option<f64>,
    pub direct_encoder_counts_per_rev: Option<u64>,
    #[serde(default)]
    pub motor_encoder_noise_counts: f64,
    #[serde(default)]
    pub direct_encoder_noise_counts: f64,
    #[serde(default)]
    pub direct_encoder_offset_um: f64,
    #[serde(default)]
    pub direct_encoder_offset_mdeg: f64,
    #[serde(default)]
    pub noise_seed: u64,
    // ---- control ----
    pub kv_per_s: f64,
    pub speed_kp_nms_per_rad: f64,
    pub speed_ti_ms: f64,
    pub speed_filter_ms: f64,
    #[serde(default = "yes")]
    pub position_from_direct: bool,
    pub physics_step_us: f64,
    pub speed_cycle_us: f64,
    pub position_cycle_us: f64,
}

fn yes() -> bool {
    true
}

/// What [`AxisConfig::build`] returns: the SI parameters of axis and cascade.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuiltConfig {
    pub axis: AxisParams,
    pub control: CascadeParams,
    /// Axis unit in m (linear: 1e-3, "mm") or rad (rotary: pi/180, "deg") for display.
    pub display_unit: f64,
    pub display_unit_name: &'static str,
}

fn positive(key: &str, v: f64) -> Result<f64, ConfigError> {
    if !v.is_finite() {
        Err(ConfigError::new(
            key,
            format!("must be a finite number, got {v}"),
        ))
    } else if v <= 0.0 {
        Err(ConfigError::new(key, format!("must be > 0, got {v}")))
    } else {
        Ok(v)
    }
}

// The largest backlash a configuration accepts, kept with the registry (crate::params).
pub use crate::params::{MAX_BACKLASH_M, MAX_BACKLASH_RAD};

/// Largest twin-pinion preload a configuration (and the drive's 0x200E) accepts, % of each
/// motor's rated torque (real drives bias 5-30 %).
pub const MAX_PRELOAD_PCT: f64 = 100.0;

/// `v <= max`, else an error naming the key, the value, the limit and why.
fn at_most(key: &str, v: f64, max: f64, why: &str) -> Result<f64, ConfigError> {
    if v > max {
        Err(ConfigError::new(
            key,
            format!("must be <= {max:?}, got {v:?}: {why}"),
        ))
    } else {
        Ok(v)
    }
}

fn non_negative(key: &str, v: f64) -> Result<f64, ConfigError> {
    if !v.is_finite() {
        Err(ConfigError::new(
            key,
            format!("must be a finite number, got {v}"),
        ))
    } else if v < 0.0 {
        Err(ConfigError::new(key, format!("must be >= 0, got {v}")))
    } else {
        Ok(v)
    }
}

/// Exactly one of two keys, the one that matches the axis kind.
fn pick(
    kind: AxisKind,
    linear: (&str, Option<f64>),
    rotary: (&str, Option<f64>),
) -> Result<f64, ConfigError> {
    let (want, other) = match kind {
        AxisKind::Linear => (linear, rotary),
        AxisKind::Rotary => (rotary, linear),
    };
    if other.1.is_some() {
        return Err(ConfigError::new(
            other.0,
            format!("not valid for a {kind:?} axis (use `{}`)", want.0).to_lowercase(),
        ));
    }
    want.1
        .ok_or_else(|| ConfigError::new(want.0, format!("missing (required for a {kind:?} axis)")))
}

impl AxisConfig {
    /// Parse a preset file's text (unknown keys are rejected) and validate it.
    pub fn from_toml(text: &str) -> Result<Self, ConfigError> {
        let cfg: AxisConfig = toml::from_str(text).map_err(|e| parse_error_in(text, e))?;
        cfg.build()?;
        Ok(cfg)
    }

    /// One of the embedded presets (`cnc1` ... `cnc5`).
    pub fn from_preset(name: &str) -> Result<Self, ConfigError> {
        let text = PRESETS
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name))
            .map(|(_, t)| *t)
            .ok_or_else(|| {
                ConfigError::new(
                    "preset",
                    format!("unknown preset `{name}` (known: cnc1, cnc2, cnc3, cnc4, cnc5)"),
                )
            })?;
        Self::from_toml(text)
    }

    /// Override one key with a value written as in TOML (`0.05`, `true`, `"text"`; a bare word
    /// is taken as a string). The result is re-parsed and validated.
    pub fn with_override(&self, key: &str, value: &str) -> Result<Self, ConfigError> {
        let mut table = toml::Table::try_from(self)
            .map_err(|e| ConfigError::new(key, format!("internal: {e}")))?;
        let parsed: toml::Value = match toml::from_str::<toml::Table>(&format!("v = {value}")) {
            Ok(mut t) => t
                .remove("v")
                .unwrap_or(toml::Value::String(value.to_string())),
            Err(_) => toml::Value::String(value.to_string()),
        };
        // Integer-typed fields accept integers only; let a float like "1e6" through for them.
        table.insert(key.to_string(), parsed);
        let cfg: AxisConfig = table.try_into().map_err(|e: toml::de::Error| {
            // The table was valid but for this key: the error is about it, whatever the
            // message quotes first (a wrong type quotes the value: "invalid type: floating
            // point `1.5`, expected u64").
            ConfigError {
                key: key.to_string(),
                ..parse_error(e)
            }
        })?;
        cfg.build()?;
        Ok(cfg)
    }

    /// Apply several `key=value` overrides in order.
    pub fn with_overrides<'a>(
        &self,
        sets: impl IntoIterator<Item = &'a str>,
    ) -> Result<Self, ConfigError> {
        let mut cfg = self.clone();
        for s in sets {
            let (k, v) = s.split_once('=').ok_or_else(|| {
                ConfigError::new(s, "an override must be written key=value".to_string())
            })?;
            cfg = cfg.with_override(k.trim(), v.trim())?;
        }
        Ok(cfg)
    }
}

impl AxisConfig {
    /// The value this configuration holds for a preset-only registry key (one with no
    /// running form: `live` is `None`), integers as numbers; `None` where the key is unset
    /// (an optional key, or one of the other kind of axis) or is not a preset-only key.
    /// What [`AxisConfig::build`] checks against the registry's range.
    pub fn preset_only_value(&self, key: &str) -> Option<f64> {
        Some(match key {
            "pitch_mm" => self.pitch_mm?,
            "pinion_diameter_mm" => self.pinion_diameter_mm?,
            "gear_ratio" => self.gear_ratio,
            "carriage_mass_kg" => self.carriage_mass_kg?,
            "table_inertia_kgm2" => self.table_inertia_kgm2?,
            "counterbalance_fraction" => self.counterbalance_fraction,
            "damping_ratio" => self.damping_ratio,
            "load_static_friction_ratio" => self.load_static_friction_ratio?,
            "stribeck_velocity_mm_per_s" => self.stribeck_velocity_mm_per_s?,
            "stribeck_velocity_deg_per_s" => self.stribeck_velocity_deg_per_s?,
            "motor_inertia_kgm2" => self.motor_inertia_kgm2,
            "torque_constant_nm_per_a" => self.torque_constant_nm_per_a,
            "rated_torque_nm" => self.rated_torque_nm,
            "rated_current_a" => self.rated_current_a,
            "max_current_a" => self.max_current_a,
            "max_speed_rpm" => self.max_speed_rpm,
            "motor_thermal_time_constant_s" => self.motor_thermal_time_constant_s,
            "current_bandwidth_hz" => self.current_bandwidth_hz,
            "motor_viscous_friction_nm_per_rad_per_s" => {
                self.motor_viscous_friction_nm_per_rad_per_s
            }
            "motor_encoder_counts_per_rev" => self.motor_encoder_counts_per_rev as f64,
            "direct_encoder_resolution_nm" => self.direct_encoder_resolution_nm?,
            "direct_encoder_counts_per_rev" => self.direct_encoder_counts_per_rev? as f64,
            "direct_encoder_noise_counts" => self.direct_encoder_noise_counts,
            "noise_seed" => self.noise_seed as f64,
            "speed_filter_ms" => self.speed_filter_ms,
            "physics_step_us" => self.physics_step_us,
            "speed_cycle_us" => self.speed_cycle_us,
            "position_cycle_us" => self.position_cycle_us,
            _ => return None,
        })
    }
}

fn finite(key: &str, v: f64) -> Result<f64, ConfigError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ConfigError::new(
            key,
            format!("must be a finite number, got {v}"),
        ))
    }
}

/// The motor's I2t thermal time constant when a machine file does not give one, s: a
/// mid-size servo motor's winding (estimate; the presets give their own).
pub const DEFAULT_MOTOR_THERMAL_TIME_CONSTANT_S: f64 = 180.0;

fn default_motor_thermal_time_constant_s() -> f64 {
    DEFAULT_MOTOR_THERMAL_TIME_CONSTANT_S
}

/// The keys of a preset file that are not parameters (what the axis is).
pub const STRUCTURAL_KEYS: [&str; 6] = [
    "name",
    "description",
    "kind",
    "transmission",
    "vertical",
    "twin_pinion",
];

/// Every key a preset file and `--set` take: the registry's preset parameters and
/// [`STRUCTURAL_KEYS`].
pub fn preset_keys() -> impl Iterator<Item = &'static str> {
    crate::params::PARAMS
        .iter()
        .filter(|p| p.preset)
        .flat_map(|p| p.forms().map(|f| f.key))
        .chain(STRUCTURAL_KEYS)
}

/// " (did you mean `x`?)" for an unknown preset key, " (now `x`)" for a moved one, or "".
fn did_you_mean_key(key: &str) -> String {
    match crate::params::moved(key) {
        Some(new) => format!(" (now `{new}`)"),
        None => crate::params::did_you_mean(key, preset_keys()),
    }
}

/// Turn a serde/toml error into a key + reason.
/// [`parse_error`] of a file's `text`: a value of the wrong type or out of its type's range
/// (`noise_seed = -1`: "invalid value: integer `-1`, expected u64") is named by the key
/// written before it on its line, not by the value the message quotes first.
fn parse_error_in(text: &str, e: toml::de::Error) -> ConfigError {
    let key_at = e.span().and_then(|span| {
        let start = text.get(..span.start)?.rfind('\n').map_or(0, |i| i + 1);
        let line = text.get(start..)?.lines().next()?;
        let (key, _) = line.split_once('=')?;
        let key = key.trim().trim_matches('"');
        let plain = !key.is_empty()
            && key
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
        plain.then(|| key.to_string())
    });
    let msg = e.message();
    let named = msg.starts_with("unknown field") || msg.starts_with("missing field");
    match key_at {
        Some(key) if !named => ConfigError {
            key,
            ..parse_error(e)
        },
        _ => parse_error(e),
    }
}

fn parse_error(e: toml::de::Error) -> ConfigError {
    let msg = e.message().to_string();
    // "unknown field `foo`, expected one of ..." / "missing field `bar`"
    let key = msg
        .split('`')
        .nth(1)
        .map(str::to_string)
        .unwrap_or_default();
    let reason = if msg.starts_with("unknown field") {
        format!("unknown key{}", did_you_mean_key(&key))
    } else if msg.starts_with("missing field") {
        "missing".to_string()
    } else {
        msg.lines().next().unwrap_or("").to_string()
    };
    ConfigError { key, reason }
}
