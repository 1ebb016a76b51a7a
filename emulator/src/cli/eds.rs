//! `drive-emu eds` and `drive-emu presets`: what a master needs to know about the drive.

use crate::drive::axis_drive::AxisDrive;
use crate::drive::vendor::{self, VendorEds};
use crate::drive::{node_setup, NodeOptions};
use crate::presets::{preset_names, AxisConfig};
use anyhow::Result;
use clap::Args;
use drive_protocol::od::eds::{EdsMeta, Real32Notation};

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

/// The EDS (CiA 306) of a drive built from a preset, generated from the node's object table:
/// every default is the value the drive has (manufacturer parameters from the preset and
/// --set), the FileInfo section complete (time from SOURCE_DATE_EPOCH if set, else now, UTC).
pub fn eds_text(args: &EdsArgs) -> Result<String> {
    Ok(eds_and_report(args)?.0)
}

/// The EDS text and, with `--from`, the build report's text.
pub fn eds_and_report(args: &EdsArgs) -> Result<(String, Option<String>)> {
    let cfg = AxisConfig::from_preset(&args.preset)?
        .with_overrides(args.set.iter().map(String::as_str))?;
    let cfg = crate::drive::machine::served(
        cfg,
        args.worn || crate::drive::machine::sets_ask_for_wear(&args.set),
    );
    let vendor = match &args.from {
        Some(p) => Some(std::sync::Arc::new(VendorEds::load(p)?)),
        None => None,
    };
    let cfg = match &vendor {
        Some(v) => v.adapt(cfg)?,
        None => cfg,
    };
    let mut drive = AxisDrive::from_config(&cfg)?;
    let quirk_profile = crate::drive::quirk_profile::QuirkProfile::from_args(
        args.profile.as_deref(),
        &args.quirk,
        &args.no_quirk,
    )?;
    let opts = NodeOptions {
        objects_base: args.objects_base,
        eds: vendor.clone(),
        quirk_profile: quirk_profile.map(std::sync::Arc::new),
        ..NodeOptions::new(args.node.unwrap_or(1))
    };
    let setup = node_setup(&mut drive, &opts)?;
    let report = match (&vendor, &setup.report) {
        (Some(v), Some(r)) => Some(vendor::report_text(r, setup.objects_base, &v.path)),
        _ => None,
    };
    let node = drive_protocol::Node::new(setup.config).map_err(|e| anyhow::anyhow!("{e}"))?;
    let secs = std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs())
        });
    let (time, date) = eds_time_date(secs);
    let stem = match &args.from {
        Some(p) => p
            .file_stem()
            .map_or_else(|| "vendor".into(), |s| s.to_string_lossy().into_owned()),
        None => args.preset.clone(),
    };
    let file_name = match args.node {
        Some(n) => format!("drive-emu-{stem}-node{n}.eds"),
        None => format!("drive-emu-{stem}.eds"),
    };
    let description = if let Some(p) = &args.from {
        format!(
            "drive-emu serving {} (preset {} behind it)",
            p.file_name()
                .map_or_else(String::new, |f| f.to_string_lossy().into_owned()),
            args.preset
        )
    } else if args.set.is_empty() {
        format!("drive-emu CiA 402 servo drive, preset {}", args.preset)
    } else {
        format!(
            "drive-emu CiA 402 servo drive, preset {} with {}",
            args.preset,
            // no '=' in a value: INI readers (eds-utils) split the line at every '='
            args.set.join(", ").replace('=', ": ")
        )
    };
    let by = format!("drive-emu {}", env!("CARGO_PKG_VERSION"));
    let meta = EdsMeta {
        file_name: &file_name,
        description: &description,
        created_by: &by,
        time: &time,
        date: &date,
        node_id: args.node,
        real32: match args.real32 {
            Real32Arg::Bits => Real32Notation::Bits,
            Real32Arg::Decimal => Real32Notation::Decimal,
        },
    };
    let eds = node.export_eds(&mut drive, &meta);
    let eds = match args.node.filter(|_| args.canopen_monitor) {
        Some(n) => with_canopen_monitor_section(&eds, n),
        None => eds,
    };
    Ok((eds, report))
}

/// The EDS with canopen-monitor's own commissioning section before the CiA 306 one (no
/// comment in it: eds-utils' reader fails on a comment line inside a section). Its
/// parser (`canopen_monitor.parse.eds`) turns section and key names into snake case and reads
/// `device_commissioning.node_id` (the node the file is attached to) and `.node_name` (shown
/// for the node); the standard `DeviceComissioning` / `NodeID` become `device_comissioning` /
/// `node_n_id`, so it attaches a CiA 306 file to no node.
fn with_canopen_monitor_section(eds: &str, node: u8) -> String {
    let section =
        format!("[DeviceCommissioning]\nNodeId={node}\nNodeName=drive-emu node {node}\n\n");
    match eds.find("[DeviceComissioning]") {
        Some(at) => format!("{}{section}{}", &eds[..at], &eds[at..]),
        None => format!("{eds}\n{section}"),
    }
}

/// CiA 306 time and date of a Unix time (UTC): `hh:mmAM`, `MM-DD-YYYY`.
pub fn eds_time_date(unix_s: u64) -> (String, String) {
    let days = (unix_s / 86_400) as i64;
    let sod = unix_s % 86_400;
    let (h, m) = (sod / 3600, (sod % 3600) / 60);
    // civil from days (H. Hinnant)
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let mo = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(mo <= 2);
    let (h12, ampm) = match h {
        0 => (12, "AM"),
        1..=11 => (h, "AM"),
        12 => (12, "PM"),
        _ => (h - 12, "PM"),
    };
    (
        format!("{h12:02}:{m:02}{ampm}"),
        format!("{mo:02}-{d:02}-{y:04}"),
    )
}

pub fn run_eds(args: &EdsArgs) -> Result<()> {
    // a bad file or argument: exit status 2 (4: a file that cannot be read)
    let (eds, report) = eds_and_report(args).map_err(super::exit::usage)?;
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
