//! The timeline: events at scenario times or on conditions, and the parameter drivers (ramps,
//! load profiles) they start. Independent of how the simulation is stepped: the offline runner,
//! a live loop on a real bus, or a test can drive it. The caller supplies the scenario time
//! and what it observed ([`Observation`]); the timeline tells which events are due.

use super::file::{ProfileShape, SensorKind};
use super::units::ParamKey;
use drive_protocol::Cia402State;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

/// When an event fires.
#[derive(Debug, Clone, PartialEq)]
pub enum Trigger {
    /// At this scenario time, us.
    At(u64),
    /// `delay_us` after the drive is first seen in this CiA 402 state (master's decoding).
    OnState { state: Cia402State, delay_us: u64 },
    /// `delay_us` after this EMCY code is first seen.
    OnEmcy { code: u16, delay_us: u64 },
}

/// A CAN fault (applied by wrapping the drive's bus in `bus::fault::FaultyBus`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum CanFault {
    Drop {
        share: f64,
        cob_id: Option<u32>,
    },
    Delay {
        share: f64,
        ticks: u32,
        cob_id: Option<u32>,
    },
    /// Every SYNC frame lost.
    SyncLoss,
    /// Every heartbeat of the master lost.
    HeartbeatLoss,
}

/// What an event does.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Set a parameter (file units) at once.
    Set { key: &'static ParamKey, value: f64 },
    /// Ramp a parameter linearly to `to` over `over_us` (from its value when the event fires,
    /// or from `from`).
    Ramp {
        key: &'static ParamKey,
        from: Option<f64>,
        to: f64,
        over_us: u64,
    },
    /// A periodic profile (cutting force): mean + amplitude * shape(f t), for `over_us` (or for
    /// ever), then back to the value the parameter had before.
    Profile {
        key: &'static ParamKey,
        shape: ProfileShape,
        mean: f64,
        amplitude: f64,
        frequency_hz: f64,
        over_us: Option<u64>,
    },
    /// Encoder fault: signal loss, count glitch, or restore.
    Sensor { kind: SensorKind, counts: i64 },
    /// CAN fault for `over_us` (or until a `Restore`).
    Can {
        fault: CanFault,
        over_us: Option<u64>,
    },
    /// Remove every CAN fault.
    CanRestore,
    /// EtherCAT fault for `over_us` (or until a restore); `run --ethercat` only.
    Ethercat {
        fault: crate::bus::ethercat::EcatFault,
        over_us: Option<u64>,
    },
    /// Remove every EtherCAT wire fault.
    EthercatRestore,
}

