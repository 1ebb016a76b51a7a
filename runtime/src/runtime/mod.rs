//! The runtime: a thin fixed-rate loop that wires bus, nodes and simulated axes together.
//!
//! One tick: drain received frames into the nodes (bounded, so a flood cannot stall the loop),
//! let every node run its state machine and hand its command to its drive, advance every
//! axis's physics by one period, send what the nodes queued. No domain logic lives here, and
//! nothing on the tick allocates, locks or logs (`tests/alloc_runtime.rs` proves it).
//!
//! Three ways to drive the tick:
//! - [`Runtime::run_realtime`]: wall clock, event-driven: the loop waits on the socket and its
//!   next control deadline together; a frame is handled the moment it arrives (a SYNC's TPDOs
//!   and an SDO answer go out at once, with the values of the last control cycle), and the
//!   control cycle is phase-locked to the SYNC ([`pll::SyncPll`]) so that sample is fresh;
//! - [`Runtime::run_lockstep`]: simulated time advances one SYNC period per SYNC received, so
//!   results do not depend on how busy the host is;
//! - [`Runtime::tick`] called by an offline driver with a virtual clock (demo, scenarios).

pub mod ethercat;
pub mod pll;
pub mod realtime;
pub mod stats;
pub mod trace;

use crate::bus::{CanBus, CanFrame, SendError};
use crate::time::Clock;
use drive_protocol::od::Slot;
use drive_protocol::{Clocks, Drive, FrameEvent, Node};
use pll::SyncPll;
use stats::LoopStats;
use std::sync::atomic::{AtomicBool, Ordering};

/// At most this many received frames are handled per tick; the rest wait for the next tick.
pub const MAX_RX_PER_TICK: usize = 256;
/// Lock-step: simulated time per SYNC when neither the caller nor the master (0x1006, 0x60C2)
/// says.
pub const DEFAULT_SYNC_PERIOD_US: u64 = 1000;
/// Falling further behind than this many periods skips ticks instead of catching up (when no
/// received frame paces the catch-up: frames read after a stall are interleaved with the ticks
/// that were due before each arrived, see [`Runtime::realtime_wake`]).
pub const MAX_CATCH_UP_TICKS: u64 = 20;
/// Frames handed to the bus at once by [`Runtime::flush_tx`] (a stack array).
pub const TX_BATCH: usize = 64;
/// A transmit queue that is full is retried after waits of this length ...
pub const TX_WAIT_STEP_US: u64 = 50;
/// ... for at most this long per flush; after that the remaining refused frames are dropped
/// and counted (a bus that never takes frames must not stall the loop).
pub const TX_WAIT_BUDGET_US: u64 = 20_000;
/// The control cycle runs this long before the predicted SYNC (at most half a tick), so the
/// values a SYNC's TPDOs carry were sampled just before it.
pub const SYNC_LEAD_US: u64 = 150;

/// A drive whose physics the runtime advances.
pub trait SimulatedDrive: Drive {
    /// Advance the simulated axis by `dt_us` of simulated time.
    fn advance(&mut self, dt_us: u64);
    /// Slots of its node's statistics object ([`stats::STATS_NAMES`] order), where the
    /// runtime publishes the loop statistics; `None`: the node has none.
    fn stats_slots(&self) -> Option<&[Slot; stats::STATS_NAMES.len()]> {
        None
    }
}

/// One axis: the CANopen node and the simulated drive behind it.
pub struct AxisSlot<D> {
    pub node: Node,
    pub drive: D,
}

/// What a tick observed, for the caller's loop control.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TickReport {
    pub frames_received: usize,
    pub syncs: usize,
}

pub struct Runtime<B, D> {
    pub bus: B,
    pub axes: Vec<AxisSlot<D>>,
    pub period_us: u64,
    /// Simulated time, microseconds.
    pub sim_time_us: u64,
    pub stats: LoopStats,
    /// The nodes' communication clock (`drive_protocol::Clocks`): the simulated time, or in
    /// lock-step the wall clock.
    comm_clock: CommClock,
    /// Lock-step: the simulated time one SYNC advances, us (0 before the first SYNC and when
    /// not in lock-step).
    pub lockstep_period_us: u64,
    /// Lock-step: ticks run on the drive's own clock while SYNC was missing.
    pub lockstep_free_ticks: u64,
}

