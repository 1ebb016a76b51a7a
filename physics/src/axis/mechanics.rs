//! Two-mass drive train: motor rotor and load, coupled through a transmission with backlash.
//!
//! Coordinates (SI): `state.motor.pos` motor angle (rad), `state.load.pos` load position (m
//! for a linear axis, rad for a rotary axis), `vel` their rates. The transmission maps motor angle to a load-side
//! position `x_1 = phi_m / ratio` (ratio = motor rad per load unit: `2 pi / pitch` times the gear
//! stage for a screw, `gear / r_pinion` for rack and pinion, the total gear ratio for a table).
//! The compliance and backlash of the whole train are lumped at the load ([`Contact`]).
//!
//! Integration: a position-Verlet (drift-kick-drift) step. Positions advance half a step, the
//! forces are evaluated there, the velocities are kicked with friction solved implicitly
//! ([`Friction::step_velocity`]), then positions advance the second half. It costs one force
//! evaluation per step, is second-order and symplectic for the conservative part (energy of a
//! free oscillation stays bounded), and stays exact at zero speed with Coulomb friction.
//!
//! Twin pinion ([`TwinPinion`], `MechParams::twin`): two motors A and B, each with its own
//! pinion, drive the one load (rack or gear wheel), the drive's torque split between them as
//! `T/2 + T_p` (A) and `T/2 - T_p` (B), each clamped at its own limit. The bias `T_p` (the
//! electrical preload) presses A against the load's positive flank and B against its negative
//! one; each motor spends `J_m/2 alpha` on its own rotor, so the pinions carry only the
//! load's share, and while that share per pinion, `|m/r^2 alpha + F|/2`, stays below `T_p`
//! the load sits between two preloaded springs: no gap to cross (docs/physics.md).
//! The parameters stay those of the lumped train (the pair as the speed loop sees it): each
//! motor has half the rotor inertia and motor friction, each pinion's contact half the
//! stiffness and damping, and both pinions the gap `contact.backlash`. Halving is exact in
//! binary floating point, so with `T_p = 0` both motors move exactly as the lumped one: the
//! model reduces to the single contact bit for bit (tested).
//!
//! [`Mechanics`] keeps three things apart: the parameters ([`MechParams`], replaced as a whole
//! through [`Mechanics::set_params`]), the constants derived from them and from the step
//! (`Derived`, `StepConstants`, private and always in sync), and the state
//! ([`MechState`], the two masses by name). The two masses are two scalars each, not a
//! vector: the integrator never mixes their coordinates (no matrix, no norm), so named fields
//! say more than `pos[0]` / `pos[1]` and nalgebra is not needed.

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
    /// A second motor and pinion with an electrical preload (`None`: one motor, one contact).
    pub twin: Option<TwinPinion>,
}

/// The second motor and pinion of a twin-pinion drive and the bias between the two.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwinPinion {
    /// Bias (preload) torque per motor, N m, >= 0: motor A is given `T/2 + preload`, motor B
    /// `T/2 - preload`, `T` the drive's torque.
    pub preload_torque: f64,
    /// Torque limit of each motor, N m (each motor clamps its share here).
    pub motor_torque_limit: f64,
}

impl TwinPinion {
    /// The drive's torque `total` split into the torques of motors A and B, each clamped at
    /// its own limit.
    #[inline(always)]
    pub fn split(&self, total: f64) -> (f64, f64) {
        let half = 0.5 * total;
        let l = self.motor_torque_limit;
        (
            (half + self.preload_torque).clamp(-l, l),
            (half - self.preload_torque).clamp(-l, l),
        )
    }
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

/// Position and velocity of one of the two masses.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MassState {
    /// Motor angle (rad), or load position (m or rad).
    pub pos: f64,
    /// Motor speed (rad/s), or load velocity (m/s or rad/s).
    pub vel: f64,
}

impl MassState {
    /// The position `dt` seconds on at the present velocity.
    #[inline(always)]
    fn drifted(&self, dt: f64) -> f64 {
        self.pos + self.vel * dt
    }
}

/// State of the two masses (three with a twin pinion).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MechState {
    /// The motor rotor (motor A of a twin pinion: the one the speed loop measures).
    pub motor: MassState,
    /// The load (carriage or table).
    pub load: MassState,
    /// Motor B of a twin pinion (unused, at rest, with one motor).
    pub motor_b: MassState,
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