impl Action {
    /// The action as a scenario file's `[[event]]` keys, one `key = value` line each, which the
    /// file reader reads back into this action (the live panel's saved session writes its
    /// injections so).
    pub fn file_lines(&self) -> String {
        use super::file::{ProfileShape as Shape, SensorKind as S};
        use crate::bus::ethercat::EcatFault as F;
        let text = |s: &str| format!("\"{s}\"");
        let time = |us: u64| format!("\"{us} us\"");
        // Debug of a finite f64 is a TOML float (0.05, 1.0, 1e-7).
        let num = |x: f64| format!("{x:?}");
        let mut kv: Vec<(&str, String)> = Vec::new();
        match self {
            Action::Set { key, value } => {
                kv.push(("set", text(key.key)));
                kv.push(("value", num(*value)));
            }
            Action::Ramp {
                key,
                from,
                to,
                over_us,
            } => {
                kv.push(("ramp", text(key.key)));
                kv.extend(from.map(|f| ("from", num(f))));
                kv.push(("to", num(*to)));
                kv.push(("over", time(*over_us)));
            }
            Action::Profile {
                key,
                shape,
                mean,
                amplitude,
                frequency_hz,
                over_us,
            } => {
                kv.push(("profile", text(key.key)));
                let shape = match shape {
                    Shape::Sine => "sine",
                    Shape::Teeth => "teeth",
                };
                kv.push(("shape", text(shape)));
                kv.push(("mean", num(*mean)));
                kv.push(("amplitude", num(*amplitude)));
                kv.push(("frequency_hz", num(*frequency_hz)));
                kv.extend(over_us.map(|o| ("over", time(o))));
            }
            Action::Sensor { kind, counts } => {
                let (name, glitch) = match kind {
                    S::MotorEncoderLoss => ("motor_encoder_loss", false),
                    S::DirectEncoderLoss => ("direct_encoder_loss", false),
                    S::MotorEncoderGlitch => ("motor_encoder_glitch", true),
                    S::DirectEncoderGlitch => ("direct_encoder_glitch", true),
                    S::Restore => ("restore", false),
                };
                kv.push(("sensor", text(name)));
                if glitch {
                    kv.push(("counts", counts.to_string()));
                }
            }
            Action::Can { fault, over_us } => {
                let cob = |c: &Option<u32>| c.map(|c| ("cob_id", text(&format!("{c:#05X}"))));
                match fault {
                    CanFault::Drop { share, cob_id } => {
                        kv.push(("can", text("drop")));
                        kv.push(("share", num(*share)));
                        kv.extend(cob(cob_id));
                    }
                    CanFault::Delay {
                        share,
                        ticks,
                        cob_id,
                    } => {
                        kv.push(("can", text("delay")));
                        kv.push(("share", num(*share)));
                        kv.push(("ticks", ticks.to_string()));
                        kv.extend(cob(cob_id));
                    }
                    CanFault::SyncLoss => kv.push(("can", text("sync_loss"))),
                    CanFault::HeartbeatLoss => kv.push(("can", text("heartbeat_loss"))),
                }
                kv.extend(over_us.map(|o| ("over", time(o))));
            }
            Action::CanRestore => kv.push(("can", text("restore"))),
            Action::Ethercat { fault, over_us } => {
                let frames_or_share = |kv: &mut Vec<(&str, String)>, frames: u32, share: f64| {
                    if frames > 0 {
                        kv.push(("frames", frames.to_string()));
                    } else {
                        kv.push(("share", num(share)));
                    }
                };
                match *fault {
                    F::Lost { frames, share } => {
                        kv.push(("ethercat", text("lost")));
                        frames_or_share(&mut kv, frames, share);
                    }
                    F::Corrupt { frames, share } => {
                        kv.push(("ethercat", text("corrupt")));
                        frames_or_share(&mut kv, frames, share);
                    }
                    F::Late { hold_us } => {
                        kv.push(("ethercat", text("late")));
                        kv.push(("hold", time(hold_us)));
                    }
                    F::LinkDown => kv.push(("ethercat", text("link_down"))),
                    F::BadWkc { share } => {
                        kv.push(("ethercat", text("bad_wkc")));
                        kv.push(("share", num(share)));
                    }
                    F::OutOfOp { al_code } => {
                        kv.push(("ethercat", text("out_of_op")));
                        kv.push(("al_code", text(&format!("{al_code:#06X}"))));
                    }
                }
                kv.extend(over_us.map(|o| ("over", time(o))));
            }
            Action::EthercatRestore => kv.push(("ethercat", text("restore"))),
        }
        kv.iter().map(|(k, v)| format!("{k} = {v}\n")).collect()
    }