impl<B: CanBus, D: SimulatedDrive> Runtime<B, D> {
    pub fn new(bus: B, axes: Vec<AxisSlot<D>>, period_us: u64) -> Self {
        assert!(period_us > 0, "tick period must be positive");
        Self {
            bus,
            axes,
            period_us,
            sim_time_us: 0,
            stats: LoopStats::new(period_us),
            comm_clock: CommClock::Simulated,
            lockstep_period_us: 0,
            lockstep_free_ticks: 0,
        }
    }

    /// Boot every node (boot-up messages go out on the first send).
    pub fn boot(&mut self) {
        let clocks = self.clocks();
        for ax in &mut self.axes {
            ax.node.boot_with(clocks);
        }
        self.flush_tx();
    }

    /// The nodes' clocks now.
    fn clocks(&self) -> Clocks {
        match &self.comm_clock {
            CommClock::Simulated => Clocks::same(self.sim_time_us),
            CommClock::Wall { now_us, .. } => Clocks {
                app_us: self.sim_time_us,
                comm_us: *now_us,
            },
        }
    }

    /// From now on the nodes' communication clock is the wall clock (lock-step), continuing
    /// from the simulated time it has reached.
    pub fn use_wall_comm_clock(&mut self) {
        if let CommClock::Simulated = self.comm_clock {
            self.comm_clock = CommClock::Wall {
                clock: crate::time::MonotonicClock::new(),
                base_us: self.sim_time_us,
                now_us: self.sim_time_us,
            };
        }
    }

    /// Lock-step: read the wall clock for the communication time of what follows; every
    /// `resync`-th call also re-measures the offset of the receive time stamps.
    fn read_comm_clock(&mut self, resync: bool) {
        if let CommClock::Wall {
            clock,
            base_us,
            now_us,
        } = &mut self.comm_clock
        {
            if resync {
                clock.sync_realtime();
            }
            *now_us = (*now_us).max(*base_us + clock.now_us());
        }
    }

    /// Lock-step: the communication time of the frame just received is its kernel receive
    /// time stamp (no clock read); a transport without stamps has the clock read.
    fn stamp_comm_clock(&mut self) {
        let stamp = self.bus.last_rx_stamp_ns();
        if let CommClock::Wall {
            clock,
            base_us,
            now_us,
        } = &mut self.comm_clock
        {
            let us = match stamp.and_then(|t| clock.realtime_to_us(t)) {
                Some(us) => us,
                None => clock.now_us(),
            };
            *now_us = (*now_us).max(*base_us + us);
        }
    }

    /// Complete every pending boot now (sends the boot-ups).
    pub fn finish_boots(&mut self) {
        let now = self.sim_time_us;
        for ax in &mut self.axes {
            ax.node.finish_boot(now);
        }
        self.flush_tx();
    }

    /// Hand received frames to every node; returns (frames, SYNCs).
    pub fn receive(&mut self) -> TickReport {
        let mut report = TickReport::default();
        while report.frames_received < MAX_RX_PER_TICK {
            match self.receive_one() {
                Some(sync) => {
                    report.frames_received += 1;
                    report.syncs += usize::from(sync);
                }
                None => break,
            }
        }
        report
    }

    /// Hand the next received frame (if any) to every node at the current simulated time.
    /// `None`: nothing to read (or a receive error, counted); `Some(true)`: it was a SYNC.
    fn receive_one(&mut self) -> Option<bool> {
        let frame = self.recv_frame()?;
        Some(self.handle_frame(&frame, 0))
    }

    fn recv_frame(&mut self) -> Option<CanFrame> {
        match self.bus.recv() {
            Ok(Some(f)) => {
                self.stats.rx_overflows = self.bus.rx_overflows();
                Some(f)
            }
            Ok(None) => None,
            Err(_) => {
                self.stats.rx_errors += 1;
                None
            }
        }
    }

