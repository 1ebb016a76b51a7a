//! The loop of `drive-emu run --ethercat IFACE`: the run's axes as EtherCAT slaves in line
//! order ([`drive_ethercat::Segment`]) on a raw packet socket. A frame is processed and sent
//! back the moment it arrives; between frames, each drive's cycle runs at the fixed tick rate
//! as the CAN runtime steps it (the node's cycle with the simulated time, then the axis
//! advances one period). Frames carry the wall clock (DC, watchdog); the drive's cycle the
//! simulated time. With `lockstep`, the drives' time advances by one period per frame that
//! carries process data (the master's cycle, as per SYNC on CAN) instead of by the tick: the
//! drive then sees exactly one cycle per master cycle however busy the machine is. When a
//! slave follows SYNC0 in lock-step, each process-data frame is a SYNC0 event and the drives'
//! time advances by the SYNC0 cycle, in whole ticks ([`lockstep_ticks`]), as per SYNC on CAN;
//! 0x2100 then says locked, with the SYNC0 period.
//!
//! Distributed clocks: once a slave follows SYNC0 (DC SYNC0 chosen and accepted at SAFE-OP,
//! [`drive_ethercat::Slave::next_sync0_ns`]), its SYNC0 pulses feed the same phase lock as
//! SYNC on CAN ([`SyncPll`], [`Sync0Lock`]): the control cycle is placed [`SYNC_LEAD_US`]
//! before each pulse. The pulses are exact (the ESC computes them from its registers, as
//! its SYNC0 line is exact), so what the lock cannot remove is the loop's own wake-up
//! lateness: 0x2100 publishes the lock state, the measured SYNC0 period and the smoothed
//! phase error of the control cycle against SYNC0 (its start minus the pulse less the lead).
//! The first slave that follows SYNC0 sets the pulses (a master gives every slave of a line
//! the same SYNC0). Nothing allocates in the loop.

use std::sync::atomic::{AtomicBool, Ordering};

use drive_ethercat::Segment;
use drive_protocol::Clocks;
use hdrhistogram::Histogram;

use super::pll::{LockState, SyncPll};
use super::stats::StatsValues;
use super::{SimulatedDrive, SYNC_LEAD_US};
use crate::bus::ethercat::{Answer, EcatFaults, PacketSocket};
use crate::time::{Clock, MonotonicClock};

/// Largest frame taken (a standard Ethernet frame without FCS, and some room).
pub const FRAME_BUFFER: usize = 1600;

/// What the loop counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EthercatStats {
    /// Frames answered.
    pub frames: u64,
    /// Frames refused (malformed, too long).
    pub refused: u64,
    /// Receive or send errors of the socket.
    pub socket_errors: u64,
    /// Drive cycles run.
    pub cycles: u64,
    /// Cycles skipped because the loop was late by more than a period.
    pub late_cycles: u64,
    /// Drive cycles run while locked to SYNC0.
    pub sync0_locked_cycles: u64,
    /// Phase error of those cycles against SYNC0 (|start - (pulse - lead)|), us: median,
    /// 99th percentile, largest (0 without SYNC0).
    pub sync0_phase_p50_us: u64,
    pub sync0_phase_p99_us: u64,
    pub sync0_phase_max_us: u64,
}

/// SYNC0 pulses fed to the lock at one wake-up at most; more (after a stall) are skipped.
const MAX_PULSES_PER_WAKE: usize = 16;
/// Largest phase error the histograms resolve, us.
const MAX_TRACKED_US: u64 = 10_000_000;
/// 0x2100 refreshed every this many drive cycles.
const PUBLISH_EVERY: u64 = 64;

/// The drive's control cycle phase-locked to SYNC0: the pulses go to a [`SyncPll`] as SYNCs
/// do on CAN; the next control tick comes from it. A pure function of the times it is given
/// (no clock), so it is tested on simulated time.
#[derive(Debug)]
pub struct Sync0Lock {
    pll: SyncPll,
    period_us: u64,
    /// Pulses before this time (slave clock, ns) were fed; `None`: none yet.
    fed_until_ns: Option<u64>,
    /// The next control tick, us.
    deadline_us: u64,
    /// Smoothed |phase error| of the ticks while locked, us.
    phase_avg_us: f64,
    /// |phase error| of each tick run while locked, us.
    phase_us: Histogram<u64>,
    /// How late each tick started after its deadline, us.
    lateness_us: Histogram<u64>,
    /// Ticks run, and those started more than a period late (skipped ones counted).
    pub ticks: u64,
    pub late: u64,
}

