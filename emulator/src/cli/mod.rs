//! Command-line subcommands.

pub mod analyze;
pub mod ballbar;
pub mod demo;
pub mod demo_panel;
pub mod eds;
pub mod exit;
pub mod figures;
pub mod fmu;
pub mod lss_store;
pub mod profiles;
pub mod run;
pub mod scenario;
pub mod sim;
pub mod sweep;
