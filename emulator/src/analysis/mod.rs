//! Signal analysis: spectra (fundamental frequency and amplitude) and the constant-velocity
//! experiment of the paper (run an axis at constant speed, find its vibration).

pub mod candump;
pub mod detector;
pub mod experiment;
pub mod spectrum;
pub mod windows;

pub use experiment::{constant_velocity_run, RunOptions, RunResult, RunSummary, Trace};
pub use spectrum::{fundamental, half_peak_to_peak, Peak, SpectrumAnalyzer};
