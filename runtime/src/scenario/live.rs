//! Scenarios live on a bus: the same timeline, injected into a running drive.
//!
//! Two threads share a [`LiveLink`] of preallocated lock-free queues:
//! - the loop thread calls [`LoopInjector::on_tick`] after every tick: it applies pending
//!   injections (parameter values, encoder faults, CAN fault rules) to the drive and the bus.
//!   Nothing there allocates, locks or logs;
//! - the scenario thread ([`run_timeline`]) follows the loop's simulated time, decides which
//!   events are due, runs ramps and load profiles, and turns them into injections. It reads
//!   what the drive reported (actual values and EMCYs of axis 0) from the observation bus
//!   ([`crate::observe`]), as every other reader does, and at the end runs the detector and
//!   checks the expectations.
//!
//! The motion comes from whatever controller is on the bus; the scenario's motion program is
//! not used live.

/// Where it was (its home is the scenario module now, used by the offline runner too).
pub use super::check_bus;
use super::expect::{check_all, ExpectResult, RunRecord};
use super::inject::{Injection, Injector};
use super::runner::detector_config;
use super::timeline::{Action, Drivers, Observation, Timeline};
use super::units::ParamKey;
use super::Scenario;
use crate::analysis::detector::{analyze, AxisTrace, DetectorReport};
use crate::bus::fault::FaultyBus;
use crate::bus::CanBus;
use crate::drive::axis_drive::AxisDrive;
use crate::observe::ring::Cursor;
use crate::presets::{AxisConfig, AxisKind};
use crate::runtime::Runtime;
use crate::samples::{Sample, SampleSource};
use crossbeam::queue::ArrayQueue;
use drive_protocol::Cia402State;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

/// The queues between the loop and the scenario thread, sized once.
pub struct LiveLink {
    pub injections: ArrayQueue<Injection>,
    /// (event index, simulated time us at which the loop applied it).
    pub applied: ArrayQueue<(u32, u64)>,
    /// The loop's simulated time, us.
    pub now_us: AtomicU64,
}

impl LiveLink {
    pub fn new() -> Self {
        Self {
            injections: ArrayQueue::new(1024),
            applied: ArrayQueue::new(256),
            now_us: AtomicU64::new(0),
        }
    }
}

impl Default for LiveLink {
    fn default() -> Self {
        Self::new()
    }
}

/// The loop thread's half: applies queued injections (owning the CAN rules in force, at most
/// 16). It reads nothing from the drive: what the drive reports reaches the scenario thread
/// through the observation bus.
pub struct LoopInjector {
    injector: Injector<16>,
}

impl LoopInjector {
    /// `master_id`: the node ID whose heartbeat a heartbeat-loss fault drops.
    pub fn new(master_id: u8) -> Self {
        Self {
            injector: Injector::new(master_id),
        }
    }

    /// After every tick: the loop's time into `link`, and the injections queued there
    /// applied to axis 0 and the bus.
    pub fn on_tick<B: CanBus>(
        &mut self,
        link: &LiveLink,
        rt: &mut Runtime<FaultyBus<B>, AxisDrive>,
    ) {
        link.now_us.store(rt.sim_time_us, Ordering::Relaxed);
        self.apply_queued(link, rt);
    }

    /// Apply the injections queued in `link` to axis 0 and the bus (each `Mark` answered with
    /// the simulated time in `link.applied`), and end the CAN rules whose time is over. Also
    /// the live panel's path: its injections come through a link of their own.
    pub fn apply_queued<B: CanBus>(
        &mut self,
        link: &LiveLink,
        rt: &mut Runtime<FaultyBus<B>, AxisDrive>,
    ) {
        let now = rt.sim_time_us;
        while let Some(inj) = link.injections.pop() {
            if let Injection::Mark { event } = inj {
                let _ = link.applied.push((event, now));
            }
            // An out-of-range value is refused by the drive and changes nothing; the scenario
            // file's own validation keeps values in range.
            let _ = self.injector.apply(inj, &mut rt.axes[0].drive, &mut rt.bus);
        }
        self.injector.expire(now, &mut rt.bus);
    }

