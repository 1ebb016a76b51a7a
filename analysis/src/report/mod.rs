//! Reports: a JSON summary and PNG plots (plotters, bitmap backend only). Text is drawn with
//! an embedded DejaVu Sans (`analysis/assets/DejaVuSans.ttf`, Bitstream Vera licence in
//! `assets/DejaVuSans-LICENSE.txt`) registered with plotters' ab_glyph backend, so drawing needs
//! no system font library (no fontconfig, no freetype).

pub mod ballbar;

/// What one user unit ("uu") is on the bus: positions, speeds and accelerations of the CiA 402
/// objects (0x607A, 0x6064, 0x606C, 0x60E4, ...) are in user units, set by the factor group
/// 0x608F/0x6091/0x6092; by default 1 uu = 1 µm on linear axes and 0.001 deg on rotary ones.
pub fn user_unit(rotary: bool) -> &'static str {
    if rotary {
        "0.001 deg"
    } else {
        "1 µm"
    }
}

use crate::detector::{AxisTrace, DetectorReport, WindowResult};
use crate::spectrum::WindowSpectra;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use std::path::{Path, PathBuf};

const FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
const W: u32 = 1000;
const H: u32 = 600;

/// Register the embedded font with plotters (once per process): call before drawing text.
pub fn font_ready() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // Cannot fail for the embedded font; if it did, plots would lack text only.
        let _ = register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

type DynErr = Box<dyn std::error::Error>;

fn err(e: impl std::fmt::Display) -> anyhow::Error {
    anyhow::anyhow!("plot: {e}")
}

/// Write any serializable value as pretty JSON.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    let s = serde_json::to_string_pretty(value)?;
    std::fs::write(path, s + "\n")?;
    Ok(())
}

/// A unit for people: the traces' "um" is µm (the embedded font has the glyph).
pub fn unit_text(unit: &str) -> String {
    unit.replace("um", "µm")
}

/// Time axis of a trace with the fast-forwarded idle stretches cut out: a step longer than
/// `GAP_FACTOR` median sample steps is shrunk to one step. Returns the compressed times
/// (starting at 0) and the cuts: (compressed time, idle seconds removed there).
fn compress_idle(t: &[f64]) -> (Vec<f64>, Vec<(f64, f64)>) {
    const GAP_FACTOR: f64 = 20.0;
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    let step = steps.get(steps.len() / 2).copied().unwrap_or(0.0).max(1e-9);
    let mut out = Vec::with_capacity(t.len());
    let mut cuts = Vec::new();
    let mut x = 0.0;
    for (i, &ti) in t.iter().enumerate() {
        if i > 0 {
            let d = ti - t[i - 1];
            if d > GAP_FACTOR * step {
                cuts.push((x + 0.5 * step, d - step));
                x += step;
            } else {
                x += d;
            }
        }
        out.push(x);
    }
    (out, cuts)
}

fn has_signal(v: &[f64]) -> bool {
    v.iter().any(|x| x.is_finite() && *x != 0.0)
}

fn range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in v.filter(|x| x.is_finite()) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-12 {
        return (lo - 1.0, hi + 1.0);
    }
    let m = 0.05 * (hi - lo);
    (lo - m, hi + m)
}

