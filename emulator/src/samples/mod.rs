//! Trace samples and the files they live in, below every layer that records or reads them.
//!
//! - [`Sample`]: one row of the sample log (`samples.csv` of a scenario report, `run --trace`),
//!   written by the reference master and by the live-run recorder, read by `drive-emu analyze`;
//! - [`csv`]: reading trace files (plain or gzip, bounded) and CSV text into named columns.

pub mod csv;

/// What the drive reported at one SYNC (the latest TPDO values), plus our own set-point.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Sample {
    pub t_s: f64,
    pub statusword: u16,
    pub mode_display: i8,
    pub target_uu: f64,
    pub setpoint_velocity_uu_s: f64,
    pub position_uu: i32,
    pub direct_position_uu: i32,
    pub velocity_uu_s: i32,
    pub torque_permille: i16,
    pub current_permille: i16,
    pub following_error_uu: i32,
}

impl Sample {
    /// The sample log's CSV header (`samples.csv` of a scenario report, `run --trace`), the
    /// layout `drive-emu analyze` reads.
    pub const CSV_HEADER: &'static str = "t_s,statusword,mode_display,target_uu,\
        setpoint_velocity_uu_s,position_uu,direct_position_uu,velocity_uu_s,torque_permille,\
        current_permille,following_error_uu";

    /// One CSV row under [`Sample::CSV_HEADER`].
    pub fn write_csv_row(&self, w: &mut impl std::io::Write) -> std::io::Result<()> {
        writeln!(
            w,
            "{:.6},{},{},{:.3},{:.3},{},{},{},{},{},{}",
            self.t_s,
            self.statusword,
            self.mode_display,
            self.target_uu,
            self.setpoint_velocity_uu_s,
            self.position_uu,
            self.direct_position_uu,
            self.velocity_uu_s,
            self.torque_permille,
            self.current_permille,
            self.following_error_uu
        )
    }
}