    /// After every drive cycle of `run --ethercat` at simulated time `now_us`: the time into
    /// `link`, and the queued injections applied to the first slave, its drive and the port's
    /// faults.
    pub fn on_ethercat_cycle(
        &mut self,
        link: &LiveLink,
        now_us: u64,
        slave: &mut drive_ethercat::slave::Slave,
        drive: &mut AxisDrive,
        faults: &mut crate::bus::ethercat::EcatFaults,
    ) {
        link.now_us.store(now_us, Ordering::Relaxed);
        self.apply_queued_ethercat(link, now_us, slave, drive, faults);
    }

    /// [`LoopInjector::apply_queued`] on EtherCAT: the injections queued in `link` applied to
    /// the first slave, its drive and the port's faults (each `Mark` answered with `now_us`).
    /// A CAN fault is refused there and changes nothing (files and the panel refuse it first).
    pub fn apply_queued_ethercat(
        &mut self,
        link: &LiveLink,
        now_us: u64,
        slave: &mut drive_ethercat::slave::Slave,
        drive: &mut AxisDrive,
        faults: &mut crate::bus::ethercat::EcatFaults,
    ) {
        while let Some(inj) = link.injections.pop() {
            if let Injection::Mark { event } = inj {
                let _ = link.applied.push((event, now_us));
            }
            let _ = self.injector.apply_ethercat(inj, drive, slave, faults);
        }
    }

    /// The node ID whose heartbeat a heartbeat-loss fault drops from now on.
    pub fn set_master_id(&mut self, master_id: u8) {
        self.injector.set_master_id(master_id);
    }
}

/// What a live scenario run found.
#[derive(Debug)]
pub struct LiveOutcome {
    pub record: RunRecord,
    pub detector: Option<DetectorReport>,
    pub expectations: Vec<ExpectResult>,
    /// (simulated time us, description) of every event that fired, in time order; the time
    /// is when the loop applied it.
    pub fired: Vec<(u64, String)>,
    /// Events that had not fired when the run ended: (file line, description).
    pub not_fired: Vec<(usize, String)>,
    /// Why the run ended, for people.
    pub end_reason: String,
    /// Ticks the scenario thread missed (it fell more than the observation ring behind).
    pub samples_lost: u64,
    /// EMCYs of ticks that raised more than a snapshot carries (counted, not recorded).
    pub emcys_lost: u64,
}

impl LiveOutcome {
    /// Every expectation held and the scenario finished (every event fired).
    pub fn passed(&self) -> bool {
        self.expectations.iter().all(|e| e.passed) && self.unfinished().is_none()
    }

    /// Why the scenario did not finish, for people: the events that had not fired when the
    /// run ended (`--duration` or the file's `duration` too short, Ctrl-C, a condition never
    /// met). `None` when every event fired.
    pub fn unfinished(&self) -> Option<String> {
        super::timeline::not_fired_text(&self.not_fired, self.record.end_us)
    }
}

/// File-unit value of every parameter key this machine has, to start ramps from.
fn initial_values(cfg: &AxisConfig, drive: &AxisDrive) -> Vec<(&'static ParamKey, f64)> {
    use super::units::AxisKind as KeyKind;
    let kind = match cfg.kind {
        AxisKind::Linear => KeyKind::Linear,
        AxisKind::Rotary => KeyKind::Rotary,
    };
    super::units::PARAM_KEYS
        .iter()
        .filter(|k| k.axis == kind || k.axis == KeyKind::Any)
        .map(|k| (k, drive.param(k.param) / k.scale))
        .collect()
}

