//! The ballbar's data without drives: the recorded path ([`BallbarTrace`]), the figures a
//! ballbar reports ([`metrics`]) and the path decoded from a CAN capture ([`capture`]). The
//! test that runs two drives is the emulator's (its `analysis::ballbar`).

pub mod capture;
pub mod metrics;

pub use metrics::{analyze, BallbarReport, DirectionReport};

/// The recorded test, one row per position cycle; positions in mm.
#[derive(Clone, Debug, Default)]
pub struct BallbarTrace {
    pub time_s: Vec<f64>,
    /// The interpolator's position (the circle, without compensation).
    pub x_cmd_mm: Vec<f64>,
    pub y_cmd_mm: Vec<f64>,
    /// Direct encoders: the measured path.
    pub x_mm: Vec<f64>,
    pub y_mm: Vec<f64>,
    /// The set-points sent to the drives (the circle plus the compensation).
    pub x_setpoint_mm: Vec<f64>,
    pub y_setpoint_mm: Vec<f64>,
    /// Motor encoders, at the load.
    pub x_motor_mm: Vec<f64>,
    pub y_motor_mm: Vec<f64>,
    /// -1 on the CW pass, +1 on the CCW pass, 0 at rest.
    pub direction: Vec<i8>,
    /// Angle travelled from the pass's data start, deg (negative on the arc-in, 0..360 on the
    /// data circle, above 360 on the arc-out; 0 at rest).
    pub travelled_deg: Vec<f64>,
    /// True while the feed ramps up or down.
    pub ramping: Vec<bool>,
}

impl BallbarTrace {
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// The CSV header of `ballbar --trace`.
    pub const COLUMNS: [&'static str; 12] = [
        "time_s",
        "x_cmd_mm",
        "y_cmd_mm",
        "x_mm",
        "y_mm",
        "x_setpoint_mm",
        "y_setpoint_mm",
        "x_motor_mm",
        "y_motor_mm",
        "direction",
        "travelled_deg",
        "ramping",
    ];

    /// Write the trace as CSV (header [`BallbarTrace::COLUMNS`]).
    pub fn write_csv(&self, w: &mut impl std::io::Write) -> std::io::Result<()> {
        writeln!(w, "{}", Self::COLUMNS.join(","))?;
        for i in 0..self.len() {
            writeln!(
                w,
                "{:.6},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9},{},{:.6},{}",
                self.time_s[i],
                self.x_cmd_mm[i],
                self.y_cmd_mm[i],
                self.x_mm[i],
                self.y_mm[i],
                self.x_setpoint_mm[i],
                self.y_setpoint_mm[i],
                self.x_motor_mm[i],
                self.y_motor_mm[i],
                self.direction[i],
                self.travelled_deg[i],
                u8::from(self.ramping[i]),
            )?;
        }
        Ok(())
    }
}
