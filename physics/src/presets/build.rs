//! [`AxisConfig::build`]: the machine file's keys, validated and converted to SI, as a list
//! of named stages. Each stage reads and checks one group of keys; the stages run in the
//! order their errors are reported (kinematics, load, drive train, friction, motor,
//! encoders, cascade, then the checks that need the assembled mechanics).

use std::f64::consts::PI;

use super::{
    at_most, finite, non_negative, pick, positive, AxisConfig, AxisKind, BuiltConfig, ConfigError,
    Transmission, MAX_BACKLASH_M, MAX_BACKLASH_RAD, MAX_PRELOAD_PCT,
};
use crate::axis::{
    AxisParams, Contact, EncoderParams, Friction, MechParams, MotorParams, TwinPinion, GRAVITY,
};
use crate::control::cascade::{cycle_ratio, CascadeParams};

/// The axis kind's display unit and limits, shared by the stages.
#[derive(Clone, Copy)]
struct KindUnits {
    kind: AxisKind,
    rotary: bool,
    /// Display unit: 1e-3 m ("mm") or pi/180 rad ("deg").
    unit: f64,
    unit_name: &'static str,
    /// Largest backlash accepted, m or rad.
    max_gap: f64,
}

impl KindUnits {
    fn of(kind: AxisKind) -> Self {
        let rotary = kind == AxisKind::Rotary;
        let (unit, unit_name, max_gap) = if rotary {
            (PI / 180.0, "deg", MAX_BACKLASH_RAD)
        } else {
            (1e-3, "mm", MAX_BACKLASH_M)
        };
        KindUnits {
            kind,
            rotary,
            unit,
            unit_name,
            max_gap,
        }
    }

    /// The key that applies to this kind of axis.
    fn key(&self, linear: &'static str, rotary: &'static str) -> &'static str {
        if self.rotary {
            rotary
        } else {
            linear
        }
    }
}

/// The load's inertia and the forces of its weight.
struct Load {
    /// kg or kg m^2.
    mass: f64,
    gravity_force: f64,
    counterbalance_force: f64,
}

/// Backlash, stiffness and damping ratio of the drive train, SI.
struct DriveTrain {
    backlash: f64,
    stiffness: f64,
    damping_ratio: f64,
}

impl AxisConfig {
    /// The axis's top speed at the load in the drive's user units per second (linear: 1 µm,
    /// rotary: 0.001 deg, as `drive::axis_drive::USER_UNIT_*`): the motor's maximum speed
    /// (`max_speed_rpm`, 0x6080) through the kinematic ratio. What a motion program may ask.
    pub fn max_speed_uu_per_s(&self) -> Result<f64, ConfigError> {
        let motor_rad_per_s = positive("max_speed_rpm", self.max_speed_rpm)? * PI / 30.0;
        let user_unit = match self.kind {
            AxisKind::Linear => 1e-6,
            AxisKind::Rotary => PI / 180.0 * 1e-3,
        };
        Ok(motor_rad_per_s / self.read_kinematic_ratio()? / user_unit)
    }

    /// Validate and convert to SI parameters.
    pub fn build(&self) -> Result<BuiltConfig, ConfigError> {
        // First: a value outside its registry range is refused under its own key, before a
        // cross-check with other keys (the physics step against the stiffness, say) could
        // refuse it under theirs.
        self.check_registry_ranges()?;
        let units = KindUnits::of(self.kind);
        let ratio = self.read_kinematic_ratio()?;
        let load = self.read_load(&units)?;
        let train = self.read_drive_train(&units)?;
        let load_friction = self.read_load_friction(&units)?;
        let (motor, motor_friction) = self.read_motor()?;
        let (motor_encoder, direct_encoder) = self.read_encoders(&units)?;
        let (control, step) = self.derive_cascade(motor.inertia)?;
        let mut mech = assemble_mechanics(
            ratio,
            motor.inertia,
            &load,
            &train,
            motor_friction,
            load_friction,
        );
        mech.twin = self.read_twin_pinion(&motor)?;
        self.check_physics_step(&mech, step)?;
        check_stiffness_holds_peak_force(&units, &mech, &motor)?;
        self.check_live_ranges(&units, &mech, &motor, &control)?;
        Ok(BuiltConfig {
            axis: AxisParams {
                mech,
                motor,
                motor_encoder,
                direct_encoder,
                rotary: units.rotary,
                step,
            },
            control,
            display_unit: units.unit,
            display_unit_name: units.unit_name,
        })
    }

