//! The drive's cascade (SINUMERIK-style, as in the paper): position P (k_v) on the direct
//! encoder (or the motor encoder), speed PI (k_sp, T_si) on the motor encoder, current loop in
//! the motor model. [`Servo`] owns the [`Axis`] and the [`Cascade`] and runs them on a fixed
//! schedule: one [`Servo::step`] = one position cycle = `n` speed cycles = `n * m` physics steps.
//!
//! Units (SI): position and velocity set-points at the load (m, m/s for linear axes; rad, rad/s
//! for rotary axes), torque at the motor (N m), speed limit at the motor (rad/s).

use crate::axis::{Axis, AxisParams, StepTooCoarse};

pub use super::params::CascadeParams;
use super::position::PositionController;
use super::speed::{SpeedController, SpeedEstimator};

/// What the cascade is asked to do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Setpoint {
    /// Power stage off: no torque, the axis coasts.
    Disabled,
    /// Position loop closed in the drive.
    Position {
        /// Position set-point, m or rad at the load.
        position: f64,
        /// Velocity feed-forward, m/s or rad/s at the load.
        velocity_ff: f64,
        /// Torque feed-forward, N m at the motor.
        torque_ff: f64,
    },
    /// Speed loop closed in the drive.
    Velocity {
        /// Velocity set-point, m/s or rad/s at the load.
        velocity: f64,
        /// Torque feed-forward, N m at the motor.
        torque_ff: f64,
    },
    /// Torque demand straight to the current loop, N m at the motor.
    Torque { torque: f64 },
}

impl Setpoint {
    fn kind(&self) -> u8 {
        match self {
            Setpoint::Disabled => 0,
            Setpoint::Position { .. } => 1,
            Setpoint::Velocity { .. } => 2,
            Setpoint::Torque { .. } => 3,
        }
    }
}

/// A set-point with the limits in force.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Command {
    pub setpoint: Setpoint,
    /// Torque limit, N m at the motor (the motor's own limit applies as well).
    pub torque_limit: f64,
    /// Motor speed limit, rad/s (`<= 0` or infinite = the motor's maximum speed).
    pub speed_limit: f64,
}

impl Command {
    /// Disabled, no extra limits.
    pub const DISABLED: Command = Command {
        setpoint: Setpoint::Disabled,
        torque_limit: f64::INFINITY,
        speed_limit: f64::INFINITY,
    };

    /// A set-point with the motor's own limits only.
    pub fn new(setpoint: Setpoint) -> Self {
        Command {
            setpoint,
            torque_limit: f64::INFINITY,
            speed_limit: f64::INFINITY,
        }
    }
}

/// What the cascade computed in its last cycles.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CascadeOutputs {
    /// Position used as actual value by the position loop, m or rad.
    pub position_actual: f64,
    /// Following error (set-point - actual), m or rad.
    pub following_error: f64,
    /// Speed-loop demand, motor rad/s.
    pub velocity_demand: f64,
    /// Measured motor speed, rad/s.
    pub motor_velocity: f64,
    /// Torque demand to the current loop, N m.
    pub torque_demand: f64,
    /// True while a torque or speed limit clipped the demand.
    pub limited: bool,
}

/// The control cascade's state.
#[derive(Clone, Debug)]
pub struct Cascade {
    /// Gains and cycles: their one copy (the controllers below hold state only).
    pub params: CascadeParams,
    pub position: PositionController,
    pub speed: SpeedController,
    pub estimator: SpeedEstimator,
    last_kind: u8,
    out: CascadeOutputs,
    /// Both encoders as sampled at the start of the last position cycle (the same instant),
    /// counts: what the drive reports as 0x6063 / 0x60E4, so a master comparing the two
    /// measuring systems sees no skew.
    sampled_motor: i64,
    sampled_direct: i64,
    /// The motor reading of the position-cycle sample, used by the first speed cycle (same
    /// instant: one reading, not two).
    fresh_motor: Option<i64>,
}

impl Cascade {
    pub fn new(params: CascadeParams, motor_counts_per_rad: f64) -> Self {
        Cascade {
            params,
            position: PositionController::new(),
            speed: SpeedController::new(),
            estimator: SpeedEstimator::new(
                motor_counts_per_rad,
                params.speed_cycle,
                params.speed_filter,
            ),
            last_kind: 0,
            out: CascadeOutputs::default(),
            sampled_motor: 0,
            sampled_direct: 0,
            fresh_motor: None,
        }
    }

    /// Motor and direct encoder counts sampled at the same instant (start of the last
    /// position cycle).
    pub fn sampled_counts(&self) -> (i64, i64) {
        (self.sampled_motor, self.sampled_direct)
    }

    /// Sample both encoders now (both live whichever closes the position loop).
    #[inline(always)]
    fn sample(&mut self, axis: &mut Axis) {
        self.sampled_motor = axis.read_motor_encoder();
        self.sampled_direct = axis.read_direct_encoder();
        self.fresh_motor = Some(self.sampled_motor);
    }

