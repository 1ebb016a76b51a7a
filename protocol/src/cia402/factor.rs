//! The factor group (0x608F position encoder resolution, 0x6091 gear ratio, 0x6092 feed
//! constant): the only place that converts between user units and motor-encoder increments.
//!
//! increments per user unit = (0x608F.1 / 0x608F.2) * (0x6091.1 / 0x6091.2) / (0x6092.1 / 0x6092.2)
//!
//! Velocity user unit = position user unit per second, acceleration = per second squared,
//! unless the device has an SI unit velocity 0x60A9 that names one (CiA 402-2: byte 3 the
//! prefix, a signed power of ten; byte 2 the unit's notation index of CiA 303-2; byte 1 the
//! denominator's, the time; byte 0 reserved): then a velocity user unit is that unit (e.g.
//! 0x00B44700 one revolution of the drive shaft per minute, 0xFFB44700 a tenth of one;
//! 0xFD010300 one mm/s where 0x60A8 is a metre) and an acceleration user unit that unit per
//! second. [`Factor::with_si_units`] applies it.
//!
//! An SI unit acceleration 0x60AA is read the same way, its denominator being the time of the
//! velocity: an acceleration user unit is that unit per that time per second (0x00B44700
//! one rev/min per second, the unit drives that count speeds in rpm give accelerations in;
//! 0x00B40300 one rev/s per second, rev/s^2). Without 0x60AA an acceleration user unit is
//! a velocity user unit per second. [`Factor::with_si_acceleration`] applies it.

use crate::drive::DriveInfo;

/// The conversion between user units and increments.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Factor {
    /// Motor-encoder increments per user unit.
    pub inc_per_uu: f64,
    /// Increments per second per velocity user unit (and per second squared per
    /// acceleration user unit, unless [`Factor::acc_inc_per_uu`] differs): `inc_per_uu`
    /// unless an SI velocity unit applies.
    pub vel_inc_per_uu: f64,
    /// Increments per second squared per acceleration user unit: `vel_inc_per_uu` unless an
    /// SI acceleration unit 0x60AA applies.
    pub acc_inc_per_uu: f64,
}

/// An SI unit object's value (0x60A8 position, 0x60A9 velocity), decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SiUnit {
    /// Power of ten (byte 3, signed): -3 milli, -1 deci, 0 none.
    pub prefix: i8,
    /// Notation index of the unit (byte 2): [`SI_METRE`], [`SI_RADIAN`], [`SI_DEGREE`],
    /// [`SI_REVOLUTION`], ...
    pub unit: u8,
    /// Notation index of the denominator (byte 1): [`SI_SECOND`], [`SI_MINUTE`],
    /// [`SI_HOUR`]; 0 none.
    pub per: u8,
}

/// CiA 303-2 notation index: metre.
pub const SI_METRE: u8 = 0x01;
/// CiA 303-2 notation index: second.
pub const SI_SECOND: u8 = 0x03;
/// CiA 303-2 notation index: radian.
pub const SI_RADIAN: u8 = 0x10;
/// CiA 303-2 notation index: degree.
pub const SI_DEGREE: u8 = 0x41;
/// CiA 303-2 notation index: minute.
pub const SI_MINUTE: u8 = 0x47;
/// CiA 303-2 notation index: hour.
pub const SI_HOUR: u8 = 0x48;
/// CiA 303-2 notation index: revolution.
pub const SI_REVOLUTION: u8 = 0xB4;

impl SiUnit {
    /// The bytes of an SI unit object's value.
    pub fn decode(raw: u32) -> SiUnit {
        SiUnit {
            prefix: (raw >> 24) as u8 as i8,
            unit: (raw >> 16) as u8,
            per: (raw >> 8) as u8,
        }
    }

    /// Seconds of the denominator (a velocity's time), if it is one this drive knows.
    pub fn per_seconds(self) -> Option<f64> {
        match self.per {
            SI_SECOND => Some(1.0),
            SI_MINUTE => Some(60.0),
            SI_HOUR => Some(3600.0),
            _ => None,
        }
    }

