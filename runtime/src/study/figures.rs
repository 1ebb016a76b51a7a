//! The paper's figures, every point measured from simulated runs: Fig. 3 (closed speed loop
//! frequency response), Fig. 10 (rotary axis at two backlash values: same frequency, larger
//! amplitude), Fig. 11 (limit-cycle frequency against k_v for the five presets) and the
//! twin-pinion figure (CNC3 with its preload lost and holding). Each is a
//! PNG (plotters, bitmap backend, the embedded font of [`crate::report`]) and a JSON file.

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::response::{log_frequencies, speed_loop_response, SpeedLoopResponse};
use super::{backlash_key, default_velocity, run_cases, Case, CaseRow, DEFAULT_DURATION_S};
use crate::analysis::{constant_velocity_run, RunOptions};
use crate::presets::{preset_names, AxisConfig};
use crate::report::{font_ready, write_json};

const W: u32 = 1000;
const H: u32 = 700;

type DynErr = Box<dyn std::error::Error>;

fn plot_err(e: DynErr) -> anyhow::Error {
    anyhow::anyhow!("plot: {e}")
}

fn cfg_err(e: crate::presets::ConfigError) -> anyhow::Error {
    anyhow::anyhow!("{e}")
}

/// Fig. 3 data: the closed speed loop of a healthy axis (backlash 0), 5 Hz - 1 kHz.
/// `sets`: `key=value` overrides applied after.
pub fn fig3_data(preset: &str, sets: &[String]) -> anyhow::Result<SpeedLoopResponse> {
    let cfg = AxisConfig::from_preset(preset).map_err(cfg_err)?;
    let cfg = cfg
        .with_override(backlash_key(&cfg), "0")
        .and_then(|c| c.with_overrides(sets.iter().map(String::as_str)))
        .map_err(cfg_err)?;
    speed_loop_response(&cfg, &log_frequencies(5.0, 1000.0, 41), 300.0, 5.0).map_err(cfg_err)
}

/// Fig. 3: magnitude and phase against frequency, the -3 dB bandwidth marked.
pub fn fig3(
    dir: &Path,
    preset: &str,
    sets: &[String],
) -> anyhow::Result<(PathBuf, SpeedLoopResponse)> {
    let r = fig3_data(preset, sets)?;
    let png = dir.join("fig3-speed-loop.png");
    write_json(&dir.join("fig3-speed-loop.json"), &r)?;
    font_ready();
    let draw = || -> Result<(), DynErr> {
        let root = BitMapBackend::new(&png, (W, H)).into_drawing_area();
        root.fill(&WHITE)?;
        let (top, bottom) = root.split_vertically(H / 2);
        let (f0, f1) = (5.0, 1000.0);
        let bw = r.bandwidth_3db_hz.map_or("-3 dB: not reached".into(), |b| {
            format!("-3 dB at {b:.0} Hz")
        });
        let mut c = ChartBuilder::on(&top)
            .caption(
                format!("Fig. 3: closed speed loop, {} (measured, {bw})", r.preset),
                ("sans-serif", 22),
            )
            .margin(8)
            .margin_right(30)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d((f0..f1).log_scale(), -25.0..6.0)?;
        c.configure_mesh()
            .x_desc("frequency, Hz")
            .y_desc("magnitude, dB")
            .draw()?;
        c.draw_series(LineSeries::new(
            r.points.iter().map(|p| (p.frequency_hz, p.magnitude_db)),
            BLUE.stroke_width(2),
        ))?
        .label("measured speed / speed set-point")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(2)));
        c.draw_series(
            r.points
                .iter()
                .map(|p| Circle::new((p.frequency_hz, p.magnitude_db), 3, BLUE.filled())),
        )?;
        c.draw_series(LineSeries::new(
            [(f0, -3.0), (f1, -3.0)],
            RED.stroke_width(1),
        ))?
        .label("-3 dB")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
        if let Some(b) = r.bandwidth_3db_hz {
            let violet = RGBColor(140, 0, 200);
            c.draw_series(LineSeries::new(
                [(b, -25.0), (b, 6.0)],
                violet.stroke_width(1),
            ))?
            .label(format!("bandwidth {b:.0} Hz"))
            .legend(move |(x, y)| PathElement::new(vec![(x + 10, y - 6), (x + 10, y + 6)], violet));
        }
        c.configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE)
            .position(SeriesLabelPosition::LowerLeft)
            .draw()?;
        let (plo, phi) = r.points.iter().fold((0.0f64, 0.0f64), |(lo, hi), p| {
            (lo.min(p.phase_deg), hi.max(p.phase_deg))
        });
        let mut c = ChartBuilder::on(&bottom)
            .margin(8)
            .margin_right(30)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d((f0..f1).log_scale(), (plo - 10.0)..(phi + 10.0))?;
        c.configure_mesh()
            .x_desc("frequency, Hz")
            .y_desc("phase, deg")
            .draw()?;
        c.draw_series(LineSeries::new(
            r.points.iter().map(|p| (p.frequency_hz, p.phase_deg)),
            BLUE.stroke_width(2),
        ))?;
        root.present()?;
        Ok(())
    };
    draw().map_err(plot_err)?;
    Ok((png, r))
}