/// When a live run ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LiveEnd {
    /// At this simulated time, us (`--duration`, or the file's `duration`).
    At(u64),
    /// Once every event has fired and what it started has run its course (ramps, profiles
    /// and CAN faults with a length), plus the longest `within` of the expectations (at least
    /// 1 s), and no earlier than the latest time an expectation names.
    EventsDone,
}

impl LiveEnd {
    /// `--duration` if given, else the file's `duration`, else [`LiveEnd::EventsDone`].
    pub fn for_scenario(s: &Scenario, duration_us: Option<u64>) -> Self {
        duration_us
            .or(s.run.duration_us)
            .map_or(LiveEnd::EventsDone, LiveEnd::At)
    }

    /// For people: "at 3 s" / "once its events have run their course (...)".
    pub fn describe(&self, s: &Scenario) -> String {
        match self {
            LiveEnd::At(t) => format!("at {}", super::expect::seconds_text(*t)),
            LiveEnd::EventsDone => format!(
                "once {} fired and run {} course, {} after (Ctrl-C ends it earlier)",
                match s.events.len() {
                    1 => "its event has".to_string(),
                    n => format!("its {n} events have"),
                },
                if s.events.len() == 1 { "its" } else { "their" },
                super::expect::seconds_text(settle_us(s).0)
            ),
        }
    }
}

/// (time left after the last event for its effect to show, latest absolute time an
/// expectation names), us.
fn settle_us(s: &Scenario) -> (u64, u64) {
    use super::expect::Expectation as E;
    let mut settle = 1_000_000u64;
    let mut horizon = 0u64;
    for e in &s.expectations {
        match &e.what {
            E::Emcy {
                within_us: Some(w), ..
            } => settle = settle.max(*w),
            E::NoEmcy { from_us, until_us } => horizon = horizon.max(until_us.unwrap_or(*from_us)),
            E::State { at_us: Some(t), .. } => horizon = horizon.max(*t),
            E::FollowingError {
                from_us, until_us, ..
            } => horizon = horizon.max(until_us.unwrap_or(*from_us)),
            E::Verdict {
                by_us,
                not_before_us,
                ..
            } => {
                horizon = horizon
                    .max(by_us.unwrap_or(0))
                    .max(not_before_us.unwrap_or(0))
            }
            _ => {}
        }
    }
    (settle, horizon)
}

/// How long what an event starts lasts, us.
fn event_length_us(a: &Action) -> u64 {
    match a {
        Action::Ramp { over_us, .. } => *over_us,
        Action::Profile { over_us, .. }
        | Action::Can { over_us, .. }
        | Action::Ethercat { over_us, .. } => over_us.unwrap_or(0),
        _ => 0,
    }
}

