//! The tick's observation bus: after every tick the loop publishes one snapshot per axis into
//! a preallocated lock-free ring ([`ring::SeqRing`]) that any number of readers follow at
//! their own pace: the trace recorder ([`trace`], `run --trace`), the detector thread
//! (the monitor module, `run --detect`), a live scenario's thread, the terminal status line and
//! the panel's stream (with its recordings and detector). None of them touches the runtime.
//!
//! The loop's half is the [`Observer`]: [`Observer::publish`] reads each axis's node (what a
//! master reads: statusword, controlword, positions, velocity, following error, NMT and CiA 402
//! state, mode), its physics (motor and load speed, motor current) and the node events of the
//! tick (EMCY raised or cleared, with the code), and writes them as one fixed-size record. It
//! does not allocate, lock, log or wait: a reader that falls behind loses the oldest records,
//! never the loop a tick. The readers' half is [`Observation`] (the rings and the loop's
//! statistics board) with a [`ring::Cursor`] each.
//!
//! The node events are drained here, once per tick, for every axis, and nowhere else: the
//! EMCYs of a tick travel in its snapshot (a reader never steals another's events).
//!
//! A reader that falls more than the ring's capacity behind loses the oldest records and its
//! [`ring::Cursor`] counts them; every reader reports that count when the run ends.

pub mod ring;
pub mod trace;

use crate::bus::CanBus;
use crate::drive::axis_drive::AxisDrive;
use crate::drive::objects::AxisParam;
use crate::runtime::trace::node_sample;
use crate::runtime::{Runtime, SimulatedDrive};
use crate::samples::Sample;
use drive_protocol::NodeEvent;
use ring::{Cursor, RingWriter, SeqRing};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::Arc;

/// Words per record.
pub const WORDS: usize = 15;
/// EMCY events a record carries per axis and tick; more in one tick are counted in
/// [`AxisSnapshot::events_over`].
pub const EVENTS_PER_TICK: usize = 4;
/// Node events kept per axis and tick for [`Observer::events`] (the node's own queue holds 32).
const EVENT_BUFFER: usize = drive_protocol::EVENT_QUEUE;
/// Sub-indices of the loop statistics object (0x2100 by default; 1..=13).
pub const STATS_SUBS: usize = crate::runtime::stats::STATS_NAMES.len();

/// An EMCY event of one tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EmcyEvent {
    /// true: the error became active; false: it went away.
    pub raised: bool,
    pub code: u16,
}

/// One axis at the end of one tick.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AxisSnapshot {
    /// What a master reads, as `run --trace` records it (time in s, positions in uu).
    pub sample: Sample,
    /// The drive's simulated time, us.
    pub t_us: u64,
    /// 0x6040 as the master last wrote it.
    pub controlword: u16,
    /// NMT state as in the heartbeat (0x00 initialising, 0x04 stopped, 0x05 operational,
    /// 0x7F pre-operational).
    pub nmt: u8,
    /// Motor speed, rpm.
    pub motor_speed_rpm: f64,
    /// Load (table, carriage) speed, user units per second.
    pub load_speed_uu_per_s: f64,
    /// Motor current, A.
    pub current_a: f64,
    /// EMCY events of this tick (the first [`EVENTS_PER_TICK`]).
    pub events: [Option<EmcyEvent>; EVENTS_PER_TICK],
    /// EMCY events of this tick beyond [`EVENTS_PER_TICK`].
    pub events_over: u8,
    /// The node's ID now (an LSS master may change it; 255: non-configured).
    pub node_id: u8,
    /// A rotary axis (positions in mdeg-like user units), else linear.
    pub rotary: bool,
    /// The drive's position loop gain k_v now, 1/s.
    pub kv_per_s: f64,
    /// The drive train's gap now, m (linear) or rad (rotary): 0 on a healthy axis.
    pub gap_si: f64,
}

fn f(x: u64) -> f64 {
    f64::from_bits(x)
}

fn event_bits(e: Option<EmcyEvent>) -> u64 {
    e.map_or(0, |e| (1 + u64::from(!e.raised)) << 16 | u64::from(e.code))
}

fn event_of(bits: u64) -> Option<EmcyEvent> {
    match (bits >> 16) & 0xFF {
        1 => Some(EmcyEvent {
            raised: true,
            code: bits as u16,
        }),
        2 => Some(EmcyEvent {
            raised: false,
            code: bits as u16,
        }),
        _ => None,
    }
}

