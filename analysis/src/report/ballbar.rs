//! The ballbar's polar plot, as a QC20's software draws it: the radial deviation of each
//! direction (from its least-squares circle) magnified around a reference circle, on rings of
//! the deviation scale, CW and CCW on one plot, with G and the reversal spikes in the legend.

use std::path::Path;

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::font_ready;
use crate::ballbar::{BallbarReport, BallbarTrace, DirectionReport};

const SIZE: u32 = 800;
/// The reference circle (zero deviation) and the scale's reach on the plot, plot radii.
const ZERO_RING: f64 = 0.6;
const SCALE_REACH: f64 = 0.35;

/// The smallest 1-2-5 step at or above `v`.
fn nice(v: f64) -> f64 {
    let v = v.max(0.1);
    let e = 10f64.powf(v.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * e)
        .find(|s| *s >= v)
        .unwrap_or(10.0 * e)
}

/// A plot's error, boxed (plotters' errors carry their backend's type).
type PlotResult = Result<(), Box<dyn std::error::Error>>;

/// The polar chart's coordinates: plot radii, the reference circle at [`ZERO_RING`].
type Polar<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Write the polar plot of both passes' data circles to `path`.
pub fn polar_plot(
    path: &Path,
    t: &BallbarTrace,
    r: &BallbarReport,
    radius_mm: f64,
) -> anyhow::Result<()> {
    let cw = radial_deviations(t, -1, &r.cw, radius_mm);
    let ccw = radial_deviations(t, 1, &r.ccw, radius_mm);
    let max = cw
        .iter()
        .chain(ccw.iter())
        .map(|p| p.1.abs())
        .fold(0.0, f64::max);
    let scale = nice(max);
    font_ready();
    let draw = || -> PlotResult {
        let root = BitMapBackend::new(path, (SIZE, SIZE + 80)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut c = ChartBuilder::on(&root)
            .caption(
                format!(
                    "Ballbar, R {radius_mm} mm: radial deviation, {:.0} µm per ring",
                    scale / 2.0
                ),
                ("sans-serif", 22),
            )
            .margin(10)
            .build_cartesian_2d(-1.05..1.05, -1.25..1.05)?;
        draw_rings_and_axes(&mut c, scale, &r.axes)?;
        draw_passes(&mut c, scale, r, [&cw, &ccw])?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| anyhow::anyhow!("plot {}: {e}", path.display()))
}

/// The radial deviations of the pass turning `sign` (-1 CW, +1 CCW) on its data circle, as
/// (angle rad, deviation um) about the direction's fitted centre.
fn radial_deviations(
    t: &BallbarTrace,
    sign: i8,
    d: &DirectionReport,
    radius_mm: f64,
) -> Vec<(f64, f64)> {
    let rr = radius_mm + d.radius_deviation_um * 1e-3;
    let [cx, cy] = d.centre_mm;
    (0..t.len())
        .filter(|&i| {
            t.direction[i] == sign && !t.ramping[i] && (0.0..=360.0).contains(&t.travelled_deg[i])
        })
        .map(|i| {
            let (dx, dy) = (t.x_mm[i] - cx, t.y_mm[i] - cy);
            (dy.atan2(dx), (dx.hypot(dy) - rr) * 1e3)
        })
        .collect()
}

/// The scale's rings (the reference circle black, +-half and +-full scale grey), the four
/// axis directions with their names, and the scale's labels.
fn draw_rings_and_axes(c: &mut Polar, scale: f64, [x, y]: &[String; 2]) -> PlotResult {
    let grey = RGBColor(170, 170, 170);
    let ring = |q: f64| {
        (0..=360).map(move |k| {
            let a = (k as f64).to_radians();
            (q * a.cos(), q * a.sin())
        })
    };
    for k in -2..=2 {
        let q = ZERO_RING + SCALE_REACH * f64::from(k) / 2.0;
        let style = if k == 0 {
            BLACK.stroke_width(1)
        } else {
            grey.stroke_width(1)
        };
        c.draw_series(LineSeries::new(ring(q), style))?;
    }
    for k in 0..4 {
        let a = f64::from(k) * std::f64::consts::FRAC_PI_2;
        let q = ZERO_RING + SCALE_REACH;
        c.draw_series(LineSeries::new(
            [(0.0, 0.0), (q * a.cos(), q * a.sin())],
            grey.stroke_width(1),
        ))?;
        let name = match k {
            0 => format!("0° (+{x})"),
            1 => format!("90° (+{y})"),
            2 => format!("180° (-{x})"),
            _ => format!("270° (-{y})"),
        };
        let (tx, ty) = ((q + 0.02) * a.cos(), (q + 0.02) * a.sin());
        c.draw_series(std::iter::once(Text::new(
            name,
            (
                tx - if k % 2 == 0 { 0.2 } else { 0.0 },
                ty + if k % 2 == 0 { 0.09 } else { 0.04 },
            ),
            ("sans-serif", 15),
        )))?;
    }
    c.draw_series(std::iter::once(Text::new(
        format!("+{scale} µm"),
        (0.02, ZERO_RING + SCALE_REACH - 0.01),
        ("sans-serif", 13),
    )))?;
    c.draw_series(std::iter::once(Text::new(
        "0",
        (0.02, ZERO_RING - 0.01),
        ("sans-serif", 13),
    )))?;
    c.draw_series(std::iter::once(Text::new(
        format!("-{scale} µm"),
        (0.02, ZERO_RING - SCALE_REACH - 0.01),
        ("sans-serif", 13),
    )))?;
    Ok(())
}

/// Both passes' deviations (CW blue, CCW red) on the rings, with G and the reversal spikes
/// in the legend.
fn draw_passes<'a, 'b: 'a>(
    c: &mut Polar<'a, 'b>,
    scale: f64,
    r: &BallbarReport,
    [cw, ccw]: [&[(f64, f64)]; 2],
) -> PlotResult {
    let rho = |dev: f64| ZERO_RING + SCALE_REACH * dev / scale;
    let to_xy = |(a, dev): (f64, f64)| {
        let q = rho(dev);
        (q * a.cos(), q * a.sin())
    };
    let [x, y] = &r.axes;
    let label = |name: &str, d: &DirectionReport| {
        format!(
            "{name}: G {:.1} µm, spikes {x} {:.1}/{:.1}, {y} {:.1}/{:.1} µm",
            d.circular_deviation_um,
            d.reversal_spikes_um[x][0],
            d.reversal_spikes_um[x][1],
            d.reversal_spikes_um[y][0],
            d.reversal_spikes_um[y][1],
        )
    };
    let blue = RGBColor(31, 119, 180);
    let red = RGBColor(214, 39, 40);
    c.draw_series(LineSeries::new(
        cw.iter().copied().map(to_xy),
        blue.stroke_width(2),
    ))?
    .label(label("CW", &r.cw))
    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], blue.stroke_width(2)));
    c.draw_series(LineSeries::new(
        ccw.iter().copied().map(to_xy),
        red.stroke_width(2),
    ))?
    .label(label("CCW", &r.ccw))
    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], red.stroke_width(2)));
    c.configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE)
        .position(SeriesLabelPosition::LowerMiddle)
        .label_font(("sans-serif", 16))
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn nice_steps() {
        assert_eq!(super::nice(3.2), 5.0);
        assert_eq!(super::nice(12.0), 20.0);
        assert_eq!(super::nice(0.0), 0.1);
    }
}
