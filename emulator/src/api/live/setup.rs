//! The axes of a live run: each node and its simulated drive built from the machine (a vendor's
//! EDS, LSS options, the wear said on stderr).

use super::args::{machine_from_args, RunArgs};
use crate::drive::axis_drive::AxisDrive;
use crate::drive::machine::{self, AxisEntry, MachineFile};
use crate::drive::vendor::{self, VendorEds};
use crate::drive::{node_setup, NodeOptions};
use crate::presets::AxisConfig;
use crate::runtime::AxisSlot;
use crate::scenario::Scenario;
use anyhow::{bail, Context, Result};
use std::sync::Arc;

/// On stderr at start: whether the axis is healthy or worn (and how to have the other), and
/// where its position window 0x6067 is tighter than the gap it was asked to have: a move then
/// ends hunting around its target, outside the window, and never sets target reached.
fn say_wear(e: &AxisEntry, ax: &mut AxisSlot<AxisDrive>) {
    use crate::drive::objects::AxisParam;
    use drive_protocol::Drive as _;
    let info = ax.drive.info();
    let gap = ax.drive.param(AxisParam::Backlash);
    let node = e.node_id;
    let Some(wear) = machine::wear_text(gap, info.rotary) else {
        eprintln!(
            "drive-emu: node {node}: a healthy axis (no backlash); the preset's worn drive \
             train, the paper's machine: --worn (or --set backlash_mm=... / backlash_deg=...)"
        );
        return;
    };
    eprintln!(
        "drive-emu: node {node}: WORN: {wear} (a healthy axis: leave out --worn and the gap)"
    );
    let mut read = |index: u16, sub: u8, fallback: u32| {
        let mut b = [0u8; 4];
        match ax.node.read_object(index, sub, &mut b, &mut ax.drive) {
            Ok(n) if n > 0 => u32::from_le_bytes(b),
            _ => fallback,
        }
    };
    let window_uu = read(0x6067, 0, u32::MAX);
    let terms = [
        read(0x608F, 1, info.encoder_increments_per_rev),
        read(0x608F, 2, 1),
        read(0x6091, 1, info.gear_motor_revs),
        read(0x6091, 2, info.gear_shaft_revs),
        read(0x6092, 1, info.feed_user_units),
        read(0x6092, 2, info.feed_shaft_revs),
    ];
    if window_uu == u32::MAX || terms.contains(&0) {
        return; // no window, or off (CiA 402), or no factor to compare with
    }
    let [enc, enc_r, gm, gs, feed, feed_r] = terms.map(f64::from);
    let inc_per_uu = enc / enc_r * (gm / gs) / (feed / feed_r);
    let window_si = f64::from(window_uu) * inc_per_uu / ax.drive.inc_per_load();
    if window_si < gap {
        eprintln!(
            "drive-emu: node {node}: its position window 0x6067 = {window_uu} uu ({}) is \
             tighter than the {wear} asked for: moves end hunting around their target, outside \
             the window, without target reached (statusword bit 10)",
            machine::wear_text(window_si, info.rotary)
                .map_or("0".into(), |t| t.replace("backlash ", ""))
        );
    }
}

/// Build the nodes and drives of a machine.
/// The LSS slave of a live run's axes: what `--lss-store` holds, and the serial number that
/// keeps the LSS address when the node-ID changes.
#[derive(Clone, Copy, Debug, Default)]
pub struct LssOptions {
    /// Power-on bit timing and whether the store goes to the file.
    pub config: drive_protocol::LssConfig,
    /// 0x1018:4 (`None`: the node-ID at power-on).
    pub serial_number: Option<u32>,
    /// `--force-lss`: an LSS slave even where the vendor's EDS has none.
    pub force: bool,
}

/// The axes of a machine, each node with `boot_delay_us` before its boot-up. With a vendor's
/// EDS, what became of its objects is said on stderr, and the entry's `objects_base` is set
/// to where the emulator's own objects went.
pub fn build_axes(
    entries: &mut [AxisEntry],
    boot_delay_us: u64,
    lss: &LssOptions,
) -> Result<Vec<AxisSlot<AxisDrive>>> {
    entries
        .iter_mut()
        .map(|e| {
            // what the user wrote (its message names the axis): exit status 2
            let cfg = e.run_config().map_err(crate::cli::exit::usage)?;
            axis_slot(cfg, e, boot_delay_us, lss)
        })
        .collect()
}

/// The node configuration and the simulated drive of one axis (what [`axis_slot`] builds its
/// node from; `run --ethercat` builds an EtherCAT slave from it).
pub(super) fn axis_setup(
    cfg: AxisConfig,
    e: &mut AxisEntry,
    boot_delay_us: u64,
    lss: &LssOptions,
) -> Result<(drive_protocol::NodeConfig, AxisDrive)> {
    // what the user wrote (preset, overrides, vendor file): exit status 2, or 4 (crate::cli::exit)
    let at = format!("axis node {}", e.node_id);
    let ctx = |err: anyhow::Error| crate::cli::exit::config(&at, err);
    let eds = match &e.eds {
        Some(p) => Some(Arc::new(VendorEds::load(p).map_err(ctx)?)),
        None => None,
    };
    let cfg = match &eds {
        Some(v) => v.adapt(cfg).map_err(ctx)?,
        None => cfg,
    };
    let mut drive = AxisDrive::from_config(&cfg).map_err(|err| ctx(err.into()))?;
    let opts = NodeOptions {
        objects_base: e.objects_base,
        eds: eds.clone(),
        lss: lss.config,
        serial_number: lss.serial_number,
        force_lss: lss.force,
        ..NodeOptions::new(e.node_id).with_boot_delay_us(boot_delay_us)
    };
    let opts = NodeOptions {
        quirk_profile: e.quirk_profile.clone(),
        ..opts
    };
    if let Some(b) = &e.quirk_profile {
        eprintln!("{}", b.announce(e.node_id, boot_delay_us / 1000));
    }
    let setup = node_setup(&mut drive, &opts).map_err(ctx)?;
    if let (Some(v), Some(r)) = (&eds, &setup.report) {
        eprint!(
            "drive-emu: node {}: {}",
            e.node_id,
            report_summary(r, setup.objects_base, &v.path)
        );
    }
    e.objects_base = Some(setup.objects_base);
    Ok((setup.config, drive))
}