/// Constants derived from the parameters alone.
#[derive(Clone, Copy, Debug)]
struct Derived {
    /// `1 / ratio`: load units per motor rad.
    inv_ratio: f64,
    /// `1 / J_m`.
    inv_jm: f64,
    /// `1 / m_load`.
    inv_m: f64,
    /// Gravity plus counterbalance on the load, N.
    static_load_force: f64,
    /// Each motor of a twin pinion (half the lumped one); unused with one motor.
    each: Half,
}

/// One motor and pinion of a twin pinion: half the lumped rotor, contact and motor friction.
#[derive(Clone, Copy, Debug)]
struct Half {
    /// `1 / (J_m / 2)`.
    inv_jm: f64,
    contact: Contact,
    motor_friction: Friction,
}

impl Half {
    fn of(p: &MechParams) -> Self {
        let f = p.motor_friction;
        Half {
            inv_jm: 1.0 / (0.5 * p.motor_inertia),
            contact: Contact {
                backlash: p.contact.backlash,
                stiffness: 0.5 * p.contact.stiffness,
                damping: 0.5 * p.contact.damping,
            },
            motor_friction: Friction {
                coulomb: 0.5 * f.coulomb,
                static_: 0.5 * f.static_,
                stribeck_velocity: f.stribeck_velocity,
                viscous: 0.5 * f.viscous,
            },
        }
    }
}

impl Derived {
    fn of(p: &MechParams) -> Self {
        Derived {
            inv_ratio: 1.0 / p.ratio,
            inv_jm: 1.0 / p.motor_inertia,
            inv_m: 1.0 / p.load_mass,
            static_load_force: p.gravity_force + p.counterbalance_force,
            each: Half::of(p),
        }
    }
}

/// Constants of one step size `h`, recomputed when the step or the parameters change.
#[derive(Clone, Copy, Debug)]
struct StepConstants {
    h: f64,
    h_inv_jm: f64,
    h_inv_m: f64,
    /// Implicit viscous factors of motor and load friction for this step.
    visc_motor: f64,
    visc_load: f64,
    /// `h / (J_m / 2)` and the viscous factor of each motor of a twin pinion.
    h_inv_jm_each: f64,
    visc_motor_each: f64,
}

impl StepConstants {
    /// Not computed for any step yet (NaN never equals a step).
    const NONE: StepConstants = StepConstants {
        h: f64::NAN,
        h_inv_jm: 0.0,
        h_inv_m: 0.0,
        visc_motor: 1.0,
        visc_load: 1.0,
        h_inv_jm_each: 0.0,
        visc_motor_each: 1.0,
    };

    fn of(h: f64, p: &MechParams, d: &Derived) -> Self {
        let h_inv_jm = h * d.inv_jm;
        let h_inv_m = h * d.inv_m;
        let h_inv_jm_each = h * d.each.inv_jm;
        StepConstants {
            h,
            h_inv_jm,
            h_inv_m,
            visc_motor: p.motor_friction.viscous_factor(h_inv_jm),
            visc_load: p.load_friction.viscous_factor(h_inv_m),
            h_inv_jm_each,
            visc_motor_each: d.each.motor_friction.viscous_factor(h_inv_jm_each),
        }
    }
}

/// The two-mass mechanics: parameters, their derived constants, and the state.
#[derive(Clone, Debug)]
pub struct Mechanics {
    params: MechParams,
    derived: Derived,
    step_constants: StepConstants,
    /// Motor and load positions and velocities.
    pub state: MechState,
    /// Contact force of the last step, N or N m (an output, not integrated).
    last_contact: f64,
}

impl Mechanics {
    pub fn new(params: MechParams) -> Self {
        Mechanics {
            params,
            derived: Derived::of(&params),
            step_constants: StepConstants::NONE,
            state: MechState::default(),
            last_contact: 0.0,
        }
    }

    /// The parameters in force.
    pub fn params(&self) -> &MechParams {
        &self.params
    }

    /// Replace the parameters, keeping the state.
    pub fn set_params(&mut self, params: MechParams) {
        self.params = params;
        self.derived = Derived::of(&params);
        let h = self.step_constants.h;
        if !h.is_nan() {
            self.step_constants = StepConstants::of(h, &self.params, &self.derived);
        }
    }

    #[inline(always)]
    fn prepare(&mut self, h: f64) {
        if h != self.step_constants.h {
            self.step_constants = StepConstants::of(h, &self.params, &self.derived);
        }
    }

    /// Deflection of the drive train at the load: `phi_m / ratio - x_load`.
    #[inline(always)]
    pub fn deflection(&self) -> f64 {
        self.state.motor.pos * self.derived.inv_ratio - self.state.load.pos
    }

