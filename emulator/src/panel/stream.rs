//! The collector thread and the stream's messages (docs/panel.md lists every field).
//!
//! Every [`PERIOD_MS`] ms the collector reads what the loop published since (every tick of
//! every axis, from its own cursors in the fan-out), writes it to a recording if one runs,
//! keeps the last seconds for the spectrum and the detector, and sends one `samples` message
//! (every axis's new ticks, at most [`MAX_STREAM_HZ`] per second, and its state) to every
//! client; `emcy` at once, `injection` when the loop has applied one, `stats` (0x2100) twice a
//! second, `spectrum` (with the detector's verdict) once a second per axis.

pub use super::rate::{decimation, stream_rate_hz, MAX_STREAM_HZ, PERIOD_MS};
use super::server::Shared;
use crate::analysis::spectrum::SpectrumAnalyzer;
use crate::master::{emcy_name, mode_short, nmt_name, state_name};
use crate::monitor::{AxisFacts, Window};
use crate::observe::{ring::Cursor, AxisSnapshot};
use crate::presets::AxisKind;
use serde_json::{json, Value};
use std::io::Write;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Seconds of samples the detector looks at.
pub const DETECTOR_WINDOW_S: f64 = 8.0;
/// Seconds of speed the spectrum is taken over (rounded down to a power of two of ticks).
pub const SPECTRUM_WINDOW_S: f64 = 4.0;
/// Axes whose spectrum and verdict are refreshed per second (round robin beyond).
const ANALYSES_PER_S: usize = 8;

fn r(x: f64, digits: i32) -> f64 {
    let k = 10f64.powi(digits);
    (x * k).round() / k
}

/// The new ticks of one axis, as columns.
#[derive(Default)]
struct Columns {
    t_s: Vec<f64>,
    position_demand_uu: Vec<f64>,
    position_actual_uu: Vec<i32>,
    following_error_uu: Vec<i32>,
    velocity_uu_s: Vec<i32>,
    motor_speed_rpm: Vec<f64>,
    load_speed_uu_per_s: Vec<f64>,
    current_a: Vec<f64>,
}

impl Columns {
    fn push(&mut self, s: &AxisSnapshot) {
        self.t_s.push(r(s.sample.t_s, 6));
        self.position_demand_uu.push(r(s.sample.target_uu, 1));
        self.position_actual_uu.push(s.sample.position_uu);
        self.following_error_uu.push(s.sample.following_error_uu);
        self.velocity_uu_s.push(s.sample.velocity_uu_s);
        self.motor_speed_rpm.push(r(s.motor_speed_rpm, 2));
        self.load_speed_uu_per_s.push(r(s.load_speed_uu_per_s, 1));
        self.current_a.push(r(s.current_a, 4));
    }

    fn take_json(&mut self) -> Value {
        let v = json!({
            "t_s": self.t_s,
            "position_demand_uu": self.position_demand_uu,
            "position_actual_uu": self.position_actual_uu,
            "following_error_uu": self.following_error_uu,
            "velocity_uu_s": self.velocity_uu_s,
            "motor_speed_rpm": self.motor_speed_rpm,
            "load_speed_uu_per_s": self.load_speed_uu_per_s,
            "current_a": self.current_a,
        });
        *self = Columns::default();
        v
    }
}

/// What the collector keeps per axis.
struct AxisFollow {
    cursor: Cursor,
    columns: Columns,
    /// Ticks since the last one the stream took.
    phase: u32,
    last: Option<AxisSnapshot>,
    /// The last seconds, every tick, for the spectrum and the detector (the same pipeline as
    /// `run --detect`'s).
    recent: Window,
    spectrum: SpectrumAnalyzer,
    speeds: Vec<f64>,
    /// `cursor.lost` already counted into a recording.
    lost_seen: u64,
}

/// The state of an axis, for the `samples` message.
pub fn state_json(s: &AxisSnapshot) -> Value {
    let sw = s.sample.statusword;
    json!({
        "t_s": r(s.sample.t_s, 6),
        "nmt": s.nmt,
        "nmt_name": if s.nmt == 0 { "INITIALISING" } else { nmt_name(s.nmt) },
        "statusword": sw,
        "controlword": s.controlword,
        "cia402_state": state_name(sw),
        "mode": s.sample.mode_display,
        "mode_name": mode_short(s.sample.mode_display),
        "position_actual_uu": s.sample.position_uu,
        "position_demand_uu": r(s.sample.target_uu, 1),
        "following_error_uu": s.sample.following_error_uu,
        "motor_speed_rpm": r(s.motor_speed_rpm, 2),
        "load_speed_uu_per_s": r(s.load_speed_uu_per_s, 1),
        "current_a": r(s.current_a, 4),
    })
}

/// The statistics object's sub-indices 1..=13 by name (as the drive's object names them).
pub use crate::runtime::stats::STATS_NAMES;

struct Collector {
    sh: Arc<Shared>,
    axes: Vec<AxisFollow>,
    decimation: u32,
    next_analysis: usize,
    json_stdout: bool,
}

