//! `drive-emu esi`: the ESI XML (ETG.2000) of the drive as `run --ethercat` serves it, for
//! masters that import one (TwinCAT, IgH's tools), as `drive-emu eds` writes the EDS for
//! CANopen masters. The same options as `run` choose the drive (preset, --set, --eds,
//! --profile, --config); the file says what the slave's SII and CoE say.

use anyhow::{bail, Result};
use clap::Args;

use super::run::{ethercat_slaves, RunArgs};

#[derive(Args, Debug, Clone)]
pub struct EsiArgs {
    /// Write the ESI here instead of stdout.
    #[arg(long, short = 'o', value_name = "FILE")]
    pub output: Option<std::path::PathBuf>,
    /// The drive: the options of `run` (--preset, --set, --eds, --profile, --config).
    #[command(flatten)]
    pub run: RunArgs,
}

/// The ESI of the run's slaves: one device; a machine whose axes are different devices
/// (another identity) is refused, one ESI per device type being the rule.
pub fn esi_text(args: &EsiArgs) -> Result<String> {
    let (_, slaves, _) = ethercat_slaves(&args.run)?;
    let Some(first) = slaves.first() else {
        bail!("no axis");
    };
    let id = |s: &drive_ethercat::Slave| {
        (1..=3u8)
            .map(|sub| s.node().object_raw(0x1018, sub).unwrap_or(0))
            .collect::<Vec<_>>()
    };
    if let Some(other) = slaves.iter().find(|s| id(s) != id(first)) {
        bail!(
            "the axes are different devices (0x1018 {:08X?} and {:08X?}): write the ESI of \
             one axis at a time (--preset / --eds)",
            id(first),
            id(other)
        );
    }
    Ok(first.esi_xml()?)
}

pub fn run_esi(args: &EsiArgs) -> Result<()> {
    let text = esi_text(args)?;
    match &args.output {
        Some(p) => {
            std::fs::write(p, text).map_err(|e| anyhow::anyhow!("writing {}: {e}", p.display()))?
        }
        None => print!("{text}"),
    }
    Ok(())
}
