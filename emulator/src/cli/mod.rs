//! Command-line subcommands.

pub mod analyze;
pub mod demo;
pub mod eds;
pub mod run;
pub mod scenario;
pub mod sim;
