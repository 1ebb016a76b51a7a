//! `drive-emu sweep`: k_v x backlash x preset, every case a constant-velocity run measured from
//! its trace, run on all cores; one CSV row and one JSON object per case.

use std::path::PathBuf;

use anyhow::Context;

use crate::cli::exit::usage_msg;
use crate::cli::param_flags::{flag_of, moved_warning};
use crate::presets::{preset_names, AxisConfig, AxisKind};
use crate::study::{
    default_velocity, own_backlash, rows_csv, run_cases, Case, ValueSpec, CASE_DURATION_S,
    DEFAULT_DURATION_S, MAX_SWEEP_CASES,
};
use drive_physics::params::AxisParam;

/// Arguments of `drive-emu sweep`.
#[derive(clap::Args, Debug, Clone)]
pub struct SweepArgs {
    /// Presets: `all` or a comma-separated list (cnc1,cnc3).
    #[arg(long, default_value = "all")]
    pub preset: String,
    /// k_v values, 1/s (`kv_per_s`): `A..B:N`, `A,B,C`; a trailing `x` is relative to the
    /// preset's own k_v (`0.5x..2x:7`).
    #[arg(long = "kv-per-s", alias = "kv_per_s", default_value = DEFAULT_KV)]
    pub kv_per_s: String,
    /// Backlash of the linear presets, mm (`backlash_mm`), same syntax (`1x` = the preset's
    /// own).
    #[arg(long = "backlash-mm", alias = "backlash_mm", default_value = DEFAULT_BACKLASH)]
    pub backlash_mm: String,
    /// Backlash of the rotary presets, deg (`backlash_deg`), same syntax.
    #[arg(long = "backlash-deg", alias = "backlash_deg", default_value = DEFAULT_BACKLASH)]
    pub backlash_deg: String,
    /// Moved to `--kv-per-s` (taken for one release, with a warning).
    #[arg(long, hide = true, conflicts_with = "kv_per_s")]
    pub kv: Option<String>,
    /// Moved to `--backlash-mm` / `--backlash-deg` (taken for one release, with a warning:
    /// in each preset's unit, as before).
    #[arg(long, hide = true, conflicts_with_all = ["backlash_mm", "backlash_deg"])]
    pub backlash: Option<String>,
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

const DEFAULT_KV: &str = "0.5x..2x:7";
const DEFAULT_BACKLASH: &str = "1x";

/// The sweep's grid axes: the registry parameter each sets (its flags are its spellings,
/// [`flag_of`]: `--kv-per-s`, `--backlash-mm` and `--backlash-deg`) and the flag it had
/// before, still taken for one release with a warning.
pub const GRID_PARAMS: &[(AxisParam, &str)] =
    &[(AxisParam::Kv, "--kv"), (AxisParam::Backlash, "--backlash")];

/// A grid axis' values as written, with the flag that gave them (the one the user wrote, or
/// the default's).
struct GridAxis {
    flag: String,
    values: ValueSpec,
}

impl SweepArgs {
    /// The flags that moved and were given: the warnings to print.
    pub fn moved_flags(&self) -> Vec<String> {
        let mut out = vec![];
        if self.kv.is_some() {
            out.push(moved_warning("--kv", "--kv-per-s"));
        }
        if self.backlash.is_some() {
            out.push(moved_warning(
                "--backlash",
                "--backlash-mm` (linear presets) or `--backlash-deg` (rotary presets)",
            ));
        }
        out
    }

    /// The text of grid axis `param` for a kind of axis (`rotary`), with the flag the user
    /// wrote (the moved one where given, else the registry spelling's); `None` for a
    /// parameter that is no axis of the grid.
    pub fn grid_text(&self, param: AxisParam, rotary: bool) -> Option<(String, &str)> {
        let key = drive_physics::params::of_live(param).form(rotary).key;
        let (text, flag) = match param {
            AxisParam::Kv => match &self.kv {
                Some(old) => (old, "--kv".to_string()),
                None => (&self.kv_per_s, flag_of(key)),
            },
            AxisParam::Backlash => match &self.backlash {
                Some(old) => (old, "--backlash".to_string()),
                None if rotary => (&self.backlash_deg, flag_of(key)),
                None => (&self.backlash_mm, flag_of(key)),
            },
            _ => return None,
        };
        Some((flag, text.as_str()))
    }

