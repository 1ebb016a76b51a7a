//! Straight-line interpolation (G1) on two or three axes, as a CNC's interpolator runs a
//! program of linear moves with exact stop at every corner (G60 / G9): each segment from rest
//! to rest, its feed a trapezoid (the path accelerates at `accel` up to the feed, holds it,
//! and decelerates to a stop at the segment's end point; a triangle where the segment is too
//! short to reach the feed), a dwell at rest before the first segment, after every segment and
//! after the last. The set-points are a closed-form function of time
//! ([`LineProgram::sample`]): sans-IO, the plan in fixed arrays, no allocation after
//! [`LineProgram::new`] (and none in it).
//!
//! Lengths in one unit (m in SI), times in s. Axis `k` of a point is `point[k]`; with two axes
//! the third coordinate is 0 throughout.

/// Most points a program holds (the start point included): `MAX_POINTS - 1` segments.
pub const MAX_POINTS: usize = 33;
/// Most axes of a program.
pub const MAX_AXES: usize = 3;
/// Dwell at rest before the first segment, after each segment and after the last, s: the
/// loops settle at the point (exact stop) before the next segment starts.
pub const DWELL_S: f64 = 0.25;

/// Why a plan is refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlanError {
    /// Fewer than one segment, or more than `MAX_POINTS - 1`.
    SegmentCount(usize),
    /// Axis count outside 1..=MAX_AXES.
    AxisCount(usize),
    /// Feed, acceleration or dwell not finite and > 0 (dwell >= 0).
    Rate,
    /// A coordinate that is not finite (point index, axis).
    Coordinate(usize, usize),
    /// A segment of zero length: point `i` is where point `i - 1` is.
    ZeroLength(usize),
}

impl std::fmt::Display for PlanError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PlanError::SegmentCount(n) => write!(
                f,
                "{n} segments: a program has 1 to {} segments",
                MAX_POINTS - 1
            ),
            PlanError::AxisCount(n) => write!(f, "{n} axes: a program has 1 to {MAX_AXES}"),
            PlanError::Rate => write!(
                f,
                "feed and acceleration must be finite and > 0, the dwell finite and >= 0"
            ),
            PlanError::Coordinate(i, k) => {
                write!(f, "point {i}: coordinate {k} is not a finite number")
            }
            PlanError::ZeroLength(i) => write!(
                f,
                "point {i} is where point {} is: a segment of zero length",
                i - 1
            ),
        }
    }
}

impl std::error::Error for PlanError {}

/// One segment's trapezoid (or triangle), precomputed.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct Profile {
    /// Start of its motion, s from the program's start.
    t0: f64,
    /// Length.
    length: f64,
    /// Peak path speed (the feed, or less on a short segment).
    v_peak: f64,
    /// Duration of the ramp up (and of the ramp down), s.
    t_ramp: f64,
    /// Duration of the motion, s (ramps and cruise).
    t_move: f64,
}

/// Where in the program a sample is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// At rest: before the first segment, at a corner, or after the last.
    Rest,
    /// Accelerating along the segment.
    Accel,
    /// At the segment's peak speed.
    Cruise,
    /// Decelerating to the segment's end point.
    Decel,
}

/// The set-point at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineSample {
    /// Commanded position per axis (unused axes 0).
    pub position: [f64; MAX_AXES],
    /// The segment this instant belongs to, 1-based: its motion and the dwell after it
    /// (0: the dwell before the first segment).
    pub segment: usize,
    pub phase: Phase,
    /// Path speed, unit/s.
    pub speed: f64,
}

/// A program of straight lines through points at one feed, exact stop at each point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineProgram {
    points: [[f64; MAX_AXES]; MAX_POINTS],
    n_points: usize,
    n_axes: usize,
    /// Path speed along each segment (the feed), unit/s.
    pub feed: f64,
    /// Path acceleration and deceleration of each segment's ramps, unit/s^2.
    pub accel: f64,
    /// Dwell at rest before, between and after the segments, s.
    pub dwell_s: f64,
    profiles: [Profile; MAX_POINTS],
}

