//! The drive adapter: [`drive_protocol::Drive`] implemented on the simulated servo axis.
//!
//! This is the one place where the drive's internal units (motor-encoder increments, per mille
//! of rated torque) meet SI. The protocol converts user units to increments (factor group);
//! this file converts increments to metres or radians at the load. Nothing else converts.
//!
//! The servo keeps its own control cycle (`position_cycle_us` of the preset) whatever the bus
//! tick: [`AxisDrive::advance`] runs as many position cycles as the elapsed time holds.

use super::objects::{param_of_tag, AxisParam, EmuObjects, ParamError, INJECT_TAG};
use crate::control::cascade::{Command, Servo, Setpoint as ServoSetpoint};
use crate::presets::{AxisConfig, AxisKind, ConfigError, Transmission};
use drive_protocol::wire::sdo::abort;
use drive_protocol::{Drive, DriveCommand, DriveInfo, Feedback, Setpoint};

use crate::runtime::SimulatedDrive;

/// CiA 402 error code for an encoder (sensor) fault.
pub const ERROR_SENSOR: u16 = 0x7300;
/// Overcurrent (CiA 402 0x2310, continuous overcurrent): the motor current left the power
/// stage's range.
pub const ERROR_OVERCURRENT: u16 = 0x2310;
/// Motor overload (CiA 402 0x2310, continuous overcurrent), from the I2t thermal model: the
/// current's heating, `(i / rated_current)^2` through a first-order lag with the motor's
/// thermal time constant, reached the level continuous rated current settles at. From cold,
/// a constant current `r` times rated trips after `tau ln(r^2 / (r^2 - 1))`; below rated it
/// never trips, and the model cools with the same time constant.
pub const ERROR_MOTOR_I2T: u16 = 0x2310;
/// Overspeed (CiA 402 0x8400, velocity speed controller): motor speed, or the load's speed
/// seen at the motor, beyond the motor's maximum speed times [`OVERSPEED_MARGIN`].
pub const ERROR_OVERSPEED: u16 = 0x8400;
/// Position range (CiA 402 0x8612, reference limit): the axis left the range the drive can
/// report in 0x6064 (32-bit user units).
pub const ERROR_POSITION_RANGE: u16 = 0x8612;
/// Physics sanity (CiA 301 0x6100, internal software): the simulated state is not finite.
pub const ERROR_PHYSICS: u16 = 0x6100;

/// Overspeed trips at the motor's maximum speed (0x6080 default) times this, as a drive's
/// n_max monitoring trips a margin above the speed limit the speed loop enforces.
pub const OVERSPEED_MARGIN: f64 = 1.2;
/// Overcurrent trips at the power stage's current limit times this (the current loop never
/// exceeds the limit; beyond it the model has left its range).
pub const OVERCURRENT_MARGIN: f64 = 1.2;
/// Lowest damping the drive train may be given, as a fraction of critical damping: a steel
/// drive train never has less (structural damping is about 0.5-5 %), and without damping the
/// contact rings forever.
pub const MIN_DAMPING_RATIO: f64 = 1e-3;

/// Supervision thresholds, derived from the preset the drive was built from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Supervision {
    /// Motor speed that trips [`ERROR_OVERSPEED`], rad/s.
    pub overspeed_rad_per_s: f64,
    /// Motor current that trips [`ERROR_OVERCURRENT`], A.
    pub overcurrent_a: f64,
    /// |load position| that trips [`ERROR_POSITION_RANGE`], m or rad.
    pub position_range: f64,
    /// Current the I2t model is normalised to (the motor's rated current), A.
    pub i2t_rated_current_a: f64,
    /// Thermal time constant of the I2t model, s.
    pub i2t_time_constant_s: f64,
}

/// User unit of the factor-group default: 1 um on a linear axis, 0.001 deg on a rotary one.
pub const USER_UNIT_LINEAR_M: f64 = 1e-6;
pub const USER_UNIT_ROTARY_RAD: f64 = std::f64::consts::PI / 180.0 * 1e-3;

/// Which encoder a fault is injected into.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoder {
    Motor,
    Direct,
}

pub struct AxisDrive {
    pub servo: Servo,
    info: DriveInfo,
    /// Motor-encoder increments per motor radian.
    inc_per_motor_rad: f64,
    /// Motor-encoder increments per load unit (m or rad).
    inc_per_load: f64,
    rated_torque_nm: f64,
    rated_current_a: f64,
    /// Load position of the home-switch cam's edge; the switch is active above it.
    home_switch_at: f64,
    /// Software-visible user unit (m or rad) for display.
    pub user_unit: f64,
    /// Simulated time not yet run by the servo, us.
    pending_us: f64,
    position_cycle_us: f64,
    fault_latched: bool,
    /// Supervision fault latched (axis held at rest until a fault reset or reset node).
    trip: Option<u16>,
    supervision: Supervision,
    /// I2t thermal load of the motor: 1.0 is the trip level, where continuous rated current
    /// settles. Belongs to the motor: kept across fault reset and reset node.
    thermal_load: f64,
    /// I2t lag per position cycle: 1 - exp(-cycle / tau).
    thermal_alpha: f64,
    /// The servo as built from the preset, at rest: what reset node restores.
    initial: Servo,
    /// A fault injected over the bus (the emulator's fault-injection object), reported until
    /// 0 is written; a fault reset meanwhile is refused.
    injected: Option<u16>,
    /// Where this drive's emulator objects are in its node's dictionary (set when the node
    /// is built, `drive::node`).
    pub objects: Option<EmuObjects>,
}

