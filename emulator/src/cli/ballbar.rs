//! `drive-emu ballbar`: the virtual ballbar (ISO 230-4 circular test) on two linear axes of a
//! preset or of a machine file, with the master's backlash compensation; the figures per
//! direction as text or JSON, the trace as CSV, the polar plot as PNG. docs/ballbar.md.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use anyhow::Context;

use crate::analysis::ballbar::{
    self, BallbarAxis, BallbarReport, BallbarSetup, DEFAULT_FEED_MM_PER_MIN, DEFAULT_RADIUS_MM,
};
use crate::drive::machine;
use crate::presets::AxisConfig;

/// Arguments of `drive-emu ballbar`.
#[derive(clap::Args, Debug, Clone)]
pub struct BallbarArgs {
    /// Preset of both axes (a linear one: cnc1, cnc2, cnc4).
    #[arg(long, default_value = "cnc1", conflicts_with = "config")]
    pub preset: String,
    /// Override a preset key on both axes, e.g. --set backlash_mm=0.05 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE", conflicts_with = "config")]
    pub set: Vec<String>,
    /// A machine file whose `[ballbar] axes = ["X", "Y"]` names the two axes (by their
    /// `name`), each with its own preset and overrides.
    #[arg(long, value_name = "MACHINE.toml")]
    pub config: Option<PathBuf>,
    /// Radius of the circle, mm.
    #[arg(long, default_value_t = DEFAULT_RADIUS_MM, allow_negative_numbers = true)]
    pub radius_mm: f64,
    /// Feed along the circle, mm/min.
    #[arg(long = "feed-mm-min", default_value_t = DEFAULT_FEED_MM_PER_MIN, allow_negative_numbers = true)]
    pub feed_mm_min: f64,
    /// The master's backlash compensation, mm: one value for both axes, or NAME=VALUE for one
    /// axis (repeatable), e.g. --backlash-comp-mm X=0.03 --backlash-comp-mm Y=0.05.
    #[arg(
        long = "backlash-comp-mm",
        value_name = "[NAME=]MM",
        allow_negative_numbers = true
    )]
    pub backlash_comp_mm: Vec<String>,
    /// Print the figures as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write the trace (commanded and measured path) as CSV to this file.
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Write the polar plot (radial deviation, both directions) as PNG to this file.
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// What `ballbar --json` prints: the setup and the figures.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BallbarOutput {
    /// Per axis, its preset.
    pub presets: BTreeMap<String, String>,
    pub radius_mm: f64,
    pub feed_mm_min: f64,
    /// Per axis, the master's backlash compensation, mm.
    pub backlash_comp_mm: BTreeMap<String, f64>,
    /// Per axis, the simulated gap, mm (the truth the estimate is compared with).
    pub backlash_mm: BTreeMap<String, f64>,
    /// Per axis, the encoder its drive closes the position loop on: "direct" (the linear
    /// scale, the presets' default) or "motor" (`--set position_from_direct=false`, the
    /// indirect measuring system a backlash compensation is for).
    pub position_loop_encoder: BTreeMap<String, &'static str>,
    #[serde(flatten)]
    pub report: BallbarReport,
}

/// What the output says of each axis, by name: its preset, the master's backlash compensation,
/// the simulated gap and the encoder its position loop closes on (the ballbar's and the
/// contour's alike).
pub(crate) struct AxesFacts {
    pub presets: BTreeMap<String, String>,
    pub backlash_comp_mm: BTreeMap<String, f64>,
    pub backlash_mm: BTreeMap<String, f64>,
    pub position_loop_encoder: BTreeMap<String, &'static str>,
}

