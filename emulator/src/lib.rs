//! The simulated CNC axis behind a CiA 402 drive, and everything that runs it.
//!
//! Data path (one tick): bus -> protocol node -> control cascade -> axis physics -> encoders ->
//! node -> bus. `axis` and `control` know nothing of CANopen; `runtime` holds no domain logic.

pub mod analysis;
pub mod axis;
pub mod bus;
pub mod cli;
pub mod control;
pub mod drive;
pub mod master;
pub mod presets;
pub mod report;
pub mod runtime;
pub mod samples;
pub mod scenario;
pub mod session;
pub mod study;
pub mod time;