/// `x` as a fraction n/d with d <= 1000, reduced.
fn fraction(x: f64) -> (u32, u32) {
    fn gcd(a: u64, b: u64) -> u64 {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }
    let d = 1000u64;
    let n = (x * d as f64).round().max(1.0) as u64;
    let g = gcd(n, d);
    ((n / g).min(u32::MAX as u64) as u32, (d / g) as u32)
}

impl AxisDrive {
    pub fn from_config(cfg: &AxisConfig) -> Result<Self, ConfigError> {
        let built = cfg.build()?;
        let servo = Servo::new(built.axis, built.control)
            .map_err(|e| ConfigError::new("physics_step_us", e.to_string()))?;
        let inc_per_motor_rad = built.axis.motor_encoder.counts_per_unit;
        let ratio = built.axis.mech.ratio;
        let rotary = cfg.kind == AxisKind::Rotary;
        let user_unit = if rotary {
            USER_UNIT_ROTARY_RAD
        } else {
            USER_UNIT_LINEAR_M
        };
        // Factor group: motor revs per driving-shaft rev (0x6091) and feed per shaft rev in
        // user units (0x6092), from the transmission as a machine builder would enter them.
        let (gear_motor_revs, gear_shaft_revs) = fraction(cfg.gear_ratio);
        let (feed_user_units, feed_shaft_revs) = match cfg.transmission {
            Transmission::LeadScrew => fraction(cfg.pitch_mm.unwrap_or(1.0) * 1e-3 / user_unit),
            Transmission::RackPinion => fraction(
                std::f64::consts::PI * cfg.pinion_diameter_mm.unwrap_or(1.0) * 1e-3 / user_unit,
            ),
            Transmission::GearWheel => (360_000, 1),
        };
        let info = DriveInfo {
            encoder_increments_per_rev: cfg.motor_encoder_counts_per_rev.min(u32::MAX as u64)
                as u32,
            gear_motor_revs,
            gear_shaft_revs,
            feed_user_units,
            feed_shaft_revs,
            rated_torque_mnm: (cfg.rated_torque_nm * 1e3).round() as u32,
            rated_current_ma: (cfg.rated_current_a * 1e3).round() as u32,
            max_motor_speed_rpm: cfg.max_speed_rpm.round() as u32,
            rotary,
        };
        let supervision = Supervision {
            overspeed_rad_per_s: built.axis.motor.max_speed * OVERSPEED_MARGIN,
            overcurrent_a: built.axis.motor.max_current * OVERCURRENT_MARGIN,
            position_range: f64::from(i32::MAX) * user_unit,
            i2t_rated_current_a: cfg.rated_current_a,
            i2t_time_constant_s: cfg.motor_thermal_time_constant_s,
        };
        let position_cycle_s = built.control.position_cycle;
        Ok(Self {
            position_cycle_us: built.control.position_cycle * 1e6,
            initial: servo.clone(),
            servo,
            trip: None,
            supervision,
            thermal_load: 0.0,
            thermal_alpha: 1.0 - (-position_cycle_s / cfg.motor_thermal_time_constant_s).exp(),
            info,
            inc_per_motor_rad,
            inc_per_load: inc_per_motor_rad * ratio,
            rated_torque_nm: cfg.rated_torque_nm,
            rated_current_a: cfg.rated_current_a,
            home_switch_at: if rotary { 1f64.to_radians() } else { 1e-3 },
            user_unit,
            pending_us: 0.0,
            fault_latched: false,
            injected: None,
            objects: None,
        })
    }

    /// An axis parameter in SI units.
    pub fn param(&self, param: AxisParam) -> f64 {
        let s = &self.servo;
        let m = s.axis.mech.params();
        match param {
            AxisParam::Backlash => m.contact.backlash,
            AxisParam::Stiffness => m.contact.stiffness,
            AxisParam::Damping => m.contact.damping,
            AxisParam::LoadCoulombFriction => m.load_friction.coulomb,
            AxisParam::LoadViscousFriction => m.load_friction.viscous,
            AxisParam::MotorCoulombFriction => m.motor_friction.coulomb,
            AxisParam::ExternalLoad => s.axis.external_load(),
            AxisParam::Kv => s.cascade.params.kv,
            AxisParam::SpeedKp => s.cascade.params.speed_kp,
            AxisParam::SpeedTi => s.cascade.params.speed_ti,
            AxisParam::MotorEncoderNoise => s.axis.motor_encoder.params.noise_counts,
            AxisParam::DirectEncoderNoise => {
                s.axis.direct_encoder.params.noise_counts
                    / s.axis.direct_encoder.params.counts_per_unit
            }
            AxisParam::DirectEncoderOffset => s.axis.direct_encoder.params.offset,
            AxisParam::PositionFromDirect => {
                f64::from(u8::from(s.cascade.params.position_from_direct))
            }
            AxisParam::Preload => s.axis.preload().unwrap_or(0.0),
        }
    }

