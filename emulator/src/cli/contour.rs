//! `drive-emu contour`: a program of straight lines (G1, exact stop at each point) on two or
//! three linear axes of a preset or of a machine file, through the real drives, with the
//! master's backlash compensation; per segment the contour error, the lost motion at each
//! reversal and the end-point error, as text or JSON; the trace as CSV. docs/contour.md.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use anyhow::Context;

use crate::analysis::ballbar::line::{
    self, ContourAxis, ContourReport, ContourSetup, DEFAULT_ACCEL_MM_S2,
};
use crate::drive::machine;
use crate::master::line::MAX_AXES;
use crate::presets::AxisConfig;

/// Arguments of `drive-emu contour`.
#[derive(clap::Args, Debug, Clone)]
pub struct ContourArgs {
    /// Preset of every axis (a linear one: cnc1, cnc2, cnc4); the axes are X and Y, and Z
    /// where the path names it.
    #[arg(long, default_value = "cnc1", conflicts_with = "config")]
    pub preset: String,
    /// Override a preset key on every axis, e.g. --set backlash_mm=0.05 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE", conflicts_with = "config")]
    pub set: Vec<String>,
    /// A machine file whose `[contour] axes = ["X", "Y", "Z"]` names the axes (two or three,
    /// by their `name`), each with its own preset and overrides.
    #[arg(long, value_name = "MACHINE.toml")]
    pub config: Option<PathBuf>,
    /// The program: points separated by `;`, each words of an axis name and a coordinate in
    /// mm (absolute, from where the axes stand at 0; an axis not named keeps its coordinate),
    /// e.g. "X10 Y5; X0 Y0".
    #[arg(long)]
    pub path: String,
    /// Feed along each segment, mm/min.
    #[arg(long = "feed-mm-min", allow_negative_numbers = true)]
    pub feed_mm_min: f64,
    /// Path acceleration of each segment's feed ramps, mm/s^2 (default: the machine file's
    /// `[contour] accel_mm_s2`, else 100).
    #[arg(long = "accel-mm-s2", allow_negative_numbers = true)]
    pub accel_mm_s2: Option<f64>,
    /// The master's backlash compensation, mm: one value for every axis, or NAME=VALUE for
    /// one axis (repeatable), e.g. --backlash-comp-mm X=0.03.
    #[arg(
        long = "backlash-comp-mm",
        value_name = "[NAME=]MM",
        allow_negative_numbers = true
    )]
    pub backlash_comp_mm: Vec<String>,
    /// Print the figures as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write the trace (commanded, measured and sent positions per axis) as CSV to this file.
    #[arg(long)]
    pub trace: Option<PathBuf>,
}

/// What `contour --json` prints: the setup and the figures.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ContourOutput {
    /// Per axis, its preset.
    pub presets: BTreeMap<String, String>,
    pub feed_mm_min: f64,
    pub accel_mm_s2: f64,
    /// The program's points per axis, mm (the first where the axes start).
    pub points_mm: Vec<BTreeMap<String, f64>>,
    /// Per axis, the master's backlash compensation, mm.
    pub backlash_comp_mm: BTreeMap<String, f64>,
    /// Per axis, the simulated gap, mm.
    pub backlash_mm: BTreeMap<String, f64>,
    /// Per axis, the encoder its position loop closes on: "direct" or "motor".
    pub position_loop_encoder: BTreeMap<String, &'static str>,
    #[serde(flatten)]
    pub report: ContourReport,
}

fn config_err(e: crate::presets::ConfigError) -> anyhow::Error {
    anyhow::anyhow!("invalid configuration: {e}")
}

/// The axis names a path's words use (the leading letters of each word), in order of first
/// appearance.
fn names_in(path: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for w in path.split([';', ' ', '\t', '\n']) {
        let n: String = w.chars().take_while(char::is_ascii_alphabetic).collect();
        if !n.is_empty() && !out.contains(&n) {
            out.push(n);
        }
    }
    out
}

/// The axes: from `--preset`/`--set` (X, Y, and Z where the path names it), or from the
/// machine file's `[contour]`; and the machine file's acceleration, if any.
/// The axes by name, and the machine file's acceleration (mm/s^2), if any.
type Axes = (Vec<(String, AxisConfig)>, Option<f64>);

