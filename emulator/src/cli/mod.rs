//! Command-line subcommands.

pub mod sim;