    /// Write an axis parameter in SI units; the new value takes effect at the next step. A
    /// value outside what the axis can take (a worn or faulty machine's physical range, what
    /// the physics step integrates) is refused with the accepted range and changes nothing.
    pub fn set_param(&mut self, param: AxisParam, value: f64) -> Result<(), ParamError> {
        use crate::presets::{
            MAX_ENCODER_NOISE_COUNTS, MAX_KV_PER_S, MAX_OFFSET_GAPS, MAX_SPEED_KP, MIN_SPEED_TI_S,
        };
        let rotary = self.info.rotary;
        // Ranges: what a worn or faulty machine can physically show, in SI at the load, and
        // what the physics step can integrate.
        let max_gap = if rotary {
            crate::presets::MAX_BACKLASH_RAD
        } else {
            crate::presets::MAX_BACKLASH_M
        };
        // The motor's peak force (torque) at the load bounds loads and friction: beyond it
        // the motor could never hold or move the axis.
        let f_peak = self.peak_load_force();
        let v_max_load = self.servo.axis.motor.params.max_speed / self.servo.axis.ratio();
        let s = &mut self.servo;
        match param {
            AxisParam::Backlash => s.axis.set_backlash(check(value, 0.0, max_gap)?),
            AxisParam::Stiffness => {
                // Softer than this, the motor's peak force deflects the drive train by more
                // than the largest backlash the drive accepts: no longer a drive train.
                let min = f_peak / max_gap;
                let k = check(value, min, f64::MAX)?;
                s.axis
                    .set_stiffness(k)
                    .map_err(|e| ParamError::OutOfRange {
                        min,
                        // The stable step scales with 1/sqrt(k).
                        max: k * (e.max_step / e.step).powi(2),
                    })?;
            }
            AxisParam::Damping => {
                let m = s.axis.mech.params();
                let min = MIN_DAMPING_RATIO * 2.0 * (m.contact.stiffness * m.reduced_mass()).sqrt();
                let c = check(value, min, f64::MAX)?;
                s.axis.set_damping(c).map_err(|e| ParamError::OutOfRange {
                    min,
                    // c h / m_red <= 0.5: the limit scales with 1/h.
                    max: c * e.max_step / e.step,
                })?;
            }
            AxisParam::LoadCoulombFriction => {
                let f = s.axis.mech.params().load_friction;
                s.axis
                    .set_load_friction(f.with_coulomb(check(value, 0.0, f_peak)?));
            }
            AxisParam::LoadViscousFriction => {
                let mut f = s.axis.mech.params().load_friction;
                // At the maximum speed the viscous force stays within the motor's force.
                f.viscous = check(value, 0.0, f_peak / v_max_load)?;
                s.axis.set_load_friction(f);
            }
            AxisParam::MotorCoulombFriction => {
                let f = s.axis.mech.params().motor_friction;
                let max = s.axis.motor.torque_limit();
                s.axis
                    .set_motor_friction(f.with_coulomb(check(value, 0.0, max)?));
            }
            AxisParam::ExternalLoad => s.axis.set_external_load(check(value, -f_peak, f_peak)?),
            // The gains within what the discrete loops stay stable with (as the preset
            // files check them: presets::AxisConfig::build).
            AxisParam::Kv => {
                let max = MAX_KV_PER_S.min(1.0 / s.cascade.params.position_cycle);
                s.set_kv(check(value, 0.0, max)?)
            }
            AxisParam::SpeedKp => {
                let ti = s.cascade.params.speed_ti;
                let jm = s.axis.motor.params.inertia;
                let max = MAX_SPEED_KP.min(2.0 * jm / s.cascade.params.speed_cycle);
                s.set_speed_gains(check(value, 0.0, max)?, ti)
            }
            AxisParam::SpeedTi => {
                let kp = s.cascade.params.speed_kp;
                s.set_speed_gains(kp, check(value, MIN_SPEED_TI_S, 10.0)?)
            }
            AxisParam::MotorEncoderNoise => {
                s.axis
                    .motor_encoder
                    .set_noise(check(value, 0.0, MAX_ENCODER_NOISE_COUNTS)?)
            }
            AxisParam::DirectEncoderNoise => {
                let cpu = s.axis.direct_encoder.params.counts_per_unit;
                s.axis
                    .direct_encoder
                    .set_noise(check(value, 0.0, max_gap)? * cpu)
            }
            AxisParam::DirectEncoderOffset => {
                let max = max_gap * MAX_OFFSET_GAPS;
                s.axis.direct_encoder.set_offset(check(value, -max, max)?)
            }
            AxisParam::PositionFromDirect => {
                s.set_position_from_direct(check(value, 0.0, 1.0)? >= 0.5)
            }
            AxisParam::Preload => {
                // A single-contact drive train has no preload: only 0 is accepted there.
                let max = if s.axis.is_twin_pinion() {
                    crate::presets::MAX_PRELOAD_PCT / 100.0
                } else {
                    0.0
                };
                let v = check(value, 0.0, max)?;
                if s.axis.is_twin_pinion() {
                    s.axis
                        .set_preload(v)
                        .map_err(|_| ParamError::OutOfRange { min: 0.0, max })?;
                }
            }
        }
        Ok(())
    }