impl Sync0Lock {
    /// Free-running at `period_us` from `start_us` until pulses come.
    pub fn new(start_us: u64, period_us: u64) -> Sync0Lock {
        let hist = || {
            Histogram::<u64>::new_with_bounds(1, MAX_TRACKED_US, 3)
                .expect("static histogram bounds are valid")
        };
        Sync0Lock {
            pll: SyncPll::new(period_us, SYNC_LEAD_US),
            period_us,
            fed_until_ns: None,
            deadline_us: start_us + period_us,
            phase_avg_us: 0.0,
            phase_us: hist(),
            lateness_us: hist(),
            ticks: 0,
            late: 0,
        }
    }

    /// Feed the SYNC0 pulses up to `now_us`; `next_pulse(t_ns)` is the first pulse at or
    /// after `t_ns` (`None`: no slave follows SYNC0). Pulses before the first call are not
    /// fed; without pulses for a few periods the lock free-runs again.
    pub fn pulses(&mut self, now_us: u64, next_pulse: impl Fn(u64) -> Option<u64>) {
        let now_ns = now_us.saturating_mul(1000);
        let mut from = self.fed_until_ns.unwrap_or(now_ns);
        let mut fed = 0;
        loop {
            match next_pulse(from) {
                Some(p) if p <= now_ns => {
                    if fed == MAX_PULSES_PER_WAKE {
                        // a stall: the rest is skipped, the lock bridges them
                        from = now_ns + 1;
                        break;
                    }
                    self.pll.on_sync(p / 1000);
                    from = p + 1;
                    fed += 1;
                }
                Some(_) => break,
                // no slave follows SYNC0 now: a later grid starts from now on
                None => {
                    from = now_ns;
                    break;
                }
            }
        }
        self.fed_until_ns = Some(from);
        self.pll.check_lost(now_us);
    }

    /// When the next control tick is due, us.
    pub fn deadline_us(&self) -> u64 {
        self.deadline_us
    }

    /// A tick started at `start_us`: record its lateness and, while locked, its phase against
    /// the SYNC0 pulse it precedes (`next_pulse` as for [`Sync0Lock::pulses`]); place the next.
    pub fn ticked(&mut self, start_us: u64, next_pulse: impl Fn(u64) -> Option<u64>) {
        self.ticks += 1;
        let late = start_us.saturating_sub(self.deadline_us);
        self.lateness_us.saturating_record(late.min(MAX_TRACKED_US));
        if self.pll.state() == LockState::Locked {
            // the pulse this tick is placed before: the first after its deadline
            if let Some(p) = next_pulse(self.deadline_us.saturating_mul(1000)) {
                let ideal = p as f64 / 1000.0 - SYNC_LEAD_US as f64;
                let e = (start_us as f64 - ideal).abs();
                self.phase_avg_us += 0.05 * (e - self.phase_avg_us);
                self.phase_us
                    .saturating_record((e.round() as u64).min(MAX_TRACKED_US));
            }
        }
        self.deadline_us = self.pll.next_deadline(self.deadline_us);
        if start_us > self.deadline_us + self.period_us {
            self.late += (start_us - self.deadline_us) / self.period_us;
            self.deadline_us = self.pll.next_deadline(start_us);
        }
    }

    /// Lock state.
    pub fn state(&self) -> LockState {
        self.pll.state()
    }

    /// The 0x2100 values ([`super::stats::STATS_NAMES`]) of this loop: ticks, late ticks,
    /// lateness p50/p99/max, the lock state, the smoothed phase error against SYNC0 and the
    /// SYNC0 period measured, us.
    pub fn stats_values(&self) -> StatsValues {
        let q = |h: &Histogram<u64>, p: f64| {
            if h.is_empty() {
                0
            } else {
                h.value_at_quantile(p)
            }
        };
        let sat = |v: u64| v.min(u64::from(u32::MAX)) as u32;
        let locked = self.pll.state() != LockState::FreeRunning;
        let mut v: StatsValues = [0; super::stats::STATS_NAMES.len()];
        v[0] = sat(self.ticks);
        v[1] = sat(self.late);
        v[2] = sat(q(&self.lateness_us, 0.5));
        v[3] = sat(q(&self.lateness_us, 0.99));
        v[4] = sat(self.lateness_us.max());
        v[7] = self.pll.state().code();
        v[8] = if locked {
            sat(self.phase_avg_us.round() as u64)
        } else {
            0
        };
        v[9] = if locked {
            sat(self.pll.sync_period_us().round() as u64)
        } else {
            0
        };
        v
    }