/// Velocity (set and motor) and current over samples `a..b` of a trace, on a time axis
/// without the fast-forwarded idle stretches (each cut marked and labelled); no current panel
/// when the trace has no current.
pub fn plot_traces(
    path: &Path,
    tr: &AxisTrace,
    a: usize,
    b: usize,
    title: &str,
) -> anyhow::Result<()> {
    font_ready();
    let unit = unit_text(&tr.position_unit);
    let with_current = has_signal(&tr.current[a..b]);
    let (t, cuts) = compress_idle(&tr.t_s[a..b]);
    let t_first = tr.t_s[a];
    let draw = || -> Result<(), DynErr> {
        let root = BitMapBackend::new(path, (W, H)).into_drawing_area();
        root.fill(&WHITE)?;
        let (top, bottom) = if with_current {
            let (x, y) = root.split_vertically(H / 2);
            (x, Some(y))
        } else {
            (root.clone(), None)
        };
        let (t0, t1) = (0.0, t[t.len() - 1].max(1e-6));
        let x_desc = if cuts.is_empty() {
            format!("time since t = {t_first:.1} s, s")
        } else {
            format!("time since t = {t_first:.1} s, s (fast-forwarded idle cut out, dashed)")
        };
        let (vlo, vhi) = range(
            tr.motor_velocity[a..b]
                .iter()
                .chain(&tr.set_velocity[a..b])
                .copied(),
        );
        // Room above the data for the cut labels and the legend.
        let vhi = vhi + 0.25 * (vhi - vlo);
        let mut c = ChartBuilder::on(&top)
            .caption(title, ("sans-serif", 22))
            .margin(8)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(t0..t1, vlo..vhi)?;
        c.configure_mesh()
            .x_desc(x_desc.as_str())
            .y_desc(format!("velocity, {unit}/s"))
            .draw()?;
        c.draw_series(LineSeries::new(
            t.iter()
                .copied()
                .zip(tr.motor_velocity[a..b].iter().copied()),
            &BLUE,
        ))?
        .label("motor speed")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
        c.draw_series(LineSeries::new(
            t.iter().copied().zip(tr.set_velocity[a..b].iter().copied()),
            &BLACK,
        ))?
        .label("set speed")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
        let grey = RGBColor(120, 120, 120);
        for &(x, idle_s) in &cuts {
            c.draw_series(DashedLineSeries::new(
                [(x, vlo), (x, vhi)],
                6,
                4,
                ShapeStyle::from(&grey).stroke_width(1),
            ))?;
            c.draw_series(std::iter::once(Text::new(
                format!("{idle_s:.0} s idle"),
                (x, vhi),
                ("sans-serif", 13).into_font().color(&grey).pos(
                    plotters::style::text_anchor::Pos::new(
                        plotters::style::text_anchor::HPos::Center,
                        plotters::style::text_anchor::VPos::Top,
                    ),
                ),
            )))?;
        }
        c.configure_series_labels()
            .position(SeriesLabelPosition::UpperMiddle)
            .border_style(BLACK)
            .background_style(WHITE)
            .draw()?;
        if let Some(bottom) = bottom {
            let (clo, chi) = range(tr.current[a..b].iter().copied());
            let mut c = ChartBuilder::on(&bottom)
                .margin(8)
                .x_label_area_size(40)
                .y_label_area_size(70)
                .build_cartesian_2d(t0..t1, clo..chi)?;
            c.configure_mesh()
                .x_desc(x_desc.as_str())
                .y_desc(format!("motor current, {}", tr.current_unit))
                .draw()?;
            c.draw_series(LineSeries::new(
                t.iter().copied().zip(tr.current[a..b].iter().copied()),
                &RED,
            ))?;
            for &(x, _) in &cuts {
                c.draw_series(DashedLineSeries::new(
                    [(x, clo), (x, chi)],
                    6,
                    4,
                    ShapeStyle::from(&grey).stroke_width(1),
                ))?;
            }
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(err)
}

/// A chart of frequency (Hz) against amplitude.
type SpectrumChart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Amplitude spectra of motor speed and current in one window, k_v/4 .. k_v band shaded, the
/// paper's 0.6 k_v marked.
pub fn plot_spectrum(path: &Path, tr: &AxisTrace, w: &WindowResult, kv: f64) -> anyhow::Result<()> {
    font_ready();
    let n = w.end - w.start;
    let dt = (tr.t_s[w.end - 1] - tr.t_s[w.start]) / (n - 1).max(1) as f64;
    let fs = 1.0 / dt.max(1e-9);
    let fmax = (2.5 * kv).min(fs / 2.0);
    let spectra = window_spectra(tr, w, fmax);
    let unit = unit_text(&tr.position_unit);
    // No current panel when the trace has no current (a capture without it).
    let panels = if has_signal(&tr.current[w.start..w.end]) {
        2
    } else {
        1
    };
    let draw = || -> Result<(), DynErr> {
        let root = BitMapBackend::new(path, (W, H)).into_drawing_area();
        root.fill(&WHITE)?;
        let halves = root.split_evenly((panels, 1));
        let labels = [
            format!("motor speed amplitude, {unit}/s"),
            format!("motor current amplitude, {}", tr.current_unit),
        ];
        for (k, area) in halves.iter().enumerate() {
            let pts = &spectra[k];
            let (_, hi) = range(pts.iter().map(|p| p.1));
            // Headroom for the peak's label below the legend (four rows, the upper third).
            let hi = hi.max(1e-9) * 1.7;
            let mut c = ChartBuilder::on(area)
                .caption(
                    if k == 0 {
                        format!(
                            "spectrum at {:.0} {unit}/s, t = {:.1} s, k_v = {kv} 1/s",
                            w.set_velocity, w.t_start_s
                        )
                    } else {
                        String::new()
                    },
                    ("sans-serif", 20),
                )
                .margin(8)
                .x_label_area_size(35)
                .y_label_area_size(70)
                .build_cartesian_2d(0.0..fmax, 0.0..hi)?;
            c.configure_mesh()
                .x_desc("frequency, Hz")
                .y_desc(labels[k].as_str())
                .draw()?;
            draw_paper_band(&mut c, kv, hi)?;
            c.draw_series(LineSeries::new(pts.iter().copied(), &BLUE))?
                .label("spectrum")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
            let peak = if k == 0 {
                w.speed_hz.map(|f| (f, w.speed_amplitude))
            } else {
                w.current_hz.map(|f| (f, w.current_amplitude))
            };
            if let Some(peak) = peak {
                mark_peak(&mut c, peak, kv, fmax)?;
            }
            c.configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .border_style(BLACK)
                .background_style(WHITE)
                .draw()?;
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(err)
}

/// The detector's own spectra of the window's motor speed and current, up to `fmax`, Hz: on
/// the samples' times (the FFT where they are even), as (frequency Hz, amplitude) points.
fn window_spectra(tr: &AxisTrace, w: &WindowResult, fmax: f64) -> Vec<Vec<(f64, f64)>> {
    let mut ws = WindowSpectra::new();
    let band = (0.5, fmax);
    let mut spectra = Vec::new();
    for sig in [&tr.motor_velocity, &tr.current] {
        let s = ws.band(&tr.t_s[w.start..w.end], &sig[w.start..w.end], band);
        let pts: Vec<(f64, f64)> = s
            .band
            .iter()
            .enumerate()
            .map(|(i, a)| (s.first_hz + i as f64 * s.resolution_hz, *a))
            .filter(|(f, _)| *f <= fmax)
            .collect();
        spectra.push(pts);
    }
    spectra
}

/// The paper's band k_v/4 .. k_v shaded and its fit 0.6 k_v marked, up to amplitude `hi`.
fn draw_paper_band(c: &mut SpectrumChart, kv: f64, hi: f64) -> Result<(), DynErr> {
    let band = RGBColor(255, 230, 150).mix(0.5).filled();
    c.draw_series(std::iter::once(Rectangle::new(
        [(kv / 4.0, 0.0), (kv, hi)],
        band,
    )))?
    .label("band k_v/4 .. k_v (paper)")
    .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], band));
    let green = RGBColor(0, 150, 0);
    c.draw_series(LineSeries::new(
        [(0.6 * kv, 0.0), (0.6 * kv, hi)],
        ShapeStyle::from(&green).stroke_width(1),
    ))?
    .label("0.6 k_v (paper's fit)")
    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], green));
    Ok(())
}

