//! Speed loop: speed measured from motor-encoder differences with a short first-order filter
//! (as a drive does), and a PI controller (k_sp, T_si) producing the torque demand.

use super::params::CascadeParams;

/// Speed from encoder count differences, filtered.
#[derive(Clone, Debug)]
pub struct SpeedEstimator {
    rad_per_count: f64,
    cycle: f64,
    /// Filter coefficient per cycle: `1 - exp(-cycle / T_f)` (1 = no filter).
    alpha: f64,
    prev: i64,
    primed: bool,
    speed: f64,
}

impl SpeedEstimator {
    /// `counts_per_rad` of the motor encoder, speed-loop `cycle` (s), filter time `filter` (s).
    pub fn new(counts_per_rad: f64, cycle: f64, filter: f64) -> Self {
        let alpha = if filter > 0.0 {
            1.0 - (-cycle / filter).exp()
        } else {
            1.0
        };
        SpeedEstimator {
            rad_per_count: 1.0 / counts_per_rad,
            cycle,
            alpha,
            prev: 0,
            primed: false,
            speed: 0.0,
        }
    }

    /// Feed this cycle's count; returns the filtered speed, rad/s.
    #[inline(always)]
    pub fn update(&mut self, counts: i64) -> f64 {
        if !self.primed {
            self.prev = counts;
            self.primed = true;
        }
        let raw = (counts - self.prev) as f64 * self.rad_per_count / self.cycle;
        self.prev = counts;
        self.speed += (raw - self.speed) * self.alpha;
        self.speed
    }

    /// Last filtered speed, rad/s.
    pub fn speed(&self) -> f64 {
        self.speed
    }
}

/// Speed PI controller, output torque (N m). It holds its state only; the gains (k_sp,
/// T_si) and the cycle come from the cascade's [`CascadeParams`], their one copy.
#[derive(Clone, Debug)]
pub struct SpeedController {
    integral: f64,
    // Cached integral gain per cycle and the (kp, ti, cycle) it was computed for.
    ki: f64,
    ki_for: (f64, f64, f64),
}

impl Default for SpeedController {
    fn default() -> Self {
        SpeedController {
            integral: 0.0,
            ki: 0.0,
            ki_for: (f64::NAN, f64::NAN, f64::NAN),
        }
    }
}

impl SpeedController {
    pub fn new() -> Self {
        SpeedController::default()
    }

    /// One speed cycle with the gains of `p`: torque demand for speed error `set - actual`,
    /// with torque feed-forward, clipped to `limit`. Conditional integration (no wind-up
    /// while saturated in the direction of the error).
    #[inline(always)]
    pub fn update(
        &mut self,
        p: &CascadeParams,
        set: f64,
        actual: f64,
        torque_ff: f64,
        limit: f64,
    ) -> f64 {
        let (kp, ti, cycle) = (p.speed_kp, p.speed_ti, p.speed_cycle);
        let e = set - actual;
        let p = kp * e;
        if self.ki_for != (kp, ti, cycle) {
            self.ki_for = (kp, ti, cycle);
            self.ki = if ti > 0.0 && ti.is_finite() {
                kp * cycle / ti
            } else {
                0.0
            };
        }
        let ki = self.ki;
        let candidate = self.integral + ki * e;
        let u = p + candidate + torque_ff;
        if u > limit {
            if e < 0.0 {
                self.integral = candidate;
            }
            limit
        } else if u < -limit {
            if e > 0.0 {
                self.integral = candidate;
            }
            -limit
        } else {
            self.integral = candidate;
            u
        }
    }

    /// Integral part, N m.
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// Set the integral part (bumpless transfer), N m.
    pub fn set_integral(&mut self, value: f64) {
        self.integral = value;
    }
}