    /// A CAN fault (the CAN bus's), or an EtherCAT one (the EtherCAT port's).
    pub fn bus(&self) -> Option<&'static str> {
        match self {
            Action::Can { .. } | Action::CanRestore => Some("can"),
            Action::Ethercat { .. } | Action::EthercatRestore => Some("ethercat"),
            _ => None,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    pub id: Option<String>,
    pub trigger: Trigger,
    pub action: Action,
    /// Line in the scenario file (for messages).
    pub line: usize,
}

impl Event {
    /// A short human description.
    pub fn describe(&self) -> String {
        match &self.action {
            Action::Set { key, value } => format!("set {} = {value}", key.key),
            Action::Ramp {
                key,
                from,
                to,
                over_us,
            } => format!(
                "ramp {} {}-> {to} over {:.0} s",
                key.key,
                from.map(|f| format!("{f} ")).unwrap_or_default(),
                *over_us as f64 * 1e-6
            ),
            Action::Profile {
                key,
                mean,
                amplitude,
                frequency_hz,
                ..
            } => format!(
                "profile {} = {mean} +- {amplitude} at {frequency_hz} Hz",
                key.key
            ),
            Action::Sensor { kind, counts } => format!("sensor: {}", sensor_text(*kind, *counts)),
            Action::Can { fault, over_us } => format!(
                "CAN: {}{}",
                can_text(fault),
                over_us.map_or(String::new(), |o| format!(
                    " for {}",
                    super::expect::seconds_text(o)
                ))
            ),
            Action::CanRestore => "CAN: faults removed".into(),
            Action::Ethercat { fault, over_us } => format!(
                "{}{}",
                fault.describe(),
                over_us.map_or(String::new(), |o| format!(
                    " for {}",
                    super::expect::seconds_text(o)
                ))
            ),
            Action::EthercatRestore => "EtherCAT: faults removed".into(),
        }
    }
}

fn sensor_text(kind: SensorKind, counts: i64) -> String {
    match kind {
        SensorKind::MotorEncoderLoss => "motor encoder signal lost".into(),
        SensorKind::DirectEncoderLoss => "direct encoder signal lost".into(),
        SensorKind::MotorEncoderGlitch => format!("motor encoder jumps {counts} counts"),
        SensorKind::DirectEncoderGlitch => format!("direct encoder jumps {counts} counts"),
        SensorKind::Restore => "encoder signals restored".into(),
    }
}

fn can_text(fault: &CanFault) -> String {
    let only = |c: &Option<u32>| c.map_or(String::new(), |c| format!(" with COB-ID {c:#05X}"));
    match fault {
        CanFault::Drop { share, cob_id } => {
            format!("{} % of the frames{} dropped", share * 100.0, only(cob_id))
        }
        CanFault::Delay {
            share,
            ticks,
            cob_id,
        } => format!(
            "{} % of the frames{} delayed by {ticks} ticks",
            share * 100.0,
            only(cob_id)
        ),
        CanFault::SyncLoss => "SYNC lost (no SYNC reaches the drive)".into(),
        CanFault::HeartbeatLoss => "master heartbeat lost (no heartbeat reaches the drive)".into(),
    }
}

/// What the driving loop saw, for conditional triggers.
#[derive(Debug, Clone, Copy, Default)]
pub struct Observation<'a> {
    /// CiA 402 state as the master decodes it from the statusword.
    pub state: Option<Cia402State>,
    /// EMCY codes received since the previous call.
    pub new_emcy: &'a [u16],
}

/// Events and their firing times.
///
/// A step costs O(log n) for n events (plus O(k log k) for the k events it fires): events
/// wait in a queue ordered by due time (timed ones from the start, conditional ones once
/// their condition arms them), and conditional events wait for their condition in lists by
/// CiA 402 state or EMCY code, which the first matching observation drains.
#[derive(Debug, Clone)]
pub struct Timeline {
    events: Vec<Event>,
    /// Scenario time at which each condition was met (armed), us.
    armed: Vec<Option<u64>>,
    fired: Vec<Option<u64>>,
    fired_count: usize,
    /// Events not yet fired whose due time is known: (due us, index), earliest first.
    queue: BinaryHeap<Reverse<(u64, usize)>>,
    /// Conditional events not yet armed, by the state that arms them.
    on_state: HashMap<Cia402State, Vec<usize>>,
    /// Conditional events not yet armed, by the EMCY code that arms them.
    on_emcy: HashMap<u16, Vec<usize>>,
    due: Vec<usize>,
}

impl Timeline {
    pub fn new(events: Vec<Event>) -> Self {
        let n = events.len();
        let mut queue = Vec::new();
        let mut on_state: HashMap<Cia402State, Vec<usize>> = HashMap::new();
        let mut on_emcy: HashMap<u16, Vec<usize>> = HashMap::new();
        for (i, e) in events.iter().enumerate() {
            match e.trigger {
                Trigger::At(t) => queue.push(Reverse((t, i))),
                Trigger::OnState { state, .. } => on_state.entry(state).or_default().push(i),
                Trigger::OnEmcy { code, .. } => on_emcy.entry(code).or_default().push(i),
            }
        }
        Self {
            events,
            armed: vec![None; n],
            fired: vec![None; n],
            fired_count: 0,
            queue: BinaryHeap::from(queue),
            on_state,
            on_emcy,
            due: Vec::with_capacity(n.min(1024)),
        }
    }

    pub fn events(&self) -> &[Event] {
        &self.events
    }

    /// Scenario time at which event `i` fired.
    pub fn fired_at(&self, i: usize) -> Option<u64> {
        self.fired[i]
    }

    /// Firing time of the event with this id.
    pub fn fired_at_id(&self, id: &str) -> Option<u64> {
        let i = self
            .events
            .iter()
            .position(|e| e.id.as_deref() == Some(id))?;
        self.fired[i]
    }

    /// Whether every event has fired.
    pub fn all_fired(&self) -> bool {
        self.fired_count == self.events.len()
    }