/// Start the collector thread.
pub fn spawn(sh: Arc<Shared>) -> anyhow::Result<std::thread::JoinHandle<()>> {
    let tick_hz = sh.setup.tick_hz.max(1);
    let spectrum_len = {
        let n = (SPECTRUM_WINDOW_S * f64::from(tick_hz)) as usize;
        (1usize << (usize::BITS - 1 - n.max(8).leading_zeros())).max(8)
    };
    let axes = sh
        .setup
        .axes
        .iter()
        .enumerate()
        .map(|(i, a)| AxisFollow {
            cursor: Cursor::at_end(&sh.obs.rings[i]),
            columns: Columns::default(),
            phase: 0,
            last: None,
            recent: Window::new(
                AxisFacts {
                    rotary: a.config.kind == AxisKind::Rotary,
                    kv_per_s: a.config.kv_per_s,
                    gap: crate::analysis::gap::GapModel::for_axis(
                        &a.config,
                        crate::analysis::gap::CurrentUnit::Permille,
                    ),
                },
                DETECTOR_WINDOW_S,
            ),
            spectrum: SpectrumAnalyzer::new(spectrum_len),
            speeds: vec![0.0; spectrum_len],
            lost_seen: 0,
        })
        .collect();
    let mut c = Collector {
        json_stdout: sh.setup.json_stdout,
        sh,
        axes,
        decimation: decimation(tick_hz),
        next_analysis: 0,
    };
    Ok(std::thread::Builder::new()
        .name("drive-emu-panel-collect".into())
        .spawn(move || c.run())?)
}

impl Collector {
    fn run(&mut self) {
        let period = Duration::from_millis(PERIOD_MS);
        let mut next = Instant::now() + period;
        let (mut last_stats, mut last_analysis) = (Instant::now(), Instant::now());
        while !super::stopping(&self.sh.stop) {
            let now = Instant::now();
            if next > now {
                std::thread::sleep(next - now);
            }
            next += period;
            if next < Instant::now() {
                next = Instant::now() + period;
            }
            self.collect();
            self.applied();
            if last_stats.elapsed() >= Duration::from_millis(500) {
                last_stats = Instant::now();
                self.stats();
            }
            if last_analysis.elapsed() >= Duration::from_secs(1) {
                last_analysis = Instant::now();
                self.analyses();
            }
        }
    }

    /// Read every axis's new ticks; one `samples` message; `emcy` messages.
    fn collect(&mut self) {
        let sh = Arc::clone(&self.sh);
        let mut rec = sh.record.lock().ok();
        let mut entries = Vec::with_capacity(self.axes.len());
        let mut emcys = Vec::new();
        for (i, ax) in self.axes.iter_mut().enumerate() {
            while let Some(s) = sh.obs.next(i, &mut ax.cursor) {
                if let Some(r) = rec.as_mut().and_then(|r| r.active.as_mut()) {
                    r.write(i, &s.sample);
                }
                ax.recent.push(&s);
                if ax.phase == 0 {
                    ax.columns.push(&s);
                }
                ax.phase = (ax.phase + 1) % self.decimation;
                for e in s.emcys() {
                    emcys.push((i, s.sample.t_s, e));
                }
                ax.last = Some(s);
            }
            if let Some(r) = rec.as_mut().and_then(|r| r.active.as_mut()) {
                r.lost += ax.cursor.lost - ax.lost_seen;
            }
            ax.lost_seen = ax.cursor.lost;
            if let Some(last) = &ax.last {
                let mut e = json!({
                    "axis": i,
                    "node_id": sh.setup.axes[i].node_id,
                    "lost": ax.cursor.lost,
                    "state": state_json(last),
                });
                e["samples"] = ax.columns.take_json();
                entries.push(e);
            }
        }
        drop(rec);
        if !entries.is_empty() {
            sh.broadcast(
                "samples",
                json!({"type": "samples", "t_s": sh.now_us() as f64 * 1e-6, "axes": entries}),
            );
        }
        for (i, t_s, e) in emcys {
            sh.broadcast(
                "emcy",
                json!({
                    "type": "emcy",
                    "axis": i,
                    "node_id": sh.setup.axes[i].node_id,
                    "t_s": r(t_s, 6),
                    "code": format!("{:#06X}", e.code),
                    "raised": e.raised,
                    "meaning": emcy_name(e.code),
                }),
            );
        }
    }

    /// The injections the loop applied since: their time into the session, a line on stdout,
    /// an `injection` message.
    fn applied(&mut self) {
        let sh = Arc::clone(&self.sh);
        while let Some((index, t_us)) = sh.link.applied.pop() {
            let what = match sh.session.lock() {
                Ok(mut s) => match s.events.get_mut(index as usize) {
                    Some(e) => {
                        e.applied_us = Some(t_us);
                        e.describe.clone()
                    }
                    None => continue,
                },
                Err(_) => continue,
            };
            let node = sh.setup.axes[0].node_id;
            let t_s = t_us as f64 * 1e-6;
            let v = json!({
                "type": "injection", "index": index, "axis": 0, "node_id": node,
                "t_s": r(t_s, 6), "event": what,
            });
            let mut out = std::io::stdout().lock();
            let _ = if self.json_stdout {
                writeln!(
                    out,
                    "{}",
                    json!({"event": "panel_injection", "t_s": r(t_s, 6),
                                          "node_id": node, "what": what})
                )
            } else {
                writeln!(out, "drive-emu: panel: t={t_s:.3} s node {node}: {what}")
            };
            let _ = out.flush();
            drop(out);
            sh.broadcast("injection", v);
        }
    }