/// What the scenario thread keeps while it follows the loop.
struct LiveTimeline {
    /// Current value (file units) of every parameter the scenario drives.
    current: Vec<(&'static ParamKey, f64)>,
    timeline: Timeline,
    drivers: Drivers,
    values: Vec<(&'static ParamKey, f64)>,
    samples: Vec<Sample>,
    emcys: Vec<(u64, u16)>,
    /// EMCY codes received since the last pass (triggers).
    new_codes: Vec<u16>,
    /// Axis 0 on the observation bus.
    cursor: Cursor,
    /// EMCYs of ticks with more than the snapshot carries (counted, not seen).
    emcys_over: u64,
    /// Per event: when the scenario thread fired it, and when the loop applied it.
    fired_us: Vec<Option<u64>>,
    applied_us: Vec<Option<u64>>,
    /// The end of what the fired events started.
    busy_until_us: u64,
    last_ramp_us: u64,
}

impl LiveTimeline {
    /// Take what the loop published: axis 0's ticks and EMCYs from the bus, the events it
    /// applied from the link.
    fn drain(&mut self, link: &LiveLink, obs: &crate::observe::Observation) {
        self.new_codes.clear();
        while let Some(snap) = obs.next(0, &mut self.cursor) {
            self.samples.push(snap.sample);
            // Every error the node raised, repeats included (the 0x1003 history saturates).
            for e in snap.emcys().filter(|e| e.raised) {
                self.emcys.push((snap.t_us, e.code));
                self.new_codes.push(e.code);
            }
            self.emcys_over += u64::from(snap.events_over);
        }
        self.drain_applied(link);
    }

    fn drain_applied(&mut self, link: &LiveLink) {
        while let Some((i, t)) = link.applied.pop() {
            if let Some(slot) = self.applied_us.get_mut(i as usize) {
                *slot = Some(t);
            }
        }
    }

    /// Fire the events due at `now` (the last sample's state and the new EMCYs decide the
    /// triggered ones): start their drivers, queue their injections and a mark.
    fn fire_due(&mut self, now: u64, inject: &impl Fn(Injection)) {
        let state = self
            .samples
            .last()
            .and_then(|x| Cia402State::from_statusword(x.statusword));
        let obs = Observation {
            state,
            new_emcy: &self.new_codes,
        };
        let due = self.timeline.due_indices(now, &obs).to_vec();
        for i in due {
            let ev = &self.timeline.events()[i];
            self.fired_us[i] = Some(now);
            self.busy_until_us = self.busy_until_us.max(now + event_length_us(&ev.action));
            match ev.action {
                Action::Set { key, value } => {
                    self.drivers.stop(key);
                    set_current(&mut self.current, key, value);
                }
                Action::Ramp { key, .. } | Action::Profile { key, .. } => {
                    let from = self
                        .current
                        .iter()
                        .find(|(k, _)| k.key == key.key)
                        .map_or(0.0, |(_, v)| *v);
                    self.drivers.start(&ev.action, now, from);
                }
                Action::Sensor { .. }
                | Action::Can { .. }
                | Action::CanRestore
                | Action::Ethercat { .. }
                | Action::EthercatRestore => {}
            }
            if let Some(inj) = Injection::of_action(&ev.action, now) {
                inject(inj);
            }
            inject(Injection::Mark { event: i as u32 });
        }
    }

    /// Ramps every 10 ms of simulated time, profiles every millisecond.
    fn drive_params(&mut self, now: u64, inject: &impl Fn(Injection)) {
        if self.drivers.is_empty()
            || !(self.drivers.has_profile() || now >= self.last_ramp_us + 10_000)
        {
            return;
        }
        self.last_ramp_us = now;
        self.drivers.values(now, &mut self.values);
        for &(key, v) in &self.values {
            set_current(&mut self.current, key, v);
            inject(Injection::Param {
                param: key.param,
                value_si: v * key.scale,
            });
        }
    }

    /// Why the run ends now, if it does.
    fn end_reason(
        &self,
        now: u64,
        end: LiveEnd,
        stop: &AtomicBool,
        s: &Scenario,
    ) -> Option<String> {
        if stop.load(Ordering::Relaxed) {
            return Some("stopped (Ctrl-C, SIGTERM or --duration of the run)".to_string());
        }
        match end {
            LiveEnd::At(t) if now >= t => Some(format!(
                "reached its end at {}",
                super::expect::seconds_text(t)
            )),
            LiveEnd::EventsDone if self.timeline.all_fired() => {
                let (settle, horizon) = settle_us(s);
                let t = (self.busy_until_us + settle).max(horizon);
                (now >= t).then(|| {
                    format!(
                        "every event fired and ran its course; ended at {}",
                        super::expect::seconds_text(now)
                    )
                })
            }
            _ => None,
        }
    }
}

/// The scenario thread: follow the loop's time until `end` (or `stop`), inject the timeline
/// through `link`, record axis 0 from the observation bus `obs` (from its next record), and
/// check the expectations.
pub fn run_timeline(
    s: &Scenario,
    cfg: &AxisConfig,
    drive_before_start: &AxisDrive,
    (link, obs): (&LiveLink, &crate::observe::Observation),
    stop: &AtomicBool,
    end: LiveEnd,
) -> LiveOutcome {
    let n_events = s.events.len();
    let mut lt = LiveTimeline {
        current: initial_values(cfg, drive_before_start),
        timeline: Timeline::new(s.events.clone()),
        drivers: Drivers::default(),
        values: Vec::new(),
        samples: Vec::new(),
        emcys: Vec::new(),
        new_codes: Vec::new(),
        cursor: Cursor::at_end(&obs.rings[0]),
        emcys_over: 0,
        fired_us: vec![None; n_events],
        applied_us: vec![None; n_events],
        busy_until_us: 0,
        last_ramp_us: 0,
    };
    let inject = |i: Injection| {
        // The loop drains the queue every tick; a full queue means the loop is stalled.
        while link.injections.push(i).is_err() && !stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(1));
        }
    };
    let end_reason = loop {
        std::thread::sleep(Duration::from_millis(1));
        let now = link.now_us.load(Ordering::Relaxed);
        lt.drain(link, obs);
        lt.fire_due(now, &inject);
        lt.drive_params(now, &inject);
        if let Some(why) = lt.end_reason(now, end, stop, s) {
            break why;
        }
    };
    // What the loop applied in the last moments (it keeps ticking until told to stop).
    std::thread::sleep(Duration::from_millis(5));
    lt.drain(link, obs);
    conclude(s, cfg, link, lt, end_reason)
}