    /// The events that have not fired, as indices into [`Timeline::events`], in file order.
    pub fn not_fired(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.events.len()).filter(|&i| self.fired[i].is_none())
    }

    /// The earliest scenario time at which something is scheduled and not yet fired (armed
    /// conditions included), for loops that skip time.
    pub fn next_due_us(&self) -> Option<u64> {
        self.queue.peek().map(|Reverse((t, _))| *t)
    }

    /// As [`Timeline::due`], as indices into [`Timeline::events`].
    pub fn due_indices(&mut self, now_us: u64, obs: &Observation) -> &[usize] {
        let _ = self.due(now_us, obs).count();
        &self.due
    }

    /// Arm the conditional events in `list` at `now_us`: each is due its delay later.
    fn arm(&mut self, list: Vec<usize>, now_us: u64) {
        for i in list {
            let delay_us = match self.events[i].trigger {
                Trigger::OnState { delay_us, .. } | Trigger::OnEmcy { delay_us, .. } => delay_us,
                Trigger::At(_) => 0,
            };
            self.armed[i] = Some(now_us);
            self.queue
                .push(Reverse((now_us.saturating_add(delay_us), i)));
        }
    }

    /// Mark and return the events due at `now_us` (each fires once), in file order. A
    /// condition arms every event waiting for it at the first observation that meets it.
    pub fn due(&mut self, now_us: u64, obs: &Observation) -> impl Iterator<Item = &Event> + '_ {
        self.due.clear();
        if let Some(list) = obs.state.and_then(|st| self.on_state.remove(&st)) {
            self.arm(list, now_us);
        }
        for code in obs.new_emcy {
            if let Some(list) = self.on_emcy.remove(code) {
                self.arm(list, now_us);
            }
        }
        while let Some(&Reverse((t, i))) = self.queue.peek() {
            if t > now_us {
                break;
            }
            self.queue.pop();
            self.fired[i] = Some(now_us);
            self.fired_count += 1;
            self.due.push(i);
        }
        self.due.sort_unstable();
        self.due.iter().map(|&i| &self.events[i])
    }
}

/// Why a run that ended at `end_us` did not finish, for people: the events (file line,
/// description) that had not fired, the first ten of them named. `None` when every event
/// fired.
pub fn not_fired_text(not_fired: &[(usize, String)], end_us: u64) -> Option<String> {
    const NAMED: usize = 10;
    if not_fired.is_empty() {
        return None;
    }
    let mut which: Vec<String> = not_fired
        .iter()
        .take(NAMED)
        .map(|(line, what)| format!("line {line}: {what}"))
        .collect();
    if not_fired.len() > NAMED {
        which.push(format!("and {} more", not_fired.len() - NAMED));
    }
    let n = not_fired.len();
    Some(format!(
        "the scenario did not finish: {n} event{} had not fired when the run ended at {} ({})",
        if n == 1 { "" } else { "s" },
        super::expect::seconds_text(end_us),
        which.join("; ")
    ))
}

/// A running parameter driver.
#[derive(Debug, Clone, PartialEq)]
struct Driver {
    key: &'static ParamKey,
    start_us: u64,
    kind: DriverKind,
}

#[derive(Debug, Clone, PartialEq)]
enum DriverKind {
    Ramp {
        from: f64,
        to: f64,
        over_us: u64,
    },
    Profile {
        shape: ProfileShape,
        mean: f64,
        amplitude: f64,
        frequency_hz: f64,
        end_us: Option<u64>,
        restore: f64,
    },
}

/// Parameter ramps and profiles in force. Values are in file units ([`ParamKey`]); the
/// caller converts with `key.scale` and applies them.
#[derive(Debug, Clone, Default)]
pub struct Drivers {
    active: Vec<Driver>,
}

impl Drivers {
    /// Start the driver of a `Ramp` or `Profile` action fired at `now_us`; `current` is the
    /// parameter's value now (file units). A new driver replaces one on the same parameter.
    /// Other actions are ignored.
    pub fn start(&mut self, action: &Action, now_us: u64, current: f64) {
        let (key, kind) = match *action {
            Action::Ramp {
                key,
                from,
                to,
                over_us,
            } => (
                key,
                DriverKind::Ramp {
                    from: from.unwrap_or(current),
                    to,
                    over_us,
                },
            ),
            Action::Profile {
                key,
                shape,
                mean,
                amplitude,
                frequency_hz,
                over_us,
            } => (
                key,
                DriverKind::Profile {
                    shape,
                    mean,
                    amplitude,
                    frequency_hz,
                    end_us: over_us.map(|o| now_us + o),
                    restore: current,
                },
            ),
            _ => return,
        };
        self.stop(key);
        self.active.push(Driver {
            key,
            start_us: now_us,
            kind,
        });
    }

