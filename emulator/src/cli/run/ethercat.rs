//! `run --ethercat IFACE`: the run's axes as EtherCAT slaves on a raw Ethernet port, with the
//! same observation bus, readers, scenario and panel as on CAN.

use super::args::{machine_from_args, RunArgs};
use super::{outcome_json, print_outcome, scenario_status};
use crate::api::live::parts::{
    gap_models, join_scenario, realtime_request, spawn_scenario, start_readers, stop_flag,
};
use crate::api::live::setup::{axis_setup, scenario_machine, LssOptions};
use crate::api::live::LiveRequest;
use crate::cli::api_error;
use crate::drive::axis_drive::AxisDrive;
use crate::drive::machine::{self, MachineFile};
use crate::runtime::realtime::{self};
use crate::scenario::live::{LiveLink, LiveOutcome, LoopInjector};
use crate::scenario::Scenario;
use anyhow::Result;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::Arc;

/// The run's axes as EtherCAT slaves (in machine-file order) and their drives, as
/// `run --ethercat` serves them and `drive-emu esi` describes them.
pub fn ethercat_slaves(
    args: &RunArgs,
) -> Result<(MachineFile, Vec<drive_ethercat::Slave>, Vec<AxisDrive>)> {
    ethercat_slaves_for(args, None)
}

/// [`ethercat_slaves`], or with a scenario its machine (one axis, as on CAN).
fn ethercat_slaves_for(
    args: &RunArgs,
    scenario: Option<&Scenario>,
) -> Result<(MachineFile, Vec<drive_ethercat::Slave>, Vec<AxisDrive>)> {
    let mut machine = match scenario {
        Some(s) => scenario_machine(&args.request_base(), s).map_err(api_error)?,
        None => machine_from_args(args)?,
    };
    machine::validate(&machine)?;
    let lss = LssOptions::default();
    let esi = match &args.esi {
        Some(path) => Some(load_esi(path)?),
        None => None,
    };
    let mut slaves = Vec::new();
    let mut drives = Vec::new();
    for e in machine.axes.iter_mut() {
        let cfg = match scenario {
            Some(s) => s.machine.configs[0].clone(),
            None => e.run_config()?,
        };
        // no boot delay: an EtherCAT slave's mailbox is there from PRE-OP on
        let (config, mut drive) = axis_setup(cfg, e, 0, &lss).map_err(api_error)?;
        let slave = match &esi {
            Some((path, dev)) => {
                drive_ethercat::Slave::with_esi(config, &mut drive, dev).map_err(|err| {
                    crate::cli::exit::usage_msg(format!(
                        "--esi {}: axis node {}: {err}",
                        crate::quote::text(&path.display().to_string()),
                        e.node_id
                    ))
                })?
            }
            None => drive_ethercat::Slave::new(config, &mut drive)
                .map_err(|err| anyhow::anyhow!("axis node {}: {err}", e.node_id))?,
        };
        slaves.push(slave);
        drives.push(drive);
    }
    Ok((machine, slaves, drives))
}

/// Read a vendor's ESI (`--esi FILE`): bounded, UTF-8, its first device; an error says the
/// file, the line and why (exit 2; 4 when the file cannot be read).
fn load_esi(path: &std::path::Path) -> Result<(PathBuf, drive_ethercat::esi::EsiDevice)> {
    let text = crate::infile::read_text(path, "ESI file", crate::infile::MAX_CONFIG_BYTES)
        .map_err(crate::cli::exit::unreadable)?;
    let dev = drive_ethercat::esi::parse(&text).map_err(|e| {
        crate::cli::exit::usage_msg(format!(
            "--esi {}: {e}",
            crate::quote::text(&path.display().to_string())
        ))
    })?;
    Ok((path.to_path_buf(), dev))
}

