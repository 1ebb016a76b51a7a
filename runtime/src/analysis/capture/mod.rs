//! Decoding a CAN capture (`candump -L`) into the detector's trace: the analysis crate's
//! ([`drive_analysis::capture`]: the log lines, following the bus, the trace), re-exported
//! here under its old paths; what needs our drive (the PDO configuration it has after reset)
//! is in [`follow`] and [`trace`].

pub use drive_analysis::capture::*;

pub mod follow;
pub mod trace;

pub use follow::DriveDefaults;
pub use trace::trace_from_candump;
