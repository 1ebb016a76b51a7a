//! Two-mass drive train: motor rotor and load, coupled through a transmission with backlash.
//!
//! Coordinates (SI): `pos[0]` motor angle (rad), `pos[1]` load position (m for a linear axis,
//! rad for a rotary axis), `vel` their rates. The transmission maps motor angle to a load-side
//! position `x_1 = phi_m / ratio` (ratio = motor rad per load unit: `2 pi / pitch` times the gear
//! stage for a screw, `gear / r_pinion` for rack and pinion, the total gear ratio for a table).
//! The compliance and backlash of the whole train are lumped at the load ([`Contact`]).
//!
//! Integration: a position-Verlet (drift-kick-drift) step. Positions advance half a step, the
//! forces are evaluated there, the velocities are kicked with friction solved implicitly
//! ([`Friction::step_velocity`]), then positions advance the second half. It costs one force
//! evaluation per step, is second-order and symplectic for the conservative part (energy of a
//! free oscillation stays bounded), and stays exact at zero speed with Coulomb friction.

use nalgebra::Vector2;

use super::backlash::Contact;
use super::friction::Friction;

/// Standard gravity, m/s^2.
pub const GRAVITY: f64 = 9.80665;

/// Mechanical parameters (SI; load quantities in m/N/kg or rad/N m/kg m^2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MechParams {
    /// Motor rad per load unit (m or rad).
    pub ratio: f64,
    /// Motor rotor (+ coupling, first gear) inertia, kg m^2.
    pub motor_inertia: f64,
    /// Load mass (kg) or table inertia (kg m^2).
    pub load_mass: f64,
    /// Backlash, stiffness and damping of the drive train, at the load.
    pub contact: Contact,
    /// Friction at the motor, N m.
    pub motor_friction: Friction,
    /// Friction at the load, N or N m.
    pub load_friction: Friction,
    /// Weight acting on the load along the axis, N (negative = pulls towards negative;
    /// `-m g` for a vertical axis whose positive direction is up, 0 otherwise).
    pub gravity_force: f64,
    /// Counterbalance (hydraulic cylinder, counterweight) force on the load, N.
    pub counterbalance_force: f64,
}

impl MechParams {
    /// Motor inertia seen at the load (kg or kg m^2): `J_m ratio^2`.
    pub fn motor_mass_at_load(&self) -> f64 {
        self.motor_inertia * self.ratio * self.ratio
    }

    /// Reduced mass of the two-mass oscillator at the load.
    pub fn reduced_mass(&self) -> f64 {
        let mm = self.motor_mass_at_load();
        mm * self.load_mass / (mm + self.load_mass)
    }

    /// Natural angular frequency of the two masses in contact (rad/s).
    pub fn contact_omega(&self) -> f64 {
        (self.contact.stiffness / self.reduced_mass()).sqrt()
    }

    /// Largest physics step this integrator is allowed to use: `omega h <= 0.5` and
    /// `c h / m_red <= 0.5`, a factor 4 inside the explicit stability limit (2) so that the
    /// contact is also resolved accurately.
    pub fn max_step(&self) -> f64 {
        let m_red = self.reduced_mass();
        let by_stiffness = 0.5 / self.contact_omega();
        let by_damping = if self.contact.damping > 0.0 {
            0.5 * m_red / self.contact.damping
        } else {
            f64::INFINITY
        };
        by_stiffness.min(by_damping)
    }
}

/// State of the two masses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MechState {
    /// Motor angle (rad), load position (m or rad).
    pub pos: Vector2<f64>,
    /// Motor speed (rad/s), load velocity (m/s or rad/s).
    pub vel: Vector2<f64>,
}

impl Default for MechState {
    fn default() -> Self {
        MechState {
            pos: Vector2::zeros(),
            vel: Vector2::zeros(),
        }
    }
}

/// Forces acting at one instant (for reporting and the derivative form).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MechForces {
    /// Transmitted contact force on the load, N or N m.
    pub contact: f64,
    /// Sum of all non-friction forces on the load, N or N m.
    pub load: f64,
    /// Sum of all non-friction torques on the motor, N m.
    pub motor: f64,
}

/// The two-mass mechanics with its state.
#[derive(Clone, Debug)]
pub struct Mechanics {
    pub params: MechParams,
    pub state: MechState,
    inv_ratio: f64,
    inv_jm: f64,
    inv_m: f64,
    static_load_force: f64,
    last_contact: f64,
    // Step constants, recomputed when the step or the parameters change.
    h: f64,
    h_inv_jm: f64,
    h_inv_m: f64,
    visc_m: f64,
    visc_l: f64,
}

