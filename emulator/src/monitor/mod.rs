//! A drive that watches itself (`drive-emu run --detect`): the backlash detector on the
//! drive's own samples while it runs, its result in the drive's objects (base + 0x102,
//! [`crate::drive::objects`]: a master can map it into a TPDO) and an EMCY warning
//! ([`EMCY_BACKLASH`]) when backlash is confirmed, so a master's condition monitoring can be
//! tested against it.
//!
//! Two halves, as the trace recorder ([`crate::runtime::trace`]):
//! - the loop thread calls [`DetectTap::on_tick`] after every tick: it pushes each axis's
//!   sample (its objects, [`node_sample`]) into a preallocated lock-free queue, and takes the
//!   detector's latest result, if any, from another one and publishes it: the objects
//!   ([`drive_protocol::Node::set_value`]) and the EMCY ([`drive_protocol::Node::raise_condition`]).
//!   No allocation, lock or I/O; a full queue is a counted loss.
//! - the [`Detector`] thread keeps the last [`DetectOptions::history_s`] of samples per axis
//!   and every [`DetectOptions::interval_s`] of new ones runs [`analyze`] on them (k_v: the
//!   drive's own, read each tick; the master's where it closes the loop itself, found by the
//!   detector), and once more on what is left when the run stops ([`Detector::finish`]).
//!   What it says for a run shorter than the history is what `drive-emu analyze` says of the
//!   run's `--trace`: the same samples, the same code.

use crate::analysis::detector::{analyze, AxisTrace, DetectorConfig, DetectorReport, Verdict};
use crate::bus::CanBus;
use crate::drive::axis_drive::AxisDrive;
use crate::drive::objects::{AxisParam, EMCY_BACKLASH};
use crate::runtime::trace::node_sample;
use crate::runtime::Runtime;
use crate::samples::{Sample, SampleSource};
use crossbeam::queue::ArrayQueue;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// Samples a queue holds: 65 s at 1 kHz, far more than the detector thread ever lags.
const QUEUE_SAMPLES: usize = 1 << 16;
/// Results a queue holds (the loop takes them every tick).
const QUEUE_RESULTS: usize = 8;

/// How the detector runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectOptions {
    /// Seconds of samples analysed (the most recent), s.
    pub history_s: f64,
    /// A new analysis after this much new drive time, s.
    pub interval_s: f64,
}

impl Default for DetectOptions {
    fn default() -> Self {
        Self {
            history_s: 60.0,
            interval_s: 2.0,
        }
    }
}

/// One result as the objects carry it.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct DetectResult {
    /// 0 nothing analysed yet, 1 inconclusive, 2 ok, 3 backlash suspected, 4 backlash.
    pub verdict: u8,
    /// Frequency of the limit cycle, Hz (0: none).
    pub frequency_hz: f32,
    /// Its displacement-equivalent amplitude, um or mdeg.
    pub amplitude: f32,
    /// The k_v it was judged against, 1/s.
    pub kv_per_s: f32,
    /// Results so far (this one included).
    pub analyses: u32,
}

/// The verdict's code in the objects.
pub fn verdict_code(v: Verdict) -> u8 {
    match v {
        Verdict::Inconclusive => 1,
        Verdict::Ok => 2,
        Verdict::BacklashSuspected => 3,
        Verdict::Backlash => 4,
    }
}

impl DetectResult {
    fn of(rep: &DetectorReport, analyses: u32) -> Self {
        Self {
            verdict: verdict_code(rep.verdict),
            frequency_hz: rep.frequency_hz.unwrap_or(0.0) as f32,
            amplitude: rep.amplitude as f32,
            kv_per_s: rep.kv_per_s as f32,
            analyses,
        }
    }

    /// The EMCY's five manufacturer bytes: verdict, frequency in 0.01 Hz, amplitude in 0.1
    /// um (or mdeg), little endian, saturated.
    pub fn emcy_info(&self) -> [u8; 5] {
        let f = (f64::from(self.frequency_hz) * 100.0)
            .round()
            .clamp(0.0, 65535.0) as u16;
        let a = (f64::from(self.amplitude) * 10.0)
            .round()
            .clamp(0.0, 65535.0) as u16;
        let [f0, f1] = f.to_le_bytes();
        let [a0, a1] = a.to_le_bytes();
        [self.verdict, f0, f1, a0, a1]
    }
}

