//! The factor group (0x608F position encoder resolution, 0x6091 gear ratio, 0x6092 feed
//! constant): the only place that converts between user units and motor-encoder increments.
//!
//! increments per user unit = (0x608F.1 / 0x608F.2) * (0x6091.1 / 0x6091.2) / (0x6092.1 / 0x6092.2)
//!
//! Velocity user unit = position user unit per second, acceleration = per second squared, so
//! the same factor converts all three.

use crate::drive::DriveInfo;

/// The conversion between user units and increments.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Factor {
    /// Motor-encoder increments per user unit.
    pub inc_per_uu: f64,
}

impl Factor {
    /// From the raw factor-group objects. Returns `None` if any term is zero.
    pub fn from_objects(
        enc_inc: u32,
        enc_revs: u32,
        gear_motor: u32,
        gear_shaft: u32,
        feed: u32,
        feed_revs: u32,
    ) -> Option<Factor> {
        if enc_inc == 0
            || enc_revs == 0
            || gear_motor == 0
            || gear_shaft == 0
            || feed == 0
            || feed_revs == 0
        {
            return None;
        }
        let inc_per_motor_rev = enc_inc as f64 / enc_revs as f64;
        let motor_rev_per_shaft_rev = gear_motor as f64 / gear_shaft as f64;
        let uu_per_shaft_rev = feed as f64 / feed_revs as f64;
        Some(Factor {
            inc_per_uu: inc_per_motor_rev * motor_rev_per_shaft_rev / uu_per_shaft_rev,
        })
    }

    /// The default factor a drive starts with.
    pub fn from_info(info: &DriveInfo) -> Option<Factor> {
        Factor::from_objects(
            info.encoder_increments_per_rev,
            1,
            info.gear_motor_revs,
            info.gear_shaft_revs,
            info.feed_user_units,
            info.feed_shaft_revs,
        )
    }

    /// User units (position, velocity or acceleration) to increments.
    #[inline]
    pub fn to_inc(self, uu: f64) -> f64 {
        uu * self.inc_per_uu
    }

    /// Increments to user units.
    #[inline]
    pub fn to_uu(self, inc: f64) -> f64 {
        inc / self.inc_per_uu
    }
}

/// Saturating conversion of a real user-unit value to the wire's I32.
#[inline]
pub fn sat_i32(x: f64) -> i32 {
    if x.is_nan() {
        0
    } else {
        x.round().clamp(i32::MIN as f64, i32::MAX as f64) as i32
    }
}

/// Saturating conversion to U32.
#[inline]
pub fn sat_u32(x: f64) -> u32 {
    if x.is_nan() {
        0
    } else {
        x.round().clamp(0.0, u32::MAX as f64) as u32
    }
}

/// User units per motor revolution (for defaults derived from [`DriveInfo`]).
pub fn uu_per_motor_rev(info: &DriveInfo) -> f64 {
    match Factor::from_info(info) {
        Some(f) => f.to_uu(info.encoder_increments_per_rev as f64),
        None => 1.0,
    }
}

/// Default 0x607F / 0x6081: the motor's maximum speed in user units per second.
pub fn max_velocity_uu(info: &DriveInfo) -> f64 {
    info.max_motor_speed_rpm as f64 / 60.0 * uu_per_motor_rev(info)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn screw_10mm_um_user_unit() {
        // 2^20 inc/rev, 1:1, 10 mm per rev, user unit 1 um.
        let f = Factor::from_objects(1 << 20, 1, 1, 1, 10_000, 1).unwrap();
        assert!((f.to_inc(10_000.0) - (1u32 << 20) as f64).abs() < 1e-6);
        assert!((f.to_uu((1u32 << 20) as f64) - 10_000.0).abs() < 1e-6);
        assert!(Factor::from_objects(1, 1, 0, 1, 1, 1).is_none());
    }
}
