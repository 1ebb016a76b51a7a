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
    /// Output directory (default out/<scenario name>/).
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
}

pub fn run(args: &ScenarioArgs) -> anyhow::Result<ExitCode> {
    let opts = RunOptions {
        idle_dwell_s: args.idle_dwell,
        progress: !args.quiet,
        ..RunOptions::default()
    };
    let (out, dir) = match run_file(&args.file, args.out.as_deref(), &opts, !args.no_plots) {
        Ok(x) => x,
        Err(RunError::File(e)) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(2));
        }
        Err(RunError::Run(e)) => return Err(e),
    };
    for r in &out.runs {
        println!(
            "[{}] scenario {:.1} s (physical {:.1} s, fast-forwarded {:.1} s) in {:.2} s wall",
            r.preset, r.scenario_s, r.physical_s, r.fast_forwarded_s, r.wall_s
        );
        if let Some(d) = &r.detector {
            println!(
                "  detector: {} | amplitude {:.2} {} | severity {:.2} | frequency {} | first flagged {}",
                d.verdict.as_str(),
                d.amplitude,
                d.position_unit,
                d.severity,
                d.frequency_hz
                    .or(d.dominant_hz)
                    .map_or("-".into(), |f| format!("{f:.2} Hz = {:.2} k_v", f / d.kv_per_s)),
                d.first_suspected_s
                    .map_or("never".into(), |t| format!("at {:.1} min", t / 60.0))
            );
        }
        for e in &r.expectations {
            println!(
                "  {} line {}: {} ({})",
                if e.passed { "ok  " } else { "FAIL" },
                e.line,
                e.expectation,
                e.detail
            );
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