/// The window's strongest line `(f Hz, amplitude)`, labelled with its frequency.
fn mark_peak(c: &mut SpectrumChart, (f, a): (f64, f64), kv: f64, fmax: f64) -> Result<(), DynErr> {
    // A line outside the band is no limit cycle of the paper's kind (often a
    // harmonic of it in the current): said so, in another colour.
    let (label, col) = if f > kv / 4.0 && f < kv {
        ("fundamental found", RED)
    } else {
        ("strongest line, outside the band", RGBColor(230, 120, 0))
    };
    c.draw_series(std::iter::once(Circle::new((f, a), 5, col.filled())))?
        .label(label)
        .legend(move |(x, y)| Circle::new((x + 10, y), 5, col.filled()));
    // Right of the peak, inside the frame (left of it near the right edge).
    let right = f < 0.8 * fmax;
    let pos = plotters::style::text_anchor::Pos::new(
        if right {
            plotters::style::text_anchor::HPos::Left
        } else {
            plotters::style::text_anchor::HPos::Right
        },
        plotters::style::text_anchor::VPos::Center,
    );
    let dx = if right { 0.015 } else { -0.015 } * fmax;
    c.draw_series(std::iter::once(Text::new(
        format!("{f:.2} Hz"),
        (f + dx, a),
        ("sans-serif", 16).into_font().color(&BLACK).pos(pos),
    )))?;
    Ok(())
}

