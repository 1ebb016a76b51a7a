//! Contour interpolation on two axes: the circular test of ISO 230-4 (the ballbar) as a CNC's
//! interpolator runs it. Per direction: an arc-in on the circle (the feed ramped up from rest,
//! then held), the full data circle at constant feed, an arc-out (held, then ramped down to
//! rest); CW first, then CCW back over the same circle, with dwells at rest before, between and
//! after. The set-points are a closed-form function of time ([`CircleTest::sample`]): sans-IO,
//! no state, no allocation.
//!
//! Angles follow the ballbar's convention: measured counter-clockwise from +X about the centre.
//! The CW pass starts at `+overrun` and ends at `-360 deg - overrun`, the CCW pass goes back from
//! there (`-overrun`, the same point) to `360 deg + overrun`. X reverses at 0 and 180 deg, Y at
//! 90 and 270 deg.

use std::f64::consts::PI;

/// Direction of a pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    /// Clockwise (the angle decreases).
    Cw,
    /// Counter-clockwise (the angle increases).
    Ccw,
}

impl Direction {
    /// -1 for CW, +1 for CCW: the sign of the angle's rate.
    pub fn sign(self) -> f64 {
        match self {
            Direction::Cw => -1.0,
            Direction::Ccw => 1.0,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Direction::Cw => "cw",
            Direction::Ccw => "ccw",
        }
    }
}

/// Where in the test a sample is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CircleSample {
    /// Commanded position, the circle's unit (m in SI).
    pub x: f64,
    pub y: f64,
    /// The pass this sample belongs to (None: at rest before, between or after).
    pub direction: Option<Direction>,
    /// Angle travelled along the pass from the start of the data circle, rad: negative on the
    /// arc-in, 0 .. 2 pi on the data circle, above 2 pi on the arc-out (0 at rest).
    pub travelled_rad: f64,
    /// True while the feed is ramped (the first and last `ramp_s` of a pass).
    pub ramping: bool,
}

/// The circular test's plan. Lengths in one unit (m in SI), times in s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CircleTest {
    /// Centre of the circle.
    pub centre: (f64, f64),
    pub radius: f64,
    /// Path speed on the circle (the feed), unit/s.
    pub feed: f64,
    /// Arc-in and arc-out angle, rad.
    pub overrun_rad: f64,
    /// Duration of the feed's ramp up (and down), s: raised cosine, no jump in acceleration at
    /// the start.
    pub ramp_s: f64,
    /// Time at rest before the first pass, between the passes and after the last, s.
    pub dwell_s: f64,
}

/// Arc-in and arc-out angle of [`CircleTest::new`], rad (90 deg).
pub const OVERRUN_RAD: f64 = PI / 2.0;
/// Longest feed ramp, s.
pub const MAX_RAMP_S: f64 = 0.5;
/// The ramp takes at most this share of the arc-in, so the loops settle at constant feed
/// before the data circle begins.
const RAMP_SHARE_OF_OVERRUN: f64 = 1.0 / 3.0;
/// Dwell of [`CircleTest::new`], s.
pub const DWELL_S: f64 = 0.5;

impl CircleTest {
    /// The plan for a circle of `radius` at `feed` about `centre`, with the default overrun,
    /// ramp and dwell.
    pub fn new(centre: (f64, f64), radius: f64, feed: f64) -> Self {
        let ramp_dist = radius * OVERRUN_RAD * RAMP_SHARE_OF_OVERRUN;
        // The ramp covers feed * ramp_s / 2 of the path.
        let ramp_s = (2.0 * ramp_dist / feed).min(MAX_RAMP_S);
        CircleTest {
            centre,
            radius,
            feed,
            overrun_rad: OVERRUN_RAD,
            ramp_s,
            dwell_s: DWELL_S,
        }
    }

    /// Path length of one pass.
    fn pass_length(&self) -> f64 {
        self.radius * (2.0 * PI + 2.0 * self.overrun_rad)
    }

    /// Duration of one pass, s (the two half ramps lose `ramp_s` against constant feed).
    pub fn pass_s(&self) -> f64 {
        self.pass_length() / self.feed + self.ramp_s
    }

    /// Duration of the whole test, s.
    pub fn duration_s(&self) -> f64 {
        3.0 * self.dwell_s + 2.0 * self.pass_s()
    }