/// One trace of Fig. 10.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Fig10Trace {
    pub backlash_deg: f64,
    pub fundamental_hz: Option<f64>,
    pub motor_velocity_amplitude_rpm: f64,
    pub time_s: Vec<f64>,
    pub motor_velocity_rpm: Vec<f64>,
}

/// Fig. 10 data.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Fig10 {
    pub preset: String,
    pub gear_ratio: f64,
    pub velocity_deg_per_s: f64,
    pub kv_per_s: f64,
    pub traces: Vec<Fig10Trace>,
}

/// Half a second of the motor speed, 2 s into the analysis window of a constant-velocity run
/// of `cfg` at `v`, with the run's fundamental and its amplitude (Fig. 10, the twin figure).
struct SpeedSnippet {
    fundamental_hz: Option<f64>,
    amplitude_rpm: f64,
    time_s: Vec<f64>,
    rpm: Vec<f64>,
}

fn speed_snippet(cfg: &AxisConfig, v: f64) -> anyhow::Result<SpeedSnippet> {
    let mut o = RunOptions::new(v, DEFAULT_DURATION_S);
    o.record = true;
    let r = constant_velocity_run(cfg, &o).map_err(cfg_err)?;
    let t0 = r.summary.window_start_s + 2.0;
    let idx: Vec<usize> = (0..r.trace.len())
        .filter(|&i| r.trace.time_s[i] >= t0 && r.trace.time_s[i] < t0 + 0.5)
        .collect();
    Ok(SpeedSnippet {
        fundamental_hz: r.summary.fundamental_hz,
        amplitude_rpm: r.summary.motor_velocity_amplitude_rpm,
        time_s: idx.iter().map(|&i| r.trace.time_s[i] - t0).collect(),
        rpm: idx.iter().map(|&i| r.trace.motor_velocity_rpm[i]).collect(),
    })
}

/// Fig. 10 data: the paper's rotary axis (CNC3: ratio 1258.5, 0.026 r/s) at 0.01 and 0.04 deg.
pub fn fig10_data() -> anyhow::Result<Fig10> {
    let base = AxisConfig::from_preset("cnc3").map_err(cfg_err)?;
    let v = default_velocity(&base);
    let mut traces = Vec::new();
    for b in [0.01, 0.04] {
        let cfg = base
            .with_override("backlash_deg", &format!("{b}"))
            .map_err(cfg_err)?;
        let s = speed_snippet(&cfg, v)?;
        traces.push(Fig10Trace {
            backlash_deg: b,
            fundamental_hz: s.fundamental_hz,
            motor_velocity_amplitude_rpm: s.amplitude_rpm,
            time_s: s.time_s,
            motor_velocity_rpm: s.rpm,
        });
    }
    Ok(Fig10 {
        preset: base.name.clone(),
        gear_ratio: base.gear_ratio,
        velocity_deg_per_s: v,
        kv_per_s: base.kv_per_s,
        traces,
    })
}

