//! What the emulator measures, without running a drive: the trace samples and the files they
//! live in, spectra, constant-velocity windows, the backlash detector and its gap estimate,
//! the decoding of a CAN capture into the detector's trace, the ballbar's figures, and the
//! report's plots. No threads, no sockets, no clocks: the emulator (crate `drive-emu`) runs
//! the drives and re-exports these modules under their old paths (its `analysis::detector`,
//! `samples`, `report`, ...). docs/decisions/0017-crate-split.md.
//!
//! Modules, bottom layer first: a module imports only modules before it in this list
//! (`emulator/tests/layering.rs`, `ANALYSIS_LAYERS`).

pub mod quote;

pub mod infile;

pub mod samples;

pub mod spectrum;

pub mod windows;

pub mod axis_trace;

pub mod verdict;

pub mod gap;

pub mod detector;

pub mod capture;

pub mod ballbar;

pub mod report;