    /// Deflection of motor B's pinion at the load: `phi_b / ratio - x_load` (twin pinion).
    #[inline(always)]
    pub fn deflection_b(&self) -> f64 {
        self.state.motor_b.pos * self.derived.inv_ratio - self.state.load.pos
    }

    /// The torques of motors A and B for the drive's torque `total` (twin pinion; with one
    /// motor, `(total, 0)`).
    #[inline(always)]
    pub fn split_torque(&self, total: f64) -> (f64, f64) {
        match &self.params.twin {
            Some(t) => t.split(total),
            None => (total, 0.0),
        }
    }

    /// The forces pinions A and B transmit to the load now, N or N m (one contact: its force
    /// and 0). A twin pinion's preload holds while A's stays positive and B's negative.
    pub fn pinion_forces(&self) -> (f64, f64) {
        if self.params.twin.is_some() {
            self.twin_contacts(&self.state)
        } else {
            let inv_ratio = self.derived.inv_ratio;
            let s = &self.state;
            let f = self.params.contact.force(
                s.motor.pos * inv_ratio - s.load.pos,
                s.motor.vel * inv_ratio - s.load.vel,
            );
            (f, 0.0)
        }
    }

    /// Contact forces of pinions A and B on the load at a given state (twin pinion), N or N m.
    #[inline(always)]
    fn twin_contacts(&self, state: &MechState) -> (f64, f64) {
        let inv_ratio = self.derived.inv_ratio;
        let c = &self.derived.each.contact;
        let fa = c.force(
            state.motor.pos * inv_ratio - state.load.pos,
            state.motor.vel * inv_ratio - state.load.vel,
        );
        let fb = c.force(
            state.motor_b.pos * inv_ratio - state.load.pos,
            state.motor_b.vel * inv_ratio - state.load.vel,
        );
        (fa, fb)
    }

    /// Non-friction forces at a given state (the derivative form of the model; friction is
    /// handled implicitly by the integrator). With a twin pinion `motor` is motor A's.
    #[inline(always)]
    pub fn forces(&self, state: &MechState, motor_torque: f64, external: f64) -> MechForces {
        let inv_ratio = self.derived.inv_ratio;
        if self.params.twin.is_some() {
            let (ta, _) = self.split_torque(motor_torque);
            let (fa, fb) = self.twin_contacts(state);
            return MechForces {
                contact: fa + fb,
                load: (fa + fb) + self.derived.static_load_force + external,
                motor: ta - fa * inv_ratio,
            };
        }
        let defl = state.motor.pos * inv_ratio - state.load.pos;
        let rate = state.motor.vel * inv_ratio - state.load.vel;
        let f = self.params.contact.force(defl, rate);
        MechForces {
            contact: f,
            load: f + self.derived.static_load_force + external,
            motor: motor_torque - f * inv_ratio,
        }
    }

    /// Time derivative of the state with friction evaluated explicitly (Coulomb as a sign
    /// function), in the state's shape: each mass's `pos` holds its velocity, its `vel` its
    /// acceleration. For analysis and tests; stepping uses [`Mechanics::step`].
    pub fn derivatives(&self, state: &MechState, motor_torque: f64, external: f64) -> MechState {
        let f = self.forces(state, motor_torque, external);
        let p = &self.params;
        let al = (f.load + p.load_friction.force_at(state.load.vel)) * self.derived.inv_m;
        if p.twin.is_some() {
            let e = &self.derived.each;
            let (_, tb) = self.split_torque(motor_torque);
            let (_, fb) = self.twin_contacts(state);
            let fm_b = tb - fb * self.derived.inv_ratio;
            let aa = (f.motor + e.motor_friction.force_at(state.motor.vel)) * e.inv_jm;
            let ab = (fm_b + e.motor_friction.force_at(state.motor_b.vel)) * e.inv_jm;
            return MechState {
                motor: MassState {
                    pos: state.motor.vel,
                    vel: aa,
                },
                load: MassState {
                    pos: state.load.vel,
                    vel: al,
                },
                motor_b: MassState {
                    pos: state.motor_b.vel,
                    vel: ab,
                },
            };
        }
        let am = (f.motor + p.motor_friction.force_at(state.motor.vel)) * self.derived.inv_jm;
        MechState {
            motor: MassState {
                pos: state.motor.vel,
                vel: am,
            },
            load: MassState {
                pos: state.load.vel,
                vel: al,
            },
            motor_b: MassState::default(),
        }
    }