impl LineProgram {
    /// The plan through `points` (the first is the start, where the axes stand at time 0),
    /// `n_axes` coordinates each (the others ignored), at `feed` with ramps of `accel`, dwelling
    /// `dwell_s` at every stop.
    pub fn new(
        points: &[[f64; MAX_AXES]],
        n_axes: usize,
        feed: f64,
        accel: f64,
        dwell_s: f64,
    ) -> Result<Self, PlanError> {
        if !(1..=MAX_AXES).contains(&n_axes) {
            return Err(PlanError::AxisCount(n_axes));
        }
        if points.len() < 2 || points.len() > MAX_POINTS {
            return Err(PlanError::SegmentCount(points.len().saturating_sub(1)));
        }
        let rates_ok = feed.is_finite() && feed > 0.0 && accel.is_finite() && accel > 0.0;
        if !(rates_ok && dwell_s.is_finite() && dwell_s >= 0.0) {
            return Err(PlanError::Rate);
        }
        let mut p = LineProgram {
            points: [[0.0; MAX_AXES]; MAX_POINTS],
            n_points: points.len(),
            n_axes,
            feed,
            accel,
            dwell_s,
            profiles: [Profile::default(); MAX_POINTS],
        };
        for (i, (pt, dst)) in points.iter().zip(p.points.iter_mut()).enumerate() {
            for (k, (v, d)) in pt.iter().zip(dst.iter_mut()).take(n_axes).enumerate() {
                if !v.is_finite() {
                    return Err(PlanError::Coordinate(i, k));
                }
                *d = *v;
            }
        }
        let mut t = dwell_s;
        for i in 1..p.n_points {
            let length = p.distance(i - 1, i);
            if length <= 0.0 {
                return Err(PlanError::ZeroLength(i));
            }
            // a trapezoid where the segment is long enough to reach the feed, else a triangle
            let v_peak = feed.min((length * accel).sqrt());
            let t_ramp = v_peak / accel;
            let t_cruise = (length - v_peak * t_ramp) / v_peak;
            let t_move = 2.0 * t_ramp + t_cruise.max(0.0);
            p.profiles[i] = Profile {
                t0: t,
                length,
                v_peak,
                t_ramp,
                t_move,
            };
            t += t_move + dwell_s;
        }
        Ok(p)
    }

    fn distance(&self, a: usize, b: usize) -> f64 {
        (0..self.n_axes)
            .map(|k| (self.points[b][k] - self.points[a][k]).powi(2))
            .sum::<f64>()
            .sqrt()
    }

    /// Number of axes.
    pub fn axes(&self) -> usize {
        self.n_axes
    }

    /// Number of segments.
    pub fn segments(&self) -> usize {
        self.n_points - 1
    }

    /// Point `i` (0: the start; segment `i` ends at point `i`).
    pub fn point(&self, i: usize) -> [f64; MAX_AXES] {
        self.points[i]
    }

    /// Start of segment `i`'s motion (1-based), s.
    pub fn segment_start_s(&self, i: usize) -> f64 {
        self.profiles[i].t0
    }

    /// Duration of segment `i`'s motion (1-based), s.
    pub fn segment_move_s(&self, i: usize) -> f64 {
        self.profiles[i].t_move
    }

    /// Duration of the whole program, s: every segment and every dwell.
    pub fn duration_s(&self) -> f64 {
        let last = &self.profiles[self.n_points - 1];
        last.t0 + last.t_move + self.dwell_s
    }

    /// Distance along a profile `t` s after its motion starts, its speed and phase.
    fn along(pr: &Profile, accel: f64, t: f64) -> (f64, f64, Phase) {
        let t_decel = pr.t_move - pr.t_ramp;
        if t < pr.t_ramp {
            (0.5 * accel * t * t, accel * t, Phase::Accel)
        } else if t < t_decel {
            (
                0.5 * pr.v_peak * pr.t_ramp + pr.v_peak * (t - pr.t_ramp),
                pr.v_peak,
                Phase::Cruise,
            )
        } else if t < pr.t_move {
            let r = pr.t_move - t;
            (pr.length - 0.5 * accel * r * r, accel * r, Phase::Decel)
        } else {
            (pr.length, 0.0, Phase::Rest)
        }
    }