    /// Increments per load unit (m or rad): the adapter's conversion factor.
    /// The servo's position-control cycle, s (the preset's `position_cycle_us`).
    pub fn position_cycle_s(&self) -> f64 {
        self.position_cycle_us * 1e-6
    }

    pub fn inc_per_load(&self) -> f64 {
        self.inc_per_load
    }

    /// Signal loss on one encoder (the reading freezes; the drive reports 0x7300).
    pub fn set_signal_lost(&mut self, which: Encoder, lost: bool) {
        match which {
            Encoder::Motor => self.servo.axis.motor_encoder.set_signal_lost(lost),
            Encoder::Direct => self.servo.axis.direct_encoder.set_signal_lost(lost),
        }
        if lost {
            self.fault_latched = true;
        }
    }

    /// A burst of missed or extra counts on one encoder.
    pub fn inject_glitch(&mut self, which: Encoder, counts: i64) {
        match which {
            Encoder::Motor => self.servo.axis.motor_encoder.inject_glitch(counts),
            Encoder::Direct => self.servo.axis.direct_encoder.inject_glitch(counts),
        }
    }

    fn torque_nm(&self, permille: f64) -> f64 {
        permille * 1e-3 * self.rated_torque_nm
    }

    /// The supervision thresholds in force.
    pub fn supervision(&self) -> Supervision {
        self.supervision
    }

    /// The latched supervision fault, if any.
    pub fn supervision_fault(&self) -> Option<u16> {
        self.trip
    }

    /// The motor's I2t thermal load: 0 cold, 1.0 the trip level (where continuous rated
    /// current settles).
    pub fn motor_thermal_load(&self) -> f64 {
        self.thermal_load
    }

    /// One position cycle of the I2t model at motor current `current_a` (exact for a current
    /// constant over the cycle). A non-finite current leaves it as it is (the physics check
    /// faults on it).
    #[inline]
    fn heat(&mut self, current_a: f64) {
        let r = current_a / self.supervision.i2t_rated_current_a;
        if r.is_finite() {
            self.thermal_load += (r * r - self.thermal_load) * self.thermal_alpha;
        }
    }

    /// Highest force (N) or torque (N m) the motor can exert at the load.
    pub fn peak_load_force(&self) -> f64 {
        self.servo.axis.motor.torque_limit() * self.servo.axis.ratio()
    }

    /// Check the state after a position cycle, as a drive's monitoring does every cycle.
    #[inline]
    fn supervise(&self) -> Option<u16> {
        let ax = &self.servo.axis;
        let st = &ax.mech.state;
        let finite = st.motor.pos.is_finite()
            && st.load.pos.is_finite()
            && st.motor.vel.is_finite()
            && st.load.vel.is_finite()
            && ax.motor.torque().is_finite();
        if !finite {
            return Some(ERROR_PHYSICS);
        }
        let lim = &self.supervision;
        if ax.motor.current().abs() > lim.overcurrent_a {
            return Some(ERROR_OVERCURRENT);
        }
        if self.thermal_load >= 1.0 {
            return Some(ERROR_MOTOR_I2T);
        }
        let measured = self.servo.motor_velocity();
        if !measured.is_finite()
            || measured.abs() > lim.overspeed_rad_per_s
            || st.motor.vel.abs() > lim.overspeed_rad_per_s
            || (st.load.vel * ax.ratio()).abs() > lim.overspeed_rad_per_s
        {
            return Some(ERROR_OVERSPEED);
        }
        if ax.direct_encoder.position().abs() > lim.position_range
            || st.load.pos.abs() > lim.position_range
        {
            return Some(ERROR_POSITION_RANGE);
        }
        None
    }

    /// A sane place to put the axis at rest: the direct encoder's position, inside the
    /// supervised range.
    fn rest_position(&self) -> f64 {
        let x = self.servo.axis.direct_encoder.position();
        let r = self.supervision.position_range * 0.999;
        if x.is_finite() {
            x.clamp(-r, r)
        } else {
            0.0
        }
    }
}