    /// `stats`: the loop statistics 0x2100, and `recording` while one runs.
    fn stats(&mut self) {
        let sh = &self.sh;
        let v = sh.obs.stats_2100();
        let mut m = serde_json::Map::new();
        m.insert("type".into(), json!("stats"));
        m.insert("t_s".into(), json!(sh.now_us() as f64 * 1e-6));
        for (name, x) in STATS_NAMES.iter().zip(v) {
            m.insert((*name).into(), json!(x));
        }
        // A lock-step loop's time is the SYNCs themselves: no phase lock to report.
        let lock = if sh.setup.lockstep {
            "lock-step"
        } else {
            crate::runtime::stats::lock_name(v[7])
        };
        m.insert("sync_lock".into(), json!(lock));
        m.insert("clients".into(), json!(sh.client_count()));
        sh.broadcast("stats", Value::Object(m));
        let rec = sh
            .record
            .lock()
            .ok()
            .and_then(|st| st.active.as_ref().map(|r| (r.samples, r.lost, r.frames())));
        if let Some((samples, lost, frames)) = rec {
            sh.broadcast(
                "recording_progress",
                json!({"type": "recording_progress", "samples": samples, "lost": lost,
                       "frames": frames}),
            );
        }
    }

    /// `spectrum` with the detector's verdict, for up to [`ANALYSES_PER_S`] axes.
    fn analyses(&mut self) {
        let n = self.axes.len();
        for _ in 0..n.min(ANALYSES_PER_S) {
            let i = self.next_analysis % n;
            self.next_analysis = (i + 1) % n;
            if let Some(v) = self.analysis(i) {
                self.sh.broadcast("spectrum", v);
            }
        }
    }

    fn analysis(&mut self, i: usize) -> Option<Value> {
        let sh = Arc::clone(&self.sh);
        let ax = &mut self.axes[i];
        let len = ax.spectrum.len();
        let recent = ax.recent.samples();
        if recent.len() < len {
            return None;
        }
        let rate = f64::from(sh.setup.tick_hz);
        for (d, s) in ax
            .speeds
            .iter_mut()
            .zip(recent.iter().skip(recent.len() - len))
        {
            *d = f64::from(s.velocity_uu_s);
        }
        // k_v as the drive has it now (an injected one included), and the axis's gap model
        let cfg = ax.recent.config();
        let kv = cfg.kv_per_s;
        let band = cfg.band_hz();
        let peak = ax.spectrum.fundamental(&ax.speeds, rate, band);
        let res = rate / len as f64;
        let f_max = (2.5 * kv).clamp(10.0, rate / 2.0);
        let bins = ((f_max / res) as usize).min(ax.spectrum.amplitudes().len());
        let amps: Vec<f64> = ax.spectrum.amplitudes()[..bins]
            .iter()
            .map(|a| r(*a, 3))
            .collect();
        let d = ax.recent.analyze()?;
        let recent = ax.recent.samples();
        Some(json!({
            "type": "spectrum",
            "axis": i,
            "node_id": sh.setup.axes[i].node_id,
            "t_s": recent.back().map_or(0.0, |s| r(s.t_s, 6)),
            "window_s": r(len as f64 / rate, 3),
            "signal": "velocity_uu_s",
            "resolution_hz": r(res, 5),
            "amplitude_uu_s": amps,
            "band_hz": [r(band.0, 3), r(band.1, 3)],
            "peak": peak.map(|p| json!({"frequency_hz": r(p.frequency_hz, 3),
                                        "amplitude_uu_s": r(p.amplitude, 3)})),
            "kv_per_s": kv,
            "detector": {
                "window_s": DETECTOR_WINDOW_S,
                "verdict": d.verdict.as_str(),
                "inconclusive": d.inconclusive.map(|x| x.as_str()),
                "amplitude": r(d.amplitude, 3),
                "unit": d.position_unit,
                "frequency_hz": d.frequency_hz.map(|f| r(f, 3)),
                "frequency_over_kv": d.frequency_over_kv.map(|f| r(f, 4)),
                "backlash_estimate": d.backlash_estimate.value().map(|v| r(v, 5)),
                "backlash_estimate_range": d.backlash_estimate.range().map(|[a, b]| [r(a, 5), r(b, 5)]),
                "backlash_estimate_unit": d.backlash_estimate.unit(),
                "backlash_estimate_method": d.backlash_estimate.method().map(|m| m.as_str()),
                "reason": d.reasons.first(),
            },
        }))
    }
}
