//! The ballbar's path from a bus capture (`drive-emu analyze --ballbar X,Y`): the decoding is
//! the analysis crate's ([`drive_analysis::ballbar::capture`], re-exported here); this module
//! gives it the PDO configuration our drive has after reset for the capture's preset.

pub use drive_analysis::ballbar::capture::*;

use crate::analysis::capture::{DriveDefaults, PdoConfig};

/// The ballbar's path in a capture of two nodes, `nodes` = [X, Y], both of `preset` (their
/// PDO mapping after reset).
pub fn from_capture(
    text: &str,
    source: &str,
    nodes: [u8; 2],
    preset: &str,
    sync_period_us: Option<u32>,
) -> anyhow::Result<CapturedCircle> {
    let defaults = |node: u8| Ok(PdoConfig::drive_defaults(node, preset)?.0);
    from_capture_with(text, source, nodes, &defaults, sync_period_us)
}
