//! Scenarios live on a bus: the same timeline, injected into a running drive.
//!
//! Two threads share a [`LiveLink`] of preallocated lock-free queues:
//! - the loop thread calls [`LoopInjector::on_tick`] after every tick: it applies pending
//!   injections (parameter values, encoder faults, CAN fault rules) to the drive and the bus,
//!   and publishes the drive's actual values and new EMCYs. Nothing there allocates, locks or
//!   logs;
//! - the scenario thread ([`run_timeline`]) follows the loop's simulated time, decides which
//!   events are due, runs ramps and load profiles, and turns them into injections. It records
//!   what the drive reported and, at the end, runs the detector and checks the expectations.
//!
//! The motion comes from whatever controller is on the bus; the scenario's motion program is
//! not used live.

use super::expect::{check_all, ExpectResult, RunRecord};
use super::runner::{detector_config, rule, sensor};
use super::timeline::{Action, CanFault, Drivers, Observation, Timeline};
use super::units::ParamKey;
use super::Scenario;
use crate::analysis::detector::{analyze, AxisTrace, DetectorReport};
use crate::bus::fault::{FaultyBus, RuleId};
use crate::bus::CanBus;
use crate::master::{state_name, Sample};
use crate::presets::{AxisConfig, AxisKind};
use crate::runtime::axis_drive::AxisDrive;
use crate::runtime::trace::node_sample;
use crate::runtime::Runtime;
use crossbeam::queue::ArrayQueue;
use drive_protocol::{AxisParam, Drive, NodeEvent};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

/// One change the scenario thread asks the loop to make. `Copy`: queued without allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Injection {
    Param {
        param: AxisParam,
        value_si: f64,
    },
    Sensor {
        kind: super::file::SensorKind,
        counts: i64,
    },
    Can {
        fault: CanFault,
        until_us: Option<u64>,
    },
    CanRestore,
}

/// The queues between the loop and the scenario thread, sized once.
pub struct LiveLink {
    pub injections: ArrayQueue<Injection>,
    /// One sample per tick: the drive's actual values as a master would read them.
    pub samples: ArrayQueue<Sample>,
    /// (simulated time us, EMCY code).
    pub emcys: ArrayQueue<(u64, u16)>,
    /// The loop's simulated time, us.
    pub now_us: AtomicU64,
    /// Samples lost because the scenario thread fell behind.
    pub samples_lost: AtomicU64,
}

impl LiveLink {
    pub fn new() -> Self {
        Self {
            injections: ArrayQueue::new(1024),
            samples: ArrayQueue::new(1 << 16),
            emcys: ArrayQueue::new(256),
            now_us: AtomicU64::new(0),
            samples_lost: AtomicU64::new(0),
        }
    }
}

impl Default for LiveLink {
    fn default() -> Self {
        Self::new()
    }
}

/// The loop thread's half: owns the CAN rules in force; drains axis 0's node events.
pub struct LoopInjector {
    master_id: u8,
    rules: heapless::Vec<(RuleId, Option<u64>), 16>,
}

impl LoopInjector {
    /// `master_id`: the node ID whose heartbeat a heartbeat-loss fault drops.
    pub fn new(master_id: u8) -> Self {
        Self {
            master_id,
            rules: heapless::Vec::new(),
        }
    }

    /// After every tick: apply injections to axis 0 and publish its actual values.
    pub fn on_tick<B: CanBus>(
        &mut self,
        link: &LiveLink,
        rt: &mut Runtime<FaultyBus<B>, AxisDrive>,
    ) {
        let now = rt.sim_time_us;
        link.now_us.store(now, Ordering::Relaxed);
        while let Some(inj) = link.injections.pop() {
            let drive = &mut rt.axes[0].drive;
            match inj {
                // An out-of-range value is refused by the drive and changes nothing; the
                // scenario file's own validation keeps values in range.
                Injection::Param { param, value_si } => {
                    let _ = drive.set_param(param, value_si);
                }
                Injection::Sensor { kind, counts } => sensor(drive, kind, counts),
                Injection::Can { fault, until_us } => {
                    let id = rt.bus.add_rule(rule(fault, self.master_id));
                    if self.rules.push((id, until_us)).is_err() {
                        rt.bus.remove_rule(id);
                    }
                }
                Injection::CanRestore => {
                    rt.bus.clear_rules();
                    self.rules.clear();
                }
            }
        }
        let mut k = 0;
        while k < self.rules.len() {
            if self.rules[k].1.is_some_and(|end| now >= end) {
                rt.bus.remove_rule(self.rules[k].0);
                self.rules.swap_remove(k);
            } else {
                k += 1;
            }
        }
        let node = &mut rt.axes[0].node;
        let sample = node_sample(node, now);
        if link.samples.push(sample).is_err() {
            link.samples_lost.fetch_add(1, Ordering::Relaxed);
        }
        // Every error the node raises, repeats included (the 0x1003 history saturates at 8).
        while let Some(e) = node.poll_event() {
            if let NodeEvent::EmcyRaised { code } = e {
                let _ = link.emcys.push((now, code));
            }
        }
    }
}

