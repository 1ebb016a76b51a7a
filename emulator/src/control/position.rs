//! Position loop: proportional gain k_v (1/s) on the position error, plus velocity
//! feed-forward. Output is a load-side velocity set-point (m/s or rad/s).

#[derive(Clone, Debug)]
pub struct PositionController {
    /// Position-loop gain k_v, 1/s.
    pub kv: f64,
    following_error: f64,
}

impl PositionController {
    pub fn new(kv: f64) -> Self {
        PositionController {
            kv,
            following_error: 0.0,
        }
    }

    /// One position cycle: velocity set-point for position set-point `set`, actual `actual`
    /// and velocity feed-forward `velocity_ff` (all load units).
    #[inline(always)]
    pub fn update(&mut self, set: f64, actual: f64, velocity_ff: f64) -> f64 {
        self.following_error = set - actual;
        self.kv * self.following_error + velocity_ff
    }

    /// Following error of the last cycle (set-point minus actual), m or rad.
    pub fn following_error(&self) -> f64 {
        self.following_error
    }

    pub fn clear(&mut self) {
        self.following_error = 0.0;
    }
}
