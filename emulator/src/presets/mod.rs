//! Axis presets (TOML data files `emulator/presets/cncN.toml`, embedded in the binary) and the
//! configuration loader: `AxisConfig::from_preset("cnc1")?.with_override("backlash_mm", "0.05")?`.
//!
//! Files carry units in their key names (mm, um, deg, kg, N/um, 1/s, ...); [`AxisConfig::build`]
//! converts to SI. Unknown keys are rejected (serde `deny_unknown_fields`), and a validation
//! pass rejects bad values with the key and the reason ([`ConfigError`]).

use serde::{Deserialize, Serialize};

use crate::axis::{AxisParams, Contact, EncoderParams, Friction, MechParams, MotorParams, GRAVITY};
use crate::control::cascade::{cycle_ratio, CascadeParams};

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

/// Largest backlash a configuration (and the drive's 0x2000) accepts: 10 mm on a linear
/// axis, 0.1 rad (5.7 deg) on a rotary one; worn machines show 0.01-0.1 mm.
pub const MAX_BACKLASH_M: f64 = 0.01;
pub const MAX_BACKLASH_RAD: f64 = 0.1;

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
        let cfg: AxisConfig = toml::from_str(text).map_err(parse_error)?;
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
            let mut err = parse_error(e);
            if err.key.is_empty() {
                err.key = key.to_string();
            }
            err
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

    /// Validate and convert to SI parameters.
    pub fn build(&self) -> Result<BuiltConfig, ConfigError> {
        let kind = self.kind;
        let rotary = kind == AxisKind::Rotary;
        let gear = positive("gear_ratio", self.gear_ratio)?;
        // Kinematic ratio: motor rad per load unit (m or rad).
        let ratio = match (kind, self.transmission) {
            (AxisKind::Linear, Transmission::LeadScrew) => {
                if self.pinion_diameter_mm.is_some() {
                    return Err(ConfigError::new(
                        "pinion_diameter_mm",
                        "not valid for a lead screw (use `pitch_mm`)",
                    ));
                }
                let pitch = self
                    .pitch_mm
                    .ok_or_else(|| ConfigError::new("pitch_mm", "missing (lead screw)"))?;
                let pitch = positive("pitch_mm", pitch)? * 1e-3;
                gear * 2.0 * std::f64::consts::PI / pitch
            }
            (AxisKind::Linear, Transmission::RackPinion) => {
                if self.pitch_mm.is_some() {
                    return Err(ConfigError::new(
                        "pitch_mm",
                        "not valid for rack and pinion (use `pinion_diameter_mm`)",
                    ));
                }
                let d = self.pinion_diameter_mm.ok_or_else(|| {
                    ConfigError::new("pinion_diameter_mm", "missing (rack and pinion)")
                })?;
                gear / (0.5 * positive("pinion_diameter_mm", d)? * 1e-3)
            }
            (AxisKind::Rotary, Transmission::GearWheel) => {
                for (k, v) in [
                    ("pitch_mm", self.pitch_mm),
                    ("pinion_diameter_mm", self.pinion_diameter_mm),
                ] {
                    if v.is_some() {
                        return Err(ConfigError::new(
                            k,
                            "not valid for a gear-wheel table (the ratio is `gear_ratio`)",
                        ));
                    }
                }
                gear
            }
            (k, t) => {
                return Err(ConfigError::new(
                    "transmission",
                    format!("{t:?} does not fit a {k:?} axis").to_lowercase(),
                ))
            }
        };
        let (unit, unit_name) = if rotary {
            (std::f64::consts::PI / 180.0, "deg")
        } else {
            (1e-3, "mm")
        };

        let mass = pick(
            kind,
            ("carriage_mass_kg", self.carriage_mass_kg),
            ("table_inertia_kgm2", self.table_inertia_kgm2),
        )?;
        let mass_key = if rotary {
            "table_inertia_kgm2"
        } else {
            "carriage_mass_kg"
        };
        let mass = positive(mass_key, mass)?;
        if self.vertical && rotary {
            return Err(ConfigError::new(
                "vertical",
                "a rotary table axis cannot be vertical in this model",
            ));
        }
        let cb = non_negative("counterbalance_fraction", self.counterbalance_fraction)?;
        if cb > 1.5 {
            return Err(ConfigError::new(
                "counterbalance_fraction",
                format!("must be <= 1.5 (fraction of the weight), got {cb}"),
            ));
        }
        let (gravity_force, counterbalance_force) = if self.vertical {
            (-mass * GRAVITY, cb * mass * GRAVITY)
        } else {
            (0.0, 0.0)
        };

        let backlash = pick(
            kind,
            ("backlash_mm", self.backlash_mm),
            ("backlash_deg", self.backlash_deg),
        )?;
        let backlash_key = if rotary {
            "backlash_deg"
        } else {
            "backlash_mm"
        };
        let max_gap = if rotary {
            MAX_BACKLASH_RAD
        } else {
            MAX_BACKLASH_M
        };
        let backlash = at_most(
            backlash_key,
            non_negative(backlash_key, backlash)?,
            max_gap / unit,
            "a worn drive train shows 0.01-0.1 mm; the drive's 0x2000 accepts no more either",
        )? * unit;
        let stiffness = pick(
            kind,
            ("stiffness_n_per_um", self.stiffness_n_per_um),
            ("stiffness_nm_per_arcsec", self.stiffness_nm_per_arcsec),
        )?;
        let stiffness = if rotary {
            positive("stiffness_nm_per_arcsec", stiffness)?
                * (180.0 * 3600.0 / std::f64::consts::PI)
        } else {
            positive("stiffness_n_per_um", stiffness)? * 1e6
        };
        let zeta = non_negative("damping_ratio", self.damping_ratio)?;
        if zeta > 2.0 {
            return Err(ConfigError::new(
                "damping_ratio",
                format!("must be <= 2, got {zeta}"),
            ));
        }

        let fc = pick(
            kind,
            ("load_coulomb_friction_n", self.load_coulomb_friction_n),
            ("load_coulomb_friction_nm", self.load_coulomb_friction_nm),
        )?;
        let fc = non_negative(
            if rotary {
                "load_coulomb_friction_nm"
            } else {
                "load_coulomb_friction_n"
            },
            fc,
        )?;
        let fv = pick(
            kind,
            (
                "load_viscous_friction_n_per_m_per_s",
                self.load_viscous_friction_n_per_m_per_s,
            ),
            (
                "load_viscous_friction_nm_per_rad_per_s",
                self.load_viscous_friction_nm_per_rad_per_s,
            ),
        )?;
        let fv = non_negative(
            if rotary {
                "load_viscous_friction_nm_per_rad_per_s"
            } else {
                "load_viscous_friction_n_per_m_per_s"
            },
            fv,
        )?;
        let static_ratio = match self.load_static_friction_ratio {
            Some(r) => {
                let r = non_negative("load_static_friction_ratio", r)?;
                if r < 1.0 {
                    return Err(ConfigError::new(
                        "load_static_friction_ratio",
                        format!("static friction cannot be below Coulomb friction: must be >= 1, got {r}"),
                    ));
                }
                r
            }
            None => 1.0,
        };
        let stribeck = if static_ratio > 1.0 {
            let v = pick(
                kind,
                (
                    "stribeck_velocity_mm_per_s",
                    self.stribeck_velocity_mm_per_s,
                ),
                (
                    "stribeck_velocity_deg_per_s",
                    self.stribeck_velocity_deg_per_s,
                ),
            )?;
            positive(
                if rotary {
                    "stribeck_velocity_deg_per_s"
                } else {
                    "stribeck_velocity_mm_per_s"
                },
                v,
            )? * unit
        } else {
            1.0
        };

        let jm = positive("motor_inertia_kgm2", self.motor_inertia_kgm2)?;
        let kt = positive("torque_constant_nm_per_a", self.torque_constant_nm_per_a)?;
        let rated_torque = positive("rated_torque_nm", self.rated_torque_nm)?;
        let rated_current = positive("rated_current_a", self.rated_current_a)?;
        let max_current = positive("max_current_a", self.max_current_a)?;
        if max_current < rated_current {
            return Err(ConfigError::new(
                "max_current_a",
                format!("must be >= rated_current_a ({rated_current}), got {max_current}"),
            ));
        }
        let max_speed =
            positive("max_speed_rpm", self.max_speed_rpm)? * std::f64::consts::PI / 30.0;
        let tau_th = positive(
            "motor_thermal_time_constant_s",
            self.motor_thermal_time_constant_s,
        )?;
        if !(1.0..=36_000.0).contains(&tau_th) {
            return Err(ConfigError::new(
                "motor_thermal_time_constant_s",
                format!("must be within 1..=36000 s (a motor winding heats in seconds to hours), got {tau_th}"),
            ));
        }
        let fc_hz = positive("current_bandwidth_hz", self.current_bandwidth_hz)?;
        let motor_fc = non_negative("motor_coulomb_friction_nm", self.motor_coulomb_friction_nm)?;
        let motor_fv = non_negative(
            "motor_viscous_friction_nm_per_rad_per_s",
            self.motor_viscous_friction_nm_per_rad_per_s,
        )?;

        if self.motor_encoder_counts_per_rev < 4 {
            return Err(ConfigError::new(
                "motor_encoder_counts_per_rev",
                format!("must be >= 4, got {}", self.motor_encoder_counts_per_rev),
            ));
        }
        let motor_cpr = self.motor_encoder_counts_per_rev as f64;
        let direct_counts_per_unit = if rotary {
            if self.direct_encoder_resolution_nm.is_some() {
                return Err(ConfigError::new(
                    "direct_encoder_resolution_nm",
                    "not valid for a rotary axis (use `direct_encoder_counts_per_rev`)",
                ));
            }
            let c = self.direct_encoder_counts_per_rev.ok_or_else(|| {
                ConfigError::new("direct_encoder_counts_per_rev", "missing (rotary axis)")
            })?;
            if c < 4 {
                return Err(ConfigError::new(
                    "direct_encoder_counts_per_rev",
                    format!("must be >= 4, got {c}"),
                ));
            }
            c as f64 / (2.0 * std::f64::consts::PI)
        } else {
            if self.direct_encoder_counts_per_rev.is_some() {
                return Err(ConfigError::new(
                    "direct_encoder_counts_per_rev",
                    "not valid for a linear axis (use `direct_encoder_resolution_nm`)",
                ));
            }
            let r = self.direct_encoder_resolution_nm.ok_or_else(|| {
                ConfigError::new("direct_encoder_resolution_nm", "missing (linear axis)")
            })?;
            1.0 / (positive("direct_encoder_resolution_nm", r)? * 1e-9)
        };
        let motor_noise = non_negative(
            "motor_encoder_noise_counts",
            self.motor_encoder_noise_counts,
        )?;
        let direct_noise = non_negative(
            "direct_encoder_noise_counts",
            self.direct_encoder_noise_counts,
        )?;
        let offset = if rotary {
            if self.direct_encoder_offset_um != 0.0 {
                return Err(ConfigError::new(
                    "direct_encoder_offset_um",
                    "not valid for a rotary axis (use `direct_encoder_offset_mdeg`)",
                ));
            }
            finite(
                "direct_encoder_offset_mdeg",
                self.direct_encoder_offset_mdeg,
            )? * 1e-3
                * unit
        } else {
            if self.direct_encoder_offset_mdeg != 0.0 {
                return Err(ConfigError::new(
                    "direct_encoder_offset_mdeg",
                    "not valid for a linear axis (use `direct_encoder_offset_um`)",
                ));
            }
            finite("direct_encoder_offset_um", self.direct_encoder_offset_um)? * 1e-6
        };

        let kv = positive("kv_per_s", self.kv_per_s)?;
        let kp = positive("speed_kp_nms_per_rad", self.speed_kp_nms_per_rad)?;
        let ti_ms = positive("speed_ti_ms", self.speed_ti_ms).map_err(|e| {
            ConfigError::new(
                "speed_ti_ms",
                format!(
                    "{} (the speed PI's integral time; the integral gain is k_sp * cycle / T_si)",
                    e.reason
                ),
            )
        })?;
        let ti = at_most(
            "speed_ti_ms",
            ti_ms,
            10_000.0,
            "the drive's 0x2009 accepts at most 10 s",
        )? * 1e-3;
        let filter = non_negative("speed_filter_ms", self.speed_filter_ms)? * 1e-3;
        let h = positive("physics_step_us", self.physics_step_us)? * 1e-6;
        let speed_cycle = positive("speed_cycle_us", self.speed_cycle_us)? * 1e-6;
        let position_cycle = positive("position_cycle_us", self.position_cycle_us)? * 1e-6;
        if cycle_ratio(speed_cycle, h).is_none() {
            return Err(ConfigError::new(
                "speed_cycle_us",
                format!(
                    "must be an integer multiple of physics_step_us ({})",
                    self.physics_step_us
                ),
            ));
        }
        // A discrete P loop x += k_v T e converges monotonically only for k_v T < 1.
        at_most(
            "kv_per_s",
            kv,
            1.0 / position_cycle,
            "k_v times the position cycle must stay below 1 for a stable discrete position loop",
        )?;
        // Inside the backlash gap the motor turns alone: the discrete speed loop on J_m is
        // stable only for k_sp T / J_m < 2.
        at_most(
            "speed_kp_nms_per_rad",
            kp,
            2.0 * jm / speed_cycle,
            "k_sp times the speed cycle over the motor inertia must stay below 2 for a stable \
             discrete speed loop",
        )?;
        if cycle_ratio(position_cycle, speed_cycle).is_none() {
            return Err(ConfigError::new(
                "position_cycle_us",
                format!(
                    "must be an integer multiple of speed_cycle_us ({})",
                    self.speed_cycle_us
                ),
            ));
        }

        let mut mech = MechParams {
            ratio,
            motor_inertia: jm,
            load_mass: mass,
            contact: Contact {
                backlash,
                stiffness,
                damping: 0.0,
            },
            motor_friction: Friction {
                coulomb: motor_fc,
                static_: motor_fc,
                stribeck_velocity: 1.0,
                viscous: motor_fv,
            },
            load_friction: Friction {
                coulomb: fc,
                static_: fc * static_ratio,
                stribeck_velocity: stribeck,
                viscous: fv,
            },
            gravity_force,
            counterbalance_force,
        };
        mech.contact.damping = 2.0 * zeta * (stiffness * mech.reduced_mass()).sqrt();
        let max_step = mech.max_step();
        if h > max_step {
            return Err(ConfigError::new(
                "physics_step_us",
                format!(
                    "{} us is too coarse for the drive-train stiffness and damping: at most {:.2} us \
                     (omega_n h <= 0.5, c h / m_red <= 0.5)",
                    self.physics_step_us,
                    max_step * 1e6
                ),
            ));
        }
        // Softer than this, the motor's peak force deflects the drive train by more than the
        // largest backlash accepted: no longer a drive train (the drive's 0x2001 likewise).
        let peak_force = kt * max_current * ratio;
        let min_stiffness = peak_force / max_gap;
        if stiffness < min_stiffness {
            let (key, scale) = if rotary {
                (
                    "stiffness_nm_per_arcsec",
                    std::f64::consts::PI / (180.0 * 3600.0),
                )
            } else {
                ("stiffness_n_per_um", 1e-6)
            };
            return Err(ConfigError::new(
                key,
                format!(
                    "must be >= {:.6}, got {}: the motor's peak force would deflect the drive \
                     train by more than the largest backlash accepted",
                    min_stiffness * scale,
                    stiffness * scale
                ),
            ));
        }
        let motor = MotorParams {
            inertia: jm,
            torque_constant: kt,
            rated_torque,
            rated_current,
            max_current,
            max_speed,
            current_bandwidth_hz: fc_hz,
        };
        let axis = AxisParams {
            mech,
            motor,
            motor_encoder: EncoderParams {
                counts_per_unit: motor_cpr / (2.0 * std::f64::consts::PI),
                offset: 0.0,
                noise_counts: motor_noise,
                seed: self.noise_seed,
            },
            direct_encoder: EncoderParams {
                counts_per_unit: direct_counts_per_unit,
                offset,
                noise_counts: direct_noise,
                seed: self.noise_seed ^ 0x5DEE_CE66_D1CE_5EED,
            },
            rotary,
            step: h,
        };
        let control = CascadeParams {
            kv,
            speed_kp: kp,
            speed_ti: ti,
            speed_filter: filter,
            position_from_direct: self.position_from_direct,
            speed_cycle,
            position_cycle,
        };
        Ok(BuiltConfig {
            axis,
            control,
            display_unit: unit,
            display_unit_name: unit_name,
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

/// Turn a serde/toml error into a key + reason.
/// The motor's I2t thermal time constant when a machine file does not give one, s: a
/// mid-size servo motor's winding (estimate; the presets give their own).
pub const DEFAULT_MOTOR_THERMAL_TIME_CONSTANT_S: f64 = 180.0;

fn default_motor_thermal_time_constant_s() -> f64 {
    DEFAULT_MOTOR_THERMAL_TIME_CONSTANT_S
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
        "unknown key".to_string()
    } else if msg.starts_with("missing field") {
        "missing".to_string()
    } else {
        msg.lines().next().unwrap_or("").to_string()
    };
    ConfigError { key, reason }
}