    /// 10^prefix.
    pub fn scale(self) -> f64 {
        10f64.powi(i32::from(self.prefix))
    }
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
        let inc_per_uu = inc_per_motor_rev * motor_rev_per_shaft_rev / uu_per_shaft_rev;
        Some(Factor {
            inc_per_uu,
            vel_inc_per_uu: inc_per_uu,
            acc_inc_per_uu: inc_per_uu,
        })
    }

    /// The factor with the SI units 0x60A8 (position, `None`: the device has none) and 0x60A9
    /// (velocity) applied: a velocity user unit becomes 0x60A9's unit where this drive can
    /// tell it in increments, i.e. revolutions of the drive shaft (0xB4: `inc_per_shaft_rev`
    /// increments each) or the position's own unit with another prefix (0x60A8 and 0x60A9
    /// name the same unit). Otherwise (an unknown unit or time, no time at all) unchanged:
    /// position user units per second. Returns the factor and whether 0x60A9 applied.
    pub fn with_si_units(
        self,
        position: Option<u32>,
        velocity: u32,
        inc_per_shaft_rev: f64,
    ) -> (Factor, bool) {
        match self.si_inc_per_uu(position, velocity, inc_per_shaft_rev) {
            Some(vel) => (
                Factor {
                    vel_inc_per_uu: vel,
                    acc_inc_per_uu: vel,
                    ..self
                },
                true,
            ),
            None => (self, false),
        }
    }

    /// The factor with the SI unit acceleration 0x60AA applied (after
    /// [`Factor::with_si_units`], if the device has 0x60A9): an acceleration user unit becomes
    /// 0x60AA's unit per its time per second where this drive can tell it in increments (the
    /// same units as 0x60A9). Otherwise unchanged. Returns the factor and whether it applied.
    pub fn with_si_acceleration(
        self,
        position: Option<u32>,
        acceleration: u32,
        inc_per_shaft_rev: f64,
    ) -> (Factor, bool) {
        match self.si_inc_per_uu(position, acceleration, inc_per_shaft_rev) {
            Some(acc) => (
                Factor {
                    acc_inc_per_uu: acc,
                    ..self
                },
                true,
            ),
            None => (self, false),
        }
    }

    /// Increments per second per unit of an SI unit value with a time denominator: the unit
    /// (revolutions of the drive shaft, or 0x60A8's unit with another prefix) with its prefix,
    /// per its time. `None` where this drive cannot tell it in increments.
    fn si_inc_per_uu(self, position: Option<u32>, raw: u32, inc_per_shaft_rev: f64) -> Option<f64> {
        let v = SiUnit::decode(raw);
        let t = v.per_seconds()?;
        let per_unit = if v.unit == SI_REVOLUTION {
            inc_per_shaft_rev
        } else {
            match position.map(SiUnit::decode) {
                // the same unit as a position user unit: the prefixes' ratio
                Some(p) if p.unit == v.unit && p.per == 0 => self.inc_per_uu / p.scale(),
                _ => return None,
            }
        };
        let x = per_unit * v.scale() / t;
        (x.is_finite() && x > 0.0).then_some(x)
    }

    /// Velocity user units to increments per second.
    #[inline]
    pub fn vel_to_inc(self, uu: f64) -> f64 {
        uu * self.vel_inc_per_uu
    }

    /// Acceleration user units to increments per second squared.
    #[inline]
    pub fn acc_to_inc(self, uu: f64) -> f64 {
        uu * self.acc_inc_per_uu
    }

    /// Increments per second squared to acceleration user units.
    #[inline]
    pub fn acc_to_uu(self, inc: f64) -> f64 {
        inc / self.acc_inc_per_uu
    }

    /// Increments per second to velocity user units.
    #[inline]
    pub fn vel_to_uu(self, inc: f64) -> f64 {
        inc / self.vel_inc_per_uu
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

    /// Position user units to increments.
    #[inline]
    pub fn to_inc(self, uu: f64) -> f64 {
        uu * self.inc_per_uu
    }

    /// Increments to position user units.
    #[inline]
    pub fn to_uu(self, inc: f64) -> f64 {
        inc / self.inc_per_uu
    }
}