    /// Stop driving a parameter (a `Set` on it does this).
    pub fn stop(&mut self, key: &'static ParamKey) {
        self.active.retain(|d| d.key.param != key.param);
    }

    pub fn is_empty(&self) -> bool {
        self.active.is_empty()
    }

    /// Whether any driver changes faster than a ramp (profiles need every tick).
    pub fn has_profile(&self) -> bool {
        self.active
            .iter()
            .any(|d| matches!(d.kind, DriverKind::Profile { .. }))
    }

    /// The value of every driven parameter at `now_us`; finished drivers give their final
    /// value once more and are then dropped.
    pub fn values(&mut self, now_us: u64, out: &mut Vec<(&'static ParamKey, f64)>) {
        out.clear();
        self.active.retain(|d| {
            let t = now_us.saturating_sub(d.start_us);
            let (v, done) = match d.kind {
                DriverKind::Ramp { from, to, over_us } => {
                    if over_us == 0 || t >= over_us {
                        (to, true)
                    } else {
                        (from + (to - from) * t as f64 / over_us as f64, false)
                    }
                }
                DriverKind::Profile {
                    shape,
                    mean,
                    amplitude,
                    frequency_hz,
                    end_us,
                    restore,
                } => {
                    if end_us.is_some_and(|e| now_us >= e) {
                        (restore, true)
                    } else {
                        let ph = 2.0 * std::f64::consts::PI * frequency_hz * t as f64 * 1e-6;
                        let s = match shape {
                            ProfileShape::Sine => ph.sin(),
                            ProfileShape::Teeth => ph.sin().max(0.0),
                        };
                        (mean + amplitude * s, false)
                    }
                }
            };
            out.push((d.key, v));
            !done
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::units::param_key;

    fn ev(trigger: Trigger, action: Action) -> Event {
        Event {
            id: None,
            trigger,
            action,
            line: 1,
        }
    }

    #[test]
    fn timed_and_conditional_events_fire_once() {
        let key = param_key("backlash_mm").unwrap();
        let mut tl = Timeline::new(vec![
            ev(Trigger::At(1000), Action::Set { key, value: 0.01 }),
            ev(
                Trigger::OnState {
                    state: Cia402State::OperationEnabled,
                    delay_us: 500,
                },
                Action::CanRestore,
            ),
            ev(
                Trigger::OnEmcy {
                    code: 0x7300,
                    delay_us: 0,
                },
                Action::CanRestore,
            ),
        ]);
        let none = Observation::default();
        assert_eq!(tl.due(0, &none).count(), 0);
        assert_eq!(tl.due(1000, &none).count(), 1);
        assert_eq!(tl.due(2000, &none).count(), 0);
        let enabled = Observation {
            state: Some(Cia402State::OperationEnabled),
            new_emcy: &[],
        };
        assert_eq!(tl.due(3000, &enabled).count(), 0);
        assert_eq!(tl.next_due_us(), Some(3500));
        assert_eq!(tl.due(3499, &none).count(), 0);
        assert_eq!(tl.due(3500, &none).count(), 1);
        let emcy = Observation {
            state: None,
            new_emcy: &[0x7300],
        };
        assert_eq!(tl.due(4000, &emcy).count(), 1);
        assert!(tl.all_fired());
        assert_eq!(tl.fired_at(1), Some(3500));
    }

    /// The timeline as it was (every event looked at every step, O(n) per step): the
    /// reference the indexed one must agree with.
    struct Naive {
        events: Vec<Event>,
        armed: Vec<Option<u64>>,
        fired: Vec<Option<u64>>,
    }

    impl Naive {
        fn due(&mut self, now_us: u64, obs: &Observation) -> Vec<usize> {
            let mut due = Vec::new();
            for i in 0..self.events.len() {
                if self.fired[i].is_some() {
                    continue;
                }
                let at = match self.events[i].trigger {
                    Trigger::At(t) => Some(t),
                    Trigger::OnState { state, delay_us } => {
                        if self.armed[i].is_none() && obs.state == Some(state) {
                            self.armed[i] = Some(now_us);
                        }
                        self.armed[i].map(|a| a.saturating_add(delay_us))
                    }
                    Trigger::OnEmcy { code, delay_us } => {
                        if self.armed[i].is_none() && obs.new_emcy.contains(&code) {
                            self.armed[i] = Some(now_us);
                        }
                        self.armed[i].map(|a| a.saturating_add(delay_us))
                    }
                };
                if at.is_some_and(|t| t <= now_us) {
                    self.fired[i] = Some(now_us);
                    due.push(i);
                }
            }
            due
        }

        fn next_due_us(&self) -> Option<u64> {
            (0..self.events.len())
                .filter(|&i| self.fired[i].is_none())
                .filter_map(|i| match self.events[i].trigger {
                    Trigger::At(t) => Some(t),
                    Trigger::OnState { delay_us, .. } | Trigger::OnEmcy { delay_us, .. } => {
                        self.armed[i].map(|a| a.saturating_add(delay_us))
                    }
                })
                .min()
        }
    }

    const STATES: [Cia402State; 3] = [
        Cia402State::SwitchOnDisabled,
        Cia402State::OperationEnabled,
        Cia402State::Fault,
    ];

    fn trigger_strategy() -> impl proptest::strategy::Strategy<Value = Trigger> {
        use proptest::prelude::*;
        prop_oneof![
            3 => (0u64..50).prop_map(|t| Trigger::At(t * 100)),
            1 => (0usize..3, 0u64..20).prop_map(|(s, d)| Trigger::OnState {
                state: STATES[s],
                delay_us: d * 100
            }),
            1 => (0u16..3, 0u64..20).prop_map(|(c, d)| Trigger::OnEmcy {
                code: 0x8100 + c,
                delay_us: d * 100
            }),
        ]
    }

    proptest::proptest! {
        /// Same events fired at the same steps, in file order, and the same next due time,
        /// as the naive timeline, over random triggers (many at one time), observations and
        /// steps (some skipping time, as the fast-forward does).
        #[test]
        fn the_indexed_timeline_fires_as_the_naive_one(
            triggers in proptest::collection::vec(trigger_strategy(), 0..40),
            steps in proptest::collection::vec(
                (0u64..700, proptest::option::of(0usize..3), proptest::collection::vec(0u16..4, 0..3)),
                1..60,
            ),
        ) {
            let events: Vec<Event> = triggers
                .into_iter()
                .map(|t| ev(t, Action::CanRestore))
                .collect();
            let mut fast = Timeline::new(events.clone());
            let n = events.len();
            let mut naive = Naive { events, armed: vec![None; n], fired: vec![None; n] };
            let mut now = 0u64;
            for (dt, state, codes) in steps {
                now += dt;
                let codes: Vec<u16> = codes.iter().map(|c| 0x8100 + c).collect();
                let obs = Observation { state: state.map(|s| STATES[s]), new_emcy: &codes };
                let want = naive.due(now, &obs);
                let got = fast.due_indices(now, &obs).to_vec();
                proptest::prop_assert_eq!(&got, &want, "at {}", now);
                proptest::prop_assert_eq!(fast.next_due_us(), naive.next_due_us());
                proptest::prop_assert_eq!(fast.all_fired(), naive.fired.iter().all(Option::is_some));
            }
            for i in 0..n {
                proptest::prop_assert_eq!(fast.fired_at(i), naive.fired[i]);
            }
        }
    }

    #[test]
    fn ramps_interpolate_and_profiles_restore() {
        let key = param_key("backlash_mm").unwrap();
        let load = param_key("load_force_n").unwrap();
        let mut d = Drivers::default();
        let ramp = Action::Ramp {
            key,
            from: None,
            to: 0.07,
            over_us: 3_600_000_000,
        };
        d.start(&ramp, 0, 0.0);
        let mut out = Vec::new();
        d.values(1_800_000_000, &mut out);
        assert!((out[0].1 - 0.035).abs() < 1e-12);
        d.values(4_000_000_000, &mut out);
        assert_eq!(out[0].1, 0.07);
        d.values(5_000_000_000, &mut out);
        assert!(out.is_empty());
        let prof = Action::Profile {
            key: load,
            shape: ProfileShape::Teeth,
            mean: 100.0,
            amplitude: 50.0,
            frequency_hz: 10.0,
            over_us: Some(1_000_000),
        };
        d.start(&prof, 0, 7.0);
        d.values(25_000, &mut out);
        assert!((out[0].1 - 150.0).abs() < 1e-9);
        d.values(75_000, &mut out);
        assert!((out[0].1 - 100.0).abs() < 1e-9);
        d.values(1_000_000, &mut out);
        assert_eq!(out[0].1, 7.0);
        assert!(d.is_empty());
    }
}
