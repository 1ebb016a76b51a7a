//! A drive that watches itself (`drive-emu run --detect`): the backlash detector on the
//! drive's own samples while it runs, its result in the drive's objects (base + 0x102,
//! [`crate::drive::objects`]: a master can map it into a TPDO) and an EMCY warning
//! ([`EMCY_BACKLASH`]) when backlash is confirmed, so a master's condition monitoring can be
//! tested against it.
//!
//! Two halves:
//! - the [`Detector`] thread reads each axis's ticks from the observation bus
//!   ([`crate::observe`]), keeps the last [`DetectOptions::history_s`] of them in a [`Window`]
//!   and every [`DetectOptions::interval_s`] of new ones runs [`analyze`] on it (k_v: the
//!   drive's own, as each snapshot carries it; the master's where it closes the loop itself,
//!   found by the detector), and once more on what is left when the run stops
//!   ([`Detector::finish`]). What it says for a run shorter than the history is what
//!   `drive-emu analyze` says of the run's `--trace`: the same samples, the same code.
//! - the loop applies the detector's latest result, if any, as an injection
//!   ([`DetectResults::apply`]): the objects ([`drive_protocol::Node::set_value`]) and the
//!   EMCY ([`drive_protocol::Node::raise_condition`]). No allocation, lock or I/O.
//!
//! [`Window`] is the one live detector pipeline: the panel's stream keeps one per axis too.

use crate::analysis::detector::{analyze, AxisTrace, DetectorConfig, DetectorReport, Verdict};
use crate::bus::CanBus;
use crate::drive::axis_drive::AxisDrive;
use crate::drive::objects::EMCY_BACKLASH;
use crate::observe::{AxisSnapshot, Observation};
use crate::runtime::Runtime;
use crate::samples::{Sample, SampleSource};
use crossbeam::queue::ArrayQueue;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

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

/// The loop's half: per axis a queue of the detector's results, sized once, which the loop
/// applies to the drive after each tick.
pub struct DetectResults {
    results: Vec<ArrayQueue<DetectResult>>,
    /// Whether the backlash EMCY is up, per axis (the loop's own state).
    warned: Vec<AtomicBool>,
    /// The last verdict published, per axis.
    published: Vec<AtomicU8>,
}

impl DetectResults {
    pub fn new(axes: usize) -> Self {
        Self {
            results: (0..axes).map(|_| ArrayQueue::new(QUEUE_RESULTS)).collect(),
            warned: (0..axes).map(|_| AtomicBool::new(false)).collect(),
            published: (0..axes).map(|_| AtomicU8::new(0)).collect(),
        }
    }

    /// After every tick (loop thread): each axis's latest result into its objects and, with
    /// backlash confirmed, its EMCY warning (cleared when the verdict is ok again). Real-time
    /// safe: no allocation, lock or I/O.
    pub fn apply<B: CanBus>(&self, rt: &mut Runtime<B, AxisDrive>) {
        for (k, ax) in rt.axes.iter_mut().enumerate() {
            self.apply_axis(k, &mut ax.node, &ax.drive);
        }
    }

