//! Signal analysis: spectra (fundamental frequency and amplitude), the backlash detector, the
//! capture decoding and the ballbar's figures are the analysis crate's (`drive-analysis`,
//! re-exported here under their old paths); what runs drives is here: the constant-velocity
//! experiment of the paper ([`experiment`]), the ballbar and line contours on two or three
//! drives ([`ballbar`]), and our drive's PDO configuration for a capture ([`capture`]).

pub use drive_analysis::{detector, gap, spectrum, windows};

pub mod ballbar;
pub mod capture;
pub mod experiment;

/// The capture reader's old name.
pub use self::capture as candump;

pub use experiment::{
    constant_velocity_run, constant_velocity_run_until, RunError, RunOptions, RunResult,
    RunSummary, Trace,
};
pub use spectrum::{fundamental, half_peak_to_peak, Peak, SpectrumAnalyzer};
