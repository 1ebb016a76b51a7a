//! Signal analysis: spectra (fundamental frequency and amplitude) and the constant-velocity
//! experiment of the paper (run an axis at constant speed, find its vibration).

pub mod ballbar;
pub mod capture;
pub mod detector;
pub mod experiment;
pub mod gap;
pub mod spectrum;
pub mod windows;

/// The capture reader's old name.
pub use self::capture as candump;

pub use experiment::{
    constant_velocity_run, constant_velocity_run_until, RunError, RunOptions, RunResult,
    RunSummary, Trace,
};
pub use spectrum::{fundamental, half_peak_to_peak, Peak, SpectrumAnalyzer};
