//! [`EdsRequest`]: the drive's EDS (CiA 306) as a master reads it (`drive-emu eds`,
//! `drive_emu.eds`).

use std::path::PathBuf;

use super::ApiError;
use crate::drive::axis_drive::AxisDrive;
use crate::drive::vendor::{self, VendorEds};
use crate::drive::{node_setup, NodeOptions};
use crate::presets::AxisConfig;
use drive_protocol::od::eds::EdsMeta;
/// How REAL32 defaults are written ([`EdsRequest::real32`]).
pub use drive_protocol::od::eds::Real32Notation;

/// The EDS of a drive built from a preset. Messages name the fields as the command line's
/// flags (`--node`, `--set`, ...).
#[derive(Debug, Clone, PartialEq)]
pub struct EdsRequest {
    /// Preset of the axis (`--preset`, default cnc1).
    pub preset: String,
    /// Node ID (1..=127) written to the DeviceComissioning section (`--node`); `None`: a
    /// generic EDS.
    pub node: Option<u8>,
    /// Preset overrides, `key=value` (`--set`).
    pub sets: Vec<String>,
    /// The EDS of `run --worn` (`--worn`).
    pub worn: bool,
    /// How REAL32 defaults are written (`--real32`; default the IEEE 754 bits in hex).
    pub real32: Real32Notation,
    /// Also write canopen-monitor's own commissioning section (`--canopen-monitor`; needs a
    /// node).
    pub canopen_monitor: bool,
    /// A vendor's EDS or DCF the drive serves (`--from`).
    pub from: Option<PathBuf>,
    /// With `from`: the first index of the emulator's own objects (`--objects-base`).
    pub objects_base: Option<u16>,
    /// A vendor behaviour profile, by name or path (`--profile`).
    pub profile: Option<String>,
    /// Quirks switched on, `NAME[.PARAM=VALUE]` (`--quirk`).
    pub quirks: Vec<String>,
    /// Quirks switched off (`--no-quirk`).
    pub no_quirks: Vec<String>,
}

impl Default for EdsRequest {
    /// The command line's defaults: the generic EDS of cnc1's healthy axis.
    fn default() -> Self {
        Self {
            preset: "cnc1".into(),
            node: None,
            sets: Vec::new(),
            worn: false,
            real32: Real32Notation::Bits,
            canopen_monitor: false,
            from: None,
            objects_base: None,
            profile: None,
            quirks: Vec::new(),
            no_quirks: Vec::new(),
        }
    }
}

/// What [`EdsRequest::build`] makes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EdsOutput {
    /// The EDS text.
    pub eds: String,
    /// With `from`: what became of every vendor object, and why (the command line writes it
    /// to stderr).
    pub report: Option<String>,
}

impl EdsRequest {
    /// The EDS text and, with [`from`](Self::from), the build report's text. A bad argument
    /// or file content is [`ApiError::Invalid`], a file that cannot be read
    /// [`ApiError::Unreadable`].
    pub fn build(&self) -> Result<EdsOutput, ApiError> {
        self.check()?;
        let (eds, report) = self.build_inner().map_err(ApiError::of_input)?;
        Ok(EdsOutput { eds, report })
    }

    /// What the command line's parser checks: the node ID's range, the options that need
    /// another.
    fn check(&self) -> Result<(), ApiError> {
        if let Some(n) = self.node {
            if !(1..=127).contains(&n) {
                return Err(ApiError::invalid(format!(
                    "--node {n}: a node ID is 1..=127"
                )));
            }
        }
        if self.canopen_monitor && self.node.is_none() {
            return Err(ApiError::invalid("--canopen-monitor needs --node"));
        }
        if self.objects_base.is_some() && self.from.is_none() {
            return Err(ApiError::invalid("--objects-base needs --from"));
        }
        Ok(())
    }

    fn build_inner(&self) -> anyhow::Result<(String, Option<String>)> {
        let args = self;
        let cfg = AxisConfig::from_preset(&args.preset)?
            .with_overrides(args.sets.iter().map(String::as_str))?;
        let cfg = crate::drive::machine::served(
            cfg,
            args.worn || crate::drive::machine::sets_ask_for_wear(&args.sets),
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
            &args.quirks,
            &args.no_quirks,
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
        } else if args.sets.is_empty() {
            format!("drive-emu CiA 402 servo drive, preset {}", args.preset)
        } else {
            format!(
                "drive-emu CiA 402 servo drive, preset {} with {}",
                args.preset,
                // no '=' in a value: INI readers (eds-utils) split the line at every '='
                args.sets.join(", ").replace('=', ": ")
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
            real32: args.real32,
        };
        let eds = node.export_eds(&mut drive, &meta);
        let eds = match args.node.filter(|_| args.canopen_monitor) {
            Some(n) => with_canopen_monitor_section(&eds, n),
            None => eds,
        };
        Ok((eds, report))
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn what_the_parser_checked_is_checked_here() {
        for (req, said) in [
            (
                EdsRequest {
                    node: Some(0),
                    ..EdsRequest::default()
                },
                "--node 0",
            ),
            (
                EdsRequest {
                    canopen_monitor: true,
                    ..EdsRequest::default()
                },
                "--canopen-monitor needs --node",
            ),
            (
                EdsRequest {
                    objects_base: Some(0x3000),
                    ..EdsRequest::default()
                },
                "--objects-base needs --from",
            ),
        ] {
            let e = req.build().unwrap_err();
            assert!(matches!(e, ApiError::Invalid(_)), "{e:?}");
            assert!(e.to_string().contains(said), "{e}");
        }
        let e = EdsRequest {
            from: Some("/nonexistent/drive-emu-api.eds".into()),
            ..EdsRequest::default()
        }
        .build()
        .unwrap_err();
        assert!(matches!(e, ApiError::Unreadable(_)), "{e:?}");
    }
}
