//! The one place a scenario's action reaches a running drive and its bus.
//!
//! An event's action becomes an [`Injection`] ([`Injection::of_action`]; ramps and load
//! profiles become `Param` injections tick by tick through their drivers), and an
//! [`Injector`] applies it to the drive and the fault-injecting bus and keeps the CAN fault
//! rules in force until they run out. The offline runner applies injections directly, the
//! live loop ([`super::live::LoopInjector`]) applies the ones the scenario thread queued. No
//! allocation: the rules in force live in a fixed-size list.

use super::file::SensorKind;
use super::timeline::{Action, CanFault};
use super::units::ParamKey;
use crate::bus::fault::{FaultRule, FaultyBus, RuleId};
use crate::bus::CanBus;
use crate::drive::axis_drive::{AxisDrive, Encoder};
use crate::drive::{AxisParam, ParamError};

/// One change a scenario makes to the drive or the bus. `Copy`: queued without allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Injection {
    Param {
        param: AxisParam,
        value_si: f64,
    },
    Sensor {
        kind: SensorKind,
        counts: i64,
    },
    Can {
        fault: CanFault,
        until_us: Option<u64>,
    },
    CanRestore,
    /// An EtherCAT fault for `over_us` from when the loop applies it (on the frames' clock).
    Ecat {
        fault: crate::bus::ethercat::EcatFault,
        over_us: Option<u64>,
    },
    EcatRestore,
    /// The injections of event `event` (index in the timeline) are in: the loop answers with
    /// the simulated time it applied them, so the reported event time is the bus's.
    Mark {
        event: u32,
    },
}

impl Injection {
    /// What an event's `action` injects when it fires at `now_us`; `None` for a ramp or a load
    /// profile, whose driver injects `Param` values from then on.
    pub fn of_action(action: &Action, now_us: u64) -> Option<Self> {
        match *action {
            Action::Set { key, value } => Some(Self::Param {
                param: key.param,
                value_si: value * key.scale,
            }),
            Action::Ramp { .. } | Action::Profile { .. } => None,
            Action::Sensor { kind, counts } => Some(Self::Sensor { kind, counts }),
            Action::Can { fault, over_us } => Some(Self::Can {
                fault,
                until_us: over_us.map(|o| now_us + o),
            }),
            Action::CanRestore => Some(Self::CanRestore),
            Action::Ethercat { fault, over_us } => Some(Self::Ecat { fault, over_us }),
            Action::EthercatRestore => Some(Self::EcatRestore),
        }
    }
}

/// Applies injections to axis 0's drive and the bus, and owns the CAN rules in force (at most
/// `N`: one more is removed again at once, so the bus never holds a rule nobody will end).
pub struct Injector<const N: usize> {
    master_id: u8,
    rules: heapless::Vec<(RuleId, Option<u64>), N>,
}

impl<const N: usize> Injector<N> {
    /// `master_id`: the node ID whose heartbeat a heartbeat-loss fault drops.
    pub fn new(master_id: u8) -> Self {
        Self {
            master_id,
            rules: heapless::Vec::new(),
        }
    }

    /// The node ID whose heartbeat a heartbeat-loss fault drops from now on (rules already in
    /// force keep theirs).
    pub fn set_master_id(&mut self, master_id: u8) {
        self.master_id = master_id;
    }

    /// Apply one injection. A value the drive refuses changes nothing and is returned as the
    /// error; `Mark` is the caller's business and does nothing here.
    pub fn apply<B: CanBus>(
        &mut self,
        inj: Injection,
        drive: &mut AxisDrive,
        bus: &mut FaultyBus<B>,
    ) -> Result<(), ParamError> {
        match inj {
            Injection::Param { param, value_si } => drive.set_param(param, value_si)?,
            Injection::Sensor { kind, counts } => sensor(drive, kind, counts),
            Injection::Can { fault, until_us } => {
                let id = bus.add_rule(rule(fault, self.master_id));
                if self.rules.push((id, until_us)).is_err() {
                    bus.remove_rule(id);
                }
            }
            Injection::CanRestore => {
                bus.clear_rules();
                self.rules.clear();
            }
            // EtherCAT faults belong to `run --ethercat` (a scenario with them is refused on
            // CAN before it starts)
            Injection::Mark { .. } | Injection::Ecat { .. } | Injection::EcatRestore => {}
        }
        Ok(())
    }

    /// Apply one injection on EtherCAT: parameters and sensors to the first slave's `drive`,
    /// wire faults to `faults` (from now on the frames' clock), a drop out of OP to
    /// `slave`. CAN faults do nothing here (a scenario with them is refused on EtherCAT).
    pub fn apply_ethercat(
        &mut self,
        inj: Injection,
        drive: &mut AxisDrive,
        slave: &mut drive_ethercat::slave::Slave,
        faults: &mut crate::bus::ethercat::EcatFaults,
    ) -> Result<(), ParamError> {
        use crate::bus::ethercat::EcatFault;
        match inj {
            Injection::Param { param, value_si } => drive.set_param(param, value_si)?,
            Injection::Sensor { kind, counts } => sensor(drive, kind, counts),
            Injection::Ecat {
                fault: EcatFault::OutOfOp { al_code },
                ..
            } => {
                slave.drop_out_of_op(al_code);
            }
            Injection::Ecat { fault, over_us } => {
                let now_us = faults.clock_us();
                faults.start(fault, over_us, now_us)
            }
            Injection::EcatRestore => faults.clear(),
            Injection::Can { .. } | Injection::CanRestore | Injection::Mark { .. } => {}
        }
        Ok(())
    }