/// The loop thread's half: per axis a sample queue to the detector and a result queue back,
/// sized once.
pub struct DetectTap {
    samples: Vec<ArrayQueue<Sample>>,
    results: Vec<ArrayQueue<DetectResult>>,
    /// The drive's own k_v (f64 bits), published by the loop every tick.
    kv_bits: Vec<AtomicU64>,
    /// Whether the backlash EMCY is up, per axis (the loop's own state).
    warned: Vec<AtomicBool>,
    /// The last verdict published, per axis.
    published: Vec<AtomicU8>,
    lost: AtomicU64,
}

impl DetectTap {
    pub fn new(axes: usize) -> Self {
        Self {
            samples: (0..axes).map(|_| ArrayQueue::new(QUEUE_SAMPLES)).collect(),
            results: (0..axes).map(|_| ArrayQueue::new(QUEUE_RESULTS)).collect(),
            kv_bits: (0..axes).map(|_| AtomicU64::new(0)).collect(),
            warned: (0..axes).map(|_| AtomicBool::new(false)).collect(),
            published: (0..axes).map(|_| AtomicU8::new(0)).collect(),
            lost: AtomicU64::new(0),
        }
    }

    /// After every tick (loop thread): one sample per axis to the detector, its latest result
    /// into the axis's objects and, with backlash confirmed, its EMCY warning (cleared when
    /// the verdict is ok again). Real-time safe: no allocation, lock or I/O.
    pub fn on_tick<B: CanBus>(&self, rt: &mut Runtime<B, AxisDrive>) {
        let now = rt.sim_time_us;
        for (k, ax) in rt.axes.iter_mut().enumerate() {
            if k >= self.samples.len() {
                break;
            }
            self.on_axis(k, &mut ax.node, &ax.drive, now);
        }
    }

    /// [`DetectTap::on_tick`] for axis `k` alone, its node and drive at `now`: for a loop
    /// other than the CAN [`Runtime`] (the EtherCAT front end's). Real-time safe.
    pub fn on_axis(&self, k: usize, node: &mut drive_protocol::Node, drive: &AxisDrive, now: u64) {
        let Some(q) = self.samples.get(k) else {
            return;
        };
        if q.push(node_sample(node, now)).is_err() {
            self.lost.fetch_add(1, Ordering::Relaxed);
        }
        self.kv_bits[k].store(drive.param(AxisParam::Kv).to_bits(), Ordering::Relaxed);
        let mut latest = None;
        while let Some(r) = self.results[k].pop() {
            latest = Some(r);
        }
        let Some(r) = latest else {
            return;
        };
        if let Some(obj) = drive.objects {
            let s = &obj.detector;
            node.set_value(s[0], u64::from(r.verdict));
            node.set_value(s[1], u64::from(r.frequency_hz.to_bits()));
            node.set_value(s[2], u64::from(r.amplitude.to_bits()));
            node.set_value(s[3], u64::from(r.kv_per_s.to_bits()));
            node.set_value(s[4], u64::from(r.analyses));
        }
        self.published[k].store(r.verdict, Ordering::Relaxed);
        let warned = self.warned[k].load(Ordering::Relaxed);
        if r.verdict == verdict_code(Verdict::Backlash) && !warned {
            node.raise_condition(EMCY_BACKLASH, r.emcy_info());
            self.warned[k].store(true, Ordering::Relaxed);
        } else if r.verdict == verdict_code(Verdict::Ok) && warned {
            node.clear_condition(EMCY_BACKLASH);
            self.warned[k].store(false, Ordering::Relaxed);
        }
    }

    /// Hand the loop a result for axis `k`, to publish at its next tick (the detector
    /// thread's side; a test may play it). A full queue drops the oldest result.
    pub fn offer(&self, k: usize, r: DetectResult) {
        if let Some(q) = self.results.get(k) {
            let _ = q.force_push(r);
        }
    }

    /// Samples dropped because the detector thread fell behind.
    pub fn lost(&self) -> u64 {
        self.lost.load(Ordering::Relaxed)
    }

