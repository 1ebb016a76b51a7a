//! `drive-emu figures`: the paper's Fig. 3, 10 and 11 from simulated runs, as PNG + JSON.

use std::path::PathBuf;

use anyhow::Context;

use crate::study::figures::{fig10, fig11, fig3, fig_drag, fig_outer_loop, fig_twin};

/// Arguments of `drive-emu figures`.
#[derive(clap::Args, Debug, Clone)]
pub struct FiguresArgs {
    /// Output directory (the README's figures live in docs/img).
    #[arg(long, default_value = "out/figures")]
    pub out: PathBuf,
    /// Which figures: comma-separated from 3, 10, 11, drag (the limit cycle's drag
    /// boundary over k_v and the gap, docs/physics.md) and outer (the master closing the
    /// position loop over the bus in CSV: f against its k_v, and against the SYNC period) and
    /// twin (CNC3's twin pinion with its preload lost and holding).
    #[arg(long, default_value = "3,10,11,drag,outer,twin")]
    pub only: String,
    /// Preset whose speed loop Fig. 3 measures.
    #[arg(long, default_value = "cnc1")]
    pub fig3_preset: String,
    /// Override a key of Fig. 3's preset, e.g. --set speed_kp_nms_per_rad=6 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Worker threads for Fig. 11 (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

pub fn run(args: &FiguresArgs) -> anyhow::Result<()> {
    let mut which = Vec::new();
    for w in args.only.split(',') {
        match w.trim() {
            "3" | "10" | "11" | "drag" | "outer" | "twin" => which.push(w.trim().to_string()),
            other => {
                anyhow::bail!("--only: unknown figure `{other}` (3, 10, 11, drag, outer, twin)")
            }
        }
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    for w in which {
        match w.as_str() {
            "3" => {
                let (p, r) = fig3(&args.out, &args.fig3_preset, &args.set)?;
                println!(
                    "Fig. 3 {}: closed speed loop of {}, -3 dB bandwidth {}",
                    p.display(),
                    r.preset,
                    r.bandwidth_3db_hz
                        .map_or("not reached below 1 kHz".into(), |b| format!("{b:.0} Hz"))
                );
            }
            "10" => {
                let (p, d) = fig10(&args.out)?;
                let s: Vec<String> = d
                    .traces
                    .iter()
                    .map(|t| {
                        format!(
                            "{} deg: {} Hz, {:.2} rpm",
                            t.backlash_deg,
                            t.fundamental_hz.map_or("-".into(), |f| format!("{f:.2}")),
                            t.motor_velocity_amplitude_rpm
                        )
                    })
                    .collect();
                println!("Fig. 10 {}: {}", p.display(), s.join("; "));
            }
            "outer" => {
                let (p, d) = fig_outer_loop(&args.out)?;
                let held = d
                    .law
                    .iter()
                    .filter(|r| {
                        r.limit_cycle && r.f_over_kv.is_some_and(|x| (x - 0.6).abs() <= 0.1)
                    })
                    .count();
                let breaks: Vec<String> = d
                    .breaks
                    .iter()
                    .map(|b| {
                        format!(
                            "{} {}",
                            b.preset,
                            b.breaks_at_ratio.map_or("holds".into(), |r| format!(
                                "breaks at {} us (T_sync f0 = {r:.3})",
                                b.breaks_at_us.unwrap_or(0)
                            ))
                        )
                    })
                    .collect();
                println!(
                    "Master position loop {}: {} of {} runs with f/k_v in 0.6 +- 0.1 at 1 ms; {}",
                    p.display(),
                    held,
                    d.law.len(),
                    breaks.join(", ")
                );
            }
            "twin" => {
                let (p, d) = fig_twin(&args.out)?;
                let s: Vec<String> = d
                    .traces
                    .iter()
                    .map(|t| {
                        format!(
                            "preload {} %: {:.3} rpm",
                            t.preload_pct, t.motor_velocity_amplitude_rpm
                        )
                    })
                    .collect();
                println!("Twin pinion {}: {}", p.display(), s.join("; "));
            }
            "drag" => {
                let (p, d) = fig_drag(&args.out, args.threads)?;
                println!(
                    "Drag boundary {}: {} runs, {} with a limit cycle in k_v/4..k_v",
                    p.display(),
                    d.rows.len(),
                    d.rows.iter().filter(|r| r.limit_cycle && r.in_band).count()
                );
            }
            _ => {
                let (p, d) = fig11(&args.out, args.threads)?;
                let ok = d
                    .rows
                    .iter()
                    .filter(|r| {
                        r.f_over_kv.is_some_and(|x| (x - 0.6).abs() <= 0.1) && r.limit_cycle
                    })
                    .count();
                println!(
                    "Fig. 11 {}: {} runs, {} with f/k_v in 0.6 +- 0.1, {} without a limit cycle",
                    p.display(),
                    d.rows.len(),
                    ok,
                    d.rows.iter().filter(|r| !r.limit_cycle).count()
                );
            }
        }
    }
    Ok(())
}
