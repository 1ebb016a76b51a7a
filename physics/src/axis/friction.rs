//! Friction on one body: Coulomb (+ optional Stribeck/static peak) and viscous.
//!
//! Coulomb friction is solved implicitly for the velocity update of one step (a
//! "velocity-clamping" stick-slip model): the friction impulse available in one step is
//! `F_c(v) h`; if it is enough to stop the body, the body sticks at exactly zero speed,
//! otherwise it slides with the impulse opposing the new velocity. This is exact at zero speed
//! (no creep, no chattering), unconditionally stable for any step, needs no transcendental
//! function and is deterministic. Viscous friction is solved implicitly as well.

/// Friction parameters of one body, in the body's own coordinate (N or N m).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Friction {
    /// Coulomb (sliding) friction, N or N m (>= 0).
    pub coulomb: f64,
    /// Static (breakaway) friction, N or N m (>= coulomb). Equal to `coulomb` = no Stribeck.
    pub static_: f64,
    /// Stribeck velocity, m/s or rad/s (> 0 when `static_ > coulomb`).
    pub stribeck_velocity: f64,
    /// Viscous coefficient, N s/m or N m s/rad (>= 0).
    pub viscous: f64,
}

impl Friction {
    /// The same friction with another Coulomb level; a Stribeck peak keeps its ratio to it.
    pub fn with_coulomb(self, coulomb: f64) -> Friction {
        let ratio = if self.coulomb > 0.0 {
            (self.static_ / self.coulomb).max(1.0)
        } else {
            1.0
        };
        Friction {
            coulomb,
            static_: coulomb * ratio,
            ..self
        }
    }

    /// Sliding friction magnitude at speed `v`: `F_c + (F_s - F_c) / (1 + (v/v_s)^2)`.
    #[inline(always)]
    pub fn coulomb_at(&self, v: f64) -> f64 {
        if self.static_ > self.coulomb {
            let r = v / self.stribeck_velocity;
            self.coulomb + (self.static_ - self.coulomb) / (1.0 + r * r)
        } else {
            self.coulomb
        }
    }

    /// Velocity after one step `h` of a body with inverse mass `inv_m` at velocity `v`, driven
    /// by the non-friction force `f_other`, with this friction solved implicitly.
    #[inline(always)]
    pub fn step_velocity(&self, v: f64, f_other: f64, inv_m: f64, h: f64) -> f64 {
        let v_free = v + f_other * inv_m * h;
        let dv_c = self.coulomb_at(v) * inv_m * h;
        let v_c = if v_free.abs() <= dv_c {
            0.0
        } else {
            v_free - dv_c.copysign(v_free)
        };
        v_c / (1.0 + self.viscous * inv_m * h)
    }

    /// [`Friction::step_velocity`] with the step constants precomputed: `dt_inv_m = h / m`,
    /// `viscous_factor = 1 / (1 + b h / m)` (see [`Friction::viscous_factor`]).
    #[inline(always)]
    pub fn step_velocity_pre(
        &self,
        v: f64,
        f_other: f64,
        dt_inv_m: f64,
        viscous_factor: f64,
    ) -> f64 {
        let v_free = v + f_other * dt_inv_m;
        let dv_c = self.coulomb_at(v) * dt_inv_m;
        let v_c = if v_free.abs() <= dv_c {
            0.0
        } else {
            v_free - dv_c.copysign(v_free)
        };
        v_c * viscous_factor
    }

    /// `1 / (1 + b h / m)` for [`Friction::step_velocity_pre`].
    pub fn viscous_factor(&self, dt_inv_m: f64) -> f64 {
        1.0 / (1.0 + self.viscous * dt_inv_m)
    }

    /// Friction force (for reporting) at speed `v`; zero when stuck.
    pub fn force_at(&self, v: f64) -> f64 {
        if v == 0.0 {
            0.0
        } else {
            -(self.coulomb_at(v).copysign(v) + self.viscous * v)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sticks_below_breakaway_and_slides_above() {
        let f = Friction {
            coulomb: 10.0,
            static_: 12.0,
            stribeck_velocity: 0.001,
            viscous: 0.0,
        };
        // At rest, 11 N is below the 12 N breakaway: stays exactly at rest, for many steps.
        let mut v = 0.0;
        for _ in 0..1000 {
            v = f.step_velocity(v, 11.0, 1.0, 1e-4);
        }
        assert_eq!(v, 0.0);
        // 13 N breaks away.
        let v = f.step_velocity(0.0, 13.0, 1.0, 1e-4);
        assert!(v > 0.0);
        // A sliding body with no drive force stops and stays stopped, without oscillating.
        let mut v = 0.01;
        for _ in 0..1000 {
            v = f.step_velocity(v, 0.0, 1.0, 1e-4);
            assert!(v >= 0.0);
        }
        assert_eq!(v, 0.0);
    }
}