impl AxisSnapshot {
    /// The record's words.
    pub fn to_words(&self) -> [u64; WORDS] {
        let s = &self.sample;
        let n_events = self.events.iter().filter(|e| e.is_some()).count() as u64;
        [
            self.t_us,
            u64::from(s.statusword)
                | u64::from(self.controlword) << 16
                | u64::from(self.nmt) << 32
                | u64::from(s.mode_display as u8) << 40
                | n_events << 48
                | u64::from(self.events_over) << 56,
            s.target_uu.to_bits(),
            s.setpoint_velocity_uu_s.to_bits(),
            u64::from(s.position_uu as u32) | u64::from(s.direct_position_uu as u32) << 32,
            u64::from(s.velocity_uu_s as u32) | u64::from(s.following_error_uu as u32) << 32,
            u64::from(s.torque_permille as u16) | u64::from(s.current_permille as u16) << 16,
            self.motor_speed_rpm.to_bits(),
            self.load_speed_uu_per_s.to_bits(),
            self.current_a.to_bits(),
            event_bits(self.events[0]) | event_bits(self.events[1]) << 32,
            event_bits(self.events[2]) | event_bits(self.events[3]) << 32,
            u64::from(self.node_id) | u64::from(self.rotary) << 8,
            self.kv_per_s.to_bits(),
            self.gap_si.to_bits(),
        ]
    }

    /// The snapshot a record holds.
    pub fn from_words(w: &[u64; WORDS]) -> Self {
        AxisSnapshot {
            sample: Sample {
                t_s: Sample::t_s_of_us(w[0]),
                statusword: w[1] as u16,
                mode_display: (w[1] >> 40) as u8 as i8,
                target_uu: f(w[2]),
                setpoint_velocity_uu_s: f(w[3]),
                position_uu: w[4] as u32 as i32,
                direct_position_uu: (w[4] >> 32) as u32 as i32,
                velocity_uu_s: w[5] as u32 as i32,
                following_error_uu: (w[5] >> 32) as u32 as i32,
                torque_permille: w[6] as u16 as i16,
                current_permille: (w[6] >> 16) as u16 as i16,
            },
            t_us: w[0],
            controlword: (w[1] >> 16) as u16,
            nmt: (w[1] >> 32) as u8,
            motor_speed_rpm: f(w[7]),
            load_speed_uu_per_s: f(w[8]),
            current_a: f(w[9]),
            events: [
                event_of(w[10] & 0xFFFF_FFFF),
                event_of(w[10] >> 32),
                event_of(w[11] & 0xFFFF_FFFF),
                event_of(w[11] >> 32),
            ],
            events_over: (w[1] >> 56) as u8,
            node_id: w[12] as u8,
            rotary: (w[12] >> 8) & 1 == 1,
            kv_per_s: f(w[13]),
            gap_si: f(w[14]),
        }
    }

    /// The EMCY events of this tick.
    pub fn emcys(&self) -> impl Iterator<Item = EmcyEvent> + '_ {
        self.events.iter().flatten().copied()
    }
}

/// The loop's statistics as the drive serves them at 0x2100 (sub 1..=13), refreshed every 256
/// ticks (when the loop refreshes the object), and the loop's simulated time.
#[derive(Default)]
pub struct LoopBoard {
    pub stats_2100: [AtomicU32; STATS_SUBS],
    pub sim_time_us: AtomicU64,
    /// Ticks published.
    pub ticks: AtomicU64,
    /// The heartbeat consumer's first entry (0x1016:1) of axis 0: the master's node ID in
    /// bits 16..23, 0 when unused.
    pub heartbeat_consumer_1016: AtomicU32,
    /// The CAN loop's own counters, every tick (0 on EtherCAT): ticks run, overruns, SYNC
    /// lock state and phase error, frames the kernel dropped, lock-step period in force.
    pub loop_ticks: AtomicU64,
    pub overruns: AtomicU64,
    pub sync_lock: AtomicU64,
    pub sync_phase_error_us: AtomicU64,
    pub rx_overflows: AtomicU64,
    pub lockstep_period_us: AtomicU64,
    /// The bus's link (a CAN interface up), as the loop last saw it; true where there is no
    /// link to lose.
    pub link_up: AtomicBool,
}

/// The readers' half: one ring per axis and the board.
pub struct Observation {
    pub rings: Vec<Arc<SeqRing<WORDS>>>,
    pub board: LoopBoard,
}

impl Observation {
    /// Capacity of each axis's ring, records.
    pub fn capacity(&self) -> usize {
        self.rings.first().map_or(0, |r| r.capacity())
    }

