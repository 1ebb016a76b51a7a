//! CAN fault injection: [`FaultyBus`] wraps any [`CanBus`] and drops or delays a share of the
//! frames that pass through it, in either direction, optionally only for some COB-IDs.
//!
//! Deterministic: the decisions come from a seeded PRNG (splitmix64), so the same seed and the
//! same traffic give the same faults. Delays are counted in ticks of the loop that owns the
//! bus: call [`FaultyBus::tick`] once per tick (the runtime's period). Typical rules:
//!
//! - SYNC loss: drop every frame with COB-ID 0x080 ([`FaultRule::sync_loss`]);
//! - master heartbeat loss: drop 0x700 + master node ID ([`FaultRule::heartbeat_loss`]);
//! - a noisy bus: drop 5 % of all frames ([`FaultRule::drop_share`]);
//! - a congested bus: delay 20 % of the frames by 3 ticks ([`FaultRule::delay_share`]).
//!
//! Wrap the drive's endpoint: received frames are the master's (SYNC, RPDOs, heartbeat, SDO
//! requests), sent frames are the drive's (TPDOs, EMCY, heartbeat, SDO responses).
//!
//! Delayed frames wait in a queue of [`DELAY_QUEUE`] frames per direction, allocated with the
//! bus: a frame that finds it full is lost (counted in [`FaultStats::delay_queue_full`]), so
//! a delay never allocates on the loop's tick nor grows without bound.

use super::{CanBus, CanFrame, RecvError, SendError};
use std::collections::VecDeque;

/// Which way a rule applies, seen from the wrapped endpoint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Direction {
    /// Frames the endpoint receives.
    Rx,
    /// Frames the endpoint sends.
    Tx,
    Both,
}

/// One fault rule. A frame is matched by the first rule whose filter accepts it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FaultRule {
    /// Only frames with this COB-ID (`None` = every frame).
    pub cob_id: Option<u32>,
    pub direction: Direction,
    /// Share of matching frames dropped, 0..=1.
    pub drop_share: f64,
    /// Share of the remaining matching frames delayed, 0..=1.
    pub delay_share: f64,
    /// Delay, in ticks.
    pub delay_ticks: u32,
}

impl FaultRule {
    /// Drop `share` of all frames both ways.
    pub fn drop_share(share: f64) -> Self {
        Self {
            cob_id: None,
            direction: Direction::Both,
            drop_share: share,
            delay_share: 0.0,
            delay_ticks: 0,
        }
    }
    /// Delay `share` of all frames both ways by `ticks`.
    pub fn delay_share(share: f64, ticks: u32) -> Self {
        Self {
            cob_id: None,
            direction: Direction::Both,
            drop_share: 0.0,
            delay_share: share,
            delay_ticks: ticks,
        }
    }
    /// Restrict the rule to one COB-ID.
    pub fn only(mut self, cob_id: u32) -> Self {
        self.cob_id = Some(cob_id);
        self
    }
    /// Restrict the rule to one direction.
    pub fn direction(mut self, direction: Direction) -> Self {
        self.direction = direction;
        self
    }
    /// Every SYNC (0x080) lost.
    pub fn sync_loss() -> Self {
        Self::drop_share(1.0).only(0x080)
    }
    /// Every heartbeat of node `master_id` lost.
    pub fn heartbeat_loss(master_id: u8) -> Self {
        Self::drop_share(1.0).only(0x700 + u32::from(master_id))
    }

    fn matches(&self, frame: &CanFrame, dir: Direction) -> bool {
        (self.direction == Direction::Both || self.direction == dir)
            && self.cob_id.is_none_or(|id| id == frame.id)
    }
}

/// Frames a [`FaultyBus`] holds back per direction: 4 ticks' worth of a 127-axis bus
/// (about 4 frames per node and tick), or 1000 ticks of 4 frames per tick.
pub const DELAY_QUEUE: usize = 4096;

/// What the injector did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct FaultStats {
    pub rx_dropped: u64,
    pub tx_dropped: u64,
    pub rx_delayed: u64,
    pub tx_delayed: u64,
    /// Frames a delay rule picked that found the delay queue full ([`DELAY_QUEUE`]): lost.
    pub delay_queue_full: u64,
}

/// Handle of a rule added with [`FaultyBus::add_rule`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RuleId(u64);

/// A bus that loses and delays frames on purpose.
pub struct FaultyBus<B> {
    inner: B,
    rules: Vec<(RuleId, FaultRule)>,
    next_rule: u64,
    rng: u64,
    tick: u64,
    rx_delayed: VecDeque<(u64, CanFrame)>,
    tx_delayed: VecDeque<(u64, CanFrame)>,
    stats: FaultStats,
    /// The last received frame came out of the delay queue (its age is not the inner bus's).
    delayed_rx: bool,
}