    /// Advance by `h` with the motor air-gap torque and the external load force held constant.
    /// With a twin pinion `motor_torque` is the drive's torque, split between the two motors
    /// ([`TwinPinion::split`]).
    #[inline(always)]
    pub fn step(&mut self, motor_torque: f64, external: f64, h: f64) {
        if self.params.twin.is_some() {
            let (ta, tb) = self.split_torque(motor_torque);
            self.step_twin(ta, tb, external, h);
            return;
        }
        let half = 0.5 * h;
        // Drift half a step.
        let s = self.state;
        let mid = MechState {
            motor: MassState {
                pos: s.motor.drifted(half),
                vel: s.motor.vel,
            },
            load: MassState {
                pos: s.load.drifted(half),
                vel: s.load.vel,
            },
            motor_b: s.motor_b,
        };
        // Kick the velocities, friction implicit.
        self.prepare(h);
        let f = self.forces(&mid, motor_torque, external);
        let p = &self.params;
        let k = &self.step_constants;
        let wm =
            p.motor_friction
                .step_velocity_pre(mid.motor.vel, f.motor, k.h_inv_jm, k.visc_motor);
        let vl = p
            .load_friction
            .step_velocity_pre(mid.load.vel, f.load, k.h_inv_m, k.visc_load);
        // Drift the second half at the new velocities.
        self.state.motor = MassState {
            pos: mid.motor.pos + wm * half,
            vel: wm,
        };
        self.state.load = MassState {
            pos: mid.load.pos + vl * half,
            vel: vl,
        };
        self.last_contact = f.contact;
    }

    /// [`Mechanics::step`] of a twin pinion with the torques of motors A and B given (N m):
    /// the same drift-kick-drift on three masses, each motor with its own pinion contact and
    /// half the friction. With one motor, B's torque is ignored.
    #[inline(always)]
    pub fn step_twin(&mut self, ta: f64, tb: f64, external: f64, h: f64) {
        if self.params.twin.is_none() {
            self.step(ta, external, h);
            return;
        }
        let half = 0.5 * h;
        let s = self.state;
        let mid = MechState {
            motor: MassState {
                pos: s.motor.drifted(half),
                vel: s.motor.vel,
            },
            load: MassState {
                pos: s.load.drifted(half),
                vel: s.load.vel,
            },
            motor_b: MassState {
                pos: s.motor_b.drifted(half),
                vel: s.motor_b.vel,
            },
        };
        self.prepare(h);
        let (fa, fb) = self.twin_contacts(&mid);
        let inv_ratio = self.derived.inv_ratio;
        let load_force = (fa + fb) + self.derived.static_load_force + external;
        let p = &self.params;
        let e = &self.derived.each;
        let k = &self.step_constants;
        let wa = e.motor_friction.step_velocity_pre(
            mid.motor.vel,
            ta - fa * inv_ratio,
            k.h_inv_jm_each,
            k.visc_motor_each,
        );
        let wb = e.motor_friction.step_velocity_pre(
            mid.motor_b.vel,
            tb - fb * inv_ratio,
            k.h_inv_jm_each,
            k.visc_motor_each,
        );
        let vl =
            p.load_friction
                .step_velocity_pre(mid.load.vel, load_force, k.h_inv_m, k.visc_load);
        self.state.motor = MassState {
            pos: mid.motor.pos + wa * half,
            vel: wa,
        };
        self.state.motor_b = MassState {
            pos: mid.motor_b.pos + wb * half,
            vel: wb,
        };
        self.state.load = MassState {
            pos: mid.load.pos + vl * half,
            vel: vl,
        };
        self.last_contact = fa + fb;
    }

    /// Contact force of the last step, N or N m (both pinions' with a twin pinion).
    pub fn contact_force(&self) -> f64 {
        self.last_contact
    }

    /// Kinetic + elastic energy (J). Potential energy of gravity is not included.
    pub fn energy(&self) -> f64 {
        let p = &self.params;
        let s = &self.state;
        if p.twin.is_some() {
            let c = &self.derived.each.contact;
            return 0.25
                * p.motor_inertia
                * (s.motor.vel * s.motor.vel + s.motor_b.vel * s.motor_b.vel)
                + 0.5 * p.load_mass * s.load.vel * s.load.vel
                + c.elastic_energy(self.deflection())
                + c.elastic_energy(self.deflection_b());
        }
        0.5 * p.motor_inertia * s.motor.vel * s.motor.vel
            + 0.5 * p.load_mass * s.load.vel * s.load.vel
            + p.contact.elastic_energy(self.deflection())
    }
}
