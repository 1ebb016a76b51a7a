//! The detector's trace from a candump log: the analysis crate's
//! ([`drive_analysis::capture::trace`], re-exported here), with our drive's PDO configuration
//! after reset for a preset.

pub use drive_analysis::capture::trace::*;

use std::path::Path;

use super::follow::{BusLog, DriveDefaults, PdoConfig};
use crate::analysis::detector::AxisTrace;

/// Read a candump log and build the detector's trace for node `node_id` of our drive with
/// `preset`. `rotary` forces rotary units; the preset decides otherwise.
pub fn trace_from_candump(
    path: &Path,
    text: &str,
    node_id: u8,
    preset: &str,
    sync_period_us: Option<u32>,
    rotary: bool,
) -> anyhow::Result<(AxisTrace, BusLog)> {
    let (defaults, preset_rotary) = PdoConfig::drive_defaults(node_id, preset)?;
    trace_from_candump_with(
        path,
        text,
        node_id,
        defaults,
        sync_period_us,
        rotary || preset_rotary,
    )
}
