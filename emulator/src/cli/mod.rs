//! Command-line subcommands.

pub mod analyze;
pub mod run;
pub mod sim;
