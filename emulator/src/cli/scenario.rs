//! `drive-emu scenario FILE`: run a scenario offline (lock-step, faster than real time), write
//! the report (summary.json, sample logs, PNG plots) and exit non-zero when an expectation
//! fails (1) or the file is bad (2).

use crate::scenario::runner::{run_file, RunError, RunOptions};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug, Clone)]
pub struct ScenarioArgs {
    /// Scenario file (scenarios/*.toml).
    pub file: PathBuf,
    /// Output directory (default out/SCENARIO_NAME/).
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Skip the PNG plots.
    #[arg(long)]
    pub no_plots: bool,
    /// No progress line.
    #[arg(long, short)]
    pub quiet: bool,
    /// Physical dwell an idle step becomes when fast-forwarded, s.
    #[arg(long, default_value_t = 0.1)]
    pub idle_dwell: f64,
    /// Run the timeline live on this CAN interface against an external controller (the
    /// scenario's motion program is not used; the drive runs on the wall clock, or on SYNC
    /// with --lockstep), instead of offline with the built-in master.
    #[arg(long)]
    pub iface: Option<String>,
    /// Node ID of the drive when live.
    #[arg(long, default_value_t = 5)]
    pub node: u8,
    /// Live: advance simulated time one SYNC period per SYNC received.
    #[arg(long, requires = "iface")]
    pub lockstep: bool,
    /// Live, lock-step: simulated time per SYNC, us. Default: the communication cycle period
    /// 0x1006 once the master writes it, else 1000.
    #[arg(long, value_name = "US", requires = "lockstep",
          value_parser = clap::value_parser!(u64).range(100..=1_000_000))]
    pub sync_period_us: Option<u64>,
    /// Live: end the scenario at this simulated time, s (default: the file's `duration`, else
    /// once every event has fired and run its course). A SYNC missing for 1 s in lock-step
    /// hands the drive's clock to the wall clock, so the run ends either way.
    #[arg(long, value_name = "S", requires = "iface", value_parser = crate::cli::run::positive_seconds)]
    pub duration: Option<f64>,
    /// Print only JSON on stdout: live, the events, EMCYs, detector and expectations (as `run
    /// --scenario --json`); offline, the summary (as summary.json). Text goes to stderr.
    #[arg(long)]
    pub json: bool,
    /// Memory cap for the master's sample log, MB: a scenario whose program needs more
    /// (e.g. a mistyped 100000 h cruise) is refused before it runs.
    #[arg(long, default_value_t = crate::scenario::runner::DEFAULT_MAX_MEMORY_MB)]
    pub max_memory_mb: f64,
    /// Live: record what the drive reports, one row per tick (as `run --trace`).
    #[arg(long, value_name = "FILE", requires = "iface")]
    pub trace: Option<PathBuf>,
}

pub fn run(args: &ScenarioArgs) -> anyhow::Result<ExitCode> {
    if !(args.idle_dwell.is_finite() && args.idle_dwell > 0.0 && args.idle_dwell <= 60.0) {
        return Err(super::exit::usage_msg(format!(
            "--idle-dwell {}: must be within 0..=60 s (> 0: the physical time an idle step keeps)",
            args.idle_dwell
        )));
    }
    if !(args.max_memory_mb.is_finite() && args.max_memory_mb > 0.0) {
        return Err(super::exit::usage_msg(format!(
            "--max-memory-mb {}: must be > 0",
            args.max_memory_mb
        )));
    }
    if let Some(iface) = &args.iface {
        return run_live(args, iface);
    }
    let opts = RunOptions {
        idle_dwell_s: args.idle_dwell,
        progress: !args.quiet && !args.json,
        max_memory_mb: args.max_memory_mb,
        ..RunOptions::default()
    };
    let (out, dir) = match run_file(&args.file, args.out.as_deref(), &opts, !args.no_plots) {
        Ok(x) => x,
        // 2: the file's content is wrong; 4: it cannot be read (crate::cli::exit)
        Err(RunError::File(e)) => return Err(super::exit::scenario_file(e)),
        Err(RunError::Run(e)) => return Err(e),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
        eprintln!(
            "{}: {}; report in {}",
            out.scenario,
            if out.passed { "passed" } else { "FAILED" },
            dir.display()
        );
        return Ok(if out.passed {
            ExitCode::SUCCESS
        } else {
            ExitCode::from(1)
        });
    }
    for r in &out.runs {
        println!(
            "[{}] scenario {:.1} s (physical {:.1} s, fast-forwarded {:.1} s) in {:.2} s wall",
            r.preset, r.scenario_s, r.physical_s, r.fast_forwarded_s, r.wall_s
        );
        if let Some(d) = r.detector.as_ref().filter(|d| d.inconclusive.is_some()) {
            println!("  detector: {}", super::run::inconclusive_text(d));
        } else if let Some(d) = &r.detector {
            println!(
                "  detector: {} | amplitude {:.2} {} | severity {:.2} | frequency {} | first flagged: {}",
                d.verdict.as_str(),
                d.amplitude,
                crate::report::unit_text(&d.position_unit),
                d.severity,
                d.frequency_hz
                    .or(d.dominant_hz)
                    .map_or("-".into(), |f| format!("{f:.2} Hz = {:.2} k_v", f / d.kv_per_s)),
                d.first_suspected_s
                    .map_or("never".into(), |t| format!("at {:.1} min", t / 60.0))
            );
        }
        for e in &r.expectations {
            println!("  {e}");
        }
        if let Some(why) = &r.program_failure {
            println!("  FAIL {why}");
        }
        if let Some(why) = &r.unfinished {
            println!("  FAIL {why}");
        }
    }
    println!(
        "{}: {} in {:.2} s; report in {}",
        out.scenario,
        if out.passed { "passed" } else { "FAILED" },
        out.wall_s,
        dir.display()
    );
    Ok(if out.passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// `--iface`: the timeline injected into a drive running on a real bus.
fn run_live(args: &ScenarioArgs, iface: &str) -> anyhow::Result<ExitCode> {
    use clap::Parser;
    let s = crate::scenario::load(&args.file).map_err(super::exit::scenario_file)?;
    // The run command's defaults, with this command's interface, node and clock.
    #[derive(Parser)]
    struct Wrap {
        #[command(flatten)]
        run: crate::cli::run::RunArgs,
    }
    let mut run = Wrap::parse_from(["drive-emu"]).run;
    run.iface = iface.to_string();
    run.node = args.node;
    run.lockstep = args.lockstep;
    run.sync_period_us = args.sync_period_us;
    run.duration = args.duration;
    run.json = args.json;
    run.trace = args.trace.clone();
    run.tick_hz = (1_000_000 / s.run.tick_us) as u32;
    let live = crate::cli::run::run_live(&run, Some(&s))?;
    let outcome = live
        .scenario
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("no scenario outcome"))?;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&crate::cli::run::outcome_json(&live, &s))?
        );
    } else {
        crate::cli::run::print_outcome(outcome);
        println!(
            "{} (live on {iface}): {}",
            s.name,
            if outcome.passed() { "passed" } else { "FAILED" }
        );
    }
    Ok(if outcome.passed() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
