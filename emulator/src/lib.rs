//! The drive-emu binary's library: the command line (`cli`) and the live panel (`panel`), over
//! the runtime crate `drive-runtime` (docs/decisions/0019-runtime-and-binary-crates.md).
//!
//! Everything below the command line and the panel (clocks, buses, the loop, the drive
//! adapter, observe, the master, analysis, monitor, session, scenario, study, the typed API)
//! is `drive-runtime`'s, and the physics' and the analysis' modules are their crates':
//! re-exported here under the names the emulator has always used, so `drive_emu::bus::...`,
//! `drive_emu::api::...` and, inside `cli` and `panel`, `crate::runtime::...` name the same
//! items as before the cut.
//!
//! Layers, bottom first: the runtime's modules (their order is drive-runtime's lib.rs), then
//! `panel`, then `cli`; a module imports only modules below it (`tests/layering.rs`,
//! docs/decisions/0006-emulator-layers.md).

// crate drive-runtime (and, through it, drive-analysis and drive-physics), re-exported:
pub use drive_runtime::{analysis, drive, master, monitor, observe, runtime};
pub use drive_runtime::{api, report, scenario, session, study};
pub use drive_runtime::{axis, control, presets};
pub use drive_runtime::{bus, infile, quote, samples, time};

#[cfg_attr(not(feature = "panel"), path = "panel/off.rs")]
pub mod panel;

pub mod cli;
