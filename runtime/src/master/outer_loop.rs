//! The position loop in the CNC, over the bus: the paper's machines close the position loop
//! in the NC (SINUMERIK: position controller in the NC on the direct measuring system, speed
//! loop in the drive) and send speed set-points to the drive. Here the reference master does
//! the same with the drive in cyclic synchronous velocity (CSV): at every SYNC it reads the
//! position the drive last reported in its TPDO (0x60E4 sub 1, the direct encoder, or 0x6064)
//! and sends the target velocity 0x60FF
//!
//! ```text
//! v = v_ref + k_v (x_ref - x)
//! ```
//!
//! where `v_ref` is its interpolator's velocity (feed-forward) and `x_ref` the interpolator's
//! position, started where the axis stands when the drive is enabled. The loop now has the
//! bus in it: the position sampled for SYNC k - 1 acts from SYNC k on, held for a period, so
//! the loop's delay is about 1.5 SYNC periods (see `emulator/tests/outer_loop_law.rs` for
//! where that starts to matter).

/// Which position the loop closes on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LoopEncoder {
    /// 0x60E4 sub 1: the direct (load-side) encoder, the paper's direct measuring system.
    Direct,
    /// 0x6064: the position actual value (motor encoder).
    Motor,
}

impl LoopEncoder {
    pub fn object(self) -> &'static str {
        match self {
            LoopEncoder::Direct => "0x60E4 sub 1 (direct encoder)",
            LoopEncoder::Motor => "0x6064 (position actual value)",
        }
    }
}

/// The master's position loop: its gain and the encoder it closes on.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PositionLoop {
    /// Position-loop gain k_v, 1/s.
    pub kv_per_s: f64,
    pub encoder: LoopEncoder,
}

/// The loop's state: its reference position, uu (None until the drive is enabled).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OuterLoop {
    pub config: PositionLoop,
    reference_uu: Option<f64>,
}

impl OuterLoop {
    pub fn new(config: PositionLoop) -> Self {
        Self {
            config,
            reference_uu: None,
        }
    }

    /// The velocity to command for the next SYNC, uu/s: `v_ref + k_v (x_ref - x)`, with the
    /// reference advanced by `v_ref * dt_s` (dt_s: the SYNC period, s) from where the axis
    /// stood (`position_uu`, the encoder's last value) when `enabled` became true. Not
    /// enabled: the reference follows the axis and the command is `v_ref`.
    pub fn command(&mut self, v_ref: f64, dt_s: f64, position_uu: f64, enabled: bool) -> f64 {
        if !enabled {
            self.reference_uu = None;
            return v_ref;
        }
        let r = self.reference_uu.get_or_insert(position_uu);
        *r += v_ref * dt_s;
        v_ref + self.config.kv_per_s * (*r - position_uu)
    }

    /// The reference position, uu (None while not enabled).
    pub fn reference_uu(&self) -> Option<f64> {
        self.reference_uu
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_command_is_feed_forward_plus_kv_times_the_error_from_where_the_axis_stood() {
        let mut l = OuterLoop::new(PositionLoop {
            kv_per_s: 30.0,
            encoder: LoopEncoder::Direct,
        });
        // Not enabled: the feed-forward alone, no reference.
        assert_eq!(l.command(0.0, 1e-3, 1234.0, false), 0.0);
        assert_eq!(l.reference_uu(), None);
        // Enabled at 1234 uu: the reference starts there and advances by v_ref dt.
        assert_eq!(l.command(1000.0, 1e-3, 1234.0, true), 1000.0 + 30.0 * 1.0);
        assert_eq!(l.reference_uu(), Some(1235.0));
        // The axis 5 uu behind: 30 1/s x 6 uu more.
        assert!((l.command(1000.0, 1e-3, 1231.0, true) - (1000.0 + 30.0 * 5.0)).abs() < 1e-9);
        // Disabled again: the reference is dropped.
        l.command(0.0, 1e-3, 0.0, false);
        assert_eq!(l.reference_uu(), None);
    }
}
