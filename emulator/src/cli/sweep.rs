//! `drive-emu sweep`: k_v x backlash x preset, every case a constant-velocity run measured from
//! its trace, run on all cores; one CSV row and one JSON object per case.

use std::path::PathBuf;

use anyhow::Context;

use crate::presets::{preset_names, AxisConfig};
use crate::study::{
    default_velocity, own_backlash, rows_csv, run_cases, Case, ValueSpec, CASE_DURATION_S,
    DEFAULT_DURATION_S, MAX_SWEEP_CASES,
};

/// Arguments of `drive-emu sweep`.
#[derive(clap::Args, Debug, Clone)]
pub struct SweepArgs {
    /// Presets: `all` or a comma-separated list (cnc1,cnc3).
    #[arg(long, default_value = "all")]
    pub preset: String,
    /// k_v values, 1/s: `A..B:N`, `A,B,C`; a trailing `x` is relative to the preset's own k_v
    /// (`0.5x..2x:7`).
    #[arg(long, default_value = "0.5x..2x:7")]
    pub kv: String,
    /// Backlash in the preset's unit (mm or deg), same syntax (`1x` = the preset's own).
    #[arg(long, default_value = "1x")]
    pub backlash: String,
    /// Cruise velocity (mm/s or deg/s; default 20 mm/s, tables 0.026 r/s).
    #[arg(long)]
    pub velocity: Option<f64>,
    /// Simulated seconds per case.
    #[arg(long, default_value_t = DEFAULT_DURATION_S)]
    pub duration: f64,
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Output directory: sweep.csv and sweep.json.
    #[arg(long, default_value = "out/sweep")]
    pub out: PathBuf,
}

pub fn run(args: &SweepArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        CASE_DURATION_S.contains(&args.duration),
        "--duration must be {}..{} s (the FFT window is the cruise after the start-up transient)",
        CASE_DURATION_S.start(),
        CASE_DURATION_S.end()
    );
    if let Some(v) = args.velocity {
        anyhow::ensure!(
            v.is_finite() && v != 0.0,
            "--velocity must be a non-zero number"
        );
    }
    let kv = ValueSpec::parse(&args.kv).map_err(|e| anyhow::anyhow!("--kv: {e}"))?;
    let bl = ValueSpec::parse(&args.backlash).map_err(|e| anyhow::anyhow!("--backlash: {e}"))?;
    let names: Vec<String> = if args.preset == "all" {
        preset_names().map(str::to_string).collect()
    } else {
        args.preset
            .split(',')
            .map(|s| s.trim().to_string())
            .collect()
    };
    // Counted before any case is built: a grid of millions is refused, not allocated.
    let total = names
        .len()
        .saturating_mul(kv.len())
        .saturating_mul(bl.len());
    if total > MAX_SWEEP_CASES {
        return Err(crate::cli::exit::usage_msg(format!(
            "{total} cases ({} presets x {} k_v x {} backlash): at most {MAX_SWEEP_CASES} in \
             one sweep (its table is held in memory); split the grid into several sweeps",
            names.len(),
            kv.len(),
            bl.len()
        )));
    }
    let mut cases = Vec::with_capacity(total);
    for name in &names {
        let cfg = AxisConfig::from_preset(name).map_err(|e| anyhow::anyhow!("--preset: {e}"))?;
        for k in kv.resolve(cfg.kv_per_s) {
            anyhow::ensure!(k > 0.0, "--kv: k_v must be > 0, got {k}");
            for b in bl.resolve(own_backlash(&cfg)) {
                cases.push((
                    cfg.clone(),
                    Case {
                        preset: cfg.name.clone(),
                        kv_per_s: k,
                        backlash: b,
                        velocity: args.velocity.unwrap_or_else(|| default_velocity(&cfg)),
                        duration_s: args.duration,
                    },
                ));
            }
        }
    }
    let t0 = std::time::Instant::now();
    let rows = run_cases(&cases, args.threads)
        .into_iter()
        .zip(&cases)
        .map(|(r, (_, c))| {
            r.map_err(|e| {
                anyhow::anyhow!(
                    "{} k_v {} backlash {}: {e}",
                    c.preset,
                    c.kv_per_s,
                    c.backlash
                )
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let csv = args.out.join("sweep.csv");
    std::fs::write(&csv, rows_csv(&rows)).with_context(|| format!("{}", csv.display()))?;
    let json = args.out.join("sweep.json");
    crate::report::write_json(&json, &rows)?;
    let cycles = rows.iter().filter(|r| r.limit_cycle).count();
    let band = rows.iter().filter(|r| r.in_band).count();
    let law = rows
        .iter()
        .filter(|r| r.limit_cycle && r.f_over_kv.is_some_and(|x| (x - 0.6).abs() <= 0.1))
        .count();
    println!(
        "{} cases in {:.1} s wall: {cycles} with a limit cycle, {band} with k_v/4 < f < k_v, \
         {law} with f/k_v in 0.6 +- 0.1\n  {}\n  {}",
        rows.len(),
        t0.elapsed().as_secs_f64(),
        csv.display(),
        json.display()
    );
    Ok(())
}