    /// Start angle of a pass, rad.
    fn start_angle(&self, d: Direction) -> f64 {
        -d.sign() * self.overrun_rad
    }

    /// The start point (where the axes stand at rest at time 0).
    pub fn start_point(&self) -> (f64, f64) {
        self.point(self.start_angle(Direction::Cw))
    }

    fn point(&self, angle: f64) -> (f64, f64) {
        (
            self.centre.0 + self.radius * angle.cos(),
            self.centre.1 + self.radius * angle.sin(),
        )
    }

    /// Path travelled `t` seconds into a pass (0 <= t <= pass_s).
    fn path_at(&self, t: f64) -> (f64, bool) {
        let (v, tr) = (self.feed, self.ramp_s);
        let total = self.pass_s();
        // raised-cosine ramp: v(t) = v (1 - cos(pi t / tr)) / 2
        let up = |t: f64| 0.5 * v * (t - tr / PI * (PI * t / tr).sin());
        if tr <= 0.0 {
            return (v * t, false);
        }
        if t < tr {
            (up(t), true)
        } else if t <= total - tr {
            (0.5 * v * tr + v * (t - tr), false)
        } else {
            (self.pass_length() - up(total - t), true)
        }
    }

    /// The set-point `t` seconds after the start.
    pub fn sample(&self, t: f64) -> CircleSample {
        let pass = self.pass_s();
        let starts = [
            (Direction::Cw, self.dwell_s),
            (Direction::Ccw, 2.0 * self.dwell_s + pass),
        ];
        for (d, t0) in starts {
            if t >= t0 && t < t0 + pass {
                let (s, ramping) = self.path_at(t - t0);
                let travelled = s / self.radius - self.overrun_rad;
                let angle = self.start_angle(d) + d.sign() * (s / self.radius);
                let (x, y) = self.point(angle);
                return CircleSample {
                    x,
                    y,
                    direction: Some(d),
                    travelled_rad: travelled,
                    ramping,
                };
            }
        }
        let d = if t < self.dwell_s {
            Direction::Cw
        } else if t < 2.0 * self.dwell_s + pass {
            // between the passes: the CW pass's end is the CCW pass's start
            Direction::Ccw
        } else {
            // after: back where the test started
            Direction::Cw
        };
        let (x, y) = self.point(self.start_angle(d));
        CircleSample {
            x,
            y,
            direction: None,
            travelled_rad: 0.0,
            ramping: false,
        }
    }
}

/// The geometric angle (ballbar convention, deg in 0..360) at which a pass has travelled
/// `travelled_deg` from its data start.
pub fn angle_deg(direction: Direction, travelled_deg: f64) -> f64 {
    (direction.sign() * travelled_deg).rem_euclid(360.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_passes_run_the_circle_both_ways_at_the_feed_and_join_at_rest() {
        let c = CircleTest::new((0.0, 0.0), 0.1, 1.0 / 60.0);
        let dt = 1e-3;
        let n = (c.duration_s() / dt) as usize;
        let mut last = c.sample(0.0);
        assert_eq!(last.direction, None);
        assert!(((last.x, last.y).0 - 0.0).abs() < 1e-12 && (last.y - 0.1).abs() < 1e-12);
        let mut max_jump = 0.0f64;
        let mut data_speed = Vec::new();
        for i in 1..=n {
            let s = c.sample(i as f64 * dt);
            let r = (s.x * s.x + s.y * s.y).sqrt();
            assert!((r - 0.1).abs() < 1e-12, "on the circle");
            let step = ((s.x - last.x).powi(2) + (s.y - last.y).powi(2)).sqrt();
            max_jump = max_jump.max(step);
            if s.direction.is_some() && !s.ramping && last.direction == s.direction {
                data_speed.push(step / dt);
            }
            last = s;
        }
        // No jump anywhere: the step never exceeds the feed's.
        assert!(max_jump <= 1.0 / 60.0 * dt * 1.0001, "{max_jump}");
        for v in data_speed {
            assert!((v - 1.0 / 60.0).abs() < 1e-4 / 60.0, "{v}");
        }
        // Angles: CW data starts at 0 and travels towards 270.
        assert!((angle_deg(Direction::Cw, 90.0) - 270.0).abs() < 1e-12);
        assert!((angle_deg(Direction::Ccw, 90.0) - 90.0).abs() < 1e-12);
    }
}
