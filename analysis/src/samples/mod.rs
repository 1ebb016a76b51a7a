//! Trace samples and the files they live in, below every layer that records or reads them.
//!
//! - [`Sample`]: one row of the sample log (`samples.csv` of a scenario report, `run --trace`),
//!   written by the reference master and by the live-run recorder, read by `drive-emu analyze`;
//!   [`SampleSource`] says which wrote it, and so what its two set-point columns mean;
//! - [`csv`]: reading trace files (plain or gzip, bounded) and CSV text into named columns.

pub mod csv;

/// Who recorded a sample log. The row is one layout ([`Sample`], [`Sample::CSV_HEADER`]), but
/// its two set-point columns mean different things by source; a reader of the log names the
/// source (the detector's trace converts by it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleSource {
    /// The reference master (scenario reports' `samples.csv`): `target_uu` is the position
    /// set-point it sent, `setpoint_velocity_uu_s` its interpolator velocity (a set velocity).
    Master,
    /// The drive's own objects (`run --trace`, live scenarios): `target_uu` is its position
    /// demand 0x6062, `setpoint_velocity_uu_s` its velocity demand 0x606B, the position
    /// controller's output, which carries the limit cycle (not a set velocity).
    Drive,
}

/// One row of a sample log at one SYNC: the drive's actual values (the latest TPDO values, or
/// its objects) and two set-point columns whose meaning depends on the [`SampleSource`].
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Sample {
    pub t_s: f64,
    pub statusword: u16,
    pub mode_display: i8,
    /// Position set-point, uu: the master's target ([`SampleSource::Master`]) or the drive's
    /// position demand 0x6062 ([`SampleSource::Drive`]).
    pub target_uu: f64,
    /// Velocity, uu/s: the master's interpolator velocity ([`SampleSource::Master`]) or the
    /// drive's velocity demand 0x606B ([`SampleSource::Drive`]).
    pub setpoint_velocity_uu_s: f64,
    pub position_uu: i32,
    pub direct_position_uu: i32,
    pub velocity_uu_s: i32,
    pub torque_permille: i16,
    pub current_permille: i16,
    pub following_error_uu: i32,
}

impl Sample {
    /// A sample's time `t_s` for a drive time in microseconds: `us / 1e6`, correctly rounded,
    /// which is the number the CSV's six decimals read back as. (`us * 1e-6` is not: 1e-6 has
    /// no exact binary value, and a time one ulp off moved a sample across a window's edge, so
    /// `run --detect` and `analyze` of the same run's `--trace` disagreed in the fifth digit.)
    pub fn t_s_of_us(us: u64) -> f64 {
        us as f64 / 1e6
    }

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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The time a sample carries is the number its CSV row reads back as, to the bit.
        #[test]
        fn a_samples_time_is_what_its_csv_row_reads_back(us in 0u64..1_000_000_000_000) {
            let t = Sample::t_s_of_us(us);
            let text = format!("{t:.6}");
            prop_assert_eq!(text.parse::<f64>().unwrap().to_bits(), t.to_bits(), "{} us: {}", us, text);
        }
    }

    #[test]
    fn the_product_with_1e_6_is_not_and_would_have_been_caught() {
        // What the times were computed as before: some microseconds give another number.
        let off = (0u64..100_000)
            .filter(|&us| {
                let t = us as f64 * 1e-6;
                format!("{t:.6}").parse::<f64>().unwrap().to_bits() != t.to_bits()
            })
            .count();
        assert!(
            off > 0,
            "every product round-trips: the test above proves nothing new"
        );
    }
}