    /// Phase error of the ticks run while locked: (count, p50, p99, max), us.
    pub fn phase_summary(&self) -> (u64, u64, u64, u64) {
        let h = &self.phase_us;
        if h.is_empty() {
            return (0, 0, 0, 0);
        }
        (
            h.len(),
            h.value_at_quantile(0.5),
            h.value_at_quantile(0.99),
            h.max(),
        )
    }
}

/// The first SYNC0 pulse at or after `t_ns` of the first slave that follows SYNC0.
fn next_pulse(seg: &Segment, t_ns: u64) -> Option<u64> {
    seg.slaves.iter().find_map(|s| s.next_sync0_ns(t_ns))
}

/// In lock-step: the SYNC0 cycle of the first slave that follows SYNC0, ns (`None`: none
/// does, or it pulses once).
fn lockstep_sync0_ns(seg: &Segment) -> Option<u64> {
    seg.slaves
        .iter()
        .find(|s| s.dc_synchronised() && s.sync0().active())
        .map(|s| u64::from(s.sync0().cycle_ns()))
        .filter(|&c| c > 0)
}

/// Drive ticks per process-data frame in lock-step: one, or the SYNC0 cycle's worth of
/// ticks (rounded, at least one) while a slave follows SYNC0: each master cycle is a SYNC0
/// event, as each SYNC is on CAN.
pub fn lockstep_ticks(sync0_ns: Option<u64>, period_us: u64) -> u64 {
    let period_ns = period_us.max(1).saturating_mul(1000);
    sync0_ns.map_or(1, |c| ((c + period_ns / 2) / period_ns).max(1))
}

/// 0x2100 in lock-step: the ticks run; following SYNC0, locked (2) with the SYNC0 period and
/// no phase error (the ticks are the SYNC0 events), else free-running.
pub fn lockstep_values(lock: &Sync0Lock, ticks: u64, sync0_ns: Option<u64>) -> StatsValues {
    let mut v = lock.stats_values();
    v[0] = ticks.min(u64::from(u32::MAX)) as u32;
    (v[7], v[8], v[9]) = match sync0_ns {
        Some(c) => (
            LockState::Locked.code(),
            0,
            (c / 1000).min(u64::from(u32::MAX)) as u32,
        ),
        None => (LockState::FreeRunning.code(), 0, 0),
    };
    v
}

/// Write the loop's statistics into every slave's statistics object (0x2100).
fn publish<D: SimulatedDrive>(seg: &mut Segment, drives: &[D], values: &StatsValues) {
    for (s, d) in seg.slaves.iter_mut().zip(drives.iter()) {
        let Some(slots) = d.stats_slots() else {
            continue;
        };
        let node = s.node_mut();
        let mut v = *values;
        v[6] = node.tx_overflows();
        for (slot, x) in slots.iter().zip(v) {
            node.set_value(*slot, u64::from(x));
        }
    }
}