/// Fig. 10: motor speed of both runs on one plot.
pub fn fig10(dir: &Path) -> anyhow::Result<(PathBuf, Fig10)> {
    let d = fig10_data()?;
    let png = dir.join("fig10-rotary-backlash.png");
    write_json(&dir.join("fig10-rotary-backlash.json"), &d)?;
    let caption = format!(
        "Fig. 10: rotary axis (ratio {}, {:.3} r/s, k_v {} 1/s), motor speed",
        d.gear_ratio,
        d.velocity_deg_per_s / 360.0,
        d.kv_per_s
    );
    let series: Vec<SpeedSeries> = d
        .traces
        .iter()
        .map(|t| SpeedSeries {
            label: format!(
                "backlash {} deg: f = {} Hz, amplitude {:.1} rpm",
                t.backlash_deg,
                t.fundamental_hz.map_or("-".into(), |f| format!("{f:.2}")),
                t.motor_velocity_amplitude_rpm
            ),
            time_s: &t.time_s,
            rpm: &t.motor_velocity_rpm,
        })
        .collect();
    speed_plot(&png, &caption, &series)?;
    Ok((png, d))
}

/// One line of a motor-speed plot.
struct SpeedSeries<'a> {
    label: String,
    time_s: &'a [f64],
    rpm: &'a [f64],
}

/// Motor speed over half a second, one line per series (blue, red, green, ...).
fn speed_plot(png: &Path, caption: &str, series: &[SpeedSeries]) -> anyhow::Result<()> {
    font_ready();
    let draw = || -> Result<(), DynErr> {
        let root = BitMapBackend::new(png, (W, H)).into_drawing_area();
        root.fill(&WHITE)?;
        let all = series.iter().flat_map(|t| t.rpm.iter());
        let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
            (l.min(x), h.max(x))
        });
        let m = 0.1 * (hi - lo).max(1e-6);
        let mut c = ChartBuilder::on(&root)
            .caption(caption, ("sans-serif", 22))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..0.5, (lo - m)..(hi + m))?;
        c.configure_mesh()
            .x_desc("time, s")
            .y_desc("motor speed, rpm")
            .draw()?;
        for (t, col) in series.iter().zip([BLUE, RED, GREEN, BLACK]) {
            c.draw_series(LineSeries::new(
                t.time_s.iter().copied().zip(t.rpm.iter().copied()),
                col.stroke_width(2),
            ))?
            .label(t.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
        }
        c.configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE)
            .position(SeriesLabelPosition::LowerRight)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(plot_err)
}

/// One run of the twin-pinion figure.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TwinTrace {
    pub preload_pct: f64,
    pub fundamental_hz: Option<f64>,
    pub motor_velocity_amplitude_rpm: f64,
    pub time_s: Vec<f64>,
    pub motor_velocity_rpm: Vec<f64>,
}

/// The twin-pinion figure's data.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FigTwin {
    pub preset: String,
    pub kv_per_s: f64,
    pub backlash_deg: f64,
    pub velocity_deg_per_s: f64,
    pub traces: Vec<TwinTrace>,
}

/// The preloads of the twin-pinion figure, % of each motor's rated torque: lost (the paper's
/// machine, as shipped) and the healthy machine of the preset file's comment.
pub const FIG_TWIN_PRELOADS_PCT: [f64; 2] = [0.0, 40.0];

/// Twin-pinion figure data: CNC3 (twin pinion and gear wheel) at its own k_v and gap, the
/// sweep's run (start ramp and knock), with the preload lost and holding.
pub fn fig_twin_data() -> anyhow::Result<FigTwin> {
    let base = AxisConfig::from_preset("cnc3").map_err(cfg_err)?;
    let v = default_velocity(&base);
    let mut traces = Vec::new();
    for pct in FIG_TWIN_PRELOADS_PCT {
        let cfg = base
            .with_override("preload_pct", &format!("{pct}"))
            .map_err(cfg_err)?;
        let s = speed_snippet(&cfg, v)?;
        traces.push(TwinTrace {
            preload_pct: pct,
            fundamental_hz: s.fundamental_hz,
            motor_velocity_amplitude_rpm: s.amplitude_rpm,
            time_s: s.time_s,
            motor_velocity_rpm: s.rpm,
        });
    }
    Ok(FigTwin {
        preset: base.name.clone(),
        kv_per_s: base.kv_per_s,
        backlash_deg: base.backlash_deg.unwrap_or(0.0),
        velocity_deg_per_s: v,
        traces,
    })
}