fn check(value: f64, min: f64, max: f64) -> Result<f64, ParamError> {
    if value.is_finite() && value >= min && value <= max {
        Ok(value)
    } else {
        Err(ParamError::OutOfRange { min, max })
    }
}

impl Drive for AxisDrive {
    fn info(&self) -> DriveInfo {
        self.info
    }

    fn feedback(&self) -> Feedback {
        let s = &self.servo;
        let cps = self.inc_per_motor_rad;
        // Both encoders as sampled at the same instant (start of the last position cycle).
        let (motor_counts, direct_counts) = s.cascade.sampled_counts();
        let direct_m = direct_counts as f64 / s.axis.direct_encoder.params.counts_per_unit;
        Feedback {
            motor_position_inc: motor_counts,
            direct_position_inc: (direct_m * self.inc_per_load).round() as i64,
            position_from_direct: s.cascade.params.position_from_direct,
            motor_velocity_inc_per_s: s.motor_velocity() * cps,
            velocity_demand_inc_per_s: s.velocity_demand() * cps,
            torque_permille: s.torque() / self.rated_torque_nm * 1e3,
            current_permille: s.current() / self.rated_current_a * 1e3,
            home_switch: s.axis.load_position() > self.home_switch_at,
            negative_limit_switch: false,
            positive_limit_switch: false,
            drive_fault: self
                .trip
                .or((self.fault_latched || s.encoder_fault()).then_some(ERROR_SENSOR))
                .or(self.injected),
        }
    }

    fn command(&mut self, command: &DriveCommand) {
        let k = self.inc_per_load;
        let setpoint = match command.setpoint {
            Setpoint::Disabled => ServoSetpoint::Disabled,
            Setpoint::Position {
                position_inc,
                velocity_ff_inc_per_s,
                torque_ff_permille,
            } => ServoSetpoint::Position {
                position: position_inc / k,
                velocity_ff: velocity_ff_inc_per_s / k,
                torque_ff: self.torque_nm(torque_ff_permille),
            },
            Setpoint::Velocity {
                velocity_inc_per_s,
                torque_ff_permille,
            } => ServoSetpoint::Velocity {
                velocity: velocity_inc_per_s / k,
                torque_ff: self.torque_nm(torque_ff_permille),
            },
            Setpoint::Torque { torque_permille } => ServoSetpoint::Torque {
                torque: self.torque_nm(torque_permille),
            },
        };
        let positive_or_inf = |x: f64| if x > 0.0 { x } else { f64::INFINITY };
        self.servo.set_command(Command {
            setpoint,
            torque_limit: positive_or_inf(self.torque_nm(command.max_torque_permille)),
            speed_limit: positive_or_inf(command.max_velocity_inc_per_s / self.inc_per_motor_rad),
        });
    }

    fn read_object(
        &mut self,
        tag: u16,
        _index: u16,
        _sub: u8,
        out: &mut [u8],
    ) -> Result<usize, u32> {
        let spec = param_of_tag(tag).ok_or(abort::NO_OBJECT)?;
        let param = spec.live.ok_or(abort::NO_OBJECT)?;
        let v = spec.form(self.info.rotary).from_si(self.param(param)) as f32;
        out[..4].copy_from_slice(&v.to_le_bytes());
        Ok(4)
    }

    fn write_object(&mut self, tag: u16, _index: u16, _sub: u8, data: &[u8]) -> Result<(), u32> {
        if tag == INJECT_TAG {
            let code = u16::from_le_bytes([data[0], *data.get(1).unwrap_or(&0)]);
            self.injected = (code != 0).then_some(code);
            return Ok(());
        }
        let spec = param_of_tag(tag).ok_or(abort::NO_OBJECT)?;
        let param = spec.live.ok_or(abort::NO_OBJECT)?;
        let bytes: [u8; 4] = data.try_into().map_err(|_| abort::LENGTH_MISMATCH)?;
        let v = f32::from_le_bytes(bytes) as f64;
        if !v.is_finite() {
            return Err(abort::VALUE_RANGE);
        }
        let si = spec.form(self.info.rotary).to_si(v);
        self.set_param(param, si).map_err(|e| e.abort_code(si))
    }

    fn reset_fault(&mut self) -> bool {
        if self.servo.encoder_fault() || self.injected.is_some() {
            return false;
        }
        self.fault_latched = false;
        if self.trip.take().is_some() {
            // Re-initialised at rest when it tripped; start again from there.
            let x = self.rest_position();
            self.servo.reset_at_rest(x);
        }
        true
    }