/// Serve `seg` with `drives` on `sock` until `stop`, one drive cycle per `period_us` (or,
/// with `lockstep`, one per process-data frame); `after_cycle(seg, drives, t_us)` after each
/// drive cycle of simulated time `t_us` (the trace, the detector, a scenario's injections:
/// real-time safe). `faults` (lost frames, a late cycle, the link down, bad working counters)
/// act on the frames on the frames' clock; `after_cycle` may start and end them.
pub fn serve<D: SimulatedDrive>(
    sock: &mut PacketSocket,
    seg: &mut Segment,
    drives: &mut [D],
    (period_us, lockstep): (u64, bool),
    stop: &AtomicBool,
    faults: &mut EcatFaults,
    mut after_cycle: impl FnMut(&mut Segment, &mut [D], &mut EcatFaults, u64),
) -> EthercatStats {
    let mut clock = MonotonicClock::new();
    let mut stats = EthercatStats::default();
    let mut buf = [0u8; FRAME_BUFFER];
    let mut sim_us = 0u64;
    let mut lock = Sync0Lock::new(clock.now_us(), period_us);
    while !stop.load(Ordering::Relaxed) {
        // every frame waiting, each answered at once
        loop {
            match sock.recv(&mut buf) {
                Ok(Some(n)) if n <= buf.len() => {
                    let now_us = clock.now_us();
                    let now_ns = now_us.saturating_mul(1000);
                    let frame = &mut buf[..n];
                    if !faults.admit(frame, now_us) {
                        if faults.corrupted() {
                            // the slaves see a bad frame check sequence: RX error counters
                            seg.frame_corrupted();
                        }
                        continue;
                    }
                    let pd_before = seg.process_data_frames;
                    if seg.process(frame, now_ns, drives).is_ok() {
                        if faults.answer(frame, now_us) == Answer::Send {
                            match sock.send(frame) {
                                Ok(()) => stats.frames += 1,
                                Err(_) => stats.socket_errors += 1,
                            }
                        }
                        if lockstep && seg.process_data_frames != pd_before {
                            // the master's cycle: the drives' period (or, following SYNC0,
                            // the SYNC0 cycle's ticks), after the answer
                            let sync0_ns = lockstep_sync0_ns(seg);
                            for _ in 0..lockstep_ticks(sync0_ns, period_us) {
                                let t = sim_us;
                                step(seg, drives, &mut sim_us, now_ns / 1000, period_us);
                                after_cycle(seg, drives, faults, t);
                                stats.cycles += 1;
                                if sync0_ns.is_some() {
                                    stats.sync0_locked_cycles += 1;
                                }
                            }
                            let v = lockstep_values(&lock, stats.cycles, sync0_ns);
                            publish(seg, drives, &v);
                        }
                    } else {
                        stats.refused += 1;
                    }
                }
                Ok(Some(_)) => stats.refused += 1,
                Ok(None) => break,
                Err(_) => {
                    stats.socket_errors += 1;
                    break;
                }
            }
        }
        let now_us = clock.now_us();
        // frames a late-cycle fault held, now due
        faults.due(now_us, |f| match sock.send(f) {
            Ok(()) => stats.frames += 1,
            Err(_) => stats.socket_errors += 1,
        });
        let held_due = faults.next_due_us().unwrap_or(u64::MAX);
        if lockstep {
            clock.wait_until_or_readable((now_us + 100_000).min(held_due), Some(sock.fd()));
            continue;
        }
        lock.pulses(now_us, |t| next_pulse(seg, t));
        if now_us >= lock.deadline_us() {
            let t = sim_us;
            step(seg, drives, &mut sim_us, now_us, period_us);
            after_cycle(seg, drives, faults, t);
            stats.cycles += 1;
            if lock.state() == LockState::Locked {
                stats.sync0_locked_cycles += 1;
            }
            lock.ticked(now_us, |t| next_pulse(seg, t));
            if stats.cycles.is_multiple_of(PUBLISH_EVERY) {
                publish(seg, drives, &lock.stats_values());
            }
            continue;
        }
        clock.wait_until_or_readable(lock.deadline_us().min(held_due), Some(sock.fd()));
    }
    if !lockstep {
        publish(seg, drives, &lock.stats_values());
    }
    stats.late_cycles = lock.late;
    let (_, p50, p99, max) = lock.phase_summary();
    (
        stats.sync0_phase_p50_us,
        stats.sync0_phase_p99_us,
        stats.sync0_phase_max_us,
    ) = (p50, p99, max);
    stats
}