    /// [`DetectResults::apply`] for axis `k` alone, its node and drive: for a loop other than
    /// the CAN [`Runtime`] (the EtherCAT front end's). Real-time safe.
    pub fn apply_axis(&self, k: usize, node: &mut drive_protocol::DriveCore, drive: &AxisDrive) {
        let Some(q) = self.results.get(k) else {
            return;
        };
        let mut latest = None;
        while let Some(r) = q.pop() {
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

    /// Hand the loop a result for axis `k`, to apply at its next tick (the detector thread's
    /// side; a test may play it). A full queue drops the oldest result.
    pub fn offer(&self, k: usize, r: DetectResult) {
        if let Some(q) = self.results.get(k) {
            let _ = q.force_push(r);
        }
    }

    /// The verdict code last applied for axis `k` (0: none yet).
    pub fn published(&self, k: usize) -> u8 {
        self.published
            .get(k)
            .map_or(0, |p| p.load(Ordering::Relaxed))
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

/// The last seconds of one axis's ticks and the detector on them: the one live detector
/// pipeline (the `--detect` thread and the panel's stream keep one per axis).
pub struct Window {
    samples: VecDeque<Sample>,
    history_s: f64,
    facts: AxisFacts,
    /// The drive's k_v as the newest snapshot carried it, 1/s (0: none yet).
    kv_per_s: f64,
}

impl Window {
    /// A window of the last `history_s` seconds of drive time.
    pub fn new(facts: AxisFacts, history_s: f64) -> Self {
        Self {
            samples: VecDeque::new(),
            history_s,
            facts,
            kv_per_s: 0.0,
        }
    }

    /// One tick: kept, and what is older than the window dropped.
    pub fn push(&mut self, s: &AxisSnapshot) {
        self.samples.push_back(s.sample);
        self.kv_per_s = s.kv_per_s;
        let newest = s.sample.t_s;
        while self
            .samples
            .front()
            .is_some_and(|f| newest - f.t_s > self.history_s)
        {
            self.samples.pop_front();
        }
    }

    /// The ticks in the window, oldest first.
    pub fn samples(&self) -> &VecDeque<Sample> {
        &self.samples
    }

    /// The k_v the detector judges against: the drive's own as last published, else the
    /// axis's from its configuration, 1/s.
    pub fn kv_per_s(&self) -> f64 {
        match self.kv_per_s {
            kv if kv > 0.0 && kv.is_finite() => kv,
            _ => self.facts.kv_per_s,
        }
    }

    /// The detector's configuration for this axis now (k_v, gap model).
    pub fn config(&self) -> DetectorConfig {
        DetectorConfig {
            gap: self.facts.gap,
            ..DetectorConfig::new(self.kv_per_s())
        }
    }

    /// The detector on the window (None: no ticks yet).
    pub fn analyze(&self) -> Option<DetectorReport> {
        if self.samples.is_empty() {
            return None;
        }
        let samples: Vec<Sample> = self.samples.iter().copied().collect();
        let tr = AxisTrace::from_sample_log(&samples, SampleSource::Drive, self.facts.rotary);
        Some(analyze(&tr, &self.config()))
    }
}

/// The detector thread.
pub struct Detector {
    stop: Arc<AtomicBool>,
    lost: Arc<AtomicU64>,
    thread: JoinHandle<Vec<Option<DetectorReport>>>,
}

/// One axis in the detector thread.
struct AxisHistory {
    window: Window,
    cursor: crate::observe::ring::Cursor,
    /// Drive time of the last analysis, s.
    analysed_at_s: f64,
    analyses: u32,
}

impl AxisHistory {
    fn analyse(&mut self, results: &DetectResults, k: usize) -> Option<DetectorReport> {
        let rep = self.window.analyze()?;
        self.analysed_at_s = self.window.samples().back().map_or(0.0, |s| s.t_s);
        self.analyses += 1;
        results.offer(k, DetectResult::of(&rep, self.analyses));
        Some(rep)
    }

    /// Whether `interval_s` of new drive time came since the last analysis.
    fn due(&self, interval_s: f64) -> bool {
        let w = self.window.samples();
        let newest = w.back().map_or(0.0, |s| s.t_s);
        newest - self.analysed_at_s.max(w.front().map_or(newest, |s| s.t_s)) >= interval_s
    }
}

impl Detector {
    /// Start the detector thread on the bus `obs` (from its next record), one entry of `axes`
    /// per axis; its results go to the loop through `results`.
    pub fn start(
        obs: Arc<Observation>,
        results: Arc<DetectResults>,
        axes: Vec<AxisFacts>,
        opts: DetectOptions,
    ) -> std::io::Result<Self> {
        assert_eq!(obs.rings.len(), axes.len(), "one entry per axis");
        let stop = Arc::new(AtomicBool::new(false));
        let lost = Arc::new(AtomicU64::new(0));
        let mut hist: Vec<AxisHistory> = axes
            .into_iter()
            .zip(obs.cursors_at_end())
            .map(|(facts, cursor)| AxisHistory {
                window: Window::new(facts, opts.history_s),
                cursor,
                analysed_at_s: f64::NEG_INFINITY,
                analyses: 0,
            })
            .collect();
        let thread = {
            let (stop, lost) = (Arc::clone(&stop), Arc::clone(&lost));
            std::thread::Builder::new()
                .name("drive-emu-detect".into())
                .spawn(move || {
                    loop {
                        // Read the flag before reading the bus: nothing published before
                        // `finish` is left out of the last analysis.
                        let last = stop.load(Ordering::Acquire);
                        for (k, h) in hist.iter_mut().enumerate() {
                            while let Some(s) = obs.next(k, &mut h.cursor) {
                                h.window.push(&s);
                            }
                            if !last && h.due(opts.interval_s) {
                                h.analyse(&results, k);
                            }
                        }
                        lost.store(hist.iter().map(|h| h.cursor.lost).sum(), Ordering::Relaxed);
                        if last {
                            break;
                        }
                        std::thread::sleep(Duration::from_millis(50));
                    }
                    hist.iter_mut()
                        .enumerate()
                        .map(|(k, h)| h.analyse(&results, k))
                        .collect()
                })?
        };
        Ok(Self { stop, lost, thread })
    }

    /// Ticks the detector thread missed so far (it fell more than the ring behind).
    pub fn lost(&self) -> u64 {
        self.lost.load(Ordering::Relaxed)
    }

    /// Call after the loop has stopped: the last analysis of each axis on every sample kept
    /// (None: an axis without samples), and the ticks the thread missed.
    pub fn finish(self) -> std::io::Result<(Vec<Option<DetectorReport>>, u64)> {
        self.stop.store(true, Ordering::Release);
        let reports = self
            .thread
            .join()
            .map_err(|_| std::io::Error::other("the detector thread panicked"))?;
        Ok((reports, self.lost.load(Ordering::Relaxed)))
    }
}