    fn reset(&mut self) {
        // Parameters back to the preset's, the state at rest where the direct encoder is;
        // an injected encoder signal loss belongs to the machine and survives the reset.
        let x = self.rest_position();
        let motor_lost = self.servo.axis.motor_encoder.fault();
        let direct_lost = self.servo.axis.direct_encoder.fault();
        self.servo.clone_from(&self.initial);
        self.servo.reset_at_rest(x);
        self.servo.axis.motor_encoder.set_signal_lost(motor_lost);
        self.servo.axis.direct_encoder.set_signal_lost(direct_lost);
        self.trip = None;
        self.fault_latched = motor_lost || direct_lost;
        self.injected = None;
        self.pending_us = 0.0;
    }
}

impl SimulatedDrive for AxisDrive {
    fn stats_slots(
        &self,
    ) -> Option<&[drive_protocol::od::Slot; crate::runtime::stats::STATS_NAMES.len()]> {
        self.objects.as_ref().map(|o| &o.stats)
    }

    fn advance(&mut self, dt_us: u64) {
        self.pending_us += dt_us as f64;
        // Half a microsecond of slack absorbs rounding of non-integer cycle times.
        while self.pending_us + 0.5 >= self.position_cycle_us {
            self.pending_us -= self.position_cycle_us;
            if self.trip.is_some() {
                // Held at rest (power stage off, holding brake closed) until reset; the
                // motor cools.
                self.heat(0.0);
                continue;
            }
            self.servo.step();
            self.heat(self.servo.axis.motor.current());
            if let Some(code) = self.supervise() {
                self.trip = Some(code);
                let x = self.rest_position();
                self.servo.reset_at_rest(x);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cnc(name: &str) -> AxisDrive {
        AxisDrive::from_config(&AxisConfig::from_preset(name).unwrap()).unwrap()
    }

    #[test]
    fn factor_group_defaults_match_the_mechanics() {
        // The protocol's factor (increments per user unit) must equal the adapter's
        // increments per load unit times the user unit, for every transmission.
        for name in ["cnc1", "cnc2", "cnc3", "cnc4", "cnc5"] {
            let d = cnc(name);
            let i = d.info();
            let inc_per_uu = f64::from(i.encoder_increments_per_rev)
                * (f64::from(i.gear_motor_revs) / f64::from(i.gear_shaft_revs))
                / (f64::from(i.feed_user_units) / f64::from(i.feed_shaft_revs));
            let want = d.inc_per_load() * d.user_unit;
            assert!(
                (inc_per_uu / want - 1.0).abs() < 2e-3,
                "{name}: factor group {inc_per_uu} inc/uu vs mechanics {want}"
            );
        }
    }

    #[test]
    fn a_position_command_moves_the_axis_there() {
        // Without backlash the position loop settles on the target (with backlash a P loop
        // hunts inside the gap, as the paper's machines do).
        let mut d = cnc("cnc1");
        d.set_param(AxisParam::Backlash, 0.0).unwrap();
        let target_inc = 0.5e-3 * d.inc_per_load(); // 0.5 mm
        for _ in 0..2000 {
            d.command(&DriveCommand {
                setpoint: Setpoint::Position {
                    position_inc: target_inc,
                    velocity_ff_inc_per_s: 0.0,
                    torque_ff_permille: 0.0,
                },
                max_torque_permille: 3000.0,
                max_velocity_inc_per_s: 0.0,
            });
            d.advance(1000);
        }
        let fb = d.feedback();
        let err_m = (fb.direct_position_inc as f64 - target_inc) / d.inc_per_load();
        assert!(
            err_m.abs() < 1e-6,
            "direct encoder {err_m} m from the target after 2 s"
        );
    }

    #[test]
    fn out_of_range_parameters_are_refused_and_change_nothing() {
        let mut d = cnc("cnc1");
        let before = d.param(AxisParam::Backlash);
        assert!(matches!(
            d.set_param(AxisParam::Backlash, -1e-5),
            Err(ParamError::OutOfRange { .. })
        ));
        assert!(d.set_param(AxisParam::Kv, f64::NAN).is_err());
        assert_eq!(d.param(AxisParam::Backlash), before);
        d.set_param(AxisParam::Backlash, 5e-5).unwrap();
        assert_eq!(d.param(AxisParam::Backlash), 5e-5);
        // Too stiff for the physics step: refused with a finite upper bound.
        match d.set_param(AxisParam::Stiffness, 1e15) {
            Err(ParamError::OutOfRange { max, .. }) => assert!(max < 1e15 && max > 1e8, "{max}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn encoder_loss_is_a_latched_sensor_fault_until_cleared_and_reset() {
        let mut d = cnc("cnc1");
        d.set_signal_lost(Encoder::Direct, true);
        d.advance(1000);
        assert_eq!(d.feedback().drive_fault, Some(ERROR_SENSOR));
        assert!(
            !d.reset_fault(),
            "fault reset must fail while the signal is lost"
        );
        d.set_signal_lost(Encoder::Direct, false);
        assert_eq!(d.feedback().drive_fault, Some(ERROR_SENSOR), "latched");
        assert!(d.reset_fault());
        assert_eq!(d.feedback().drive_fault, None);
    }

    fn torque_command(permille: f64) -> DriveCommand {
        DriveCommand {
            setpoint: Setpoint::Torque {
                torque_permille: permille,
            },
            max_torque_permille: 3000.0,
            max_velocity_inc_per_s: 0.0,
        }
    }

    /// Run `ms` position cycles with `cmd`; the first supervision fault and when it came.
    fn run_until_fault(d: &mut AxisDrive, cmd: &DriveCommand, ms: u64) -> Option<(u16, u64)> {
        for t in 0..ms {
            d.command(cmd);
            d.advance(1000);
            if let Some(code) = d.feedback().drive_fault {
                return Some((code, t));
            }
        }
        None
    }

    #[test]
    fn cst_at_full_torque_faults_on_overspeed_and_never_runs_away() {
        // A drive's n_max monitoring: at full torque with nothing to resist, the motor must
        // fault a margin above its maximum speed, on every preset, and stay there.
        for name in ["cnc1", "cnc2", "cnc3", "cnc4", "cnc5"] {
            let mut d = cnc(name);
            let max = d.supervision().overspeed_rad_per_s;
            let mut peak = 0.0f64;
            let mut fault = None;
            // 100 s simulated at full (peak) torque.
            for _ in 0..100_000 {
                d.command(&torque_command(10_000.0));
                d.advance(1000);
                peak = peak.max(d.servo.axis.motor_speed().abs());
                if let Some(code) = d.feedback().drive_fault {
                    fault.get_or_insert(code);
                }
            }
            assert_eq!(fault, Some(ERROR_OVERSPEED), "{name}");
            // One position cycle of overshoot at most beyond the threshold.
            assert!(
                peak < max * 1.5,
                "{name}: peak {peak} rad/s, trips at {max}"
            );
            let fb = d.feedback();
            assert!(
                fb.motor_velocity_inc_per_s.abs() < 1.0,
                "{name}: held at rest"
            );
        }
    }

    #[test]
    fn normal_operation_does_not_trip_supervision() {
        // Full-speed positioning with the preset's own limits: no fault.
        for name in ["cnc1", "cnc2", "cnc3", "cnc4", "cnc5"] {
            let mut d = cnc(name);
            let target_inc = 0.02 * d.inc_per_load(); // 20 mm or 1.1 deg
            let cmd = DriveCommand {
                setpoint: Setpoint::Position {
                    position_inc: target_inc,
                    velocity_ff_inc_per_s: 0.0,
                    torque_ff_permille: 0.0,
                },
                max_torque_permille: 3000.0,
                max_velocity_inc_per_s: 0.0,
            };
            assert_eq!(run_until_fault(&mut d, &cmd, 3000), None, "{name}");
        }
    }

    #[test]
    fn unphysical_parameters_are_refused_with_the_limit_that_applies() {
        for name in ["cnc1", "cnc2", "cnc3", "cnc4", "cnc5"] {
            let mut d = cnc(name);
            // The preset itself is inside the limits.
            for p in [
                AxisParam::Stiffness,
                AxisParam::Damping,
                AxisParam::LoadCoulombFriction,
                AxisParam::LoadViscousFriction,
                AxisParam::MotorCoulombFriction,
                AxisParam::ExternalLoad,
            ] {
                let v = d.param(p);
                d.set_param(p, v)
                    .unwrap_or_else(|e| panic!("{name}: preset {p:?} = {v} refused: {e:?}"));
            }
            let too_low = |r| matches!(r, Err(ParamError::OutOfRange { min, .. }) if min > 0.0);
            assert!(too_low(d.set_param(AxisParam::Damping, 0.0)), "{name}");
            assert!(too_low(d.set_param(AxisParam::Stiffness, 1e-24)), "{name}");
            let f = d.peak_load_force();
            for (p, v) in [
                (AxisParam::ExternalLoad, 1.01 * f),
                (AxisParam::ExternalLoad, -1.01 * f),
                (AxisParam::LoadCoulombFriction, 1.01 * f),
                (AxisParam::LoadCoulombFriction, -1.0),
                (AxisParam::LoadViscousFriction, -1.0),
                (AxisParam::LoadViscousFriction, 1e12),
                (AxisParam::MotorCoulombFriction, -1.0),
                (AxisParam::MotorCoulombFriction, 1e6),
                (AxisParam::Damping, f64::INFINITY),
                (AxisParam::Stiffness, f64::NAN),
            ] {
                let before = d.param(p);
                assert!(
                    matches!(d.set_param(p, v), Err(ParamError::OutOfRange { .. })),
                    "{name}: {p:?} = {v} accepted"
                );
                assert_eq!(d.param(p), before, "{name}: refused but changed");
            }
            // Loads the motor can hold are accepted.
            d.set_param(AxisParam::ExternalLoad, 0.5 * f).unwrap();
        }
    }

    #[test]
    fn a_runaway_faults_and_reset_node_restores_the_preset_at_rest() {
        // The sequence: the writes that would make the model unphysical are refused;
        // a load the motor could hold, on an axis nobody holds, runs away and the drive
        // faults on overspeed before anything absurd happens; after reset node the axis is
        // at rest with the preset's parameters and positions normally again.
        let mut d = cnc("cnc1");
        let k0 = d.param(AxisParam::Stiffness);
        assert!(d.set_param(AxisParam::Damping, 0.0).is_err());
        assert!(d.set_param(AxisParam::Stiffness, 1e-30 * 1e6).is_err());
        d.set_param(AxisParam::ExternalLoad, 1e4).unwrap();
        let disabled = DriveCommand {
            setpoint: Setpoint::Disabled,
            max_torque_permille: 3000.0,
            max_velocity_inc_per_s: 0.0,
        };
        let (code, _) = run_until_fault(&mut d, &disabled, 5000).expect("no fault");
        assert_eq!(code, ERROR_OVERSPEED);
        // 5 s more: held, nothing moves, values stay finite and small.
        for _ in 0..5000 {
            d.advance(1000);
        }
        let fb = d.feedback();
        assert!(fb.motor_velocity_inc_per_s.abs() < 1.0);
        assert!(fb.motor_position_inc.unsigned_abs() < (1u64 << 40));
        d.set_param(AxisParam::Stiffness, k0).unwrap();
        d.reset();
        assert_eq!(d.feedback().drive_fault, None);
        assert_eq!(d.param(AxisParam::ExternalLoad), 0.0);
        // Usable: positions 1 mm further and settles there.
        d.set_param(AxisParam::Backlash, 0.0).unwrap();
        let start = d.feedback().direct_position_inc as f64;
        let target_inc = start + 1e-3 * d.inc_per_load();
        let cmd = DriveCommand {
            setpoint: Setpoint::Position {
                position_inc: target_inc,
                velocity_ff_inc_per_s: 0.0,
                torque_ff_permille: 0.0,
            },
            max_torque_permille: 3000.0,
            max_velocity_inc_per_s: 0.0,
        };
        assert_eq!(run_until_fault(&mut d, &cmd, 2000), None);
        let err_m = (d.feedback().direct_position_inc as f64 - target_inc) / d.inc_per_load();
        assert!(err_m.abs() < 1e-6, "{err_m} m off after reset");
    }

    #[test]
    fn fault_reset_after_a_trip_starts_from_rest() {
        let mut d = cnc("cnc4");
        let (code, _) =
            run_until_fault(&mut d, &torque_command(10_000.0), 100_000).expect("no fault");
        assert_eq!(code, ERROR_OVERSPEED);
        assert!(d.reset_fault());
        assert_eq!(d.feedback().drive_fault, None);
        d.advance(1000);
        assert_eq!(
            d.feedback().drive_fault,
            None,
            "a fresh start does not trip at once"
        );
        assert!(d.servo.axis.motor_speed().abs() < 1.0);
    }

    #[test]
    fn both_encoders_are_sampled_at_the_same_instant_and_the_direct_one_is_always_live() {
        // Constant speed, no backlash: motor encoder (at the load) and direct encoder agree
        // within their quantisation, whichever encoder closes the position loop.
        for direct in [1.0, 0.0] {
            let mut d = cnc("cnc1");
            d.set_param(AxisParam::Backlash, 0.0).unwrap();
            d.set_param(AxisParam::PositionFromDirect, direct).unwrap();
            let v = 10e-3 * d.inc_per_load(); // 10 mm/s
            let mut worst: f64 = 0.0;
            let mut first = None;
            for t in 0..3000 {
                d.command(&DriveCommand {
                    setpoint: Setpoint::Velocity {
                        velocity_inc_per_s: v,
                        torque_ff_permille: 0.0,
                    },
                    max_torque_permille: 3000.0,
                    max_velocity_inc_per_s: 0.0,
                });
                d.advance(1000);
                let fb = d.feedback();
                if t == 1000 {
                    first = Some(fb.direct_position_inc);
                }
                if t > 1000 {
                    // Static deflection of the drive train under the friction force is part
                    // of the difference; quantisation of the 10 nm scale is the rest.
                    let diff = (fb.motor_position_inc - fb.direct_position_inc) as f64;
                    worst = worst.max((diff / d.inc_per_load()).abs());
                }
            }
            let moved =
                (d.feedback().direct_position_inc - first.unwrap()) as f64 / d.inc_per_load();
            assert!(
                moved > 15e-3,
                "direct encoder frozen: moved {moved} m (direct={direct})"
            );
            // 10 mm/s for 0.875 ms would be 8.75 um.
            assert!(
                worst < 0.5e-6,
                "motor - direct up to {worst} m (direct={direct})"
            );
        }
    }
}