/// One drive cycle of every slave at simulated time `sim_us` (frames' clock `comm_us`), then
/// each axis advances one period.
fn step<D: SimulatedDrive>(
    seg: &mut Segment,
    drives: &mut [D],
    sim_us: &mut u64,
    comm_us: u64,
    period_us: u64,
) {
    let clocks = Clocks {
        app_us: *sim_us,
        comm_us,
    };
    seg.cycle(clocks, drives);
    for d in drives.iter_mut() {
        d.advance(period_us);
    }
    *sim_us += period_us;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SYNC0 every `cycle_ns` from `first_ns` (until `end_ns`), as a slave computes it.
    fn grid(first_ns: u64, cycle_ns: u64, end_ns: u64) -> impl Fn(u64) -> Option<u64> {
        move |t| {
            let p = if t <= first_ns {
                first_ns
            } else {
                first_ns + (t - first_ns).div_ceil(cycle_ns) * cycle_ns
            };
            (p <= end_ns).then_some(p)
        }
    }

    /// The loop on simulated time: wake at each deadline `late(k)` us late, feed the pulses,
    /// tick. Returns, per tick, (start, the pulse after it) in us.
    fn run(
        lock: &mut Sync0Lock,
        pulses: &impl Fn(u64) -> Option<u64>,
        ticks: usize,
        late: impl Fn(usize) -> u64,
    ) -> Vec<(u64, Option<u64>)> {
        let mut out = Vec::new();
        for k in 0..ticks {
            let now = lock.deadline_us() + late(k);
            lock.pulses(now, pulses);
            let now = now.max(lock.deadline_us());
            out.push((now, pulses(now * 1000).map(|p| p / 1000)));
            lock.ticked(now, pulses);
        }
        out
    }

    #[test]
    fn lockstep_runs_the_sync0_cycles_ticks_per_process_data_frame() {
        assert_eq!(lockstep_ticks(None, 1000), 1);
        assert_eq!(lockstep_ticks(Some(1_000_000), 1000), 1);
        assert_eq!(lockstep_ticks(Some(1_000_000), 250), 4);
        assert_eq!(lockstep_ticks(Some(2_000_000), 1000), 2);
        assert_eq!(lockstep_ticks(Some(125_000), 1000), 1, "at least one");
        assert_eq!(lockstep_ticks(Some(1_600_000), 1000), 2, "rounded");
        let lock = Sync0Lock::new(0, 250);
        let v = lockstep_values(&lock, 4000, Some(1_000_000));
        assert_eq!((v[0], v[7], v[8], v[9]), (4000, 2, 0, 1000));
        let v = lockstep_values(&lock, 17, None);
        assert_eq!((v[0], v[7], v[8], v[9]), (17, 0, 0, 0));
    }

    #[test]
    fn the_tick_follows_sync0_in_simulated_time() {
        // SYNC0 at 1 ms from 50.437 ms on; the free-running tick starts off its phase
        let mut lock = Sync0Lock::new(0, 1000);
        let pulses = grid(50_437_000, 1_000_000, u64::MAX);
        assert_eq!(lock.stats_values()[7], 0, "free-running at first");
        let ticks = run(&mut lock, &pulses, 600, |_| 0);
        assert_eq!(lock.state(), LockState::Locked);
        // after the lock: each tick SYNC_LEAD_US before its pulse, one tick per pulse
        for &(start, pulse) in &ticks[400..] {
            let before = pulse.unwrap() as i64 - start as i64;
            assert!(
                (before - SYNC_LEAD_US as i64).abs() <= 2,
                "tick {start} us, pulse {pulse:?}"
            );
        }
        let pulses_hit: Vec<u64> = ticks[400..].iter().map(|t| t.1.unwrap()).collect();
        assert!(pulses_hit.windows(2).all(|w| w[1] - w[0] == 1000));
        let v = lock.stats_values();
        assert_eq!(v[0], 600);
        assert_eq!(v[7], 2, "locked");
        assert!(v[8] <= 2, "phase error {} us", v[8]);
        assert_eq!(v[9], 1000, "SYNC0 period");
        let (n, p50, p99, _) = lock.phase_summary();
        assert!(n > 300 && p50 <= 1 && p99 <= 2, "{n} {p50} {p99}");
    }

    #[test]
    fn a_late_loop_shows_in_the_phase_error_and_silence_unlocks() {
        let mut lock = Sync0Lock::new(0, 1000);
        let end = 700_000_000;
        let pulses = grid(3_000_000, 1_000_000, end);
        // every fourth wake-up 80 us late
        run(&mut lock, &pulses, 600, |k| if k % 4 == 0 { 80 } else { 0 });
        assert_eq!(lock.state(), LockState::Locked);
        let v = lock.stats_values();
        assert!(
            (10..=40).contains(&v[8]),
            "smoothed phase error {} us",
            v[8]
        );
        let (_, p50, p99, max) = lock.phase_summary();
        assert!(
            p50 <= 2 && (70..=90).contains(&p99) && max <= 90,
            "{p50} {p99} {max}"
        );
        // the pulses stop (SYNC0 off): free-running again within a few periods
        let ticks = run(&mut lock, &pulses, 200, |_| 0);
        assert_eq!(lock.state(), LockState::FreeRunning);
        let last: Vec<u64> = ticks[150..].iter().map(|t| t.0).collect();
        assert!(last.windows(2).all(|w| w[1] - w[0] == 1000), "{last:?}");
        assert_eq!(lock.stats_values()[7], 0);
    }

    #[test]
    fn a_stall_skips_pulses_without_a_tick_storm() {
        let mut lock = Sync0Lock::new(0, 1000);
        let pulses = grid(2_000_000, 1_000_000, u64::MAX);
        run(&mut lock, &pulses, 300, |_| 0);
        assert_eq!(lock.state(), LockState::Locked);
        // the loop wakes 50 ms late: one tick, the deadlines then resume on the grid
        let ticks = run(&mut lock, &pulses, 100, |k| if k == 0 { 50_000 } else { 0 });
        assert!(lock.late >= 45, "{} late", lock.late);
        assert!(ticks[1].0 > ticks[0].0 + 400, "{:?}", &ticks[..3]);
        assert_eq!(lock.state(), LockState::Locked);
        let (start, pulse) = ticks[99];
        assert_eq!(pulse.unwrap() - start, SYNC_LEAD_US);
    }
}
