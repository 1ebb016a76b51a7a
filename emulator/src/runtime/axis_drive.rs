//! The drive adapter: [`drive_protocol::Drive`] implemented on the simulated servo axis.
//!
//! This is the one place where the drive's internal units (motor-encoder increments, per mille
//! of rated torque) meet SI. The protocol converts user units to increments (factor group);
//! this file converts increments to metres or radians at the load. Nothing else converts.
//!
//! The servo keeps its own control cycle (`position_cycle_us` of the preset) whatever the bus
//! tick: [`AxisDrive::advance`] runs as many position cycles as the elapsed time holds.

use crate::control::cascade::{Command, Servo, Setpoint as ServoSetpoint};
use crate::presets::{AxisConfig, AxisKind, ConfigError, Transmission};
use drive_protocol::{AxisParam, Drive, DriveCommand, DriveInfo, Feedback, ParamError, Setpoint};

use super::SimulatedDrive;

/// CiA 402 error code for an encoder (sensor) fault.
pub const ERROR_SENSOR: u16 = 0x7300;

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
        Ok(Self {
            position_cycle_us: built.control.position_cycle * 1e6,
            servo,
            info,
            inc_per_motor_rad,
            inc_per_load: inc_per_motor_rad * ratio,
            rated_torque_nm: cfg.rated_torque_nm,
            rated_current_a: cfg.rated_current_a,
            home_switch_at: if rotary { 1f64.to_radians() } else { 1e-3 },
            user_unit,
            pending_us: 0.0,
            fault_latched: false,
        })
    }

    /// Increments per load unit (m or rad): the adapter's conversion factor.
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
        Feedback {
            motor_position_inc: s.axis.motor_encoder.counts(),
            direct_position_inc: (s.direct_encoder_position() * self.inc_per_load).round() as i64,
            position_from_direct: s.cascade.params.position_from_direct,
            motor_velocity_inc_per_s: s.motor_velocity() * cps,
            velocity_demand_inc_per_s: s.velocity_demand() * cps,
            torque_permille: s.torque() / self.rated_torque_nm * 1e3,
            current_permille: s.current() / self.rated_current_a * 1e3,
            home_switch: s.axis.load_position() > self.home_switch_at,
            negative_limit_switch: false,
            positive_limit_switch: false,
            drive_fault: (self.fault_latched || s.encoder_fault()).then_some(ERROR_SENSOR),
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

    fn param(&self, param: AxisParam) -> Result<f64, ParamError> {
        let s = &self.servo;
        let m = &s.axis.mech.params;
        Ok(match param {
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
            _ => return Err(ParamError::Unsupported),
        })
    }

    fn set_param(&mut self, param: AxisParam, value: f64) -> Result<(), ParamError> {
        let rotary = self.info.rotary;
        // Ranges: what a worn or faulty machine can physically show, in SI at the load.
        let max_gap = if rotary { 0.1 } else { 0.01 }; // 5.7 deg / 10 mm
        let s = &mut self.servo;
        match param {
            AxisParam::Backlash => s.axis.set_backlash(check(value, 0.0, max_gap)?),
            AxisParam::Stiffness => {
                let k = check(value, f64::MIN_POSITIVE, f64::MAX)?;
                s.axis
                    .set_stiffness(k)
                    .map_err(|e| ParamError::OutOfRange {
                        min: 0.0,
                        // The stable step scales with 1/sqrt(k).
                        max: k * (e.max_step / e.step).powi(2),
                    })?;
            }
            AxisParam::Damping => {
                let c = check(value, 0.0, f64::MAX)?;
                s.axis.set_damping(c).map_err(|_| ParamError::OutOfRange {
                    min: 0.0,
                    max: s.axis.mech.params.contact.damping,
                })?;
            }
            AxisParam::LoadCoulombFriction => {
                let f = s.axis.mech.params.load_friction;
                s.axis
                    .set_load_friction(f.with_coulomb(check(value, 0.0, 1e7)?));
            }
            AxisParam::LoadViscousFriction => {
                let mut f = s.axis.mech.params.load_friction;
                f.viscous = check(value, 0.0, 1e9)?;
                s.axis.set_load_friction(f);
            }
            AxisParam::MotorCoulombFriction => {
                let f = s.axis.mech.params.motor_friction;
                s.axis
                    .set_motor_friction(f.with_coulomb(check(value, 0.0, 1e4)?));
            }
            AxisParam::ExternalLoad => s.axis.set_external_load(check(value, -1e7, 1e7)?),
            AxisParam::Kv => s.set_kv(check(value, 0.0, 1000.0)?),
            AxisParam::SpeedKp => {
                let ti = s.cascade.params.speed_ti;
                s.set_speed_gains(check(value, 0.0, 1e4)?, ti)
            }
            AxisParam::SpeedTi => {
                let kp = s.cascade.params.speed_kp;
                s.set_speed_gains(kp, check(value, 1e-4, 10.0)?)
            }
            AxisParam::MotorEncoderNoise => s.axis.motor_encoder.set_noise(check(value, 0.0, 1e6)?),
            AxisParam::DirectEncoderNoise => {
                let cpu = s.axis.direct_encoder.params.counts_per_unit;
                s.axis
                    .direct_encoder
                    .set_noise(check(value, 0.0, max_gap)? * cpu)
            }
            AxisParam::DirectEncoderOffset => {
                s.axis
                    .direct_encoder
                    .set_offset(check(value, -max_gap * 100.0, max_gap * 100.0)?)
            }
            AxisParam::PositionFromDirect => {
                s.set_position_from_direct(check(value, 0.0, 1.0)? >= 0.5)
            }
            _ => return Err(ParamError::Unsupported),
        }
        Ok(())
    }

    fn reset_fault(&mut self) -> bool {
        if self.servo.encoder_fault() {
            return false;
        }
        self.fault_latched = false;
        true
    }
}

impl SimulatedDrive for AxisDrive {
    fn advance(&mut self, dt_us: u64) {
        self.pending_us += dt_us as f64;
        // Half a microsecond of slack absorbs rounding of non-integer cycle times.
        while self.pending_us + 0.5 >= self.position_cycle_us {
            self.servo.step();
            self.pending_us -= self.position_cycle_us;
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
        let before = d.param(AxisParam::Backlash).unwrap();
        assert!(matches!(
            d.set_param(AxisParam::Backlash, -1e-5),
            Err(ParamError::OutOfRange { .. })
        ));
        assert!(d.set_param(AxisParam::Kv, f64::NAN).is_err());
        assert_eq!(d.param(AxisParam::Backlash).unwrap(), before);
        d.set_param(AxisParam::Backlash, 5e-5).unwrap();
        assert_eq!(d.param(AxisParam::Backlash).unwrap(), 5e-5);
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
}