    /// Hand a frame read `late_us` after it arrived to every node; true if it was a SYNC.
    fn handle_frame(&mut self, frame: &CanFrame, late_us: u64) -> bool {
        let clocks = self.clocks();
        let mut sync = false;
        for ax in &mut self.axes {
            if let FrameEvent::Sync { .. } =
                ax.node.handle_with(frame, clocks, late_us, &mut ax.drive)
            {
                sync = true;
            }
        }
        if sync {
            self.stats.syncs += 1;
        }
        sync
    }

    /// Let every node act and advance every axis by one period.
    pub fn step(&mut self) {
        let clocks = self.clocks();
        for ax in &mut self.axes {
            ax.node.poll_with(clocks, &mut ax.drive);
            ax.drive.advance(self.period_us);
        }
        self.sim_time_us += self.period_us;
    }

    /// Send everything the nodes queued, in order, in batches of up to [`TX_BATCH`] frames
    /// (one `sendmmsg` each on SocketCAN). A full transmit queue (ENOBUFS) is waited out in
    /// steps of [`TX_WAIT_STEP_US`] (counted), up to [`TX_WAIT_BUDGET_US`] per flush; only
    /// then, or with the interface down, is a frame dropped (counted).
    pub fn flush_tx(&mut self) {
        let mut budget_us = TX_WAIT_BUDGET_US;
        let mut batch = [CanFrame::default(); TX_BATCH];
        let mut axis = 0;
        loop {
            let mut n = 0;
            while n < TX_BATCH && axis < self.axes.len() {
                match self.axes[axis].node.pop_tx() {
                    Some(f) => {
                        batch[n] = f;
                        n += 1;
                    }
                    None => axis += 1,
                }
            }
            if n == 0 {
                return;
            }
            let mut sent = 0;
            while sent < n {
                let (taken, err) = self.bus.send_batch(&batch[sent..n]);
                sent += taken;
                // Nothing taken and no reason given: as a full queue (bounded).
                let err = err.or((taken == 0).then_some(SendError::Full));
                match err {
                    None => {}
                    Some(SendError::Full) if budget_us > 0 => {
                        self.stats.tx_full_waits += 1;
                        self.bus.wait_writable(TX_WAIT_STEP_US);
                        budget_us = budget_us.saturating_sub(TX_WAIT_STEP_US);
                    }
                    Some(_) => {
                        self.stats.tx_dropped += 1;
                        sent += 1;
                    }
                }
            }
        }
    }

    /// One whole tick at the current simulated time.
    pub fn tick(&mut self) -> TickReport {
        let r = self.receive();
        self.step();
        self.flush_tx();
        self.bus.end_tick();
        r
    }

    /// Copy the loop statistics into every node's statistics object (0x2100 by default).
    pub fn publish_stats(&mut self) {
        let s = self.stats.summary();
        let sat = |v: u64| v.min(u64::from(u32::MAX)) as u32;
        for ax in &mut self.axes {
            let Some(slots) = ax.drive.stats_slots() else {
                continue;
            };
            let values: stats::StatsValues = [
                sat(s.ticks),
                sat(s.overruns),
                sat(s.lateness_p50_us),
                sat(s.lateness_p99_us),
                sat(s.lateness_max_us),
                sat(s.tx_dropped),
                ax.node.tx_overflows(),
                s.sync_lock_state,
                sat(s.sync_phase_error_us),
                sat(s.sync_period_us),
                sat(s.tx_full_waits),
                ax.node.sync_window_missed(),
                sat(s.rx_overflows),
            ];
            for (slot, v) in slots.iter().zip(values) {
                ax.node.set_value(*slot, u64::from(v));
            }
        }
    }

    /// Run on the wall clock until `stop` is set. `hook` is called after every control tick
    /// with the runtime (status snapshots, scenario injections); it is on the real-time path:
    /// it must not block, lock, log or allocate.
    pub fn run_realtime<C: Clock>(
        &mut self,
        clock: &mut C,
        stop: &AtomicBool,
        mut hook: impl FnMut(&mut Self),
    ) {
        let mut state = RealtimeLoop::new(clock.now_us(), self.period_us);
        while !stop.load(Ordering::Relaxed) {
            self.realtime_wake(&mut state, clock, &mut hook);
        }
        self.publish_stats();
    }

