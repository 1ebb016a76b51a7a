//! `drive-emu run`: the drive(s) on a real or virtual CAN bus, at a fixed rate. The run on CAN
//! is the typed API's [`LiveRequest`](crate::api::live::LiveRequest); this module converts the
//! options into it and attaches what only the command line has.
//!
//! - [`args`]: the options, the request they describe;
//! - [`status`]: the terminal status line, the ready line, the LSS store service, the panel,
//!   attached to the API's run ([`run_live`]);
//! - [`ethercat`]: the run on EtherCAT (its own path, on the API's parts).

mod args;
mod ethercat;
mod status;

pub use crate::api::live::parts::inconclusive_text;
pub use crate::api::live::setup::{build_axes, LssOptions};
use crate::scenario::live::LiveOutcome;
use crate::scenario::Scenario;
use anyhow::{bail, Result};
pub use args::{
    machine_from_args, parse_index, positive_seconds, RunArgs, DEFAULT_BOOT_DELAY_MS,
    MAX_DURATION_S, MAX_SYNC_PERIOD_US,
};
pub use ethercat::ethercat_slaves;
use ethercat::run_ethercat;
pub use status::run_live;

pub fn run(args: &RunArgs) -> Result<()> {
    if let (Some(p), None) = (&args.esi, &args.ethercat) {
        return Err(super::exit::usage_msg(format!(
            "--esi {}: an ESI describes an EtherCAT slave; it needs --ethercat IFACE (on CAN, \
             serve a vendor's EDS with --eds FILE)",
            crate::quote::text(&p.display().to_string())
        )));
    }
    if let Some(iface) = &args.ethercat {
        return run_ethercat(args, iface);
    }
    let scenario = match &args.scenario {
        Some(path) => Some(crate::scenario::load(path).map_err(super::exit::scenario_file)?),
        None => None,
    };
    let outcome = run_live(args, scenario.as_ref())?;
    if let (Some(o), Some(s)) = (&outcome.scenario, &scenario) {
        if args.json {
            println!(
                "{}",
                serde_json::to_string_pretty(&outcome_json(&outcome, s))?
            );
        } else {
            print_outcome(o);
            println!(
                "{} (live on {}): {}",
                s.name,
                args.bus_label(),
                if o.passed() { "passed" } else { "FAILED" }
            );
        }
        if let Some(why) = o.unfinished() {
            bail!("{why}");
        }
        if !o.passed() {
            bail!("scenario expectations failed");
        }
    } else if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&outcome_json_stats(&outcome))?
        );
    }
    Ok(())
}

fn outcome_json_stats(run: &crate::api::live::LiveOutcome) -> serde_json::Value {
    let mut v = serde_json::json!({
        "stats": run.stats,
        "lockstep_sync_period_us": run.lockstep_period_us,
        "free_run_ticks_without_sync": run.free_run_ticks,
    });
    if !run.detector.is_empty() {
        v["detect"] = serde_json::json!(run
            .detector
            .iter()
            .map(|(node_id, rep)| serde_json::json!({ "node_id": node_id, "report": rep }))
            .collect::<Vec<_>>());
    }
    v
}

/// The JSON document of `run --scenario --json` and `scenario --iface --json`.
pub fn outcome_json(run: &crate::api::live::LiveOutcome, s: &Scenario) -> serde_json::Value {
    let mut v = outcome_json_stats(run);
    if let Some(o) = &run.scenario {
        v["scenario"] = serde_json::json!({
            "name": s.name,
            "passed": o.passed(),
            "finished": o.unfinished().is_none(),
            "failure": o.unfinished(),
            "end_s": o.record.end_us as f64 * 1e-6,
            "end_reason": o.end_reason,
            "events": o.fired.iter().map(|(t, what)| serde_json::json!({
                "t_s": *t as f64 * 1e-6, "event": what })).collect::<Vec<_>>(),
            "events_not_fired": o.not_fired.iter().map(|(line, what)| serde_json::json!({
                "line": line, "event": what })).collect::<Vec<_>>(),
            "emcys": o.record.emcys.iter().map(|(t, c)| serde_json::json!({
                "t_s": *t as f64 * 1e-6, "code": format!("{c:#06X}"),
                "meaning": crate::master::emcy_name(*c) })).collect::<Vec<_>>(),
            "detector": o.detector,
            "expectations": o.expectations,
            "samples": o.record.samples.len(),
            "samples_lost": o.samples_lost,
            "emcys_lost": o.emcys_lost,
        });
    }
    v
}

/// Print what a live scenario run found.
pub fn print_outcome(o: &LiveOutcome) {
    println!("  run {}", o.end_reason);
    for (t, what) in &o.fired {
        println!("  t={:>9.3} s  event: {what}", *t as f64 * 1e-6);
    }
    for (line, what) in &o.not_fired {
        println!("  not fired: line {line}: {what}");
    }
    for (t, code) in &o.record.emcys {
        println!(
            "  t={:>9.3} s  EMCY {code:#06X} ({})",
            *t as f64 * 1e-6,
            crate::master::emcy_name(*code)
        );
    }
    if let Some(d) = o.detector.as_ref().filter(|d| d.inconclusive.is_some()) {
        println!("  detector: {}", inconclusive_text(d));
    } else if let Some(d) = &o.detector {
        println!(
            "  detector: {} | amplitude {:.2} {} | frequency {}",
            d.verdict.as_str(),
            d.amplitude,
            crate::report::unit_text(&d.position_unit),
            d.frequency_hz.map_or("-".into(), |f| format!("{f:.2} Hz"))
        );
    }
    for e in &o.expectations {
        println!("  {e}");
    }
    if let Some(why) = o.unfinished() {
        println!("  FAIL {why}");
    }
    if o.samples_lost > 0 {
        println!(
            "  ({} samples lost: the scenario thread fell more than the observation ring behind)",
            o.samples_lost
        );
    }
    if o.emcys_lost > 0 {
        println!(
            "  ({} EMCYs not recorded: more in one tick than a snapshot carries)",
            o.emcys_lost
        );
    }
}

/// The exit status of a live scenario: it did not finish, or an expectation failed.
fn scenario_status(o: &LiveOutcome) -> Result<()> {
    if let Some(why) = o.unfinished() {
        bail!("{why}");
    }
    if !o.passed() {
        bail!("scenario expectations failed");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_inconclusive_detector_is_said_without_an_amplitude() {
        use crate::analysis::detector::{DetectorConfig, DetectorReport, Inconclusive};
        let d = DetectorReport::inconclusive(
            &DetectorConfig::new(30.0),
            Inconclusive::NoConstantSpeed,
            "no window of constant set speed".into(),
            "um",
        );
        let t = inconclusive_text(&d);
        assert!(
            t.starts_with("inconclusive (no_constant_speed): ") && t.contains("constant"),
            "{t}"
        );
        assert!(!t.contains("amplitude") && !t.contains("0.00"), "{t}");
        // Said once, not "inconclusive (x): inconclusive (x): ...".
        assert_eq!(t.matches("inconclusive (").count(), 1, "{t}");
    }
}
