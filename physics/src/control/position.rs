//! Position loop: proportional gain k_v (1/s) on the position error, plus velocity
//! feed-forward. Output is a load-side velocity set-point (m/s or rad/s).
//!
//! The controller holds its state only; the gain comes from the cascade's
//! [`CascadeParams`](super::params::CascadeParams), its one copy.

/// The position loop's state: the last following error.
#[derive(Clone, Debug, Default)]
pub struct PositionController {
    following_error: f64,
}

impl PositionController {
    pub fn new() -> Self {
        PositionController::default()
    }

    /// One position cycle with gain `kv` (1/s): velocity set-point for position set-point
    /// `set`, actual `actual` and velocity feed-forward `velocity_ff` (all load units).
    #[inline(always)]
    pub fn update(&mut self, kv: f64, set: f64, actual: f64, velocity_ff: f64) -> f64 {
        self.following_error = set - actual;
        kv * self.following_error + velocity_ff
    }

    /// Following error of the last cycle (set-point minus actual), m or rad.
    pub fn following_error(&self) -> f64 {
        self.following_error
    }

    pub fn clear(&mut self) {
        self.following_error = 0.0;
    }
}