/// Displacement amplitude per window over time, with the thresholds, and optionally a
/// parameter (e.g. the backlash the timeline set) on a second axis.
pub fn plot_amplitude_trend(
    path: &Path,
    rep: &DetectorReport,
    param: Option<(&str, &[(f64, f64)])>,
) -> anyhow::Result<()> {
    font_ready();
    let draw = || -> Result<(), DynErr> {
        let root = BitMapBackend::new(path, (W, H)).into_drawing_area();
        root.fill(&WHITE)?;
        let pts: Vec<(f64, f64)> = rep
            .windows
            .iter()
            .map(|w| (w.t_start_s / 60.0, w.displacement_amplitude))
            .collect();
        let (t0, t1) = range(pts.iter().map(|p| p.0));
        // From zero, with headroom above the highest point for the legend.
        let top = pts
            .iter()
            .map(|p| p.1)
            .chain([rep.config.alarm_um])
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
        let hi = (top * 1.4).max(1e-9);
        let mut c = ChartBuilder::on(&root)
            .caption(
                format!(
                    "limit-cycle amplitude per window; verdict {}",
                    rep.verdict.as_str()
                ),
                ("sans-serif", 22),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .right_y_label_area_size(if param.is_some() { 70 } else { 0 })
            .build_cartesian_2d(t0.min(0.0)..t1, 0.0..hi)?
            .set_secondary_coord(t0.min(0.0)..t1, {
                let (_, phi) = range(param.map_or(&[][..], |p| p.1).iter().map(|p| p.1));
                0.0..phi.max(1e-9)
            });
        let unit = unit_text(&rep.position_unit);
        c.configure_mesh()
            .x_desc("scenario time, min")
            .y_desc(format!("displacement amplitude, {unit}"))
            .draw()?;
        use crate::detector::Verdict;
        let orange = RGBColor(230, 140, 0);
        let colour = |v: Verdict| match v {
            Verdict::Inconclusive => RGBColor(128, 128, 128),
            Verdict::Ok => BLUE,
            Verdict::BacklashSuspected => orange,
            Verdict::Backlash => RED,
        };
        for (lvl, col, what) in [
            (rep.config.suspect_um, orange, "suspect threshold"),
            (rep.config.alarm_um, RED, "alarm threshold"),
        ] {
            c.draw_series(DashedLineSeries::new(
                [(t0.min(0.0), lvl), (t1, lvl)],
                8,
                5,
                ShapeStyle::from(&col).stroke_width(1),
            ))?
            .label(format!("{what} {lvl} {unit}"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
        }
        // One legend entry per verdict colour, drawn with the windows of that level.
        for v in [
            Verdict::Inconclusive,
            Verdict::Ok,
            Verdict::BacklashSuspected,
            Verdict::Backlash,
        ] {
            if !rep.windows.iter().any(|w| w.level == v) {
                continue;
            }
            let col = colour(v);
            c.draw_series(
                pts.iter()
                    .zip(&rep.windows)
                    .filter(|(_, w)| w.level == v)
                    .map(|(p, _)| Circle::new(*p, 4, col.filled())),
            )?
            .label(format!("window: {}", v.as_str().replace('_', " ")))
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, col.filled()));
        }
        if let Some((name, series)) = param {
            c.configure_secondary_axes().y_desc(name).draw()?;
            c.draw_secondary_series(LineSeries::new(
                series.iter().map(|(t, v)| (t / 60.0, *v)),
                ShapeStyle::from(&BLACK).stroke_width(1),
            ))?
            .label(format!("{name} (timeline, right axis)"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
        }
        c.configure_series_labels()
            .position(SeriesLabelPosition::UpperMiddle)
            .border_style(BLACK)
            .background_style(WHITE)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(err)
}

/// One machine's point for the paper's Fig. 11.
#[derive(Debug, Clone, serde::Serialize)]
pub struct KvPoint {
    pub name: String,
    pub kv_per_s: f64,
    pub frequency_hz: f64,
}

/// Frequency against k_v with the paper's bounds k_v/4 and k_v and its fit 0.6 k_v (Fig. 11).
pub fn plot_frequency_vs_kv(path: &Path, points: &[KvPoint]) -> anyhow::Result<()> {
    font_ready();
    let draw = || -> Result<(), DynErr> {
        let root = BitMapBackend::new(path, (W, H)).into_drawing_area();
        root.fill(&WHITE)?;
        let kmax = points.iter().map(|p| p.kv_per_s).fold(10.0, f64::max) * 1.2;
        let mut c = ChartBuilder::on(&root)
            .caption(
                "vibration frequency vs position gain (paper Fig. 11)",
                ("sans-serif", 22),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..kmax, 0.0..kmax)?;
        c.configure_mesh()
            .x_desc("k_v, 1/s")
            .y_desc("f, Hz")
            .draw()?;
        for (slope, label, col) in [
            (1.0, "f = k_v", RED),
            (0.6, "f = 0.6 k_v", GREEN),
            (0.25, "f = k_v/4", RGBColor(140, 0, 200)),
        ] {
            c.draw_series(LineSeries::new([(0.0, 0.0), (kmax, slope * kmax)], &col))?
                .label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
        }
        c.draw_series(
            points
                .iter()
                .map(|p| Circle::new((p.kv_per_s, p.frequency_hz), 6, BLUE.filled())),
        )?
        .label("measured")
        .legend(|(x, y)| Circle::new((x + 10, y), 5, BLUE.filled()));
        c.draw_series(points.iter().map(|p| {
            Text::new(
                format!(" {}", p.name),
                (p.kv_per_s, p.frequency_hz),
                ("sans-serif", 16),
            )
        }))?;
        c.configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .border_style(BLACK)
            .background_style(WHITE)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(err)
}

/// The detector's plots for one trace into `dir` with file-name prefix `prefix`: traces and
/// spectrum of the strongest window, amplitude along time. Returns the files written.
pub fn detector_plots(
    dir: &Path,
    prefix: &str,
    tr: &AxisTrace,
    rep: &DetectorReport,
    param: Option<(&str, &[(f64, f64)])>,
) -> anyhow::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let strongest = rep.windows.iter().max_by(|a, b| {
        a.displacement_amplitude
            .total_cmp(&b.displacement_amplitude)
    });
    if let Some(w) = strongest {
        // Half a second either side of the window.
        let dt = (tr.t_s[w.end - 1] - tr.t_s[w.start]) / (w.end - w.start).max(2) as f64;
        let pad = if dt > 0.0 { (0.5 / dt) as usize } else { 0 };
        let (a, b) = (w.start.saturating_sub(pad), (w.end + pad).min(tr.len()));
        let p = dir.join(format!("{prefix}traces.png"));
        plot_traces(
            &p,
            tr,
            a,
            b,
            &format!("strongest window at t = {:.1} s", w.t_start_s),
        )?;
        out.push(p);
        let p = dir.join(format!("{prefix}spectrum.png"));
        plot_spectrum(&p, tr, w, rep.kv_per_s)?;
        out.push(p);
    }
    // A trend needs a few windows along time (a wear ramp, a long capture).
    if rep.windows.len() >= 3 {
        let p = dir.join(format!("{prefix}amplitude.png"));
        plot_amplitude_trend(&p, rep, param)?;
        out.push(p);
    }
    Ok(out)
}