/// `run --ethercat IFACE`: the machine's axes as EtherCAT slaves on a raw Ethernet port; with
/// `--scenario`, its machine on one slave and its timeline (parameters, sensor and EtherCAT
/// faults) injected as on CAN.
pub(super) fn run_ethercat(args: &RunArgs, iface: &str) -> Result<()> {
    let scenario = ethercat_scenario(args)?;
    let (machine, slaves, mut drives) = ethercat_slaves_for(args, scenario.as_ref())?;
    let mut sock = crate::bus::ethercat::PacketSocket::open(iface)?;
    // the API's request of these options: the readers, stop flag and scenario thread are CAN's
    let req = LiveRequest {
        scenario: scenario.clone(),
        ..args.request_base()
    };
    let stop = stop_flag(&req)?;
    let period_us = 1_000_000 / u64::from(machine.tick_hz);
    announce_ethercat(args, iface, &machine, scenario.as_ref());
    // The observation bus, as on CAN: published after each drive cycle
    let (mut observer, obs) = crate::observe::channel(
        slaves.len(),
        crate::observe::run_ring_capacity(machine.tick_hz),
    );
    // --trace, --detect: the same readers as on CAN
    let readers = start_readers(
        &req,
        &obs,
        slaves.iter().map(|s| s.node().node_id()).zip(drives.iter()),
        gap_models(&machine, scenario.as_ref()),
    )?;
    let detect = readers.detect.clone();
    // --scenario: its thread follows the drives' time and feeds the first slave injections
    let link = Arc::new(LiveLink::new());
    let mut injector = scenario
        .as_ref()
        .map(|s| LoopInjector::new(s.run.master.master_id));
    // --panel: the same panel as on CAN, its bus faults EtherCAT's; it takes the scenario's
    // injections into its own injector
    let context = crate::panel::RunContext {
        bus: crate::panel::PanelBus::Ethercat,
        iface: None,
        node: args.node,
        lockstep: args.lockstep,
        json: args.json,
        machine: &machine,
        scenario: scenario.as_ref(),
    };
    let (panel, mut panel_loop) =
        crate::panel::start_for_run(&args.panel, context, (&link, &obs), &mut injector)?.unzip();
    let scenario_thread = match &scenario {
        Some(s) => Some(spawn_scenario(&req, s, (&link, &obs), &stop).map_err(api_error)?),
        None => None,
    };
    let mut faults =
        crate::bus::ethercat::EcatFaults::new(scenario.as_ref().map_or(1, |s| s.run.seed));
    let mut seg = drive_ethercat::Segment::new(slaves);
    // The loop runs on this thread: real-time scheduling, CPU and locked memory as on CAN.
    let report = realtime::apply(&realtime_request(&req));
    for w in &report.warnings {
        eprintln!("drive-emu: warning: {w}");
    }
    eprintln!("drive-emu: loop thread: {report}");
    let stats = crate::runtime::ethercat::serve(
        &mut sock,
        &mut seg,
        &mut drives,
        (period_us, args.lockstep),
        &stop,
        &mut faults,
        |seg, drives, faults, t_us| {
            // publish: every slave's node beside its drive, its events drained
            observer.publish_axes(
                t_us,
                seg.slaves
                    .iter_mut()
                    .map(|s| s.node_mut())
                    .zip(drives.iter()),
            );
            // apply the injections: the panel's and the scenario's, the detector's results
            if let Some(p) = panel_loop.as_mut() {
                p.on_ethercat_cycle(seg, drives, faults, t_us);
            } else if let (Some(inj), Some(slave), Some(drive)) = (
                injector.as_mut(),
                seg.slaves.first_mut(),
                drives.first_mut(),
            ) {
                inj.on_ethercat_cycle(&link, t_us, slave, drive, faults);
            }
            if let Some(d) = &detect {
                for (k, (s, drive)) in seg.slaves.iter_mut().zip(drives.iter()).enumerate() {
                    d.apply_axis(k, s.node_mut(), drive);
                }
            }
        },
    );
    // the loop has stopped: a scenario still running ends now
    stop.store(true, Ordering::Relaxed);
    if let Some(p) = panel {
        p.stop();
    }
    let detector = readers.finish()?;
    let outcome = join_scenario(scenario_thread)?;
    ethercat_summary(
        &stats,
        &faults,
        (detector.detector, outcome),
        (iface, scenario.as_ref()),
        args,
    )
}