    /// Forget the controller state (estimator, integrator, following error, outputs), as at
    /// power-up, and sample the encoders at the axis' present position.
    pub fn reset(&mut self, axis: &mut Axis) {
        let counts_per_rad = axis.motor_encoder.params.counts_per_unit;
        *self = Cascade::new(self.params, counts_per_rad);
        self.sample(axis);
        self.fresh_motor = None;
    }

    pub fn outputs(&self) -> &CascadeOutputs {
        &self.out
    }

    /// Mode switch handling, called at the start of a position cycle. Position <-> velocity
    /// keeps the speed integrator (the torque is continuous); from torque mode the integrator
    /// is preset to the last torque demand (minus feed-forward) so that the torque does not
    /// jump; from disabled it starts at zero, as a drive that has just enabled its power stage.
    fn switch_mode(&mut self, sp: &Setpoint) {
        let kind = sp.kind();
        if kind == self.last_kind {
            return;
        }
        let ff = match *sp {
            Setpoint::Position { torque_ff, .. } | Setpoint::Velocity { torque_ff, .. } => {
                torque_ff
            }
            _ => 0.0,
        };
        match (self.last_kind, kind) {
            (3, 1) | (3, 2) => self.speed.set_integral(self.out.torque_demand - ff),
            (_, 0) | (0, _) => self.speed.set_integral(0.0),
            _ => {}
        }
        if kind != 1 {
            self.position.clear();
        }
        self.last_kind = kind;
    }

    /// Position cycle: sample the position encoder and compute the speed set-point.
    #[inline(always)]
    pub fn position_cycle(&mut self, axis: &mut Axis, cmd: &Command) {
        self.switch_mode(&cmd.setpoint);
        let ratio = axis.ratio();
        self.sample(axis);
        let actual = if self.params.position_from_direct {
            axis.direct_encoder.position()
        } else {
            axis.motor_encoder.position() / ratio
        };
        self.out.position_actual = actual;
        let speed_limit = speed_limit(axis, cmd);
        let v = match cmd.setpoint {
            Setpoint::Position {
                position,
                velocity_ff,
                ..
            } => self
                .position
                .update(self.params.kv, position, actual, velocity_ff),
            Setpoint::Velocity { velocity, .. } => velocity,
            _ => 0.0,
        };
        let w = v * ratio;
        self.out.limited = w.abs() > speed_limit;
        self.out.velocity_demand = w.clamp(-speed_limit, speed_limit);
        self.out.following_error = self.position.following_error();
    }

    /// Speed cycle: sample the motor encoder, run the speed PI, set the motor's torque demand.
    #[inline(always)]
    pub fn speed_cycle(&mut self, axis: &mut Axis, cmd: &Command) {
        let counts = match self.fresh_motor.take() {
            Some(c) => c,
            None => axis.read_motor_encoder(),
        };
        let w = self.estimator.update(counts);
        self.out.motor_velocity = w;
        let limit = cmd.torque_limit.abs().min(axis.motor.torque_limit());
        let torque = match cmd.setpoint {
            Setpoint::Disabled => {
                axis.motor.disable();
                self.out.torque_demand = 0.0;
                return;
            }
            Setpoint::Torque { torque } => torque.clamp(-limit, limit),
            Setpoint::Position { torque_ff, .. } | Setpoint::Velocity { torque_ff, .. } => self
                .speed
                .update(&self.params, self.out.velocity_demand, w, torque_ff, limit),
        };
        self.out.torque_demand = torque;
        axis.motor.set_demand(torque);
    }
}

#[inline(always)]
fn speed_limit(axis: &Axis, cmd: &Command) -> f64 {
    let own = axis.motor.params.max_speed;
    if cmd.speed_limit > 0.0 {
        cmd.speed_limit.min(own)
    } else {
        own
    }
}

/// Why a servo could not be built.
#[derive(Clone, Debug, PartialEq)]
pub enum ServoError {
    StepTooCoarse(StepTooCoarse),
    /// A cycle time is not an integer multiple of the next faster one.
    Cycles(String),
}

impl std::fmt::Display for ServoError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ServoError::StepTooCoarse(e) => e.fmt(f),
            ServoError::Cycles(s) => f.write_str(s),
        }
    }
}

impl std::error::Error for ServoError {}

/// Integer ratio `slow / fast`, if it is one (within 1e-9 relative).
pub fn cycle_ratio(slow: f64, fast: f64) -> Option<u32> {
    if !(slow > 0.0 && fast > 0.0) {
        return None;
    }
    let r = slow / fast;
    let n = r.round();
    if n >= 1.0 && (r - n).abs() < 1e-9 * n {
        Some(n as u32)
    } else {
        None
    }
}

