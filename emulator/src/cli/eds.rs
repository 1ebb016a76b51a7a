//! `drive-emu eds` and `drive-emu presets`: what a master needs to know about the drive.

use crate::presets::{preset_names, AxisConfig};
use crate::runtime::axis_drive::AxisDrive;
use anyhow::Result;
use clap::Args;
use drive_protocol::{Drive, Node};

#[derive(Args, Debug, Clone)]
pub struct EdsArgs {
    /// Preset of the axis: cnc1 ... cnc5.
    #[arg(long, default_value = "cnc1")]
    pub preset: String,
    /// Node ID the EDS is written for (default values with $NODEID are resolved by masters).
    #[arg(long, default_value_t = 5)]
    pub node: u8,
    /// Override a preset key, e.g. --set backlash_mm=0.05 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

/// The EDS (CiA 306) of a drive built from a preset, generated from the node's object table.
pub fn eds_text(args: &EdsArgs) -> Result<String> {
    let cfg = AxisConfig::from_preset(&args.preset)?
        .with_overrides(args.set.iter().map(String::as_str))?;
    let drive = AxisDrive::from_config(&cfg)?;
    let node = Node::new(args.node, drive.info()).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(node.export_eds())
}

pub fn run_eds(args: &EdsArgs) -> Result<()> {
    print!("{}", eds_text(args)?);
    Ok(())
}

/// One line per preset: name, kind, key figures.
pub fn run_presets() -> Result<()> {
    println!(
        "{:<6} {:<8} {:>9} {:>11} {:>10}  description",
        "name", "kind", "kv_per_s", "backlash", "1 uu ="
    );
    for name in preset_names() {
        let c = AxisConfig::from_preset(name)?;
        let backlash = match (c.backlash_mm, c.backlash_deg) {
            (Some(mm), _) => format!("{mm} mm"),
            (_, Some(deg)) => format!("{deg} deg"),
            _ => "-".into(),
        };
        let rotary = c.kind == crate::presets::AxisKind::Rotary;
        println!(
            "{:<6} {:<8} {:>9} {:>11} {:>10}  {}",
            name,
            if rotary { "rotary" } else { "linear" },
            c.kv_per_s,
            backlash,
            crate::report::user_unit(rotary),
            c.description
        );
    }
    println!(
        "\nuu = user unit: positions and speeds on the bus (0x607A, 0x6064, 0x606C, ...) are in \
         user units, set by the factor group 0x608F/0x6091/0x6092."
    );
    Ok(())
}