    /// One wake-up of the real-time loop: wait for a frame or the next control deadline,
    /// whichever comes first; handle every frame that arrived, each the moment it is read,
    /// after the control ticks that were due before it arrived (so a burst read after a stall
    /// is handled as if it had been read on time: one TPDO set per SYNC, in order); then the
    /// ticks that are due now. Every SYNC also feeds the phase lock, which places the next
    /// control deadlines.
    pub fn realtime_wake<C: Clock>(
        &mut self,
        l: &mut RealtimeLoop,
        clock: &mut C,
        hook: &mut impl FnMut(&mut Self),
    ) {
        let fd = self.bus.rx_fd();
        clock.wait_for(l.deadline_us, fd);
        // No clock read between the wake-up and the answer unless needed (each is a system
        // call, expensive under user-mode Linux or a hypervisor): a frame's arrival comes from
        // its kernel timestamp, converted without one; the clock is read (for each frame: the
        // loop may have been stopped between two) only when the arrival is unknown or a
        // synchronous window (0x1007) needs how late a frame is handled.
        let mut drained = false;
        for _ in 0..MAX_RX_PER_TICK {
            let Some(frame) = self.recv_frame() else {
                drained = true;
                break;
            };
            let stamp = self
                .bus
                .last_rx_stamp_ns()
                .and_then(|t| clock.realtime_to_us(t));
            let now = match stamp {
                Some(_) if !l.sync_window => None,
                _ => Some(clock.now_us()),
            };
            let arrived = stamp.or(now).unwrap_or_default();
            self.run_due_ticks(l, clock, arrived, None, hook);
            let late_us = now.map_or(0, |n| n.saturating_sub(arrived));
            if self.handle_frame(&frame, late_us) {
                l.pll.on_sync(arrived);
                self.stats.sync_lock_state = l.pll.state().code();
                self.stats.sync_phase_error_us = l.pll.phase_error_avg_us().round() as u64;
                self.stats.sync_period_us = l.pll.sync_period_us().round() as u64;
            }
            self.flush_tx();
        }
        // A flood that keeps the socket busy still gets its ticks, paced by the frames'
        // arrival times; the ticks due now wait until the socket is drained.
        if drained {
            let now = clock.now_us();
            l.pll.check_lost(now);
            self.stats.sync_lock_state = l.pll.state().code();
            self.run_due_ticks(l, clock, now, Some(now), hook);
        }
    }

    /// Run the control ticks whose deadline is at or before `until_us`. `now_us`: the time,
    /// if the caller just read it (it starts the first tick; each later one starts when the
    /// one before finished: one clock read per tick, not two).
    fn run_due_ticks<C: Clock>(
        &mut self,
        l: &mut RealtimeLoop,
        clock: &mut C,
        until_us: u64,
        now_us: Option<u64>,
        hook: &mut impl FnMut(&mut Self),
    ) {
        let mut now_us = now_us;
        let behind = until_us.saturating_sub(l.deadline_us) / self.period_us;
        if behind > MAX_CATCH_UP_TICKS {
            self.stats.skipped_ticks += behind;
            l.deadline_us += behind * self.period_us;
        }
        while l.deadline_us <= until_us {
            let start = now_us.unwrap_or_else(|| clock.now_us());
            self.step();
            self.flush_tx();
            self.bus.end_tick();
            let done = clock.now_us();
            now_us = Some(done);
            self.stats.record_tick(
                start.saturating_sub(l.deadline_us),
                done.saturating_sub(start),
            );
            // Statistics object refreshed every 256 ticks: cheap, and fresh enough for SDO;
            // the wall clock's offset (for frame arrival times) as often.
            if self.stats.ticks.is_multiple_of(256) {
                self.publish_stats();
                clock.sync_realtime();
            }
            hook(self);
            l.sync_window = self.axes.iter().any(|a| a.node.sync_window_us() > 0);
            l.deadline_us = l.pll.next_deadline(l.deadline_us);
        }
    }