/// The twin-pinion figure: motor speed with the preload lost and holding, on one plot.
pub fn fig_twin(dir: &Path) -> anyhow::Result<(PathBuf, FigTwin)> {
    let d = fig_twin_data()?;
    let png = dir.join("fig-twin-pinion.png");
    write_json(&dir.join("fig-twin-pinion.json"), &d)?;
    let caption = format!(
        "Twin pinion: {} ({} deg gap, k_v {} 1/s, {:.3} r/s), motor speed",
        d.preset,
        d.backlash_deg,
        d.kv_per_s,
        d.velocity_deg_per_s / 360.0
    );
    let series: Vec<SpeedSeries> = d
        .traces
        .iter()
        .map(|t| SpeedSeries {
            label: format!(
                "preload {} %: amplitude {:.2} rpm{}",
                t.preload_pct,
                t.motor_velocity_amplitude_rpm,
                t.fundamental_hz
                    .filter(|_| t.preload_pct == 0.0)
                    .map_or(String::new(), |f| format!(" at {f:.2} Hz"))
            ),
            time_s: &t.time_s,
            rpm: &t.motor_velocity_rpm,
        })
        .collect();
    speed_plot(&png, &caption, &series)?;
    Ok((png, d))
}

/// Fig. 11 data: every preset at its own backlash over half to twice its k_v, and CNC1 over
/// 10..80 1/s.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Fig11 {
    pub rows: Vec<CaseRow>,
    /// The presets' own k_v, for marking.
    pub own_kv: Vec<(String, f64)>,
}

/// The cases of Fig. 11.
pub fn fig11_cases() -> anyhow::Result<Vec<(AxisConfig, Case)>> {
    let mut cases = Vec::new();
    for name in preset_names() {
        let cfg = AxisConfig::from_preset(name).map_err(cfg_err)?;
        let own = cfg.kv_per_s;
        let mut kvs: Vec<f64> = (0..7).map(|i| own * (0.5 + 0.25 * i as f64)).collect();
        if name == "cnc1" {
            kvs = (1..=8).map(|i| 10.0 * i as f64).collect();
        }
        for kv in kvs {
            cases.push((
                cfg.clone(),
                Case {
                    preset: name.to_string(),
                    kv_per_s: kv,
                    backlash: super::own_backlash(&cfg),
                    velocity: default_velocity(&cfg),
                    duration_s: DEFAULT_DURATION_S,
                },
            ));
        }
    }
    Ok(cases)
}

