//! What runs the simulated CNC axis behind a CiA 402 drive: everything of the emulator below
//! its command line and its live panel (those are the binary crate, `drive-emu`).
//!
//! Data path (one tick): bus -> protocol node -> control cascade -> axis physics -> encoders ->
//! node -> bus. `axis` and `control` know nothing of CANopen; `runtime` holds no domain logic.
//!
//! Modules, bottom layer first: a module imports only modules before it in this list
//! (`emulator/tests/layering.rs`, docs/decisions/0006-emulator-layers.md and
//! docs/decisions/0019-runtime-and-binary-crates.md).

// What measures without running a drive (file content in messages, the bounded input-file
// reader, trace samples, and above the runtime the detector's and the report's modules) is its
// own crate, `drive-analysis`: re-exported here under the names the emulator has always used.
// `analysis` stays a module here: it re-exports the crate's detector, spectra and capture
// decoding and holds what runs drives (experiments, the ballbar, line contours).
pub use drive_analysis::{infile, quote, report, samples};

pub mod time;

pub mod bus;

// The physics (axis, servo cascade, presets) is its own crate, `drive-physics`: re-exported
// here under the names the emulator's modules and users have always used.
pub use drive_physics::{axis, control, presets};

pub mod runtime;

pub mod drive;

pub mod observe;

pub mod master;

pub mod analysis;

pub mod monitor;

pub mod session;

pub mod scenario;

pub mod study;

pub mod api;