impl<B: CanBus> FaultyBus<B> {
    pub fn new(inner: B, seed: u64) -> Self {
        Self {
            inner,
            // Rules are added on the live loop's tick: no allocation for the first 16.
            rules: Vec::with_capacity(16),
            next_rule: 0,
            rng: seed,
            tick: 0,
            rx_delayed: VecDeque::with_capacity(DELAY_QUEUE),
            tx_delayed: VecDeque::with_capacity(DELAY_QUEUE),
            stats: FaultStats::default(),
            delayed_rx: false,
        }
    }

    pub fn inner(&self) -> &B {
        &self.inner
    }
    pub fn inner_mut(&mut self) -> &mut B {
        &mut self.inner
    }
    pub fn into_inner(self) -> B {
        self.inner
    }
    pub fn stats(&self) -> FaultStats {
        self.stats
    }
    /// Rules in force, in matching order.
    pub fn rules(&self) -> impl Iterator<Item = &FaultRule> {
        self.rules.iter().map(|(_, r)| r)
    }

    pub fn add_rule(&mut self, rule: FaultRule) -> RuleId {
        let id = RuleId(self.next_rule);
        self.next_rule += 1;
        self.rules.push((id, rule));
        id
    }

    /// Remove a rule; frames it already delayed are still delivered.
    pub fn remove_rule(&mut self, id: RuleId) -> bool {
        let before = self.rules.len();
        self.rules.retain(|(i, _)| *i != id);
        self.rules.len() != before
    }

    /// Remove every rule.
    pub fn clear_rules(&mut self) {
        self.rules.clear();
    }

    /// Advance the delay clock by one tick and send the delayed frames that are due.
    pub fn tick(&mut self) {
        self.tick += 1;
        while let Some(&(due, f)) = self.tx_delayed.front() {
            if due > self.tick {
                break;
            }
            self.tx_delayed.pop_front();
            // A refused delayed frame is lost, like any refused frame.
            let _ = self.inner.send(&f);
        }
    }

    /// splitmix64: uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        self.rng = self.rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    /// What happens to a frame: None = pass, Some(0) = drop, Some(n) = delay n ticks.
    fn decide(&mut self, frame: &CanFrame, dir: Direction) -> Option<u32> {
        let rule = *self
            .rules
            .iter()
            .map(|(_, r)| r)
            .find(|r| r.matches(frame, dir))?;
        if rule.drop_share > 0.0 && self.uniform() < rule.drop_share {
            return Some(0);
        }
        if rule.delay_share > 0.0 && rule.delay_ticks > 0 && self.uniform() < rule.delay_share {
            return Some(rule.delay_ticks);
        }
        None
    }
}

impl<B: CanBus> CanBus for FaultyBus<B> {
    fn send_batch(&mut self, frames: &[CanFrame]) -> (usize, Option<SendError>) {
        if self.rules.is_empty() {
            return self.inner.send_batch(frames);
        }
        for (i, f) in frames.iter().enumerate() {
            if let Err(e) = self.send(f) {
                return (i, Some(e));
            }
        }
        (frames.len(), None)
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        match self.decide(frame, Direction::Tx) {
            None => self.inner.send(frame),
            Some(0) => {
                // Lost on the wire: the sender does not know.
                self.stats.tx_dropped += 1;
                Ok(())
            }
            Some(n) => {
                if self.tx_delayed.len() >= DELAY_QUEUE {
                    self.stats.delay_queue_full += 1;
                    return Ok(());
                }
                self.stats.tx_delayed += 1;
                self.tx_delayed
                    .push_back((self.tick + u64::from(n), *frame));
                Ok(())
            }
        }
    }