    /// Remove the rules whose time is over at `now_us`.
    pub fn expire<B: CanBus>(&mut self, now_us: u64, bus: &mut FaultyBus<B>) {
        let mut k = 0;
        while k < self.rules.len() {
            if self.rules[k].1.is_some_and(|end| now_us >= end) {
                bus.remove_rule(self.rules[k].0);
                self.rules.swap_remove(k);
            } else {
                k += 1;
            }
        }
    }
}

/// The values a live drive accepts for a scenario parameter key, in the key's file unit
/// (`backlash_mm`: mm): the key's own lower bound (what scenario files accept) and the drive's
/// range for its parameter, asked of `drive` without changing it (a value that is not a number
/// is refused with the range). `None` when the drive has no such parameter.
pub fn param_bounds(drive: &mut AxisDrive, key: &ParamKey) -> Option<(f64, f64)> {
    match drive.set_param(key.param, f64::NAN) {
        Err(ParamError::OutOfRange { min, max }) => {
            let (a, b) = (min / key.scale, max / key.scale);
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            Some((lo.max(key.min), hi))
        }
        _ => None,
    }
}

/// Apply an encoder fault event to a drive.
fn sensor(drive: &mut AxisDrive, kind: SensorKind, counts: i64) {
    match kind {
        SensorKind::MotorEncoderLoss => drive.set_signal_lost(Encoder::Motor, true),
        SensorKind::DirectEncoderLoss => drive.set_signal_lost(Encoder::Direct, true),
        SensorKind::MotorEncoderGlitch => drive.inject_glitch(Encoder::Motor, counts),
        SensorKind::DirectEncoderGlitch => drive.inject_glitch(Encoder::Direct, counts),
        SensorKind::Restore => {
            drive.set_signal_lost(Encoder::Motor, false);
            drive.set_signal_lost(Encoder::Direct, false);
        }
    }
}

/// The bus rule that injects a CAN fault.
fn rule(fault: CanFault, master_id: u8) -> FaultRule {
    match fault {
        CanFault::Drop { share, cob_id } => {
            let r = FaultRule::drop_share(share);
            cob_id.map_or(r, |c| r.only(c))
        }
        CanFault::Delay {
            share,
            ticks,
            cob_id,
        } => {
            let r = FaultRule::delay_share(share, ticks);
            cob_id.map_or(r, |c| r.only(c))
        }
        CanFault::SyncLoss => FaultRule::sync_loss(),
        CanFault::HeartbeatLoss => FaultRule::heartbeat_loss(master_id),
    }
}

/// Every value a scenario's events give the drive (a `set`, both ends of a `ramp`, a
/// `profile`'s extremes) checked against what the drive of `cfg` accepts ([`param_bounds`]),
/// before the run starts: a value it would refuse when the event fires (offline: the run
/// stops there; live: the drive would keep its value) is an error at the event's line now.
pub fn check_ranges(
    s: &super::Scenario,
    cfg: &crate::presets::AxisConfig,
) -> Result<(), super::ScenarioError> {
    use super::timeline::Action;
    let mut drive = None;
    for ev in &s.events {
        let (key, values): (&ParamKey, heapless::Vec<f64, 2>) = match &ev.action {
            Action::Set { key, value } => (key, heapless::Vec::from_slice(&[*value]).unwrap()),
            Action::Ramp { key, from, to, .. } => {
                let mut v = heapless::Vec::new();
                let _ = v.push(*to);
                if let Some(f) = from {
                    let _ = v.push(*f);
                }
                (key, v)
            }
            Action::Profile {
                key,
                shape,
                mean,
                amplitude,
                ..
            } => {
                // mean + amplitude * shape, shape within -1..1 (sine) or 0..1 (teeth).
                let low = match shape {
                    super::file::ProfileShape::Sine => -1.0,
                    super::file::ProfileShape::Teeth => 0.0,
                };
                let (a, b) = (mean + amplitude * low, mean + amplitude);
                (key, heapless::Vec::from_slice(&[a, b]).unwrap())
            }
            Action::Sensor { .. }
            | Action::Can { .. }
            | Action::CanRestore
            | Action::Ethercat { .. }
            | Action::EthercatRestore => continue,
        };
        if drive.is_none() {
            drive = Some(
                AxisDrive::from_config(cfg).map_err(|e| super::ScenarioError {
                    file: s.path.clone(),
                    line: 0,
                    column: 0,
                    key: String::new(),
                    reason: format!("{}: {e}", cfg.name),
                })?,
            );
        }
        let d = drive.as_mut().expect("built above");
        let err = |reason: String| super::ScenarioError {
            file: s.path.clone(),
            line: ev.line,
            column: 1,
            key: String::new(),
            reason,
        };
        let Some((lo, hi)) = param_bounds(d, key) else {
            return Err(err(format!(
                "{}: the drive of {} has no such parameter",
                key.key, cfg.name
            )));
        };
        if let Some(v) = values.iter().find(|v| !(**v >= lo && **v <= hi)) {
            let unit = drive_physics::params::find(key.key).map_or("", |(_, f)| f.unit);
            return Err(err(format!(
                "{} = {v} is outside what the drive of {} accepts: {lo} .. {hi} {unit}",
                key.key, cfg.name
            )));
        }
    }
    Ok(())
}