    /// Motor rad per load unit (m or rad), from the transmission and its keys.
    fn read_kinematic_ratio(&self) -> Result<f64, ConfigError> {
        let gear = positive("gear_ratio", self.gear_ratio)?;
        match (self.kind, self.transmission) {
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
                Ok(gear * 2.0 * PI / pitch)
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
                Ok(gear / (0.5 * positive("pinion_diameter_mm", d)? * 1e-3))
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
                Ok(gear)
            }
            (k, t) => Err(ConfigError::new(
                "transmission",
                format!("{t:?} does not fit a {k:?} axis").to_lowercase(),
            )),
        }
    }

    /// Carriage mass or table inertia; on a vertical axis its weight and counterbalance.
    fn read_load(&self, units: &KindUnits) -> Result<Load, ConfigError> {
        let mass = pick(
            units.kind,
            ("carriage_mass_kg", self.carriage_mass_kg),
            ("table_inertia_kgm2", self.table_inertia_kgm2),
        )?;
        let mass = positive(units.key("carriage_mass_kg", "table_inertia_kgm2"), mass)?;
        if self.vertical && units.rotary {
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
        Ok(Load {
            mass,
            gravity_force,
            counterbalance_force,
        })
    }

    /// Backlash (bounded by the largest gap the drive accepts), stiffness, damping ratio.
    fn read_drive_train(&self, units: &KindUnits) -> Result<DriveTrain, ConfigError> {
        let backlash = pick(
            units.kind,
            ("backlash_mm", self.backlash_mm),
            ("backlash_deg", self.backlash_deg),
        )?;
        let backlash_key = units.key("backlash_mm", "backlash_deg");
        let backlash = at_most(
            backlash_key,
            non_negative(backlash_key, backlash)?,
            units.max_gap / units.unit,
            "a worn drive train shows 0.01-0.1 mm; the drive's 0x2000 accepts no more either",
        )? * units.unit;
        let stiffness = pick(
            units.kind,
            ("stiffness_n_per_um", self.stiffness_n_per_um),
            ("stiffness_nm_per_arcsec", self.stiffness_nm_per_arcsec),
        )?;
        let stiffness = if units.rotary {
            positive("stiffness_nm_per_arcsec", stiffness)? * (180.0 * 3600.0 / PI)
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
        Ok(DriveTrain {
            backlash,
            stiffness,
            damping_ratio: zeta,
        })
    }

    /// A twin pinion's second motor and preload; a single-contact drive train refuses a
    /// preload (there is no second pinion to bias against).
    fn read_twin_pinion(&self, motor: &MotorParams) -> Result<Option<TwinPinion>, ConfigError> {
        let pct = non_negative("preload_pct", self.preload_pct)?;
        let pct = at_most(
            "preload_pct",
            pct,
            MAX_PRELOAD_PCT,
            "the bias is a share of each motor's rated torque (real drives: 5-30 %)",
        )?;
        if !self.twin_pinion {
            if pct != 0.0 {
                return Err(ConfigError::new(
                    "preload_pct",
                    format!(
                        "a single-contact drive train has no preload (got {pct}): set \
                         `twin_pinion = true` for two motors biased against each other"
                    ),
                ));
            }
            return Ok(None);
        }
        if self.transmission == Transmission::LeadScrew {
            return Err(ConfigError::new(
                "twin_pinion",
                "a lead screw has no twin pinion (use `rack_pinion` or `gear_wheel`)",
            ));
        }
        // Each motor is half the pair: half the rated torque, half the torque limit.
        Ok(Some(TwinPinion {
            preload_torque: pct / 100.0 * 0.5 * motor.rated_torque,
            motor_torque_limit: 0.5 * motor.torque_constant * motor.max_current,
        }))
    }

    /// Coulomb, static (Stribeck) and viscous friction at the load.
    fn read_load_friction(&self, units: &KindUnits) -> Result<Friction, ConfigError> {
        let fc = pick(
            units.kind,
            ("load_coulomb_friction_n", self.load_coulomb_friction_n),
            ("load_coulomb_friction_nm", self.load_coulomb_friction_nm),
        )?;
        let fc = non_negative(
            units.key("load_coulomb_friction_n", "load_coulomb_friction_nm"),
            fc,
        )?;
        let fv = pick(
            units.kind,
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
            units.key(
                "load_viscous_friction_n_per_m_per_s",
                "load_viscous_friction_nm_per_rad_per_s",
            ),
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
                units.kind,
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
                units.key("stribeck_velocity_mm_per_s", "stribeck_velocity_deg_per_s"),
                v,
            )? * units.unit
        } else {
            1.0
        };
        Ok(Friction {
            coulomb: fc,
            static_: fc * static_ratio,
            stribeck_velocity: stribeck,
            viscous: fv,
        })
    }

    /// The motor's ratings and its own friction.
    fn read_motor(&self) -> Result<(MotorParams, Friction), ConfigError> {
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
        let max_speed = positive("max_speed_rpm", self.max_speed_rpm)? * PI / 30.0;
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
        let motor = MotorParams {
            inertia: jm,
            torque_constant: kt,
            rated_torque,
            rated_current,
            max_current,
            max_speed,
            current_bandwidth_hz: fc_hz,
        };
        let friction = Friction {
            coulomb: motor_fc,
            static_: motor_fc,
            stribeck_velocity: 1.0,
            viscous: motor_fv,
        };
        Ok((motor, friction))
    }

    /// Motor encoder and direct (load) encoder: resolution, noise, offset, seeds.
    fn read_encoders(
        &self,
        units: &KindUnits,
    ) -> Result<(EncoderParams, EncoderParams), ConfigError> {
        if self.motor_encoder_counts_per_rev < 4 {
            return Err(ConfigError::new(
                "motor_encoder_counts_per_rev",
                format!("must be >= 4, got {}", self.motor_encoder_counts_per_rev),
            ));
        }
        let motor_cpr = self.motor_encoder_counts_per_rev as f64;
        let direct_counts_per_unit = self.read_direct_encoder_resolution(units)?;
        let motor_noise = non_negative(
            "motor_encoder_noise_counts",
            self.motor_encoder_noise_counts,
        )?;
        let direct_noise = non_negative(
            "direct_encoder_noise_counts",
            self.direct_encoder_noise_counts,
        )?;
        let offset = self.read_direct_encoder_offset(units)?;
        let motor_encoder = EncoderParams {
            counts_per_unit: motor_cpr / (2.0 * PI),
            offset: 0.0,
            noise_counts: motor_noise,
            seed: self.noise_seed,
        };
        let direct_encoder = EncoderParams {
            counts_per_unit: direct_counts_per_unit,
            offset,
            noise_counts: direct_noise,
            seed: self.noise_seed ^ 0x5DEE_CE66_D1CE_5EED,
        };
        Ok((motor_encoder, direct_encoder))
    }

    /// The direct encoder's counts per m or per rad.
    fn read_direct_encoder_resolution(&self, units: &KindUnits) -> Result<f64, ConfigError> {
        if units.rotary {
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
            Ok(c as f64 / (2.0 * PI))
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
            Ok(1.0 / (positive("direct_encoder_resolution_nm", r)? * 1e-9))
        }
    }

    /// The direct encoder's zero offset, m or rad.
    fn read_direct_encoder_offset(&self, units: &KindUnits) -> Result<f64, ConfigError> {
        if units.rotary {
            if self.direct_encoder_offset_um != 0.0 {
                return Err(ConfigError::new(
                    "direct_encoder_offset_um",
                    "not valid for a rotary axis (use `direct_encoder_offset_mdeg`)",
                ));
            }
            Ok(finite(
                "direct_encoder_offset_mdeg",
                self.direct_encoder_offset_mdeg,
            )? * 1e-3
                * units.unit)
        } else {
            if self.direct_encoder_offset_mdeg != 0.0 {
                return Err(ConfigError::new(
                    "direct_encoder_offset_mdeg",
                    "not valid for a linear axis (use `direct_encoder_offset_um`)",
                ));
            }
            Ok(finite("direct_encoder_offset_um", self.direct_encoder_offset_um)? * 1e-6)
        }
    }

    /// The cascade's gains and cycles, checked for discrete stability against the motor
    /// inertia `jm`; also returns the physics step, s, the cycles are multiples of.
    fn derive_cascade(&self, jm: f64) -> Result<(CascadeParams, f64), ConfigError> {
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
        let control = CascadeParams {
            kv,
            speed_kp: kp,
            speed_ti: ti,
            speed_filter: filter,
            position_from_direct: self.position_from_direct,
            speed_cycle,
            position_cycle,
        };
        Ok((control, h))
    }

    /// The physics step `h`, s, must resolve the drive train's contact dynamics (and be at least
    /// [`MIN_PHYSICS_STEP_US`]).
    fn check_physics_step(&self, mech: &MechParams, h: f64) -> Result<(), ConfigError> {
        // A finer step only costs time: 1 us already means a million steps per second.
        if h < MIN_PHYSICS_STEP_US * 1e-6 {
            return Err(ConfigError::new(
                "physics_step_us",
                format!(
                    "{} us is below the finest step of {MIN_PHYSICS_STEP_US} us (a run would \
                     not end in reasonable time)",
                    compact(self.physics_step_us)
                ),
            ));
        }
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
        Ok(())
    }
}