/// Fig. 11: f against k_v with the lines k_v/4, 0.6 k_v and k_v (f in Hz, k_v in 1/s).
pub fn fig11(dir: &Path, threads: usize) -> anyhow::Result<(PathBuf, Fig11)> {
    let cases = fig11_cases()?;
    let rows = run_cases(&cases, threads)
        .into_iter()
        .collect::<Result<Vec<_>, _>>()
        .map_err(cfg_err)?;
    let own_kv = preset_names()
        .map(|n| {
            AxisConfig::from_preset(n)
                .map(|c| (n.to_string(), c.kv_per_s))
                .map_err(cfg_err)
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let d = Fig11 { rows, own_kv };
    let png = dir.join("fig11-f-vs-kv.png");
    write_json(&dir.join("fig11-f-vs-kv.json"), &d)?;
    font_ready();
    let draw = || -> Result<(), DynErr> {
        let root = BitMapBackend::new(&png, (W, H)).into_drawing_area();
        root.fill(&WHITE)?;
        let kmax = 85.0;
        let mut c = ChartBuilder::on(&root)
            .caption(
                "Fig. 11: limit-cycle frequency against k_v (every point a simulated run)",
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
        for (k, label, col) in [
            // The band's edges in two colours of their own (none of the presets' five).
            (1.0, "f = k_v (band's upper edge)", BLACK),
            (0.6, "f = 0.6 k_v (eq. 13)", RGBColor(0, 130, 0)),
            (
                0.25,
                "f = k_v / 4 (band's lower edge)",
                RGBColor(140, 140, 140),
            ),
        ] {
            c.draw_series(LineSeries::new(
                [(0.0, 0.0), (kmax, k * kmax)],
                col.stroke_width(if k == 0.6 { 2 } else { 1 }),
            ))?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
        }
        let colors = [
            RGBColor(31, 119, 180),
            RGBColor(255, 127, 14),
            RGBColor(44, 160, 44),
            RGBColor(214, 39, 40),
            RGBColor(148, 103, 189),
        ];
        for ((name, own), col) in d.own_kv.iter().zip(colors) {
            let pts: Vec<(f64, f64)> = d
                .rows
                .iter()
                .filter(|r| &r.preset == name && r.limit_cycle)
                .filter_map(|r| r.fundamental_hz.map(|f| (r.kv_per_s, f)))
                .collect();
            c.draw_series(pts.iter().map(|&p| Circle::new(p, 4, col.filled())))?
                .label(format!("{name} (own k_v {own})"))
                .legend(move |(x, y)| Circle::new((x + 10, y), 4, col.filled()));
            // The preset's own k_v: a larger ring.
            c.draw_series(
                pts.iter()
                    .filter(|p| (p.0 - own).abs() < 1e-9)
                    .map(|&p| Circle::new(p, 9, col.stroke_width(2))),
            )?;
            // Cases without a limit cycle: a cross on the axis.
            c.draw_series(
                d.rows
                    .iter()
                    .filter(|r| &r.preset == name && !r.limit_cycle)
                    .map(|r| Cross::new((r.kv_per_s, 0.5), 5, col.stroke_width(2))),
            )?;
        }
        // What the ring and the cross mean, in the legend only (empty series).
        let grey = RGBColor(90, 90, 90);
        c.draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
            .label("ring: the preset's own k_v")
            .legend(move |(x, y)| Circle::new((x + 10, y), 7, grey.stroke_width(2)));
        c.draw_series(std::iter::empty::<Cross<(f64, f64), i32>>())?
            .label("cross on the axis: no limit cycle")
            .legend(move |(x, y)| Cross::new((x + 10, y), 5, grey.stroke_width(2)));
        c.configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE)
            .position(SeriesLabelPosition::UpperLeft)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(plot_err)?;
    Ok((png, d))
}

/// The limit cycle's drag boundary (docs/physics.md, "Limits"): CNC1 at its own drag over a
/// k_v x gap grid, every point a run, with the lines of constant drag number
/// `D / (m k_v^2 b)` between which the cycle dies.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DragMap {
    pub rows: Vec<CaseRow>,
    /// The preset's drag at the cruise velocity, N.
    pub drag_n: f64,
    pub load_mass_kg: f64,
    /// Drag numbers drawn as lines.
    pub drag_numbers: Vec<f64>,
}

/// The drag-boundary map as PNG + JSON in `dir`.
pub fn fig_drag(dir: &Path, threads: usize) -> anyhow::Result<(PathBuf, DragMap)> {
    let cfg = AxisConfig::from_preset("cnc1").map_err(cfg_err)?;
    let velocity = default_velocity(&cfg);
    let mut cases = Vec::new();
    for i in 0..15 {
        for j in 0..13 {
            cases.push((
                cfg.clone(),
                Case {
                    preset: cfg.name.clone(),
                    kv_per_s: 5.0 + 2.5 * i as f64,
                    backlash: 0.01 + 0.005 * j as f64,
                    velocity,
                    duration_s: DEFAULT_DURATION_S,
                },
            ));
        }
    }
    let rows = run_cases(&cases, threads)
        .into_iter()
        .collect::<Result<Vec<_>, _>>()
        .map_err(cfg_err)?;
    // The drag number is D / (m k_v^2 b); at k_v = 1, b = 1 m it is D / m.
    let d_over_m = super::drag_number(&cfg, 1.0, 1e3, velocity);
    let load_mass_kg = cfg.carriage_mass_kg.unwrap_or(f64::NAN);
    let d = DragMap {
        rows,
        drag_n: d_over_m * load_mass_kg,
        load_mass_kg,
        drag_numbers: vec![1.25, 1.67],
    };
    let png = dir.join("fig-drag-boundary.png");
    write_json(&dir.join("fig-drag-boundary.json"), &d)?;
    font_ready();
    let draw = || -> Result<(), DynErr> {
        let root = BitMapBackend::new(&png, (W, H)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut c = ChartBuilder::on(&root)
            .caption(
                "CNC1: limit cycle or none over k_v and the gap (drag 4 N, 800 kg)",
                ("sans-serif", 22),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..42.5, 0.0..0.08)?;
        c.configure_mesh()
            .x_desc("k_v, 1/s")
            .y_desc("gap, mm")
            .draw()?;
        for (pi, col) in d.drag_numbers.iter().zip([RGBColor(0, 130, 0), BLACK]) {
            // b [mm] = 1e3 D / (pi m k_v^2)
            let pts: Vec<(f64, f64)> = (0..=200)
                .map(|i| 3.0 + 0.2 * i as f64)
                .map(|kv| (kv, 1e3 * d_over_m / (pi * kv * kv)))
                .filter(|p| p.1 <= 0.08)
                .collect();
            c.draw_series(LineSeries::new(pts, col.stroke_width(2)))?
                .label(format!("drag number {pi}"))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
        }
        let in_band = |r: &&CaseRow| r.limit_cycle && r.in_band;
        c.draw_series(
            d.rows
                .iter()
                .filter(in_band)
                .map(|r| Circle::new((r.kv_per_s, r.backlash), 5, BLUE.filled())),
        )?
        .label("limit cycle, k_v/4 < f < k_v")
        .legend(|(x, y)| Circle::new((x + 10, y), 5, BLUE.filled()));
        c.draw_series(
            d.rows
                .iter()
                .filter(|r| !in_band(r))
                .map(|r| Cross::new((r.kv_per_s, r.backlash), 5, RED.stroke_width(2))),
        )?
        .label("none (or only the encoder-quantisation line)")
        .legend(|(x, y)| Cross::new((x + 10, y), 5, RED.stroke_width(2)));
        c.configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE)
            .position(SeriesLabelPosition::UpperRight)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(plot_err)?;
    Ok((png, d))
}

/// The paper's set-up on the bus: the master closes the position loop on the direct encoder
/// (0x60E4) in CSV ([`super::outer_loop`]). Left: f against the master's k_v on every preset at
/// a 1 ms SYNC, with k_v/4, 0.6 k_v and k_v; right: f / k_v against the SYNC period over the
/// limit cycle's period (T_sync f0), each preset at its own k_v.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FigOuterLoop {
    pub law: Vec<super::outer_loop::OuterLoopRow>,
    pub sync: Vec<super::outer_loop::OuterLoopRow>,
    pub breaks: Vec<super::outer_loop::SyncBreak>,
}

/// The master-loop figure as PNG + JSON in `dir`.
pub fn fig_outer_loop(dir: &Path) -> anyhow::Result<(PathBuf, FigOuterLoop)> {
    use super::outer_loop::{law_cases, run_outer_loops, sync_breaks, sync_cases};
    let run = |cases: Vec<(AxisConfig, super::outer_loop::OuterLoopCase)>| {
        run_outer_loops(&cases)
            .into_iter()
            .collect::<Result<Vec<_>, _>>()
            .map_err(cfg_err)
    };
    let law = run(law_cases().map_err(cfg_err)?)?;
    let sync = run(sync_cases().map_err(cfg_err)?)?;
    let breaks = sync_breaks(&sync);
    let d = FigOuterLoop { law, sync, breaks };
    let png = dir.join("fig-outer-loop.png");
    write_json(&dir.join("fig-outer-loop.json"), &d)?;
    font_ready();
    let colors = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
    ];
    let names: Vec<String> = preset_names().map(str::to_string).collect();
    let draw = || -> Result<(), DynErr> {
        let root = BitMapBackend::new(&png, (W + 400, H)).into_drawing_area();
        root.fill(&WHITE)?;
        let (left, right) = root.split_horizontally((W + 400) / 2);
        draw_outer_loop_law(&left, &d, &names, colors)?;
        draw_outer_loop_sync(&right, &d, &names, colors)?;
        root.present()?;
        Ok(())
    };
    draw().map_err(plot_err)?;
    Ok((png, d))
}

/// The master-loop figure's left panel: f against the master's k_v, with the lines k_v,
/// 0.6 k_v and k_v / 4.
fn draw_outer_loop_law(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    d: &FigOuterLoop,
    names: &[String],
    colors: [RGBColor; 5],
) -> Result<(), DynErr> {
    let kmax = 70.0;
    let mut c = ChartBuilder::on(area)
        .caption(
            "The CNC's position loop over the bus (CSV, 0x60E4, SYNC 1 ms)",
            ("sans-serif", 20),
        )
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..kmax, 0.0..kmax)?;
    c.configure_mesh()
        .x_desc("the master's k_v, 1/s")
        .y_desc("f, Hz")
        .draw()?;
    for (k, label, col) in [
        (1.0, "f = k_v", BLACK),
        (0.6, "f = 0.6 k_v", RGBColor(0, 130, 0)),
        (0.25, "f = k_v / 4", RGBColor(140, 140, 140)),
    ] {
        c.draw_series(LineSeries::new(
            [(0.0, 0.0), (kmax, k * kmax)],
            col.stroke_width(if k == 0.6 { 2 } else { 1 }),
        ))?
        .label(label)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
    }
    for (name, col) in names.iter().zip(colors) {
        let pts: Vec<(f64, f64)> = d
            .law
            .iter()
            .filter(|r| &r.case.preset == name && r.limit_cycle)
            .filter_map(|r| r.fundamental_hz.map(|f| (r.case.kv_per_s, f)))
            .collect();
        c.draw_series(pts.iter().map(|&p| Circle::new(p, 4, col.filled())))?
            .label(name.clone())
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, col.filled()));
    }
    c.configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    Ok(())
}

