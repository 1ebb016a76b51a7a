//! The typed library API under both the command line and the Python module: one request type
//! per offline job, each run by a method returning a typed result or an [`ApiError`].
//!
//! - [`SimRequest`]: a preset axis at constant velocity (`drive-emu sim`, `drive_emu.sim`);
//! - [`AnalyzeRequest`]: the backlash detector on a trace (`drive-emu analyze`,
//!   `drive_emu.analyze`);
//! - [`EdsRequest`]: the drive's EDS (`drive-emu eds`, `drive_emu.eds`);
//! - [`LiveRequest`]: the drive(s) live on a CAN bus (`drive-emu run`): [`LiveRequest::start`]
//!   gives a [`LiveRun`] handle (`stop`, `wait` for its [`LiveOutcome`]); the command line
//!   attaches its status line, LSS store service and panel through
//!   [`LiveRequest::start_with`] and the run's observation bus.
//!
//! No clap here: the command line converts its parsed arguments into these requests
//! (`cli::sim`, `cli::analyze`, `cli::eds`); the Python module builds them from its own
//! arguments. Every field has the command line's default ([`Default`] or `new`). The error
//! kinds map to the command line's exit statuses in one place, [`ApiError::exit_code`].
//! `run --ethercat` has no request type yet: it stays in `cli::run` on [`live::parts`].

pub mod analyze;
pub mod eds;
pub mod error;
pub mod live;
pub mod sim;

pub use analyze::{Analysis, AnalyzeInput, AnalyzeOutput, AnalyzeRequest};
pub use eds::{EdsOutput, EdsRequest};
pub use error::ApiError;
pub use live::{LiveBusSpec, LiveOutcome, LiveRequest, LiveRun};
pub use sim::SimRequest;
