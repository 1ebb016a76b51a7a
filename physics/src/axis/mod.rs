//! The simulated CNC feed axis: motor with current loop, two-mass drive train with backlash,
//! friction, gravity/counterbalance, external load, and two encoders.
//!
//! One [`Axis::substep`] runs the pipeline stages in order: current loop (motor torque) ->
//! mechanics (one integration step) . Encoders are sampled by the controller at its own cycle
//! ([`Axis::read_motor_encoder`], [`Axis::read_direct_encoder`]). Everything is SI; the load
//! coordinate is m for a linear axis and rad for a rotary axis. No CANopen here.

pub mod backlash;
pub mod encoder;
pub mod friction;
pub mod mechanics;
pub mod motor;

pub use backlash::Contact;
pub use encoder::{Encoder, EncoderParams, XorShift64};
pub use friction::Friction;
pub use mechanics::{MassState, MechParams, MechState, Mechanics, TwinPinion, GRAVITY};
pub use motor::{Motor, MotorParams};

/// Everything needed to build an [`Axis`] (SI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisParams {
    pub mech: MechParams,
    pub motor: MotorParams,
    /// Motor encoder: counts per motor radian.
    pub motor_encoder: EncoderParams,
    /// Direct encoder (linear scale or table encoder): counts per load unit (m or rad).
    pub direct_encoder: EncoderParams,
    /// True for a rotary (table) axis, false for a linear axis.
    pub rotary: bool,
    /// Physics step, s.
    pub step: f64,
}

/// Why an axis could not be built.
#[derive(Clone, Debug, PartialEq)]
pub struct StepTooCoarse {
    pub step: f64,
    pub max_step: f64,
}

impl std::fmt::Display for StepTooCoarse {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "physics step {:.3} us is too coarse for the drive-train stiffness: at most {:.3} us \
             (omega_n h <= 0.5, c h / m_red <= 0.5)",
            self.step * 1e6,
            self.max_step * 1e6
        )
    }
}

impl std::error::Error for StepTooCoarse {}

/// The axis: physics plus sensors.
#[derive(Clone, Debug)]
pub struct Axis {
    pub mech: Mechanics,
    pub motor: Motor,
    pub motor_encoder: Encoder,
    pub direct_encoder: Encoder,
    rotary: bool,
    step: f64,
    external_load: f64,
    steps: u64,
}

impl Axis {
    /// Build the axis at rest, in contact-free centre of the gap, at position 0.
    pub fn new(params: AxisParams) -> Result<Self, StepTooCoarse> {
        let max_step = params.mech.max_step();
        if params.step.is_nan() || params.step > max_step {
            return Err(StepTooCoarse {
                step: params.step,
                max_step,
            });
        }
        Ok(Axis {
            mech: Mechanics::new(params.mech),
            motor: Motor::new(params.motor, params.step),
            motor_encoder: Encoder::new(params.motor_encoder),
            direct_encoder: Encoder::new(params.direct_encoder),
            rotary: params.rotary,
            step: params.step,
            external_load: 0.0,
            steps: 0,
        })
    }

    /// One physics step: current loop, then mechanics. A twin pinion's motors share the
    /// current loop's torque with the preload between them ([`TwinPinion::split`]); with the
    /// power stage off neither has any torque, the preload included.
    #[inline(always)]
    pub fn substep(&mut self) {
        let tau = self.motor.step();
        if self.mech.params().twin.is_some() && !self.motor.enabled() {
            self.mech.step_twin(0.0, 0.0, self.external_load, self.step);
        } else {
            self.mech.step(tau, self.external_load, self.step);
        }
        self.steps += 1;
    }

    /// True for a twin-pinion drive (two motors and pinions on the load, with a preload).
    pub fn is_twin_pinion(&self) -> bool {
        self.mech.params().twin.is_some()
    }

    /// The torques of motors A and B now, N m (one motor: its torque and 0).
    pub fn motor_torques(&self) -> (f64, f64) {
        if self.is_twin_pinion() && !self.motor.enabled() {
            return (0.0, 0.0);
        }
        self.mech.split_torque(self.motor.torque())
    }

    /// The drive's torque delivered to the drive train now, N m: the motor's, or the sum of a
    /// twin pinion's two (less than the current loop's when a motor clamps at its limit).
    pub fn torque(&self) -> f64 {
        if self.is_twin_pinion() {
            let (a, b) = self.motor_torques();
            a + b
        } else {
            self.motor.torque()
        }
    }