    /// Lock-step: simulated time only moves when a SYNC arrives, by `sync_period_us`, in ticks
    /// of `period_us`. Frames other than SYNC are handled at the current simulated time. `hook`
    /// runs after every simulated tick, as in [`Runtime::run_realtime`].
    pub fn run_lockstep(
        &mut self,
        sync_period_us: u64,
        stop: &AtomicBool,
        hook: impl FnMut(&mut Self),
    ) {
        let cfg = Lockstep {
            sync_period_us: Some(sync_period_us),
            free_run_after_us: None,
        };
        self.run_lockstep_with(cfg, stop, hook);
    }

    /// Lock-step as [`Runtime::run_lockstep`], with the SYNC period from the master when
    /// `cfg.sync_period_us` is `None` (axis 0's 0x1006 once the master writes it, else its
    /// 0x60C2, else 1 ms),
    /// and, with `cfg.free_run_after_us`, the drive's own
    /// clock taking over when SYNC stops (see [`Lockstep`]). The period in force is published
    /// in [`Runtime::lockstep_period_us`].
    pub fn run_lockstep_with(
        &mut self,
        cfg: Lockstep,
        stop: &AtomicBool,
        mut hook: impl FnMut(&mut Self),
    ) {
        // Communication time (the wall clock, us) of the last SYNC.
        let mut last_sync: Option<u64> = None;
        // Ticks run on the wall clock since SYNC stopped.
        let mut free_ticks = 0u64;
        let wait_us = cfg
            .free_run_after_us
            .map_or(10_000, |_| self.period_us.min(10_000));
        // What a master measures on its own clock (heartbeats, event timers, the boot delay)
        // runs on the wall clock; the drive's time waits for SYNC.
        self.use_wall_comm_clock();
        let mut wakes = 0u64;
        let mut wait = wait_us.min(self.lockstep_comm());
        while !stop.load(Ordering::Relaxed) {
            self.bus.wait_readable(wait);
            // Frames in bus order: each SYNC advances time before the frames after it are
            // seen, so a batch read after a stall gives the same run as frames read one by one
            // (a set-point sent after SYNC k belongs to SYNC k+1, not k).
            let mut frames = 0;
            while frames < MAX_RX_PER_TICK {
                let Some(frame) = self.recv_frame() else {
                    break;
                };
                self.stamp_comm_clock();
                let sync = self.handle_frame(&frame, 0);
                frames += 1;
                self.flush_tx();
                if !sync {
                    continue;
                }
                last_sync = Some(self.clocks().comm_us);
                free_ticks = 0;
                let sync_us = cfg
                    .sync_period_us
                    .or_else(|| self.master_sync_period_us())
                    .unwrap_or(DEFAULT_SYNC_PERIOD_US);
                let ticks_per_sync = ((sync_us + self.period_us / 2) / self.period_us).max(1);
                self.lockstep_period_us = ticks_per_sync * self.period_us;
                for _ in 0..ticks_per_sync {
                    self.lockstep_tick(&mut hook);
                }
            }
            // After the answers: the clock read for the free run and the communication timers,
            // once the socket is drained. A batch cut at MAX_RX_PER_TICK leaves frames queued
            // that arrived before now (a drive behind its master on a busy host): the time
            // stays at the last frame's arrival, or a heartbeat still in the queue would be
            // taken for a missed one (EMCY 0x8130) and a set-point for a lost SYNC.
            wakes += 1;
            if frames < MAX_RX_PER_TICK {
                self.read_comm_clock(wakes.is_multiple_of(256));
            }
            // SYNC stopped: after the grace time the drive's clock runs on the wall's.
            if let (Some(limit), Some(last)) = (cfg.free_run_after_us, last_sync) {
                let since_us = self.clocks().comm_us.saturating_sub(last);
                if since_us > limit {
                    let due = (since_us - limit) / self.period_us;
                    let n = due.saturating_sub(free_ticks).min(MAX_CATCH_UP_TICKS);
                    for _ in 0..n {
                        self.lockstep_tick(&mut hook);
                    }
                    free_ticks += n;
                    self.lockstep_free_ticks += n;
                }
            }
            wait = wait_us.min(self.lockstep_comm());
        }
        self.publish_stats();
    }

