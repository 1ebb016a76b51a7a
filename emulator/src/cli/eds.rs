//! `drive-emu eds` and `drive-emu presets`: what a master needs to know about the drive.

use crate::api::EdsRequest;
use crate::presets::{preset_names, AxisConfig};
use anyhow::Result;
use clap::Args;
use drive_protocol::od::eds::Real32Notation;

#[derive(Args, Debug, Clone)]
pub struct EdsArgs {
    /// Preset of the axis: cnc1 ... cnc5.
    #[arg(long, default_value = "cnc1")]
    pub preset: String,
    /// Node ID of the drive: written to the DeviceComissioning section, key NodeID, from which masters
    /// (python canopen, Lely) resolve the $NODEID defaults (canopen-monitor: see
    /// --canopen-monitor). Without it, a generic EDS.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=127))]
    pub node: Option<u8>,
    /// Override a preset key, e.g. --set backlash_mm=0.05 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// The EDS of `run --worn`: the preset's worn drive train (its backlash in the
    /// emulator's backlash object). Without it, of the healthy axis `run` serves by default,
    /// unless --set gives a gap (docs/decisions/0014-healthy-default.md).
    #[arg(long)]
    pub worn: bool,
    /// How REAL32 defaults (0x2000-0x200C) are written: `bits`, the IEEE 754 bit pattern in
    /// hex (kv_per_s 30.0 = 0x41F00000), as Lely's dcfchk/dcfgen and ros2_canopen read them;
    /// or `decimal` (30.0), as python canopen reads them (it leaves a hex REAL32 default
    /// None; Lely rejects a decimal one). eds-validate accepts both.
    #[arg(long, value_enum, default_value_t = Real32Arg::Bits)]
    pub real32: Real32Arg,
    /// For canopen-monitor 4.1.0 only: also write the section it takes the node ID from,
    /// `[DeviceCommissioning]` with `NodeId` and `NodeName` (its spelling; CiA 306 writes
    /// `[DeviceComissioning] NodeID`, which it cannot read). eds-validate and dcfchk reject
    /// the extra section: give this file to canopen-monitor alone.
    #[arg(long, requires = "node")]
    pub canopen_monitor: bool,
    /// Write the EDS a drive serves with this vendor's EDS or DCF (`run --eds FILE`): the
    /// vendor's objects, identity and PDO defaults, 0x6502 cut to the modes the emulator
    /// runs, the emulator's own objects where the file leaves room. On stderr: what became of
    /// every object (simulated, stored, dropped, added, hidden) and why.
    #[arg(long, value_name = "FILE")]
    pub from: Option<std::path::PathBuf>,
    /// With --from: the first index of the emulator's own objects (default: the first free
    /// of 0x2000, 0x3000, 0x4000, 0x5000, ...).
    #[arg(long, value_name = "INDEX", requires = "from", value_parser = crate::cli::run::parse_index)]
    pub objects_base: Option<u16>,
    /// The EDS of a drive run with this vendor behaviour profile (`run --profile`): its
    /// [identity] and the defaults its switches change (TPDO COB-IDs with bit 30 for
    /// tpdo_rtr_unsupported, 0x1017 for bootup_then_heartbeat).
    #[arg(long, value_name = "NAME|PATH")]
    pub profile: Option<String>,
    /// As `run --quirk`.
    #[arg(long = "quirk", value_name = "NAME[.PARAM=VALUE]")]
    pub quirk: Vec<String>,
    /// As `run --no-quirk`.
    #[arg(long = "no-quirk", value_name = "NAME")]
    pub no_quirk: Vec<String>,
}

/// `--real32`: notation of REAL32 defaults in the EDS.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Real32Arg {
    /// IEEE 754 bits in hex (Lely dcf-tools, ros2_canopen).
    #[default]
    Bits,
    /// Decimal (python canopen).
    Decimal,
}

impl EdsArgs {
    /// The request these arguments make.
    pub fn request(&self) -> EdsRequest {
        EdsRequest {
            preset: self.preset.clone(),
            node: self.node,
            sets: self.set.clone(),
            worn: self.worn,
            real32: match self.real32 {
                Real32Arg::Bits => Real32Notation::Bits,
                Real32Arg::Decimal => Real32Notation::Decimal,
            },
            canopen_monitor: self.canopen_monitor,
            from: self.from.clone(),
            objects_base: self.objects_base,
            profile: self.profile.clone(),
            quirks: self.quirk.clone(),
            no_quirks: self.no_quirk.clone(),
        }
    }
}

/// The EDS (CiA 306) of a drive built from a preset, generated from the node's object table:
/// every default is the value the drive has (manufacturer parameters from the preset and
/// --set), the FileInfo section complete (time from SOURCE_DATE_EPOCH if set, else now, UTC).
pub fn eds_text(args: &EdsArgs) -> Result<String> {
    Ok(eds_and_report(args)?.0)
}

/// The EDS text and, with `--from`, the build report's text ([`EdsRequest::build`]), with the
/// command line's errors (exit status 2; 4: a file that cannot be read).
pub fn eds_and_report(args: &EdsArgs) -> Result<(String, Option<String>)> {
    let out = args.request().build().map_err(super::api_error)?;
    Ok((out.eds, out.report))
}

pub use crate::api::eds::eds_time_date;

pub fn run_eds(args: &EdsArgs) -> Result<()> {
    // a bad file or argument: exit status 2 (4: a file that cannot be read)
    let (eds, report) = eds_and_report(args)?;
    if let Some(r) = report {
        eprint!("{r}");
    }
    print!("{eds}");
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