    /// The preload of a twin pinion as a fraction of each motor's rated torque (half the
    /// pair's `rated_torque`); `None` with one motor.
    pub fn preload(&self) -> Option<f64> {
        self.mech
            .params()
            .twin
            .map(|t| t.preload_torque / (0.5 * self.motor.params.rated_torque))
    }

    /// Set a twin pinion's preload as a fraction of each motor's rated torque (>= 0, at the
    /// next step). Refused (`Err` with the reason, nothing changed) with one motor, where
    /// there is no second pinion to bias against.
    pub fn set_preload(&mut self, fraction_of_rated: f64) -> Result<(), &'static str> {
        let mut p = *self.mech.params();
        let Some(twin) = p.twin.as_mut() else {
            return Err("a single-contact drive train has no preload (not a twin pinion)");
        };
        if !(fraction_of_rated >= 0.0 && fraction_of_rated.is_finite()) {
            return Err("the preload must be a finite fraction >= 0 of the rated torque");
        }
        twin.preload_torque = fraction_of_rated * 0.5 * self.motor.params.rated_torque;
        self.mech.set_params(p);
        Ok(())
    }

    /// Physics step, s.
    pub fn step_size(&self) -> f64 {
        self.step
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.steps as f64 * self.step
    }

    pub fn is_rotary(&self) -> bool {
        self.rotary
    }

    /// Kinematic ratio: motor rad per load unit (rad/m for linear, rad/rad for rotary axes).
    pub fn ratio(&self) -> f64 {
        self.mech.params().ratio
    }

    /// Sample the motor encoder (counts).
    #[inline(always)]
    pub fn read_motor_encoder(&mut self) -> i64 {
        self.motor_encoder.read(self.mech.state.motor.pos)
    }

    /// Sample the direct encoder (counts).
    #[inline(always)]
    pub fn read_direct_encoder(&mut self) -> i64 {
        self.direct_encoder.read(self.mech.state.load.pos)
    }

    // ---- true state (for traces and tests only; controllers use the encoders) ----

    /// True motor angle, rad.
    pub fn motor_angle(&self) -> f64 {
        self.mech.state.motor.pos
    }
    /// True motor speed, rad/s.
    pub fn motor_speed(&self) -> f64 {
        self.mech.state.motor.vel
    }
    /// True load position, m or rad.
    pub fn load_position(&self) -> f64 {
        self.mech.state.load.pos
    }
    /// True load velocity, m/s or rad/s.
    pub fn load_velocity(&self) -> f64 {
        self.mech.state.load.vel
    }

    /// Put both masses at `load_position` (m or rad), at rest, the gap centred.
    pub fn set_position(&mut self, load_position: f64) {
        self.mech.state.load.pos = load_position;
        self.mech.state.motor.pos = load_position * self.mech.params().ratio;
        self.mech.state.motor.vel = 0.0;
        self.mech.state.load.vel = 0.0;
        self.mech.state.motor_b = self.mech.state.motor;
    }

    // ---- parameter setters (take effect at the next step) ----

    pub fn external_load(&self) -> f64 {
        self.external_load
    }
    /// External load force (N) or torque (N m) on the load, e.g. a cutting force.
    pub fn set_external_load(&mut self, f: f64) {
        self.external_load = f;
    }
    pub fn set_backlash(&mut self, backlash: f64) {
        let mut p = *self.mech.params();
        p.contact.backlash = backlash;
        self.mech.set_params(p);
    }
    /// Stiffness at the load; rejected (returns the limit) if the step would become too coarse.
    pub fn set_stiffness(&mut self, stiffness: f64) -> Result<(), StepTooCoarse> {
        let mut p = *self.mech.params();
        p.contact.stiffness = stiffness;
        self.try_set_mech(p)
    }
    pub fn set_damping(&mut self, damping: f64) -> Result<(), StepTooCoarse> {
        let mut p = *self.mech.params();
        p.contact.damping = damping;
        self.try_set_mech(p)
    }
    pub fn set_load_friction(&mut self, friction: Friction) {
        let mut p = *self.mech.params();
        p.load_friction = friction;
        self.mech.set_params(p);
    }
    pub fn set_motor_friction(&mut self, friction: Friction) {
        let mut p = *self.mech.params();
        p.motor_friction = friction;
        self.mech.set_params(p);
    }
    fn try_set_mech(&mut self, p: MechParams) -> Result<(), StepTooCoarse> {
        let max_step = p.max_step();
        if self.step.is_nan() || self.step > max_step {
            return Err(StepTooCoarse {
                step: self.step,
                max_step,
            });
        }
        self.mech.set_params(p);
        Ok(())
    }
}