fn axes(args: &ContourArgs) -> anyhow::Result<Axes> {
    match &args.config {
        None => {
            let cfg = AxisConfig::from_preset(&args.preset)
                .and_then(|c| c.with_overrides(args.set.iter().map(String::as_str)))
                .map_err(config_err)?;
            let mut names = vec!["X", "Y"];
            if names_in(&args.path).iter().any(|n| n == "Z") {
                names.push("Z");
            }
            Ok((
                names
                    .into_iter()
                    .map(|n| (n.to_string(), cfg.clone()))
                    .collect(),
                None,
            ))
        }
        Some(file) => {
            let m = machine::load(file)?;
            let origin = file.display();
            let c = m.contour.as_ref().with_context(|| {
                format!(
                    "{origin}: no [contour] section: add `[contour] axes = [\"X\", \"Y\"]` with \
                     the names of two or three linear axes (`name = \"X\"` in their [[axis]])"
                )
            })?;
            let mut out = Vec::with_capacity(c.axes.len());
            for name in &c.axes {
                // machine::validate made sure the name exists
                let e = m
                    .axes
                    .iter()
                    .find(|a| a.name.as_deref() == Some(name.as_str()))
                    .with_context(|| format!("{origin}: no axis is named {name:?}"))?;
                let mut cfg = AxisConfig::from_preset(&e.preset)
                    .map_err(|err| anyhow::anyhow!("{origin}: axis {name}: {err}"))?;
                for (k, v) in &e.set {
                    cfg = cfg
                        .with_override(k, &machine::value_text(v))
                        .map_err(|err| anyhow::anyhow!("{origin}: axis {name}: {err}"))?;
                }
                out.push((name.clone(), cfg));
            }
            Ok((out, c.accel_mm_s2))
        }
    }
}

/// The program's points from `--path`: the start (every axis at 0) first. Each point is
/// words `NAME` + coordinate (mm, absolute); an axis a point does not name keeps its
/// coordinate. Errors name the word and the point.
pub fn parse_path(text: &str, names: &[String]) -> anyhow::Result<Vec<[f64; MAX_AXES]>> {
    let shown = |s: &str| format!("\"{}\"", crate::quote::text(s));
    let mut points = vec![[0.0; MAX_AXES]];
    let parts: Vec<&str> = text.split(';').collect();
    for (i, part) in parts.iter().enumerate() {
        let no = i + 1;
        if part.trim().is_empty() {
            // a trailing `;` ends the program
            if i + 1 == parts.len() && i > 0 {
                continue;
            }
            anyhow::bail!(
                "--path {}: point {no} is empty (points are `X10 Y5` separated by `;`)",
                shown(text)
            );
        }
        let mut p = *points.last().expect("the start");
        let mut named = [false; MAX_AXES];
        for word in part.split_whitespace() {
            // the longest axis name the word starts with (names are letters: `Xten` is X and
            // a bad number, `A5` no axis)
            let name: String = word.chars().take_while(char::is_ascii_alphabetic).collect();
            let k = (0..names.len())
                .filter(|&k| word.starts_with(names[k].as_str()))
                .max_by_key(|&k| names[k].len());
            let k = k.with_context(|| {
                format!(
                    "--path word {} (point {no}): no axis {} (the axes are {})",
                    shown(word),
                    if name.is_empty() {
                        "named".to_string()
                    } else {
                        shown(&name)
                    },
                    names.join(", ")
                )
            })?;
            let number = &word[names[k].len()..];
            let v: f64 = number
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .with_context(|| {
                    format!(
                        "--path word {} (point {no}): {} is not a coordinate in mm (write {}10 or \
                     {}-2.5)",
                        shown(word),
                        shown(number),
                        names[k],
                        names[k]
                    )
                })?;
            anyhow::ensure!(
                !named[k],
                "--path word {} (point {no}): axis {} is named twice in the point",
                shown(word),
                names[k]
            );
            named[k] = true;
            p[k] = v;
        }
        points.push(p);
    }
    Ok(points)
}

/// `--backlash-comp-mm` values per axis name.
fn compensation(args: &ContourArgs, names: &[String]) -> anyhow::Result<Vec<f64>> {
    let mut out = vec![0.0; names.len()];
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
            None => out.iter_mut().for_each(|o| *o = c),
            Some(n) => {
                let k = names.iter().position(|x| x == n).with_context(|| {
                    format!(
                        "--backlash-comp-mm {}: no axis {} (the axes are {})",
                        crate::quote::text(v),
                        crate::quote::text(n),
                        names.join(", ")
                    )
                })?;
                out[k] = c;
            }
        }
    }
    Ok(out)
}