    /// The SYNC period the master told axis 0: its communication cycle period 0x1006, else
    /// (Lely and ros2_canopen do not write 0x1006, but a CSP or IP set-up writes the
    /// interpolation time period, which CiA 402 makes the time between set-points, one per
    /// SYNC) its interpolation time period 0x60C2.
    fn master_sync_period_us(&self) -> Option<u64> {
        let node = &self.axes.first()?.node;
        node.object_raw(0x1006, 0)
            .filter(|&p| p > 0)
            .map(u64::from)
            .or_else(|| node.interpolation_period_us())
    }

    /// Lock-step: simulated time stands still without SYNC, but what a master measures on its
    /// own clock does not: the nodes' communication timers (the boot delay after power-on or
    /// an NMT reset, the heartbeat producer and consumer, event-driven TPDOs, SDO time-outs)
    /// run on the wall clock between SYNCs. Returns how long the loop may wait for frames, us.
    fn lockstep_comm(&mut self) -> u64 {
        let mut wait_us = 10_000u64;
        let now = self.clocks().comm_us;
        for ax in &mut self.axes {
            if ax.node.poll_at_comm().is_some_and(|t| t <= now) {
                ax.node.poll_comm(now, &mut ax.drive);
            }
            if let Some(t) = ax.node.poll_at_comm() {
                wait_us = wait_us.min(t.saturating_sub(now));
            }
        }
        self.flush_tx();
        wait_us.max(1)
    }

    fn lockstep_tick(&mut self, hook: &mut impl FnMut(&mut Self)) {
        self.step();
        self.flush_tx();
        self.bus.end_tick();
        self.stats.record_tick(0, 0);
        // 0x2100 refreshed as in the real-time loop.
        if self.stats.ticks.is_multiple_of(256) {
            self.publish_stats();
        }
        hook(self);
    }
}

/// The nodes' communication clock.
#[derive(Debug)]
enum CommClock {
    /// The simulated time (real-time loop: it is the wall clock; offline: a virtual clock).
    Simulated,
    /// The wall clock (lock-step): `base_us` plus `clock`'s time, as last read or as the
    /// kernel's receive time stamp of the frame being handled (`now_us`). A clock read is a
    /// system call under user-mode Linux or a hypervisor: none is made between a frame's
    /// arrival and the answer, one after the answer (for the communication timers).
    Wall {
        clock: crate::time::MonotonicClock,
        base_us: u64,
        now_us: u64,
    },
}

/// How [`Runtime::run_lockstep_with`] turns SYNCs into simulated time.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Lockstep {
    /// Simulated time per SYNC, us (rounded to whole ticks). `None`: axis 0's communication
    /// cycle period 0x1006 when the master has set it, else its interpolation time period
    /// 0x60C2 when set, else [`DEFAULT_SYNC_PERIOD_US`]. (Not
    /// the interval seen on the wall clock: lock-step results must not depend on the host.)
    pub sync_period_us: Option<u64>,
    /// When no SYNC has arrived for this long (wall clock, us) after the first one, the
    /// drive's own clock takes over, one tick per period of wall time, until SYNC returns, as
    /// a real drive's clock would: its SYNC supervision reports the loss and a run with an end
    /// reaches it. `None`: simulated time waits for SYNC forever.
    pub free_run_after_us: Option<u64>,
}

/// The real-time loop's state between wake-ups: the next control deadline and the SYNC lock.
#[derive(Clone, Debug)]
pub struct RealtimeLoop {
    /// Next control tick, microseconds on the loop's clock.
    pub deadline_us: u64,
    pub pll: SyncPll,
    /// Some node has a synchronous window (0x1007): frames need the time they are handled
    /// at (refreshed every control tick).
    pub sync_window: bool,
}

impl RealtimeLoop {
    pub fn new(start_us: u64, period_us: u64) -> Self {
        Self {
            deadline_us: start_us,
            pll: SyncPll::new(period_us, SYNC_LEAD_US),
            sync_window: false,
        }
    }
}
