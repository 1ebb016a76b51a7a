//! Motion generators in increments: the trapezoid (PP, homing moves), velocity ramps (PV,
//! homing search) and stop ramps (quick stop, halt, slow-down option codes).

/// Position and velocity of a generated demand, increments and increments/s.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Axis {
    pub pos: f64,
    pub vel: f64,
}

/// Move `v` toward `target` by at most `step`.
#[inline]
pub fn approach(v: f64, target: f64, step: f64) -> f64 {
    if v < target {
        (v + step).min(target)
    } else {
        (v - step).max(target)
    }
}

impl Axis {
    /// One step of a trapezoid move to `target` limited by `vmax`, `acc`, `dec` (all > 0).
    /// Returns true when the target is reached (then `vel` is 0).
    pub fn move_to(&mut self, target: f64, vmax: f64, acc: f64, dec: f64, dt: f64) -> bool {
        let dist = target - self.pos;
        if dist.abs() < 1e-6 && self.vel.abs() <= dec * dt {
            self.pos = target;
            self.vel = 0.0;
            return true;
        }
        let v_stop = (2.0 * dec * dist.abs()).sqrt();
        let v_des = dist.signum() * vmax.min(v_stop);
        let speeding_up = self.vel * v_des >= 0.0 && v_des.abs() > self.vel.abs();
        let a = if speeding_up { acc } else { dec };
        self.vel = approach(self.vel, v_des, a * dt);
        let step = self.vel * dt;
        if (dist > 0.0 && step >= dist) || (dist < 0.0 && step <= dist) {
            self.pos = target;
            self.vel = 0.0;
            return true;
        }
        self.pos += step;
        false
    }

    /// One step of a velocity ramp toward `target_v` (PV): `acc` when speeding up, `dec`
    /// when slowing down (also through zero).
    pub fn ramp_velocity(&mut self, target_v: f64, acc: f64, dec: f64, dt: f64) {
        let speeding_up = self.vel * target_v >= 0.0 && target_v.abs() > self.vel.abs();
        let a = if speeding_up { acc } else { dec };
        self.vel = approach(self.vel, target_v, a * dt);
        self.pos += self.vel * dt;
    }

    /// One step of a stop ramp; true once standing.
    pub fn stop(&mut self, dec: f64, dt: f64) -> bool {
        self.ramp_velocity(0.0, dec, dec, dt);
        self.vel == 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_reaches_target_without_exceeding_limits() {
        let mut a = Axis::default();
        let dt = 0.001;
        let mut vmax_seen: f64 = 0.0;
        let mut steps = 0;
        while !a.move_to(1000.0, 500.0, 2000.0, 2000.0, dt) {
            vmax_seen = vmax_seen.max(a.vel);
            assert!(a.pos <= 1000.0);
            steps += 1;
            assert!(steps < 10_000);
        }
        assert_eq!(a.pos, 1000.0);
        assert!(vmax_seen <= 500.0 + 1e-9);
        // 1000 inc at 500 inc/s with 0.25 s ramps: about 2.25 s
        assert!((2000..2500).contains(&steps), "{steps}");
    }
}
