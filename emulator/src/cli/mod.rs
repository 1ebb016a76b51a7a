//! Command-line subcommands.

pub mod analyze;
pub mod run;
pub mod scenario;
pub mod sim;