    /// The values of grid axis `param` for a kind of axis, parsed.
    fn axis(&self, param: AxisParam, rotary: bool) -> Result<GridAxis, anyhow::Error> {
        let (flag, text) = self
            .grid_text(param, rotary)
            .ok_or_else(|| anyhow::anyhow!("internal: {param:?} is no axis of the sweep's grid"))?;
        let values = ValueSpec::parse(text).map_err(|e| usage_msg(format!("{flag}: {e}")))?;
        Ok(GridAxis { flag, values })
    }
}

/// Every value of `axis` for preset `cfg`, resolved (`1x`: the preset's own) and checked where
/// the key enters (`AxisConfig::with_override`: the registry's range, the drive's range of a
/// running parameter): a value out of range is refused before any case runs, naming the flag.
fn resolved(
    axis: &GridAxis,
    param: AxisParam,
    cfg: &AxisConfig,
) -> Result<Vec<f64>, anyhow::Error> {
    let rotary = cfg.kind == AxisKind::Rotary;
    let key = drive_physics::params::of_live(param).form(rotary).key;
    let own = match param {
        AxisParam::Kv => cfg.kv_per_s,
        _ => own_backlash(cfg),
    };
    let values = axis.values.resolve(own);
    for &v in &values {
        cfg.with_override(key, &format!("{v:e}")).map_err(|e| {
            usage_msg(format!(
                "{} {v} on {}: {}: {}",
                axis.flag, cfg.name, e.key, e.reason
            ))
        })?;
    }
    Ok(values)
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
    for w in args.moved_flags() {
        eprintln!("{w}");
    }
    let names: Vec<String> = if args.preset == "all" {
        preset_names().map(str::to_string).collect()
    } else {
        args.preset
            .split(',')
            .map(|s| s.trim().to_string())
            .collect()
    };
    let mut configs = Vec::with_capacity(names.len());
    for name in &names {
        configs.push(AxisConfig::from_preset(name).map_err(|e| anyhow::anyhow!("--preset: {e}"))?);
    }
    // Each preset's axes (its kind of axis' flags), counted before any case is built: a grid
    // of millions is refused, not allocated.
    let mut grids = Vec::with_capacity(configs.len());
    let mut total = 0usize;
    for cfg in &configs {
        let rotary = cfg.kind == AxisKind::Rotary;
        let kv = args.axis(AxisParam::Kv, rotary)?;
        let bl = args.axis(AxisParam::Backlash, rotary)?;
        total = total.saturating_add(kv.values.len().saturating_mul(bl.values.len()));
        grids.push((kv, bl));
    }
    if total > MAX_SWEEP_CASES {
        let sizes: Vec<(usize, usize)> = grids
            .iter()
            .map(|(kv, bl)| (kv.values.len(), bl.values.len()))
            .collect();
        let how = if sizes.windows(2).all(|w| w[0] == w[1]) {
            format!(
                "{} presets x {} k_v x {} backlash",
                names.len(),
                sizes[0].0,
                sizes[0].1
            )
        } else {
            let each: Vec<String> = configs
                .iter()
                .zip(&sizes)
                .map(|(c, (k, b))| format!("{}: {k} k_v x {b} backlash", c.name))
                .collect();
            each.join(", ")
        };
        return Err(usage_msg(format!(
            "{total} cases ({how}): at most {MAX_SWEEP_CASES} in one sweep (its table is held \
             in memory); split the grid into several sweeps"
        )));
    }
    let mut cases = Vec::with_capacity(total);
    for (cfg, (kv, bl)) in configs.iter().zip(&grids) {
        let backlashes = resolved(bl, AxisParam::Backlash, cfg)?;
        for k in resolved(kv, AxisParam::Kv, cfg)? {
            for &b in &backlashes {
                cases.push((
                    cfg.clone(),
                    Case {
                        preset: cfg.name.clone(),
                        kv_per_s: k,
                        backlash: b,
                        velocity: args.velocity.unwrap_or_else(|| default_velocity(cfg)),
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