/// The fraction `num / den` nearest `x` (> 0) whose terms fit UNSIGNED32, as a factor-group
/// object holds a real ratio (0x6092 for a user unit in radians: 2*pi*10^-prefix per shaft
/// revolution): the last continued-fraction convergent of `x` within range. `None` for a
/// value out of range (0 or less, not finite, above `u32::MAX` or below `1 / u32::MAX`).
pub fn ratio_u32(x: f64) -> Option<(u32, u32)> {
    let max = f64::from(u32::MAX);
    if !(x.is_finite() && x > 0.0 && x <= max && x >= 1.0 / max) {
        return None;
    }
    // convergents h/k: h(n) = a(n) h(n-1) + h(n-2), likewise k
    let (mut h0, mut h1, mut k0, mut k1) = (0.0f64, 1.0f64, 1.0f64, 0.0f64);
    let mut best = None;
    let mut r = x;
    for _ in 0..64 {
        let a = r.floor();
        let (h2, k2) = (a * h1 + h0, a * k1 + k0);
        if h2 > max || k2 > max {
            break;
        }
        if h2 >= 1.0 {
            best = Some((h2 as u32, k2 as u32));
        }
        (h0, h1, k0, k1) = (h1, h2, k1, k2);
        let frac = r - a;
        if frac < 1e-12 || (h2 / k2 - x).abs() <= x * f64::EPSILON {
            break;
        }
        r = 1.0 / frac;
    }
    best
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

    #[test]
    fn ratio_u32_is_the_nearest_fraction_that_fits() {
        use std::f64::consts::TAU;
        for x in [
            TAU,
            TAU * 1e3,
            TAU * 1e6,
            TAU * 1e-3,
            0.5,
            3.0,
            1e9,
            1.0 / 7.0,
        ] {
            let (n, d) = ratio_u32(x).unwrap();
            let err = (f64::from(n) / f64::from(d) - x).abs() / x;
            assert!(err < 1e-12, "{x}: {n}/{d}, relative error {err}");
        }
        assert_eq!(ratio_u32(3.0), Some((3, 1)));
        assert_eq!(ratio_u32(0.25), Some((1, 4)));
        // 2*pi*1e6 (a micro-radian user unit): the denominator is what keeps it exact
        let (n, d) = ratio_u32(TAU * 1e6).unwrap();
        assert!(d > 1 && n > 6_000_000, "{n}/{d}");
        for x in [0.0, -1.0, f64::NAN, f64::INFINITY, 5e9, 1e-10] {
            assert_eq!(ratio_u32(x), None, "{x}");
        }
    }

    #[test]
    fn si_velocity_units() {
        // 2000 inc/rev, 1 uu = 1 inc
        let f = Factor::from_objects(2000, 1, 1, 1, 2000, 1).unwrap();
        assert_eq!(f.vel_inc_per_uu, 1.0);
        // rev/min: 2000/60 inc/s per uu; 0.1 rev/min a tenth of that
        let (r, on) = f.with_si_units(None, 0x00B4_4700, 2000.0);
        assert!(on && (r.vel_inc_per_uu - 2000.0 / 60.0).abs() < 1e-9);
        assert_eq!(r.inc_per_uu, 1.0);
        let (r, _) = f.with_si_units(None, 0xFFB4_4700, 2000.0);
        assert!((r.vel_inc_per_uu - 200.0 / 60.0).abs() < 1e-9);
        // rev/s
        let (r, _) = f.with_si_units(None, 0x00B4_0300, 2000.0);
        assert!((r.vel_inc_per_uu - 2000.0).abs() < 1e-9);
        // position in um (0xFA010000), velocity in mm/s (0xFD010300): 1000 position uu per s
        let g = Factor::from_objects(1 << 20, 1, 1, 1, 10_000, 1).unwrap();
        let (r, on) = g.with_si_units(Some(0xFA01_0000), 0xFD01_0300, f64::from(1u32 << 20));
        assert!(on && (r.vel_inc_per_uu - 1000.0 * g.inc_per_uu).abs() < 1e-6);
        // not known: unchanged
        for v in [0x00B5_0000, 0x0001_0300, 0x00B4_9900, 0] {
            assert_eq!(f.with_si_units(None, v, 2000.0), (f, false), "{v:#x}");
        }
        assert!(!g.with_si_units(Some(0x0041_0000), 0xFD01_0300, 1.0).1);
    }

    #[test]
    fn si_acceleration_units() {
        // 2000 inc/rev, 1 uu = 1 inc; velocity in rpm, so acceleration in rpm/s
        let f = Factor::from_objects(2000, 1, 1, 1, 2000, 1).unwrap();
        let (v, _) = f.with_si_units(None, 0x00B4_4700, 2000.0);
        assert_eq!(v.acc_inc_per_uu, v.vel_inc_per_uu);
        assert!((v.acc_to_inc(60.0) - 2000.0).abs() < 1e-9);
        // 0x60AA rev/s per second: 2000 inc/s^2 per uu
        let (a, on) = v.with_si_acceleration(None, 0x00B4_0300, 2000.0);
        assert!(on && (a.acc_inc_per_uu - 2000.0).abs() < 1e-9);
        assert_eq!(a.vel_inc_per_uu, v.vel_inc_per_uu);
        assert!((a.acc_to_uu(a.acc_to_inc(7.0)) - 7.0).abs() < 1e-12);
        // 0x60AA 0.1 rev/min per second on a drive without 0x60A9
        let (a, on) = f.with_si_acceleration(None, 0xFFB4_4700, 2000.0);
        assert!(on && (a.acc_inc_per_uu - 200.0 / 60.0).abs() < 1e-9);
        assert_eq!(a.vel_inc_per_uu, 1.0);
        // not known: unchanged
        assert_eq!(
            f.with_si_acceleration(None, 0x00B5_0300, 2000.0),
            (f, false)
        );
    }
}