    fn recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        self.delayed_rx = false;
        if let Some(&(due, f)) = self.rx_delayed.front() {
            if due <= self.tick {
                self.rx_delayed.pop_front();
                // Delivered now by the injector: its arrival time is now.
                self.delayed_rx = true;
                return Ok(Some(f));
            }
        }
        loop {
            let Some(f) = self.inner.recv()? else {
                return Ok(None);
            };
            match self.decide(&f, Direction::Rx) {
                None => return Ok(Some(f)),
                Some(0) => self.stats.rx_dropped += 1,
                Some(_) if self.rx_delayed.len() >= DELAY_QUEUE => {
                    self.stats.delay_queue_full += 1;
                }
                Some(n) => {
                    self.stats.rx_delayed += 1;
                    self.rx_delayed.push_back((self.tick + u64::from(n), f));
                }
            }
        }
    }

    fn end_tick(&mut self) {
        self.tick();
    }

    fn wait_readable(&mut self, timeout_us: u64) {
        if self
            .rx_delayed
            .front()
            .is_some_and(|&(due, _)| due <= self.tick)
        {
            return;
        }
        self.inner.wait_readable(timeout_us);
    }

    fn rx_fd(&self) -> Option<std::os::fd::RawFd> {
        self.inner.rx_fd()
    }

    fn last_rx_stamp_ns(&self) -> Option<i128> {
        if self.delayed_rx {
            None
        } else {
            self.inner.last_rx_stamp_ns()
        }
    }

    fn wait_writable(&mut self, timeout_us: u64) {
        self.inner.wait_writable(timeout_us);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::inproc::InProcBus;

    fn pair() -> (FaultyBus<crate::bus::inproc::InProcEndpoint>, impl CanBus) {
        let mut eps = InProcBus::endpoints(2, 10_000);
        let b = eps.pop().unwrap();
        let a = eps.pop().unwrap();
        (FaultyBus::new(a, 42), b)
    }

    #[test]
    fn sync_loss_drops_only_sync() {
        let (mut fb, mut peer) = pair();
        fb.add_rule(FaultRule::sync_loss());
        peer.send(&CanFrame::new(0x080, &[])).unwrap();
        peer.send(&CanFrame::new(0x205, &[1, 2])).unwrap();
        assert_eq!(fb.recv().unwrap().unwrap().id, 0x205);
        assert_eq!(fb.recv().unwrap(), None);
        assert_eq!(fb.stats().rx_dropped, 1);
    }

    #[test]
    fn drop_share_is_deterministic_and_near_the_share() {
        let run = |seed| {
            let mut eps = InProcBus::endpoints(2, 10_000);
            let mut peer = eps.pop().unwrap();
            let mut fb = FaultyBus::new(eps.pop().unwrap(), seed);
            fb.add_rule(FaultRule::drop_share(0.25));
            for i in 0..4000u32 {
                peer.send(&CanFrame::new(0x180 + (i % 4), &[])).unwrap();
            }
            let mut got = 0;
            while fb.recv().unwrap().is_some() {
                got += 1;
            }
            got
        };
        let a = run(7);
        assert_eq!(a, run(7));
        assert!((2850..=3150).contains(&a), "{a}");
    }

    #[test]
    fn delayed_frames_arrive_after_n_ticks_in_order() {
        let (mut fb, mut peer) = pair();
        fb.add_rule(FaultRule::delay_share(1.0, 3).only(0x185));
        peer.send(&CanFrame::new(0x185, &[1])).unwrap();
        peer.send(&CanFrame::new(0x285, &[2])).unwrap();
        assert_eq!(fb.recv().unwrap().unwrap().id, 0x285);
        assert_eq!(fb.recv().unwrap(), None);
        fb.tick();
        fb.tick();
        assert_eq!(fb.recv().unwrap(), None);
        fb.tick();
        assert_eq!(fb.recv().unwrap().unwrap().data[0], 1);
        // Transmit side.
        let id = fb.add_rule(FaultRule::delay_share(1.0, 2).direction(Direction::Tx));
        fb.send(&CanFrame::new(0x701, &[5])).unwrap();
        assert_eq!(peer.recv().unwrap(), None);
        fb.tick();
        fb.tick();
        assert_eq!(peer.recv().unwrap().unwrap().id, 0x701);
        assert!(fb.remove_rule(id));
        assert_eq!(fb.stats().tx_delayed, 1);
    }

    #[test]
    fn a_full_delay_queue_loses_frames_and_counts_them() {
        let (mut fb, mut peer) = pair();
        fb.add_rule(FaultRule::delay_share(1.0, 1000));
        let n = DELAY_QUEUE + 10;
        let cap = (fb.rx_delayed.capacity(), fb.tx_delayed.capacity());
        for i in 0..n {
            peer.send(&CanFrame::new(0x185, &[i as u8])).unwrap();
            assert_eq!(fb.recv().unwrap(), None);
            fb.send(&CanFrame::new(0x285, &[i as u8])).unwrap();
        }
        // nothing grew: the queues are the ones allocated with the bus
        assert_eq!((fb.rx_delayed.capacity(), fb.tx_delayed.capacity()), cap);
        let st = fb.stats();
        assert_eq!(st.rx_delayed + st.tx_delayed, 2 * DELAY_QUEUE as u64);
        assert_eq!(st.delay_queue_full, 20);
        for _ in 0..1000 {
            fb.tick();
        }
        let mut got = 0;
        while fb.recv().unwrap().is_some() {
            got += 1;
        }
        assert_eq!(got, DELAY_QUEUE);
    }

    #[test]
    fn heartbeat_loss_filters_the_master_heartbeat() {
        let (mut fb, mut peer) = pair();
        fb.add_rule(FaultRule::heartbeat_loss(0x7F));
        peer.send(&CanFrame::new(0x77F, &[5])).unwrap();
        peer.send(&CanFrame::new(0x705, &[5])).unwrap();
        assert_eq!(fb.recv().unwrap().unwrap().id, 0x705);
        assert_eq!(fb.recv().unwrap(), None);
    }
}