/// After the run: the detector on the drive's samples, the event times (the loop's), the
/// record and the expectations.
fn conclude(
    s: &Scenario,
    cfg: &AxisConfig,
    link: &LiveLink,
    lt: LiveTimeline,
    end_reason: String,
) -> LiveOutcome {
    let LiveTimeline {
        timeline,
        samples,
        emcys,
        fired_us,
        applied_us,
        cursor,
        emcys_over,
        ..
    } = lt;
    let rotary = cfg.kind == AxisKind::Rotary;
    let detector = s.detector.enabled.then(|| {
        analyze(
            &AxisTrace::from_sample_log(&samples, SampleSource::Drive, rotary),
            &detector_config(s, cfg),
        )
    });
    let mut events = std::collections::HashMap::new();
    let mut fired = Vec::new();
    let mut not_fired = Vec::new();
    for (i, e) in timeline.events().iter().enumerate() {
        // The time the drive got it; the scenario thread's when the loop stopped first.
        match applied_us[i].or(fired_us[i]) {
            Some(t) => {
                if let Some(id) = &e.id {
                    events.insert(id.clone(), t);
                }
                fired.push((t, e.describe()));
            }
            None => not_fired.push((e.line, e.describe())),
        }
    }
    fired.sort_by_key(|f| f.0);
    let record = RunRecord {
        end_us: link.now_us.load(Ordering::Relaxed),
        samples,
        emcys,
        events,
        detector: detector.clone(),
        // Live, the motion belongs to the external controller: there is no program to fail.
        program_finished: true,
        program_error: None,
    };
    let mut expectations = check_all(&s.expectations, &record);
    // An expectation on an event that had not fired says so plainly.
    for x in &mut expectations {
        if !x.passed && x.detail.contains("never fired") {
            x.detail = format!(
                "{} before the run ended at {}",
                x.detail.replace("never fired", "had not fired"),
                super::expect::seconds_text(record.end_us)
            );
        }
    }
    LiveOutcome {
        record,
        detector,
        expectations,
        fired,
        not_fired,
        end_reason,
        samples_lost: cursor.lost,
        emcys_lost: emcys_over,
    }
}

fn set_current(current: &mut [(&'static ParamKey, f64)], key: &'static ParamKey, v: f64) {
    if let Some(slot) = current.iter_mut().find(|(k, _)| k.key == key.key) {
        slot.1 = v;
    }
}