    /// The set-point `t` seconds after the start.
    pub fn sample(&self, t: f64) -> LineSample {
        // the last segment whose motion has started (0: none yet)
        let mut seg = 0;
        for i in 1..self.n_points {
            if t >= self.profiles[i].t0 {
                seg = i;
            } else {
                break;
            }
        }
        if seg == 0 {
            return LineSample {
                position: self.points[0],
                segment: 0,
                phase: Phase::Rest,
                speed: 0.0,
            };
        }
        let pr = &self.profiles[seg];
        let (s, speed, phase) = Self::along(pr, self.accel, t - pr.t0);
        let (a, b) = (self.points[seg - 1], self.points[seg]);
        let f = s / pr.length;
        let mut position = [0.0; MAX_AXES];
        for (k, p) in position.iter_mut().enumerate().take(self.n_axes) {
            *p = if phase == Phase::Rest {
                b[k]
            } else {
                a[k] + (b[k] - a[k]) * f
            };
        }
        LineSample {
            position,
            segment: seg,
            phase,
            speed,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square there and back at a feed and acceleration: the path stays on each segment's
    /// line, never exceeds the feed or the acceleration, stops at every corner, and the
    /// timing is the trapezoid's (a short segment a triangle).
    #[test]
    fn segments_run_rest_to_rest_within_feed_and_accel() {
        let pts = [
            [0.0, 0.0, 0.0],
            [0.010, 0.0, 0.0],
            [0.010, 0.005, 0.0],
            [0.0, 0.0, 0.0],
            [0.0001, 0.0, 0.0],
        ];
        let (v, a) = (0.02, 0.2);
        let p = LineProgram::new(&pts, 2, v, a, 0.1).unwrap();
        assert_eq!(p.segments(), 4);
        // segment 1: 10 mm at 20 mm/s, 0.2 m/s^2: ramps of 0.1 s, cruise 0.4 s
        assert!((p.segment_move_s(1) - 0.6).abs() < 1e-12);
        // segment 4: 0.1 mm, a triangle: v_peak = sqrt(L a) = 4.47 mm/s
        assert!((p.segment_move_s(4) - 2.0 * (1e-4f64 / a).sqrt()).abs() < 1e-12);
        let dt = 1e-4;
        let n = (p.duration_s() / dt) as usize + 2;
        let mut last = p.sample(0.0);
        let mut last_v = 0.0;
        let mut stops = 0;
        for i in 1..=n {
            let s = p.sample(i as f64 * dt);
            let step = ((s.position[0] - last.position[0]).powi(2)
                + (s.position[1] - last.position[1]).powi(2))
            .sqrt();
            assert!(step <= v * dt * (1.0 + 1e-9), "{step}");
            assert!((s.speed - last_v).abs() <= a * dt * (1.0 + 1e-9) + 1e-12);
            if s.segment > 0 {
                // on the segment's line: cross product with its direction is nil
                let (pa, pb) = (pts[s.segment - 1], pts[s.segment]);
                let cross = (pb[0] - pa[0]) * (s.position[1] - pa[1])
                    - (pb[1] - pa[1]) * (s.position[0] - pa[0]);
                assert!(cross.abs() < 1e-15, "{cross}");
            }
            if s.phase == Phase::Rest && last.phase != Phase::Rest {
                stops += 1;
                assert_eq!(s.position, pts[s.segment]);
            }
            last_v = s.speed;
            last = s;
        }
        assert_eq!(stops, 4);
        assert_eq!(last.position, pts[4]);
        assert_eq!(last.segment, 4);
    }

    #[test]
    fn bad_plans_are_refused() {
        let p = [[0.0; 3], [1.0, 0.0, 0.0]];
        assert_eq!(
            LineProgram::new(&p[..1], 2, 1.0, 1.0, 0.0),
            Err(PlanError::SegmentCount(0))
        );
        assert_eq!(
            LineProgram::new(&p, 4, 1.0, 1.0, 0.0),
            Err(PlanError::AxisCount(4))
        );
        assert_eq!(LineProgram::new(&p, 2, 0.0, 1.0, 0.0), Err(PlanError::Rate));
        assert_eq!(
            LineProgram::new(&p, 2, 1.0, f64::NAN, 0.0),
            Err(PlanError::Rate)
        );
        assert_eq!(
            LineProgram::new(&[[0.0; 3], [0.0; 3]], 2, 1.0, 1.0, 0.0),
            Err(PlanError::ZeroLength(1))
        );
        assert_eq!(
            LineProgram::new(&[[0.0; 3], [f64::INFINITY, 0.0, 0.0]], 2, 1.0, 1.0, 0.0),
            Err(PlanError::Coordinate(1, 0))
        );
        // a third coordinate is ignored on two axes: the same point is zero length
        assert_eq!(
            LineProgram::new(&[[0.0; 3], [0.0, 0.0, 1.0]], 2, 1.0, 1.0, 0.0),
            Err(PlanError::ZeroLength(1))
        );
    }
}