/// Build the setup from the arguments (checked by [`line::validate`] when run).
pub fn setup(args: &ContourArgs) -> anyhow::Result<ContourSetup> {
    let (axes, file_accel) = axes(args)?;
    let names: Vec<String> = axes.iter().map(|(n, _)| n.clone()).collect();
    let points_mm = parse_path(&args.path, &names)?;
    let comp = compensation(args, &names)?;
    Ok(ContourSetup {
        axes: axes
            .into_iter()
            .zip(comp)
            .map(|((name, config), c)| ContourAxis {
                name,
                config,
                backlash_comp_mm: c,
            })
            .collect(),
        points_mm,
        feed_mm_per_min: args.feed_mm_min,
        accel_mm_s2: args
            .accel_mm_s2
            .or(file_accel)
            .unwrap_or(DEFAULT_ACCEL_MM_S2),
    })
}

pub fn run(args: &ContourArgs) -> anyhow::Result<()> {
    // what the user wrote: exit status 2 (4: a file that cannot be read)
    let setup = setup(args).map_err(super::exit::usage)?;
    line::validate(&setup).map_err(super::exit::usage)?;
    // the trace file is opened before the run: a bad path fails at once
    let trace_file = match &args.trace {
        Some(p) => Some(
            std::fs::File::create(p).with_context(|| format!("cannot create {}", p.display()))?,
        ),
        None => None,
    };
    let run = match line::run(&setup, &AtomicBool::new(false)) {
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
    let names: Vec<String> = setup.axes.iter().map(|a| a.name.clone()).collect();
    let super::ballbar::AxesFacts {
        presets,
        backlash_comp_mm,
        backlash_mm,
        position_loop_encoder,
    } = super::ballbar::axes_facts(&setup.axes);
    let out = ContourOutput {
        presets,
        feed_mm_min: setup.feed_mm_per_min,
        accel_mm_s2: setup.accel_mm_s2,
        points_mm: setup
            .points_mm
            .iter()
            .map(|p| names.iter().cloned().zip(p.iter().copied()).collect())
            .collect(),
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

fn print_text(o: &ContourOutput) {
    let r = &o.report;
    let axes: Vec<String> = r
        .axes
        .iter()
        .map(|a| {
            format!(
                "{a} = {} (backlash {} mm, compensation {} mm, {} loop)",
                o.presets[a], o.backlash_mm[a], o.backlash_comp_mm[a], o.position_loop_encoder[a]
            )
        })
        .collect();
    println!(
        "contour: {} segments at {} mm/min, ramps {} mm/s^2, exact stop; {}",
        r.segments.len(),
        o.feed_mm_min,
        o.accel_mm_s2,
        axes.join(", ")
    );
    println!(
        "  {:>3} {:<28} {:>14} {:>14} {:>16}  lost motion at reversal [um]",
        "seg", "to [mm]", "max err [um]", "rms err [um]", "end error [um]"
    );
    for s in &r.segments {
        let to: Vec<String> = r
            .axes
            .iter()
            .map(|a| format!("{a}{}", s.to_mm[a]))
            .collect();
        let lost: Vec<String> = s
            .lost_motion_um
            .iter()
            .map(|(a, v)| format!("{a} {v:.2}"))
            .collect();
        println!(
            "  {:>3} {:<28} {:>14.2} {:>14.2} {:>16.2}  {}",
            s.segment,
            to.join(" "),
            s.max_contour_error_um,
            s.rms_contour_error_um,
            s.end_point_error_norm_um,
            if lost.is_empty() {
                "-".to_string()
            } else {
                lost.join(", ")
            }
        );
    }
    let worst: Vec<String> = r
        .axes
        .iter()
        .map(|a| {
            format!(
                "{a} {:.2} um over {} reversals",
                r.max_lost_motion_um[a], r.reversals[a]
            )
        })
        .collect();
    println!("  largest lost motion: {}", worst.join(", "));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_parse_modally_and_errors_name_the_word() {
        let names = ["X".to_string(), "Y".to_string()];
        let p = parse_path("X10 Y5; X0; Y-2.5;", &names).unwrap();
        assert_eq!(
            p,
            vec![
                [0.0; 3],
                [10.0, 5.0, 0.0],
                [0.0, 5.0, 0.0],
                [0.0, -2.5, 0.0]
            ]
        );
        for (text, want) in [
            (
                "X10 A5",
                "word \"A5\" (point 1): no axis \"A\" (the axes are X, Y)",
            ),
            (
                "X10; Xfoo",
                "word \"Xfoo\" (point 2): \"foo\" is not a coordinate",
            ),
            ("X10;; X0", "point 2 is empty"),
            ("", "point 1 is empty"),
            ("X1 X2", "axis X is named twice"),
            ("5", "no axis named"),
            ("XNaN", "is not a coordinate"),
        ] {
            let e = parse_path(text, &names).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }
}