/// What a live scenario run found.
#[derive(Debug)]
pub struct LiveOutcome {
    pub record: RunRecord,
    pub detector: Option<DetectorReport>,
    pub expectations: Vec<ExpectResult>,
    pub fired: Vec<(u64, String)>,
    pub samples_lost: u64,
}

impl LiveOutcome {
    pub fn passed(&self) -> bool {
        self.expectations.iter().all(|e| e.passed)
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
        .filter_map(|k| drive.param(k.param).ok().map(|v| (k, v / k.scale)))
        .collect()
}

/// The scenario thread: follow the loop's time until the scenario's duration (or `stop`),
/// inject the timeline, record, and check the expectations.
pub fn run_timeline(
    s: &Scenario,
    cfg: &AxisConfig,
    drive_before_start: &AxisDrive,
    link: &LiveLink,
    stop: &AtomicBool,
) -> LiveOutcome {
    let mut current = initial_values(cfg, drive_before_start);
    let mut timeline = Timeline::new(s.events.clone());
    let mut drivers = Drivers::default();
    let mut values = Vec::new();
    let mut samples: Vec<Sample> = Vec::new();
    let mut emcys: Vec<(u64, u16)> = Vec::new();
    let mut new_codes: Vec<u16> = Vec::new();
    let mut fired = Vec::new();
    let end_us = s.run.duration_us.unwrap_or_else(|| s.program_duration_us());
    let mut last_ramp_us = 0u64;
    let inject = |i: Injection| {
        // The loop drains the queue every tick; a full queue means the loop is stalled.
        while link.injections.push(i).is_err() && !stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(1));
        }
    };
    loop {
        std::thread::sleep(Duration::from_millis(1));
        let now = link.now_us.load(Ordering::Relaxed);
        while let Some(smp) = link.samples.pop() {
            samples.push(smp);
        }
        new_codes.clear();
        while let Some((t, code)) = link.emcys.pop() {
            emcys.push((t, code));
            new_codes.push(code);
        }
        let state = samples.last().map(|x| state_name(x.statusword));
        let obs = Observation {
            state,
            new_emcy: &new_codes,
        };
        let due: Vec<_> = timeline.due(now, &obs).cloned().collect();
        for ev in due {
            fired.push((now, ev.describe()));
            match ev.action {
                Action::Set { key, value } => {
                    drivers.stop(key);
                    set_current(&mut current, key, value);
                    inject(Injection::Param {
                        param: key.param,
                        value_si: value * key.scale,
                    });
                }
                Action::Ramp { key, .. } | Action::Profile { key, .. } => {
                    let from = current
                        .iter()
                        .find(|(k, _)| k.key == key.key)
                        .map_or(0.0, |(_, v)| *v);
                    drivers.start(&ev.action, now, from);
                }
                Action::Sensor { kind, counts } => inject(Injection::Sensor { kind, counts }),
                Action::Can { fault, over_us } => inject(Injection::Can {
                    fault,
                    until_us: over_us.map(|o| now + o),
                }),
                Action::CanRestore => inject(Injection::CanRestore),
            }
        }
        // Ramps every 10 ms of simulated time, profiles every millisecond.
        if !drivers.is_empty() && (drivers.has_profile() || now >= last_ramp_us + 10_000) {
            last_ramp_us = now;
            drivers.values(now, &mut values);
            for &(key, v) in &values {
                set_current(&mut current, key, v);
                inject(Injection::Param {
                    param: key.param,
                    value_si: v * key.scale,
                });
            }
        }
        if now >= end_us || stop.load(Ordering::Relaxed) {
            break;
        }
    }
    let rotary = cfg.kind == AxisKind::Rotary;
    let detector = s.detector.enabled.then(|| {
        analyze(
            &AxisTrace::from_drive_samples(&samples, rotary),
            &detector_config(s, cfg),
        )
    });
    let mut events = std::collections::HashMap::new();
    for (i, e) in timeline.events().iter().enumerate() {
        if let (Some(id), Some(t)) = (&e.id, timeline.fired_at(i)) {
            events.insert(id.clone(), t);
        }
    }
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
    let expectations = check_all(&s.expectations, &record);
    LiveOutcome {
        record,
        detector,
        expectations,
        fired,
        samples_lost: link.samples_lost.load(Ordering::Relaxed),
    }
}

fn set_current(current: &mut [(&'static ParamKey, f64)], key: &'static ParamKey, v: f64) {
    if let Some(slot) = current.iter_mut().find(|(k, _)| k.key == key.key) {
        slot.1 = v;
    }
}
