//! Built-in motion: constant-velocity segments joined by acceleration ramps, and a trapezoid
//! point-to-point move. Both produce a position set-point and a velocity feed-forward per
//! position cycle (load units: m, m/s or rad, rad/s). No allocation after construction.

/// One constant-velocity segment: reach `velocity` (with the profile's acceleration) and hold
/// it until `duration` seconds after the segment started.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    pub velocity: f64,
    pub duration: f64,
}

/// Position set-point and velocity feed-forward for one cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotionSample {
    pub position: f64,
    pub velocity: f64,
}

/// Constant-velocity segments with acceleration-limited transitions. After the last segment
/// the velocity ramps to zero and the position holds.
#[derive(Clone, Debug)]
pub struct VelocityProfile {
    segments: Vec<Segment>,
    accel: f64,
    index: usize,
    t_in_segment: f64,
    pos: f64,
    vel: f64,
}

impl VelocityProfile {
    /// `accel` (> 0) limits the velocity change, load units/s^2.
    pub fn new(start: f64, accel: f64, segments: &[Segment]) -> Self {
        VelocityProfile {
            segments: segments.to_vec(),
            accel: accel.abs(),
            index: 0,
            t_in_segment: 0.0,
            pos: start,
            vel: 0.0,
        }
    }

    /// A single move at constant `velocity` from `start`, ramped with `accel`, lasting forever.
    pub fn constant(start: f64, velocity: f64, accel: f64) -> Self {
        Self::new(
            start,
            accel,
            &[Segment {
                velocity,
                duration: f64::INFINITY,
            }],
        )
    }

    /// Current sample, without advancing.
    pub fn sample(&self) -> MotionSample {
        MotionSample {
            position: self.pos,
            velocity: self.vel,
        }
    }

    /// Advance by `dt` and return the new sample. Position integrates the velocity
    /// trapezoidally, so position and feed-forward stay consistent.
    pub fn next(&mut self, dt: f64) -> MotionSample {
        let target = match self.segments.get(self.index) {
            Some(s) => s.velocity,
            None => 0.0,
        };
        let dv = (target - self.vel).clamp(-self.accel * dt, self.accel * dt);
        let v0 = self.vel;
        self.vel += dv;
        self.pos += 0.5 * (v0 + self.vel) * dt;
        if let Some(s) = self.segments.get(self.index) {
            self.t_in_segment += dt;
            if self.t_in_segment >= s.duration {
                self.index += 1;
                self.t_in_segment = 0.0;
            }
        }
        self.sample()
    }
}

/// Trapezoid (or triangle) point-to-point move, evaluated analytically.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trapezoid {
    start: f64,
    dir: f64,
    accel: f64,
    v_peak: f64,
    t_acc: f64,
    t_const: f64,
    distance: f64,
}

impl Trapezoid {
    /// Move from `start` to `target` with speed limit `v_max` and acceleration `accel` (> 0).
    pub fn new(start: f64, target: f64, v_max: f64, accel: f64) -> Self {
        let distance = (target - start).abs();
        let accel = accel.abs();
        let v_max = v_max.abs();
        let (v_peak, t_acc, t_const) = if v_max * v_max / accel >= distance {
            let v = (distance * accel).sqrt();
            (v, v / accel, 0.0)
        } else {
            let t_acc = v_max / accel;
            (v_max, t_acc, (distance - v_max * t_acc) / v_max)
        };
        Trapezoid {
            start,
            dir: if target >= start { 1.0 } else { -1.0 },
            accel,
            v_peak,
            t_acc,
            t_const,
            distance,
        }
    }

    /// Total duration, s.
    pub fn duration(&self) -> f64 {
        2.0 * self.t_acc + self.t_const
    }

    /// Set-point at time `t` after the start.
    pub fn sample(&self, t: f64) -> MotionSample {
        let (s, v) = if t <= 0.0 {
            (0.0, 0.0)
        } else if t < self.t_acc {
            (0.5 * self.accel * t * t, self.accel * t)
        } else if t < self.t_acc + self.t_const {
            let s_acc = 0.5 * self.accel * self.t_acc * self.t_acc;
            (s_acc + self.v_peak * (t - self.t_acc), self.v_peak)
        } else if t < self.duration() {
            let r = self.duration() - t;
            (self.distance - 0.5 * self.accel * r * r, self.accel * r)
        } else {
            (self.distance, 0.0)
        };
        MotionSample {
            position: self.start + self.dir * s,
            velocity: self.dir * v,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_reaches_target_with_limits() {
        let t = Trapezoid::new(1.0, 0.0, 0.1, 1.0);
        let end = t.sample(t.duration() + 1.0);
        assert_eq!(end.position, 0.0);
        let mid = t.sample(t.duration() / 2.0);
        assert!((mid.velocity + 0.1).abs() < 1e-12);
    }

    #[test]
    fn velocity_profile_integrates_consistently() {
        let mut p = VelocityProfile::new(
            0.0,
            1.0,
            &[Segment {
                velocity: 0.5,
                duration: 2.0,
            }],
        );
        let mut last = p.sample();
        for _ in 0..4000 {
            last = p.next(1e-3);
        }
        // ramp 0.5 s up (0.125), 1.5 s at 0.5 (0.75), ramp down 0.5 s (0.125)
        // Within one cycle's travel at the segment speed (the segment clock is per cycle).
        assert!(
            (last.position - 1.0).abs() < 0.5 * 1e-3 + 1e-9,
            "{}",
            last.position
        );
        assert_eq!(last.velocity, 0.0);
    }
}