pub(crate) fn axes_facts(axes: &[crate::analysis::ballbar::BallbarAxis]) -> AxesFacts {
    let mut f = AxesFacts {
        presets: BTreeMap::new(),
        backlash_comp_mm: BTreeMap::new(),
        backlash_mm: BTreeMap::new(),
        position_loop_encoder: BTreeMap::new(),
    };
    for a in axes {
        f.presets.insert(a.name.clone(), a.config.name.clone());
        f.backlash_comp_mm
            .insert(a.name.clone(), a.backlash_comp_mm);
        f.backlash_mm
            .insert(a.name.clone(), a.config.backlash_mm.unwrap_or(0.0));
        let encoder = if a.config.position_from_direct {
            "direct"
        } else {
            "motor"
        };
        f.position_loop_encoder.insert(a.name.clone(), encoder);
    }
    f
}

fn config_err(e: crate::presets::ConfigError) -> anyhow::Error {
    anyhow::anyhow!("invalid configuration: {e}")
}

/// The two axes: both from `--preset`/`--set` (named X and Y), or from the machine file.
fn axes(args: &BallbarArgs) -> anyhow::Result<[(String, AxisConfig); 2]> {
    match &args.config {
        None => {
            let cfg = AxisConfig::from_preset(&args.preset)
                .and_then(|c| c.with_overrides(args.set.iter().map(String::as_str)))
                .map_err(config_err)?;
            Ok([("X".into(), cfg.clone()), ("Y".into(), cfg)])
        }
        Some(path) => {
            let m = machine::load(path)?;
            let origin = path.display();
            let plane = m.ballbar.as_ref().with_context(|| {
                format!(
                    "{origin}: no [ballbar] section: add `[ballbar] axes = [\"X\", \"Y\"]` with \
                     the names of two linear axes (`name = \"X\"` in their [[axis]])"
                )
            })?;
            let one = |name: &str| -> anyhow::Result<(String, AxisConfig)> {
                // validate() made sure the name exists
                let e = m
                    .axes
                    .iter()
                    .find(|a| a.name.as_deref() == Some(name))
                    .with_context(|| format!("{origin}: no axis is named {name:?}"))?;
                let mut cfg = AxisConfig::from_preset(&e.preset)
                    .map_err(|err| anyhow::anyhow!("{origin}: axis {name}: {err}"))?;
                for (k, v) in &e.set {
                    cfg = cfg
                        .with_override(k, &machine::value_text(v))
                        .map_err(|err| anyhow::anyhow!("{origin}: axis {name}: {err}"))?;
                }
                Ok((name.to_string(), cfg))
            };
            Ok([one(&plane.axes[0])?, one(&plane.axes[1])?])
        }
    }
}

/// `--backlash-comp-mm` values per axis name.
fn compensation(args: &BallbarArgs, names: &[String; 2]) -> anyhow::Result<[f64; 2]> {
    let mut out = [0.0; 2];
    for v in &args.backlash_comp_mm {
        let (who, num) = match v.split_once('=') {
            Some((n, x)) => (Some(n.trim()), x.trim()),
            None => (None, v.trim()),
        };
        let c: f64 = num.parse().map_err(|_| {
            anyhow::anyhow!(
                "--backlash-comp-mm {}: not a number of mm (write 0.03, or X=0.03 for one axis)",
                crate::quote::text(v)
            )
        })?;
        match who {
            None => out = [c, c],
            Some(n) => {
                let k = names.iter().position(|x| x == n).with_context(|| {
                    format!(
                        "--backlash-comp-mm {}: no axis {} (the axes are {} and {})",
                        crate::quote::text(v),
                        crate::quote::text(n),
                        names[0],
                        names[1]
                    )
                })?;
                out[k] = c;
            }
        }
    }
    Ok(out)
}

/// Build the setup from the arguments (checked by [`ballbar::validate`] when run).
pub fn setup(args: &BallbarArgs) -> anyhow::Result<BallbarSetup> {
    let [(nx, cx), (ny, cy)] = axes(args)?;
    let names = [nx, ny];
    let comp = compensation(args, &names)?;
    let [nx, ny] = names;
    Ok(BallbarSetup {
        axes: [
            BallbarAxis {
                name: nx,
                config: cx,
                backlash_comp_mm: comp[0],
            },
            BallbarAxis {
                name: ny,
                config: cy,
                backlash_comp_mm: comp[1],
            },
        ],
        radius_mm: args.radius_mm,
        feed_mm_per_min: args.feed_mm_min,
    })
}