/// `run --ethercat`'s options and scenario, checked before anything opens: the scenario read
/// and its bus faults EtherCAT's.
fn ethercat_scenario(args: &RunArgs) -> Result<Option<Scenario>> {
    args.request_base().check().map_err(api_error)?;
    crate::panel::check_args(&args.panel)?;
    let scenario = match &args.scenario {
        Some(path) => Some(crate::scenario::load(path).map_err(crate::cli::exit::scenario_file)?),
        None => None,
    };
    if let Some(s) = &scenario {
        crate::scenario::check_bus(s, "ethercat").map_err(crate::cli::exit::usage)?;
    }
    Ok(scenario)
}

/// What runs where, on stderr, and with `--ready` the ready line on stdout.
fn announce_ethercat(
    args: &RunArgs,
    iface: &str,
    machine: &MachineFile,
    scenario: Option<&Scenario>,
) {
    eprintln!(
        "drive-emu: {} EtherCAT slave(s) on {iface}, {} Hz{}{}",
        machine.axes.len(),
        machine.tick_hz,
        if args.lockstep {
            " per process-data cycle (lock-step)"
        } else {
            ""
        },
        scenario.map_or(String::new(), |s| format!("; scenario {}", s.name)),
    );
    if args.ready {
        let nodes: Vec<serde_json::Value> = machine
            .axes
            .iter()
            .map(|e| serde_json::json!({"node_id": e.node_id, "preset": e.preset}))
            .collect();
        println!(
            "{}",
            serde_json::json!({"event": "ready", "ethercat": iface, "nodes": nodes,
                "scenario": scenario.map(|s| s.name.clone()),
                "pid": std::process::id()})
        );
        use std::io::Write;
        std::io::stdout().flush().ok();
    }
}

/// What the EtherCAT loop did and, with a scenario, what it found: on stderr, on stdout
/// (text, or `--json`), and the run's exit status.
fn ethercat_summary(
    stats: &crate::runtime::ethercat::EthercatStats,
    faults: &crate::bus::ethercat::EcatFaults,
    (detector, outcome): (
        Vec<(u8, Option<crate::analysis::detector::DetectorReport>)>,
        Option<LiveOutcome>,
    ),
    (iface, scenario): (&str, Option<&Scenario>),
    args: &RunArgs,
) -> Result<()> {
    let fs = faults.stats();
    eprintln!(
        "drive-emu: stopped. {} frames answered, {} refused, {} socket errors, {} cycles ({} late); \
         faults: {} frames lost, {} held, {} with bad working counters",
        stats.frames,
        stats.refused,
        stats.socket_errors,
        stats.cycles,
        stats.late_cycles,
        fs.lost + fs.hold_full,
        fs.held,
        fs.bad_wkc
    );
    if let (Some(o), Some(s)) = (&outcome, &scenario) {
        if !args.json {
            print_outcome(o);
            println!(
                "{} (live on EtherCAT {iface}): {}",
                s.name,
                if o.passed() { "passed" } else { "FAILED" }
            );
        }
    }
    if args.json {
        let mut v = serde_json::json!({"frames": stats.frames, "refused": stats.refused,
            "socket_errors": stats.socket_errors, "cycles": stats.cycles,
            "late_cycles": stats.late_cycles, "faults": fs,
            "sync0_locked_cycles": stats.sync0_locked_cycles,
            "sync0_phase_p50_us": stats.sync0_phase_p50_us,
            "sync0_phase_p99_us": stats.sync0_phase_p99_us,
            "sync0_phase_max_us": stats.sync0_phase_max_us,
            "detect": detector.iter().map(|(node_id, rep)|
                serde_json::json!({ "node_id": node_id, "report": rep }))
                .collect::<Vec<_>>()});
        if let (Some(o), Some(s)) = (outcome, &scenario) {
            let run = crate::api::live::LiveOutcome {
                stats: Default::default(),
                trace: None,
                detector: Vec::new(),
                detector_lost: 0,
                lockstep_period_us: None,
                free_run_ticks: 0,
                scenario: Some(o),
            };
            v["scenario"] = outcome_json(&run, s)["scenario"].take();
            println!("{v}");
            let o = run.scenario.as_ref().expect("just set");
            return scenario_status(o);
        }
        println!("{v}");
    } else if let Some(o) = &outcome {
        return scenario_status(o);
    }
    Ok(())
}
