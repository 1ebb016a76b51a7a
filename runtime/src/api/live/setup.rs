//! The machine and axes of a live run: the request checked as the command line checks it, the
//! machine it describes, each node and its simulated drive built from the machine (a vendor's
//! EDS, LSS options, the wear said on stderr).

use super::{
    LiveRequest, MAX_BOOT_DELAY_MS, MAX_DURATION_S, MAX_SYNC_PERIOD_US, MIN_SYNC_PERIOD_US,
};
use crate::api::ApiError;
use crate::drive::axis_drive::AxisDrive;
use crate::drive::machine::{self, AxisEntry, MachineFile};
use crate::drive::vendor::{self, VendorEds};
use crate::drive::{node_setup, NodeOptions};
use crate::presets::AxisConfig;
use crate::runtime::AxisSlot;
use crate::scenario::{Scenario, ScenarioError};
use anyhow::{bail, Result};
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
) -> Result<Vec<AxisSlot<AxisDrive>>, ApiError> {
    entries
        .iter_mut()
        .map(|e| {
            // what the user wrote (its message names the axis)
            let cfg = e.run_config().map_err(ApiError::of_input)?;
            axis_slot(cfg, e, boot_delay_us, lss)
        })
        .collect()
}

/// The node configuration and the simulated drive of one axis (what [`axis_slot`] builds its
/// node from; `run --ethercat` builds an EtherCAT slave from it).
pub fn axis_setup(
    cfg: AxisConfig,
    e: &mut AxisEntry,
    boot_delay_us: u64,
    lss: &LssOptions,
) -> Result<(drive_protocol::NodeConfig, AxisDrive), ApiError> {
    // what the user wrote (preset, overrides, vendor file): invalid, or unreadable
    let at = format!("axis node {}", e.node_id);
    let ctx = |err: anyhow::Error| config_error(&at, err);
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
) -> Result<AxisSlot<AxisDrive>, ApiError> {
    let (config, drive) = axis_setup(cfg, e, boot_delay_us, lss)?;
    let node = drive_protocol::Node::new(config)
        .map_err(|err| ApiError::Failed(anyhow::anyhow!("axis node {}: {err}", e.node_id)))?;
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
    req: &LiveRequest,
) -> Result<(MachineFile, Vec<AxisSlot<AxisDrive>>), ApiError> {
    let scenario = req.scenario.as_ref();
    let machine = match scenario {
        Some(s) => scenario_machine(req, s)?,
        None => machine_of(req)?,
    };
    machine::validate(&machine).map_err(ApiError::of_input)?;
    let mut machine = machine;
    let lss = lss_options(req, &mut machine)?;
    let boot_delay_us = req.boot_delay_ms * 1000;
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
pub fn scenario_machine(req: &LiveRequest, s: &Scenario) -> Result<MachineFile, ApiError> {
    let cfg = s
        .machine
        .configs
        .first()
        .ok_or_else(|| ApiError::invalid("the scenario has no machine"))?;
    Ok(MachineFile {
        tick_hz: req.tick_hz,
        axes: vec![AxisEntry {
            node_id: req.node_id,
            name: None,
            preset: cfg.name.clone(),
            set: Default::default(),
            // the scenario's machine is as its file says (the preset's wear, its
            // overrides): scenarios are where wear is studied
            worn: true,
            eds: req.eds.clone(),
            objects_base: req.objects_base,
            profile: req.profile.clone(),
            quirks: None,
            quirk_profile: quirk_profile(req)?.map(Arc::new),
        }],
        ballbar: None,
        contour: None,
    })
}

/// `--lss-store FILE`: the drive's non-volatile memory (one axis). What it holds replaces the
/// node-ID (the serial number stays `--node`'s, so the LSS address does not move), and a
/// store configuration is written to it (by the caller's hook).
fn lss_options(req: &LiveRequest, machine: &mut MachineFile) -> Result<LssOptions, ApiError> {
    let Some(mem) = &req.lss_memory else {
        return Ok(LssOptions {
            force: req.force_lss,
            ..LssOptions::default()
        });
    };
    let path = &mem.path;
    if machine.axes.len() != 1 {
        return Err(ApiError::invalid(format!(
            "--lss-store {}: one axis only (the machine has {}): it is one drive's memory",
            path.display(),
            machine.axes.len()
        )));
    }
    let configured = machine.axes[0].node_id;
    let mut opts = LssOptions {
        config: drive_protocol::LssConfig {
            store_external: true,
            ..Default::default()
        },
        serial_number: Some(u32::from(configured)),
        force: req.force_lss,
    };
    match mem.stored {
        Some(s) => {
            let id = s.node_id.unwrap_or(255);
            machine.axes[0].node_id = id;
            opts.config.bit_timing_index = s.bit_timing_index;
            eprintln!(
                "drive-emu: LSS store {}: node-ID {id}, bit timing {} (instead of --node {configured})",
                path.display(),
                (mem.bit_timing_text)(s.bit_timing_index),
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

/// The error of building an axis from what the user wrote (its preset, overrides and vendor
/// file), said with `prefix`: unreadable where a file could not be read, else invalid.
fn config_error(prefix: &str, err: anyhow::Error) -> ApiError {
    let unreadable = err
        .chain()
        .any(|c| c.downcast_ref::<crate::infile::InputError>().is_some());
    let e = anyhow::anyhow!("{prefix}: {err:#}");
    if unreadable {
        ApiError::Unreadable(e)
    } else {
        ApiError::Invalid(e)
    }
}

/// A scenario file's error: unreadable when it could not be read (no line), else invalid.
pub fn scenario_error(e: ScenarioError) -> ApiError {
    if e.line == 0 {
        ApiError::Unreadable(anyhow::Error::new(e))
    } else {
        ApiError::Invalid(anyhow::Error::new(e))
    }
}

/// The vendor profile and switches of `--profile`, `--quirk`, `--no-quirk`.
fn quirk_profile(
    req: &LiveRequest,
) -> Result<Option<crate::drive::quirk_profile::QuirkProfile>, ApiError> {
    crate::drive::quirk_profile::QuirkProfile::from_args(
        req.profile.as_deref(),
        &req.quirks,
        &req.no_quirks,
    )
    .map_err(|e| ApiError::of_input(e.into()))
}

impl LiveRequest {
    /// Check the request as the command line checks its flags (what clap checked, and what
    /// `run` checked after it), before anything opens: each error names its flag, and a
    /// scenario's bus faults must be CAN's and its values within what axis 0's drive accepts
    /// (the live loop would drop a refused one silently).
    pub fn check(&self) -> Result<(), ApiError> {
        self.check_numbers().map_err(ApiError::Invalid)?;
        if let (Some(p), true) = (&self.lss_memory, self.lockstep) {
            // The store is written between ticks, and lock-step runs no tick without SYNC (a
            // master configuring by LSS sends none): the answer would never come.
            return Err(ApiError::invalid(format!(
                "--lss-store {} and --lockstep: not together (in lock-step the loop stands \
                 still without SYNC, and the store is answered from the loop); without \
                 --lss-store a store configuration is kept in memory",
                p.path.display()
            )));
        }
        if let Some(s) = &self.scenario {
            crate::scenario::check_bus(s, "can").map_err(ApiError::Invalid)?;
            if let Some(cfg) = s.machine.configs.first() {
                crate::scenario::inject::check_ranges(s, cfg).map_err(scenario_error)?;
            }
        }
        Ok(())
    }

    /// The numeric fields: in range, as `drive-emu run --help` says.
    fn check_numbers(&self) -> Result<()> {
        if let Some(d) = self.duration_s {
            if !(d.is_finite() && d > 0.0 && d <= MAX_DURATION_S) {
                bail!(
                    "--duration {d}: must be a number of seconds > 0 and <= {MAX_DURATION_S:e} \
                     (omit it to run until Ctrl-C / SIGTERM)"
                );
            }
        }
        if !(0..=99).contains(&self.rt_priority) {
            bail!(
                "--rt-priority {}: must be 0..=99 (SCHED_FIFO priorities; 0 = normal scheduling)",
                self.rt_priority
            );
        }
        if let Some(cpu) = self.cpu {
            let n = std::thread::available_parallelism().map_or(1, |n| n.get());
            if cpu >= n {
                bail!("--cpu {cpu}: this machine has CPUs 0..={}", n - 1);
            }
        }
        if self.boot_delay_ms > MAX_BOOT_DELAY_MS {
            bail!(
                "--boot-delay-ms {}: must be 0..={MAX_BOOT_DELAY_MS}",
                self.boot_delay_ms
            );
        }
        let h = self.detect_history_s;
        if !(h.is_finite() && h > 0.0 && h < MAX_DURATION_S) {
            bail!("--detect-history {h}: a duration in seconds, more than 0");
        }
        if let Some(b) = self.objects_base.filter(|b| !(0x2000..=0x5F00).contains(b)) {
            bail!(
                "--objects-base 0x{b:04X}: outside the manufacturer area 0x2000..=0x5F00 \
                 (CiA 301)"
            );
        }
        if let Some(p) = self.sync_period_us {
            if !(MIN_SYNC_PERIOD_US..=MAX_SYNC_PERIOD_US).contains(&p) {
                bail!(
                    "--sync-period-us {p}: must be {MIN_SYNC_PERIOD_US}..={MAX_SYNC_PERIOD_US} \
                     us"
                );
            }
            let tick_us = 1_000_000 / u64::from(self.tick_hz.max(1));
            if self.lockstep && !p.is_multiple_of(tick_us) {
                bail!(
                    "--sync-period-us {p}: must be a whole multiple of the tick period \
                     ({tick_us} us at --tick-hz {}) between {tick_us} and \
                     {MAX_SYNC_PERIOD_US} us: each SYNC advances simulated time by whole ticks",
                    self.tick_hz
                );
            }
        }
        Ok(())
    }
}

/// The machine the request describes: its one axis (`--node`, `--preset`, `--set`, ...) or
/// the machine file (`--config`). Its errors are [`ApiError::Invalid`], or
/// [`ApiError::Unreadable`] where a file cannot be read.
pub fn machine_of(req: &LiveRequest) -> Result<MachineFile, ApiError> {
    let quirk_profile = quirk_profile(req)?;
    if let Some(path) = &req.machine_file {
        if quirk_profile.is_some() {
            return Err(ApiError::invalid(format!(
                "--profile / --quirk / --no-quirk with --config {}: set `profile =` and `quirks \
                 = {{...}}` per [[axis]] in the machine file",
                path.display()
            )));
        }
        let mut m = machine::load(path).map_err(ApiError::of_input)?;
        for a in &mut m.axes {
            a.worn |= req.worn;
        }
        return Ok(m);
    }
    // Said as the user wrote it (machine::validate would name the machine file's key).
    if !(1..=127).contains(&req.node_id) && req.node_id != 255 {
        return Err(ApiError::invalid(format!(
            "--node {}: outside 1..=127 (255: non-configured, a drive out of the box that \
             answers LSS only)",
            req.node_id
        )));
    }
    let mut set = std::collections::BTreeMap::new();
    for s in &req.sets {
        let Some((k, v)) = s.split_once('=') else {
            return Err(ApiError::invalid(format!(
                "--set {s}: an override must be written key=value"
            )));
        };
        let value = toml::from_str::<toml::Table>(&format!("v = {v}"))
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(v.to_string()));
        set.insert(k.trim().to_string(), value);
    }
    let m = MachineFile {
        tick_hz: req.tick_hz,
        axes: vec![AxisEntry {
            node_id: req.node_id,
            name: None,
            preset: req.preset.clone(),
            set,
            worn: req.worn,
            eds: req.eds.clone(),
            objects_base: req.objects_base,
            profile: req.profile.clone(),
            quirks: None,
            quirk_profile: quirk_profile.map(Arc::new),
        }],
        ballbar: None,
        contour: None,
    };
    machine::validate(&m).map_err(ApiError::of_input)?;
    Ok(m)
}
