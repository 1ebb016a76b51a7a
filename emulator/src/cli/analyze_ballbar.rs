//! `drive-emu analyze CAPTURE --ballbar X,Y`: the ballbar's figures from a bus capture of a
//! master interpolating the circle on two drives ([`crate::analysis::ballbar::capture`]), the
//! same figures and JSON report as `drive-emu ballbar` (docs/ballbar.md).

use std::collections::BTreeMap;
use std::path::Path;

use super::exit;
use crate::analysis::ballbar::{capture, metrics};

/// What `analyze --ballbar --json` prints.
#[derive(serde::Serialize)]
struct Output {
    capture: String,
    nodes: BTreeMap<String, u8>,
    /// The commanded circle: fitted radius and centre, mm.
    radius_mm: f64,
    centre_mm: [f64; 2],
    /// The radius the figures are against (--radius-mm, else the fitted one), mm.
    nominal_radius_mm: f64,
    passes: usize,
    report: metrics::BallbarReport,
}

/// `spec` "X,Y": the two node IDs.
fn nodes(spec: &str) -> anyhow::Result<[u8; 2]> {
    let v: Vec<&str> = spec.split(',').map(str::trim).collect();
    let parse = |s: &str| s.parse::<u8>().ok().filter(|n| (1..=127).contains(n));
    match v.as_slice() {
        [a, b] => match (parse(a), parse(b)) {
            (Some(x), Some(y)) => Ok([x, y]),
            _ => Err(exit::usage_msg(format!(
                "--ballbar {spec}: two node IDs in 1..=127, X first (e.g. --ballbar 5,6)"
            ))),
        },
        _ => Err(exit::usage_msg(format!(
            "--ballbar {spec}: two node IDs, X first (e.g. --ballbar 5,6)"
        ))),
    }
}

/// What `analyze --ballbar` reads of `analyze`'s arguments.
pub struct BallbarArgs<'a> {
    /// The capture (`candump -L`).
    pub trace: &'a Path,
    /// Both drives' preset (`--preset`; `None`: cnc1).
    pub preset: Option<&'a str>,
    /// `--sync-period-us`.
    pub sync_period_us: Option<u32>,
    /// `--radius-mm`; `None`: the commanded circle's fitted radius.
    pub radius_mm: Option<f64>,
    /// `--json`.
    pub json: bool,
}

/// Run it; the exit status is 0 with figures, else the error's (crate::cli::exit).
pub fn run(args: &BallbarArgs, spec: &str) -> anyhow::Result<()> {
    let ids = nodes(spec)?;
    if let Some(r) = args.radius_mm {
        if !(r.is_finite() && r > 0.0) {
            return Err(exit::usage_msg(format!(
                "--radius-mm {r}: must be a finite radius > 0"
            )));
        }
    }
    let preset = args.preset.unwrap_or("cnc1");
    let text = crate::samples::csv::read_trace_text(args.trace).map_err(exit::unreadable)?;
    let source = args.trace.display().to_string();
    let c = capture::from_capture(&text, &source, ids, preset, args.sync_period_us)
        .map_err(exit::usage)?;
    let radius = args.radius_mm.unwrap_or(c.radius_mm);
    let names = ["X".to_string(), "Y".to_string()];
    let report =
        metrics::analyze(&metrics::TracePath::of(&c.trace), radius, &names).map_err(exit::usage)?;
    let out = Output {
        capture: source,
        nodes: BTreeMap::from([("X".into(), ids[0]), ("Y".into(), ids[1])]),
        radius_mm: c.radius_mm,
        centre_mm: [c.centre_mm.0, c.centre_mm.1],
        nominal_radius_mm: radius,
        passes: c.passes.len(),
        report,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    let r = &out.report;
    println!(
        "ballbar from {}: X = node {}, Y = node {}; commanded circle r = {:.4} mm about \
         ({:.3}, {:.3}) mm, {} passes",
        out.capture, ids[0], ids[1], out.radius_mm, out.centre_mm[0], out.centre_mm[1], out.passes
    );
    for (name, d) in [("CW", &r.cw), ("CCW", &r.ccw)] {
        let (sx, sy) = (d.reversal_spikes_um["X"], d.reversal_spikes_um["Y"]);
        println!(
            "  {name:<4} G {:.2} um, radius deviation {:.2} um, spikes X {:.2} / {:.2} um, Y {:.2} / {:.2} um",
            d.circular_deviation_um, d.radius_deviation_um, sx[0], sx[1], sy[0], sy[1]
        );
    }
    println!(
        "  backlash estimate: X {:.4} mm, Y {:.4} mm (mean of the axis's four reversal spikes)",
        r.backlash_estimate_mm["X"], r.backlash_estimate_mm["Y"]
    );
    Ok(())
}
