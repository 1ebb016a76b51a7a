//! Backlash contact between the motor side of the drive train and the load.
//!
//! ElastoBacklash-style (as Modelica's `ElastoBacklash`): inside the gap no force at all; in
//! contact a spring + damper acting on the penetration, with the total force clipped so that
//! the contact never pulls. Unlike a dead-zone model this gives no unphysical force when the
//! damping is non-zero (Nordin & Gutman 2002), and it lets the load coast freely inside the gap,
//! which is what makes the backlash limit cycle of the paper appear.
//!
//! Everything is expressed at the load: deflection in m (linear) or rad (rotary), force in N or
//! N m.

/// Parameters of the drive train with backlash, at the load.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// Total backlash (gap width), m or rad. Contact starts at |deflection| > backlash / 2.
    pub backlash: f64,
    /// Drive-train stiffness in contact, N/m or N m/rad.
    pub stiffness: f64,
    /// Drive-train damping in contact, N s/m or N m s/rad.
    pub damping: f64,
}

impl Contact {
    /// Transmitted force on the load (and, divided by the ratio, reaction on the motor).
    ///
    /// `deflection` = motor-side position (motor angle / ratio) minus load position;
    /// `rate` its time derivative. Positive force pushes the load in the positive direction.
    #[inline(always)]
    pub fn force(&self, deflection: f64, rate: f64) -> f64 {
        let half = 0.5 * self.backlash;
        if deflection > half {
            // Motor flank pushes the load forward: force may only be >= 0.
            let f = self.stiffness * (deflection - half) + self.damping * rate;
            f.max(0.0)
        } else if deflection < -half {
            let f = self.stiffness * (deflection + half) + self.damping * rate;
            f.min(0.0)
        } else {
            0.0
        }
    }

    /// Elastic energy stored in the contact spring (J), for energy checks.
    pub fn elastic_energy(&self, deflection: f64) -> f64 {
        let half = 0.5 * self.backlash;
        let p = if deflection > half {
            deflection - half
        } else if deflection < -half {
            deflection + half
        } else {
            0.0
        };
        0.5 * self.stiffness * p * p
    }

    /// True when the flanks touch (|deflection| beyond half the gap).
    pub fn in_contact(&self, deflection: f64) -> bool {
        deflection.abs() > 0.5 * self.backlash
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_force_inside_gap_and_never_pulls() {
        let c = Contact {
            backlash: 2e-5,
            stiffness: 2e8,
            damping: 1e5,
        };
        assert_eq!(c.force(0.0, 1.0), 0.0);
        assert_eq!(c.force(0.9e-5, -1.0), 0.0);
        // In contact, separating fast: the damper would pull, the clip forbids it.
        assert_eq!(c.force(1.1e-5, -1.0), 0.0);
        assert_eq!(c.force(-1.1e-5, 1.0), 0.0);
        assert!(c.force(1.1e-5, 0.0) > 0.0);
        assert!(c.force(-1.1e-5, 0.0) < 0.0);
    }
}