    /// The newest snapshot of `axis`, if one was published (for a reader that wants the state
    /// now, not every tick: the status line).
    pub fn latest(&self, axis: usize) -> Option<AxisSnapshot> {
        let ring = self.rings.get(axis)?;
        let mut w = [0u64; WORDS];
        // A record overwritten while read: the next newest one is there (a few tries).
        for _ in 0..4 {
            let head = ring.written();
            if head == 0 {
                return None;
            }
            if ring.read(head - 1, &mut w).is_ok() {
                return Some(AxisSnapshot::from_words(&w));
            }
        }
        None
    }

    /// A cursor per axis at the newest record (reads what comes from now on).
    pub fn cursors_at_end(&self) -> Vec<Cursor> {
        self.rings.iter().map(|r| Cursor::at_end(r)).collect()
    }

    /// The next snapshot of `axis` for `cursor`, if any.
    pub fn next(&self, axis: usize, cursor: &mut Cursor) -> Option<AxisSnapshot> {
        let mut w = [0u64; WORDS];
        cursor
            .next(&self.rings[axis], &mut w)
            .then(|| AxisSnapshot::from_words(&w))
    }

    /// The 0x2100 values (sub 1..=13, index 0 = sub 1).
    pub fn stats_2100(&self) -> [u32; STATS_SUBS] {
        std::array::from_fn(|i| self.board.stats_2100[i].load(Ordering::Relaxed))
    }
}

/// The loop's half: the rings' writers and the events of the last tick.
pub struct Observer {
    writers: Vec<RingWriter<WORDS>>,
    events: Vec<heapless::Vec<NodeEvent, EVENT_BUFFER>>,
    shared: Arc<Observation>,
    /// Ticks published (for the board's refresh).
    published: u64,
}

/// Capacity of each axis's ring: about one second of ticks at `tick_hz` (a power of two, at
/// least 1024), so a reader that polls every few tens of milliseconds loses nothing.
pub fn ring_capacity(tick_hz: u32) -> usize {
    (tick_hz as usize).next_power_of_two().max(1024)
}

/// Capacity of each axis's ring in a live run, whose readers write files and run the
/// detector: about [`RUN_RING_S`] seconds of ticks at `tick_hz` (a power of two, at least
/// 1024), so a reader held up by a slow disk or a busy machine for seconds still loses nothing
/// (128 bytes a record: 1 MiB per axis at 1 kHz).
pub fn run_ring_capacity(tick_hz: u32) -> usize {
    (RUN_RING_S * tick_hz as usize)
        .next_power_of_two()
        .max(1024)
}

/// Seconds of ticks a live run's rings hold.
pub const RUN_RING_S: usize = 8;

/// The fan-out for `n_axes` axes, each ring `capacity` records, allocated here once.
pub fn channel(n_axes: usize, capacity: usize) -> (Observer, Arc<Observation>) {
    let (writers, rings): (Vec<_>, Vec<_>) = (0..n_axes).map(|_| SeqRing::new(capacity)).unzip();
    let shared = Arc::new(Observation {
        rings,
        board: LoopBoard {
            link_up: AtomicBool::new(true),
            ..LoopBoard::default()
        },
    });
    (
        Observer {
            writers,
            events: (0..n_axes).map(|_| heapless::Vec::new()).collect(),
            shared: Arc::clone(&shared),
            published: 0,
        },
        shared,
    )
}

impl Observer {
    /// After every tick (loop thread): drain every node's events, and publish one snapshot per
    /// axis. No allocation, lock, log or wait.
    pub fn publish<B: CanBus>(&mut self, rt: &mut Runtime<B, AxisDrive>) {
        let now = rt.sim_time_us;
        let b = &self.shared.board;
        let st = &rt.stats;
        b.loop_ticks.store(st.ticks, Ordering::Relaxed);
        b.overruns.store(st.overruns, Ordering::Relaxed);
        b.sync_lock
            .store(u64::from(st.sync_lock_state), Ordering::Relaxed);
        b.sync_phase_error_us
            .store(st.sync_phase_error_us, Ordering::Relaxed);
        b.rx_overflows.store(st.rx_overflows, Ordering::Relaxed);
        b.lockstep_period_us
            .store(rt.lockstep_period_us, Ordering::Relaxed);
        self.publish_axes(now, rt.axes.iter_mut().map(|a| (&mut *a.node, &a.drive)));
    }

    /// The bus's link as the loop sees it now (a CAN interface that went down).
    pub fn set_link_up(&self, up: bool) {
        self.shared.board.link_up.store(up, Ordering::Relaxed);
    }