/// One axis from its configuration and its machine entry (node ID, vendor EDS, objects base),
/// its LSS slave as `lss` says.
fn axis_slot(
    cfg: AxisConfig,
    e: &mut AxisEntry,
    boot_delay_us: u64,
    lss: &LssOptions,
) -> Result<AxisSlot<AxisDrive>> {
    let (config, drive) = axis_setup(cfg, e, boot_delay_us, lss)?;
    let node = drive_protocol::Node::new(config)
        .map_err(|err| anyhow::anyhow!("axis node {}: {err}", e.node_id))?;
    Ok(AxisSlot { node, drive })
}

/// The first line and the notes of a build report (the whole report: `drive-emu eds --from`).
fn report_summary(
    r: &drive_protocol::od::BuildReport,
    base: u16,
    path: &std::path::Path,
) -> String {
    vendor::report_text(r, base, path)
        .lines()
        .filter(|l| !l.starts_with("  0x"))
        .map(|l| format!("{l}\n"))
        .collect()
}

/// The machine a live run serves and its axes, validated, with the boot delay set: the
/// scenario's machine (its first preset, the file's overrides applied) on `--node`, or the
/// machine file / flags.
pub(super) fn live_axes(
    args: &RunArgs,
    scenario: Option<&Scenario>,
) -> Result<(MachineFile, Vec<AxisSlot<AxisDrive>>)> {
    let machine = match scenario {
        Some(s) => scenario_machine(args, s)?,
        None => machine_from_args(args)?,
    };
    machine::validate(&machine)?;
    let mut machine = machine;
    let lss = lss_options(args, &mut machine)?;
    let boot_delay_us = args.boot_delay_ms * 1000;
    let axes = match scenario {
        Some(s) => vec![axis_slot(
            s.machine.configs[0].clone(),
            &mut machine.axes[0],
            boot_delay_us,
            &lss,
        )?],
        None => build_axes(&mut machine.axes, boot_delay_us, &lss)?,
    };
    let mut axes = axes;
    for (e, ax) in machine.axes.iter().zip(&mut axes) {
        say_wear(e, ax);
    }
    for ax in &axes {
        if ax.node.node_id() == 255 {
            eprintln!(
                "drive-emu: node-ID 255: non-configured, silent but for LSS (CiA 305, COB-ID \
                 0x7E5) until a master gives it a node-ID"
            );
        }
    }
    Ok((machine, axes))
}

/// The scenario's machine: its first preset with the file's overrides applied, one axis on
/// `--node` (the same on CAN and on EtherCAT).
pub(super) fn scenario_machine(args: &RunArgs, s: &Scenario) -> Result<MachineFile> {
    let cfg = s
        .machine
        .configs
        .first()
        .context("the scenario has no machine")?;
    Ok(MachineFile {
        tick_hz: args.tick_hz,
        axes: vec![AxisEntry {
            node_id: args.node,
            name: None,
            preset: cfg.name.clone(),
            set: Default::default(),
            // the scenario's machine is as its file says (the preset's wear, its
            // overrides): scenarios are where wear is studied
            worn: true,
            eds: args.eds.clone(),
            objects_base: args.objects_base,
            profile: args.profile.clone(),
            quirks: None,
            quirk_profile: crate::drive::quirk_profile::QuirkProfile::from_args(
                args.profile.as_deref(),
                &args.quirk,
                &args.no_quirk,
            )?
            .map(Arc::new),
        }],
        ballbar: None,
        contour: None,
    })
}

/// `--lss-store FILE`: the drive's non-volatile memory (one axis). What it holds replaces the
/// node-ID (the serial number stays `--node`'s, so the LSS address does not move), and a
/// store configuration is written to it.
fn lss_options(args: &RunArgs, machine: &mut MachineFile) -> Result<LssOptions> {
    let Some(path) = &args.lss_store else {
        return Ok(LssOptions {
            force: args.force_lss,
            ..LssOptions::default()
        });
    };
    if machine.axes.len() != 1 {
        bail!(
            "--lss-store {}: one axis only (the machine has {}): it is one drive's memory",
            path.display(),
            machine.axes.len()
        );
    }
    let configured = machine.axes[0].node_id;
    let mut opts = LssOptions {
        config: drive_protocol::LssConfig {
            store_external: true,
            ..Default::default()
        },
        serial_number: Some(u32::from(configured)),
        force: args.force_lss,
    };
    match crate::cli::lss_store::load(path)? {
        Some(s) => {
            let id = s.node_id.unwrap_or(255);
            machine.axes[0].node_id = id;
            opts.config.bit_timing_index = s.bit_timing_index;
            eprintln!(
                "drive-emu: LSS store {}: node-ID {id}, bit timing {} (instead of --node {configured})",
                path.display(),
                crate::cli::lss_store::bit_timing_text(s.bit_timing_index),
            );
        }
        None => eprintln!(
            "drive-emu: LSS store {}: nothing stored yet (written at the first LSS store \
             configuration)",
            path.display()
        ),
    }
    Ok(opts)
}