    /// The verdict code last published for axis `k` (0: none yet).
    pub fn published(&self, k: usize) -> u8 {
        self.published
            .get(k)
            .map_or(0, |p| p.load(Ordering::Relaxed))
    }

    fn kv(&self, k: usize) -> f64 {
        f64::from_bits(self.kv_bits[k].load(Ordering::Relaxed))
    }
}

/// What the detector needs to know of an axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisFacts {
    /// Rotary axis (mdeg) or linear (um).
    pub rotary: bool,
    /// The axis's k_v when the loop has not published it yet, 1/s.
    pub kv_per_s: f64,
    /// The axis's mechanics for the gap estimate (current in per mille of rated, as the
    /// drive's samples have it); None: only from the two encoders, without the elastic part.
    pub gap: Option<crate::analysis::gap::GapModel>,
}

/// The detector thread.
pub struct Detector {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<Vec<Option<DetectorReport>>>,
}

/// One axis's samples in the detector thread.
struct AxisHistory {
    facts: AxisFacts,
    samples: VecDeque<Sample>,
    /// Drive time of the last analysis, s.
    analysed_at_s: f64,
    analyses: u32,
}

impl AxisHistory {
    fn analyse(&mut self, tap: &DetectTap, k: usize) -> Option<DetectorReport> {
        let samples: Vec<Sample> = self.samples.iter().copied().collect();
        let last = samples.last()?;
        self.analysed_at_s = last.t_s;
        let kv = match tap.kv(k) {
            kv if kv > 0.0 && kv.is_finite() => kv,
            _ => self.facts.kv_per_s,
        };
        let tr = AxisTrace::from_sample_log(&samples, SampleSource::Drive, self.facts.rotary);
        let cfg = DetectorConfig {
            gap: self.facts.gap,
            ..DetectorConfig::new(kv)
        };
        let rep = analyze(&tr, &cfg);
        self.analyses += 1;
        tap.offer(k, DetectResult::of(&rep, self.analyses));
        Some(rep)
    }
}

impl Detector {
    /// Start the detector thread on `tap`'s samples, one entry of `axes` per axis.
    pub fn start(
        tap: Arc<DetectTap>,
        axes: Vec<AxisFacts>,
        opts: DetectOptions,
    ) -> std::io::Result<Self> {
        assert_eq!(tap.samples.len(), axes.len(), "one tap queue per axis");
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = Arc::clone(&stop);
            std::thread::Builder::new()
                .name("drive-emu-detect".into())
                .spawn(move || {
                    let mut hist: Vec<AxisHistory> = axes
                        .into_iter()
                        .map(|facts| AxisHistory {
                            facts,
                            samples: VecDeque::new(),
                            analysed_at_s: f64::NEG_INFINITY,
                            analyses: 0,
                        })
                        .collect();
                    loop {
                        // Read the flag before draining: nothing pushed before `finish` is
                        // left out of the last analysis.
                        let last = stop.load(Ordering::Acquire);
                        for (k, h) in hist.iter_mut().enumerate() {
                            while let Some(s) = tap.samples[k].pop() {
                                h.samples.push_back(s);
                            }
                            let newest = h.samples.back().map_or(0.0, |s| s.t_s);
                            while h
                                .samples
                                .front()
                                .is_some_and(|s| newest - s.t_s > opts.history_s)
                            {
                                h.samples.pop_front();
                            }
                            if !last
                                && newest
                                    - h.analysed_at_s
                                        .max(h.samples.front().map_or(newest, |s| s.t_s))
                                    >= opts.interval_s
                            {
                                h.analyse(&tap, k);
                            }
                        }
                        if last {
                            break;
                        }
                        std::thread::sleep(Duration::from_millis(50));
                    }
                    hist.iter_mut()
                        .enumerate()
                        .map(|(k, h)| h.analyse(&tap, k))
                        .collect()
                })?
        };
        Ok(Self { stop, thread })
    }

    /// Call after the loop has stopped: the last analysis of each axis on every sample kept
    /// (None: an axis without samples).
    pub fn finish(self) -> std::io::Result<Vec<Option<DetectorReport>>> {
        self.stop.store(true, Ordering::Release);
        self.thread
            .join()
            .map_err(|_| std::io::Error::other("the detector thread panicked"))
    }
}
