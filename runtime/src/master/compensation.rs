//! The master's backlash compensation, one per axis, as a CNC does it (SINUMERIK MD32450
//! `BACKLASH`, LinuxCNC `[JOINT_n]BACKLASH`, Fanuc 1851/1852): the set-point sent to the drive
//! is the interpolator's position plus half the compensation value in the direction of the
//! commanded motion, so every reversal of the commanded direction steps the set-point by the
//! whole value `C`, on the set-point side.
//!
//! The direction is the sign of the commanded position's last non-zero increment: while the
//! commanded velocity is zero (a dwell, the cycles around a reversal where the interpolator's
//! increments are nil) the sign is held, so standing still never undoes the compensation.
//! Before the first motion the offset is zero: the axis is taken to stand with its gap
//! centred (the simulated axis starts so), and the first motion steps it by `C / 2`.
//!
//! The step is applied in one position cycle (SINUMERIK's default; its MD36500 spreads it over
//! several cycles, LinuxCNC ramps it at the joint's limits). Sans-IO and allocation-free: one
//! call per position cycle, on the real-time path of a master.

/// One axis's compensation state. Positions in any unit, the same for the value and the
/// set-points (mm in the ballbar, uu on the bus, m in SI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BacklashCompensation {
    amount: f64,
    direction: i8,
    last: Option<f64>,
    reversals: u32,
}

impl BacklashCompensation {
    /// A compensation of `amount` (the gap to compensate, >= 0; 0 = none).
    pub fn new(amount: f64) -> Self {
        BacklashCompensation {
            amount,
            direction: 0,
            last: None,
            reversals: 0,
        }
    }

    /// The compensation value `C`.
    pub fn amount(&self) -> f64 {
        self.amount
    }

    /// The set-point to send for the interpolator's `position` of this cycle:
    /// `position + direction * C / 2`, the direction updated from the increment since the last
    /// call (held when the increment is zero).
    #[inline]
    pub fn apply(&mut self, position: f64) -> f64 {
        if let Some(last) = self.last {
            let d = position - last;
            let dir = if d > 0.0 {
                1
            } else if d < 0.0 {
                -1
            } else {
                self.direction
            };
            if dir != self.direction && self.direction != 0 {
                self.reversals += 1;
            }
            self.direction = dir;
        }
        self.last = Some(position);
        position + self.offset()
    }

    /// The offset now added to the set-point: `+-C / 2`, or 0 before the first motion.
    pub fn offset(&self) -> f64 {
        f64::from(self.direction) * self.amount * 0.5
    }

    /// The direction of the commanded motion: +1, -1, or 0 before the first motion.
    pub fn direction(&self) -> i8 {
        self.direction
    }

    /// Reversals of the commanded direction seen so far (the first motion is not one).
    pub fn reversals(&self) -> u32 {
        self.reversals
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_by_the_whole_value_at_each_reversal_and_holds_at_standstill() {
        let mut c = BacklashCompensation::new(0.04);
        // At rest: no offset.
        assert_eq!(c.apply(1.0), 1.0);
        assert_eq!(c.apply(1.0), 1.0);
        assert_eq!(c.direction(), 0);
        // First motion up: + C/2.
        assert!((c.apply(1.1) - 1.12).abs() < 1e-12);
        // Standing still: the sign is held.
        assert!((c.apply(1.1) - 1.12).abs() < 1e-12);
        assert_eq!(c.reversals(), 0);
        // Reversal: the set-point steps down by C.
        assert!((c.apply(1.05) - 1.03).abs() < 1e-12);
        assert_eq!(c.reversals(), 1);
        assert_eq!(c.direction(), -1);
        // Up again.
        assert!((c.apply(1.06) - 1.08).abs() < 1e-12);
        assert_eq!(c.reversals(), 2);
        // Zero compensation changes nothing.
        let mut z = BacklashCompensation::new(0.0);
        for p in [0.0, 1.0, 0.5, 0.5, 2.0] {
            assert_eq!(z.apply(p), p);
        }
    }
}