/// The finest physics step accepted, us.
pub const MIN_PHYSICS_STEP_US: f64 = 1.0;

/// The two-mass drive train; the contact damping follows from the damping ratio and the
/// reduced mass.
fn assemble_mechanics(
    ratio: f64,
    motor_inertia: f64,
    load: &Load,
    train: &DriveTrain,
    motor_friction: Friction,
    load_friction: Friction,
) -> MechParams {
    let mut mech = MechParams {
        ratio,
        motor_inertia,
        load_mass: load.mass,
        contact: Contact {
            backlash: train.backlash,
            stiffness: train.stiffness,
            damping: 0.0,
        },
        motor_friction,
        load_friction,
        gravity_force: load.gravity_force,
        counterbalance_force: load.counterbalance_force,
        twin: None,
    };
    mech.contact.damping =
        2.0 * train.damping_ratio * (train.stiffness * mech.reduced_mass()).sqrt();
    mech
}

/// Softer than this, the motor's peak force deflects the drive train by more than the
/// largest backlash accepted: no longer a drive train (the drive's 0x2001 likewise).
fn check_stiffness_holds_peak_force(
    units: &KindUnits,
    mech: &MechParams,
    motor: &MotorParams,
) -> Result<(), ConfigError> {
    let stiffness = mech.contact.stiffness;
    let peak_force = motor.torque_constant * motor.max_current * mech.ratio;
    let min_stiffness = peak_force / units.max_gap;
    if stiffness < min_stiffness {
        let (key, scale) = if units.rotary {
            ("stiffness_nm_per_arcsec", PI / (180.0 * 3600.0))
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
    Ok(())
}

impl AxisConfig {
    /// The parameters the drive also takes while running (its 0x2000.. objects) within the
    /// range its object accepts (the emulator's `AxisDrive::set_param`; the test
    /// `param_registry` walks the registry through both): a preset, `--set`, a machine file,
    /// a sweep case or Python's `sim` never start an axis the drive would refuse.
    fn check_live_ranges(
        &self,
        units: &KindUnits,
        mech: &MechParams,
        motor: &MotorParams,
        control: &CascadeParams,
    ) -> Result<(), ConfigError> {
        // What the motor can exert at the load, and the load's top speed.
        let f_peak = motor.torque_constant * motor.max_current * mech.ratio;
        let v_max_load = motor.max_speed / mech.ratio;
        let why = "the drive's parameter object accepts no more: beyond it the motor could \
                   never hold or move the axis";
        at_most(
            units.key("load_coulomb_friction_n", "load_coulomb_friction_nm"),
            mech.load_friction.coulomb,
            f_peak,
            why,
        )?;
        at_most(
            units.key(
                "load_viscous_friction_n_per_m_per_s",
                "load_viscous_friction_nm_per_rad_per_s",
            ),
            mech.load_friction.viscous,
            f_peak / v_max_load,
            why,
        )?;
        at_most(
            "motor_coulomb_friction_nm",
            mech.motor_friction.coulomb,
            motor.torque_constant * motor.max_current,
            why,
        )?;
        at_most(
            "motor_encoder_noise_counts",
            self.motor_encoder_noise_counts,
            MAX_ENCODER_NOISE_COUNTS,
            "the drive's 0x200A accepts no more",
        )?;
        let offset = if units.rotary {
            (
                "direct_encoder_offset_mdeg",
                self.direct_encoder_offset_mdeg,
                1e-3 * units.unit,
            )
        } else {
            (
                "direct_encoder_offset_um",
                self.direct_encoder_offset_um,
                1e-6,
            )
        };
        let max_offset = MAX_OFFSET_GAPS * units.max_gap / offset.2;
        if offset.1.abs() > max_offset {
            return Err(ConfigError::new(
                offset.0,
                format!(
                    "must be within -{0} .. {0}, got {1}: the drive's 0x200C accepts no more",
                    compact(max_offset),
                    compact(offset.1)
                ),
            ));
        }
        at_most(
            "kv_per_s",
            control.kv,
            MAX_KV_PER_S,
            "the drive's 0x2007 accepts no more",
        )?;
        at_most(
            "speed_kp_nms_per_rad",
            control.speed_kp,
            MAX_SPEED_KP,
            "the drive's 0x2008 accepts no more",
        )?;
        if control.speed_ti < MIN_SPEED_TI_S {
            return Err(ConfigError::new(
                "speed_ti_ms",
                format!(
                    "must be >= {}, got {}: the drive's 0x2009 accepts no less",
                    MIN_SPEED_TI_S * 1e3,
                    compact(control.speed_ti * 1e3)
                ),
            ));
        }
        Ok(())
    }
}

impl AxisConfig {
    /// Every preset-only parameter within its registry range (`params::Form::check`): the
    /// range keeps an accepted value from giving NaN or a run that cannot end
    /// (emulator/tests/param_registry.rs runs each end). Checked before the stages' own
    /// checks, so a value outside is refused naming its own key and range with its unit.
    fn check_registry_ranges(&self) -> Result<(), ConfigError> {
        let preset_only = crate::params::PARAMS
            .iter()
            .filter(|p| p.preset && p.live.is_none());
        for form in preset_only.flat_map(|p| p.forms()) {
            if let Some(v) = self.preset_only_value(form.key) {
                form.check(v).map_err(|r| ConfigError::new(form.key, r))?;
            }
        }
        Ok(())
    }
}

/// Largest encoder noise the drive takes, counts (0x200A).
pub const MAX_ENCODER_NOISE_COUNTS: f64 = 1e6;
/// Largest direct-encoder offset, in largest backlashes (0x200C: a scale's thermal drift).
pub const MAX_OFFSET_GAPS: f64 = 100.0;
/// Largest position-loop gain, 1/s (0x2007).
pub const MAX_KV_PER_S: f64 = 1000.0;
/// Largest speed-loop gain, N m s/rad (0x2008).
pub const MAX_SPEED_KP: f64 = 1e4;
/// Shortest speed-loop integral time, s (0x2009).
pub const MIN_SPEED_TI_S: f64 = 1e-4;

/// A number as people write it: plain between 1e-4 and 1e6, else in exponent form (1e-12, not
/// 0.000000000001; 1e300, not 300 digits).
fn compact(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || (1e-4..1e6).contains(&a) || !x.is_finite() {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}