impl Mechanics {
    pub fn new(params: MechParams) -> Self {
        let mut m = Mechanics {
            params,
            state: MechState::default(),
            inv_ratio: 0.0,
            inv_jm: 0.0,
            inv_m: 0.0,
            static_load_force: 0.0,
            last_contact: 0.0,
            h: 0.0,
            h_inv_jm: 0.0,
            h_inv_m: 0.0,
            visc_m: 1.0,
            visc_l: 1.0,
        };
        m.set_params(params);
        m
    }

    /// Replace the parameters, keeping the state.
    pub fn set_params(&mut self, params: MechParams) {
        self.params = params;
        self.inv_ratio = 1.0 / params.ratio;
        self.inv_jm = 1.0 / params.motor_inertia;
        self.inv_m = 1.0 / params.load_mass;
        self.static_load_force = params.gravity_force + params.counterbalance_force;
        let h = self.h;
        self.h = f64::NAN;
        self.prepare(h);
    }

    #[inline(always)]
    fn prepare(&mut self, h: f64) {
        if h != self.h {
            self.h = h;
            self.h_inv_jm = h * self.inv_jm;
            self.h_inv_m = h * self.inv_m;
            self.visc_m = self.params.motor_friction.viscous_factor(self.h_inv_jm);
            self.visc_l = self.params.load_friction.viscous_factor(self.h_inv_m);
        }
    }

    /// Deflection of the drive train at the load: `phi_m / ratio - x_load`.
    #[inline(always)]
    pub fn deflection(&self) -> f64 {
        self.state.pos[0] * self.inv_ratio - self.state.pos[1]
    }

    /// Non-friction forces at a given state (the derivative form of the model; friction is
    /// handled implicitly by the integrator).
    #[inline(always)]
    pub fn forces(&self, state: &MechState, motor_torque: f64, external: f64) -> MechForces {
        let defl = state.pos[0] * self.inv_ratio - state.pos[1];
        let rate = state.vel[0] * self.inv_ratio - state.vel[1];
        let f = self.params.contact.force(defl, rate);
        MechForces {
            contact: f,
            load: f + self.static_load_force + external,
            motor: motor_torque - f * self.inv_ratio,
        }
    }

    /// Time derivative of the state with friction evaluated explicitly (Coulomb as a sign
    /// function): `(d pos, d vel)`. For analysis and tests; stepping uses [`Mechanics::step`].
    pub fn derivatives(
        &self,
        state: &MechState,
        motor_torque: f64,
        external: f64,
    ) -> (Vector2<f64>, Vector2<f64>) {
        let f = self.forces(state, motor_torque, external);
        let p = &self.params;
        let am = (f.motor + p.motor_friction.force_at(state.vel[0])) * self.inv_jm;
        let al = (f.load + p.load_friction.force_at(state.vel[1])) * self.inv_m;
        (state.vel, Vector2::new(am, al))
    }

    /// Advance by `h` with the motor air-gap torque and the external load force held constant.
    #[inline(always)]
    pub fn step(&mut self, motor_torque: f64, external: f64, h: f64) {
        let half = 0.5 * h;
        let mid = MechState {
            pos: self.state.pos + self.state.vel * half,
            vel: self.state.vel,
        };
        self.prepare(h);
        let f = self.forces(&mid, motor_torque, external);
        let p = &self.params;
        let wm =
            p.motor_friction
                .step_velocity_pre(mid.vel[0], f.motor, self.h_inv_jm, self.visc_m);
        let vl = p
            .load_friction
            .step_velocity_pre(mid.vel[1], f.load, self.h_inv_m, self.visc_l);
        self.state.vel = Vector2::new(wm, vl);
        self.state.pos = mid.pos + self.state.vel * half;
        self.last_contact = f.contact;
    }

    /// Contact force of the last step, N or N m.
    pub fn contact_force(&self) -> f64 {
        self.last_contact
    }

    /// Kinetic + elastic energy (J). Potential energy of gravity is not included.
    pub fn energy(&self) -> f64 {
        let p = &self.params;
        let s = &self.state;
        0.5 * p.motor_inertia * s.vel[0] * s.vel[0]
            + 0.5 * p.load_mass * s.vel[1] * s.vel[1]
            + p.contact.elastic_energy(self.deflection())
    }
}