    /// [`Observer::publish`] for any front end: the axes as (node, drive) pairs in axis order
    /// (CAN: the runtime's; EtherCAT: each slave's node beside its drive) at simulated time
    /// `now`. Every node's events are drained here, and nowhere else while the fan-out runs.
    pub fn publish_axes<'a>(
        &mut self,
        now: u64,
        axes: impl Iterator<Item = (&'a mut drive_protocol::DriveCore, &'a AxisDrive)>,
    ) {
        let mut first: Option<(&'a mut drive_protocol::DriveCore, &'a AxisDrive)> = None;
        for (((node, drive), w), evs) in axes.zip(&mut self.writers).zip(&mut self.events) {
            evs.clear();
            while let Some(e) = node.poll_event() {
                // A full buffer cannot happen (it is the node's own queue size); if it did,
                // the newest events would be dropped, as the node's queue does.
                let _ = evs.push(e);
            }
            let mut snap = AxisSnapshot {
                sample: node_sample(node, now),
                t_us: now,
                controlword: node.object_raw(0x6040, 0).unwrap_or(0) as u16,
                nmt: node.nmt_state() as u8,
                motor_speed_rpm: drive.servo.axis.motor_speed() * 60.0 / std::f64::consts::TAU,
                load_speed_uu_per_s: drive.servo.axis.load_velocity() / drive.user_unit,
                current_a: drive.servo.axis.motor.current(),
                events: [None; EVENTS_PER_TICK],
                events_over: 0,
                node_id: node.node_id(),
                rotary: drive_protocol::Drive::info(drive).rotary,
                kv_per_s: drive.param(AxisParam::Kv),
                gap_si: drive.param(AxisParam::Backlash),
            };
            let mut k = 0;
            for e in evs.iter() {
                let ev = match *e {
                    NodeEvent::EmcyRaised { code } => EmcyEvent { raised: true, code },
                    NodeEvent::EmcyCleared { code } => EmcyEvent {
                        raised: false,
                        code,
                    },
                    _ => continue,
                };
                if k < EVENTS_PER_TICK {
                    snap.events[k] = Some(ev);
                    k += 1;
                } else {
                    snap.events_over = snap.events_over.saturating_add(1);
                }
            }
            w.push(&snap.to_words());
            if first.is_none() {
                first = Some((node, drive));
            }
        }
        let board = &self.shared.board;
        if self.published.is_multiple_of(256) {
            if let Some((node, drive)) = first {
                // The statistics object where the drive put it (base + 0x100; 0x2100 unless
                // moved by --objects-base or a vendor's EDS).
                if let Some(slots) = drive.stats_slots() {
                    for (s, slot) in board.stats_2100.iter().zip(slots) {
                        let v = node.value(*slot).unwrap_or(0) as u32;
                        s.store(v, Ordering::Relaxed);
                    }
                }
                let hb = node.object_raw(0x1016, 1).unwrap_or(0);
                board.heartbeat_consumer_1016.store(hb, Ordering::Relaxed);
            }
        }
        self.published += 1;
        board.sim_time_us.store(now, Ordering::Relaxed);
        board.ticks.store(self.published, Ordering::Release);
    }

    /// The node events `publish` drained from `axis` this tick, oldest first.
    pub fn events(&self, axis: usize) -> &[NodeEvent] {
        self.events.get(axis).map_or(&[], |v| v.as_slice())
    }

    /// The readers' half.
    pub fn observation(&self) -> &Arc<Observation> {
        &self.shared
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_snapshot_survives_its_words() {
        let s = AxisSnapshot {
            sample: Sample {
                t_s: 12_345_678.0 * 1e-6,
                statusword: 0x1637,
                mode_display: -3,
                target_uu: 12345.5,
                setpoint_velocity_uu_s: -987.25,
                position_uu: -2_000_000_000,
                direct_position_uu: 2_000_000_001,
                velocity_uu_s: -16_000,
                torque_permille: -1200,
                current_permille: 999,
                following_error_uu: -42,
            },
            t_us: 12_345_678,
            controlword: 0x001F,
            nmt: 0x7F,
            motor_speed_rpm: -1234.5,
            load_speed_uu_per_s: 16_666.7,
            current_a: -3.25,
            events: [
                Some(EmcyEvent {
                    raised: true,
                    code: 0x7300,
                }),
                Some(EmcyEvent {
                    raised: false,
                    code: 0x8130,
                }),
                None,
                None,
            ],
            events_over: 3,
            node_id: 127,
            rotary: true,
            kv_per_s: 31.5,
            gap_si: 3e-5,
        };
        let back = AxisSnapshot::from_words(&s.to_words());
        assert_eq!(back, s);
        assert_eq!(back.emcys().count(), 2);
    }
}