/// The master-loop figure's right panel: f / k_v against T_sync f0, the 0.6 +- 0.1 band.
fn draw_outer_loop_sync(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    d: &FigOuterLoop,
    names: &[String],
    colors: [RGBColor; 5],
) -> Result<(), DynErr> {
    let f0_of = |name: &str| {
        d.breaks
            .iter()
            .find(|b| b.preset == name)
            .map_or(f64::NAN, |b| b.f0_hz)
    };
    let xmax = d
        .sync
        .iter()
        .map(|r| f64::from(r.case.sync_period_us) * 1e-6 * f0_of(&r.case.preset))
        .filter(|x| x.is_finite())
        .fold(0.0f64, f64::max)
        .max(0.05)
        * 1.05;
    let mut c = ChartBuilder::on(area)
        .caption(
            "Where the bus cycle matters (each preset at its own k_v)",
            ("sans-serif", 20),
        )
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..xmax, 0.0..0.8)?;
    c.configure_mesh()
        .x_desc("SYNC period / limit-cycle period at 1 ms (T_sync f0)")
        .y_desc("f / k_v")
        .draw()?;
    let band = RGBColor(90, 90, 90);
    for y in [0.5, 0.7] {
        c.draw_series(DashedLineSeries::new(
            [(0.0, y), (xmax, y)],
            6,
            4,
            band.stroke_width(1),
        ))?;
    }
    c.draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
        .label("dashed: 0.6 +- 0.1 (the law held)")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], band));
    for (name, col) in names.iter().zip(colors) {
        let f0 = f0_of(name);
        let pts: Vec<(f64, f64)> = d
            .sync
            .iter()
            .filter(|r| &r.case.preset == name && r.limit_cycle)
            .filter_map(|r| {
                r.f_over_kv
                    .map(|x| (f64::from(r.case.sync_period_us) * 1e-6 * f0, x))
            })
            .collect();
        c.draw_series(LineSeries::new(pts.clone(), col.stroke_width(2)))?
            .label(format!("{name}: 1..16 ms"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
        c.draw_series(pts.iter().map(|&p| Circle::new(p, 3, col.filled())))?;
    }
    c.configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}