pub fn run(args: &BallbarArgs) -> anyhow::Result<()> {
    // what the user wrote: exit status 2 (4: a file that cannot be read)
    let setup = setup(args).map_err(super::exit::usage)?;
    ballbar::validate(&setup).map_err(super::exit::usage)?;
    // Outputs are opened before the run: a bad path fails at once, not after the circle.
    let trace_file = match &args.trace {
        Some(p) => Some(
            std::fs::File::create(p).with_context(|| format!("cannot create {}", p.display()))?,
        ),
        None => None,
    };
    let run = match ballbar::run(&setup, &AtomicBool::new(false)) {
        Ok(r) => r,
        Err(e) => {
            // no empty trace left behind by a run that failed
            if let (Some(p), Some(_)) = (&args.trace, &trace_file) {
                let _ = std::fs::remove_file(p);
            }
            return Err(e);
        }
    };
    if let Some(file) = trace_file {
        let mut w = std::io::BufWriter::new(file);
        run.trace.write_csv(&mut w)?;
        w.flush()?;
    }
    if let Some(p) = &args.png {
        crate::report::ballbar::polar_plot(p, &run.trace, &run.report, setup.radius_mm)?;
    }
    let AxesFacts {
        presets,
        backlash_comp_mm,
        backlash_mm,
        position_loop_encoder,
    } = axes_facts(&setup.axes);
    let out = BallbarOutput {
        presets,
        radius_mm: setup.radius_mm,
        feed_mm_min: setup.feed_mm_per_min,
        backlash_comp_mm,
        backlash_mm,
        position_loop_encoder,
        report: run.report,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        print_text(&out);
    }
    Ok(())
}

fn print_text(o: &BallbarOutput) {
    let r = &o.report;
    let [x, y] = &r.axes;
    println!(
        "ballbar: circle of {} mm at {} mm/min, X = {x} ({}, backlash {} mm, compensation {} mm), \
         Y = {y} ({}, backlash {} mm, compensation {} mm)",
        o.radius_mm,
        o.feed_mm_min,
        o.presets[x],
        o.backlash_mm[x],
        o.backlash_comp_mm[x],
        o.presets[y],
        o.backlash_mm[y],
        o.backlash_comp_mm[y],
    );
    println!(
        "  {:<5} {:>10} {:>12} {:>22} {:>22}",
        "", "G [um]", "radius [um]", "spikes X 0/180 [um]", "spikes Y 90/270 [um]"
    );
    for (name, d) in [("CW", &r.cw), ("CCW", &r.ccw)] {
        let sx = d.reversal_spikes_um[x];
        let sy = d.reversal_spikes_um[y];
        println!(
            "  {name:<5} {:>10.2} {:>12.2} {:>22} {:>22}",
            d.circular_deviation_um,
            d.radius_deviation_um,
            format!("{:.2} / {:.2}", sx[0], sx[1]),
            format!("{:.2} / {:.2}", sy[0], sy[1]),
        );
    }
    println!(
        "  backlash estimate: {x} {:.4} mm, {y} {:.4} mm (mean of the axis's four reversal spikes)",
        r.backlash_estimate_mm[x], r.backlash_estimate_mm[y]
    );
    for a in [x, y] {
        if o.position_loop_encoder[a] == "direct" && o.backlash_comp_mm[a] > 0.0 {
            println!(
                "  note: axis {a} closes its position loop on the direct encoder, which sees the \
                 gap itself: a backlash compensation on top adds lost motion instead of removing \
                 it (compensation is for the motor encoder's loop: --set \
                 position_from_direct=false; docs/ballbar.md)"
            );
        }
    }
}