/// Axis + cascade on a fixed schedule.
#[derive(Clone, Debug)]
pub struct Servo {
    pub axis: Axis,
    pub cascade: Cascade,
    command: Command,
    substeps_per_speed: u32,
    speeds_per_position: u32,
    cycles: u64,
}

impl Servo {
    pub fn new(axis: AxisParams, control: CascadeParams) -> Result<Self, ServoError> {
        let substeps = cycle_ratio(control.speed_cycle, axis.step).ok_or_else(|| {
            ServoError::Cycles(format!(
                "speed cycle {} us is not an integer multiple of the physics step {} us",
                control.speed_cycle * 1e6,
                axis.step * 1e6
            ))
        })?;
        let speeds = cycle_ratio(control.position_cycle, control.speed_cycle).ok_or_else(|| {
            ServoError::Cycles(format!(
                "position cycle {} us is not an integer multiple of the speed cycle {} us",
                control.position_cycle * 1e6,
                control.speed_cycle * 1e6
            ))
        })?;
        let counts_per_rad = axis.motor_encoder.counts_per_unit;
        let axis = Axis::new(axis).map_err(ServoError::StepTooCoarse)?;
        Ok(Servo {
            axis,
            cascade: Cascade::new(control, counts_per_rad),
            command: Command::DISABLED,
            substeps_per_speed: substeps,
            speeds_per_position: speeds,
            cycles: 0,
        })
    }

    /// Set the command used from the next position cycle on.
    #[inline(always)]
    pub fn set_command(&mut self, command: Command) {
        self.command = command;
    }

    pub fn command(&self) -> &Command {
        &self.command
    }

    /// Advance one position cycle (`position_cycle` seconds of simulated time).
    #[inline]
    pub fn step(&mut self) {
        let cmd = self.command;
        self.cascade.position_cycle(&mut self.axis, &cmd);
        for _ in 0..self.speeds_per_position {
            self.cascade.speed_cycle(&mut self.axis, &cmd);
            for _ in 0..self.substeps_per_speed {
                self.axis.substep();
            }
        }
        self.cycles += 1;
    }

    /// Position cycle, s (the time one [`Servo::step`] advances).
    pub fn cycle_time(&self) -> f64 {
        self.cascade.params.position_cycle
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.cycles as f64 * self.cascade.params.position_cycle
    }

    /// Physics steps per position cycle.
    pub fn substeps_per_cycle(&self) -> u32 {
        self.substeps_per_speed * self.speeds_per_position
    }

    // ---- gains (take effect at the next cycle) ----
    pub fn set_kv(&mut self, kv: f64) {
        self.cascade.params.kv = kv;
    }
    pub fn set_speed_gains(&mut self, kp: f64, ti: f64) {
        self.cascade.params.speed_kp = kp;
        self.cascade.params.speed_ti = ti;
    }
    pub fn set_position_from_direct(&mut self, direct: bool) {
        self.cascade.params.position_from_direct = direct;
    }

    /// Re-initialise the state at rest at `load_position` (m or rad): both masses still, the
    /// gap centred, power stage off, controllers as at power-up. Parameters are kept.
    pub fn reset_at_rest(&mut self, load_position: f64) {
        self.axis.set_position(load_position);
        self.axis.motor.disable();
        self.cascade.reset(&mut self.axis);
        self.command = Command::DISABLED;
    }

    // ---- what a drive reports (encoder-based, SI) ----

    /// Motor-encoder position, motor rad.
    pub fn motor_encoder_angle(&self) -> f64 {
        self.axis.motor_encoder.position()
    }
    /// Motor-encoder position expressed at the load, m or rad.
    pub fn motor_encoder_position(&self) -> f64 {
        self.axis.motor_encoder.position() / self.axis.ratio()
    }
    /// Direct-encoder position, m or rad.
    pub fn direct_encoder_position(&self) -> f64 {
        self.axis.direct_encoder.position()
    }
    /// Measured motor speed, rad/s.
    pub fn motor_velocity(&self) -> f64 {
        self.cascade.out.motor_velocity
    }
    /// Speed demand, motor rad/s.
    pub fn velocity_demand(&self) -> f64 {
        self.cascade.out.velocity_demand
    }
    /// Actual motor torque, N m (a twin pinion's: both motors' together).
    pub fn torque(&self) -> f64 {
        self.axis.torque()
    }
    /// Actual motor current, A (a twin pinion's: both motors' together).
    pub fn current(&self) -> f64 {
        self.axis.torque() / self.axis.motor.params.torque_constant
    }
    /// Following error, m or rad.
    pub fn following_error(&self) -> f64 {
        self.cascade.out.following_error
    }
    /// True while an encoder signal is lost.
    pub fn encoder_fault(&self) -> bool {
        self.axis.motor_encoder.fault() || self.axis.direct_encoder.fault()
    }
}
