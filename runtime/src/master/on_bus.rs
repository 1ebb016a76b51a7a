//! The reference master on a real bus: the sans-IO [`Master`] driven by the wall clock at its
//! SYNC period, reading and writing a [`CanBus`] (a SocketCAN interface in practice). The
//! drive on the other end is whatever answers: `drive-emu run`, another emulator, or a real
//! servo drive.

use super::Master;
use crate::bus::CanBus;
use crate::time::Clock;
use std::sync::atomic::{AtomicBool, Ordering};

/// What the bus did to the master during a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct BusRunStats {
    /// Loop cycles (one per SYNC period).
    pub cycles: u64,
    pub frames_sent: u64,
    /// SYNCs among them.
    pub syncs_sent: u64,
    pub frames_received: u64,
    /// Frames the interface refused (transmit queue full, link down).
    pub send_refused: u64,
    pub recv_errors: u64,
    /// Cycles that started more than one period late.
    pub late_cycles: u64,
}

/// Run `master` on `bus` until its program is finished or failed, `limit_us` of wall time has
/// passed, or `stop` is set. Each cycle, at an absolute deadline: hand the master what was
/// received, let it act (SYNC, RPDOs, SDO, heartbeat), send what it queued. The master's
/// clock is its cycle count times the period (load-independent timeouts); `limit_us` is wall
/// time.
pub fn run_on_bus<B: CanBus, C: Clock>(
    master: &mut Master,
    bus: &mut B,
    clock: &mut C,
    limit_us: u64,
    stop: &AtomicBool,
) -> BusRunStats {
    let period_us = u64::from(master.config().sync_period_us.max(1));
    let start_us = clock.now_us();
    let mut stats = BusRunStats::default();
    let mut deadline = start_us;
    while !master.finished() && !stop.load(Ordering::Relaxed) {
        let woke = clock.sleep_until(deadline);
        if woke > deadline + period_us {
            stats.late_cycles += 1;
        }
        if woke - start_us >= limit_us {
            break;
        }
        // The master's clock counts its SYNC periods, not the wall clock: on a busy host a
        // stalled cycle does not eat its SDO and step timeouts, and its samples sit at k *
        // period as the SYNCs it sent do.
        let now = stats.cycles * period_us;
        loop {
            match bus.recv() {
                Ok(Some(f)) => {
                    stats.frames_received += 1;
                    master.handle(&f, now);
                }
                Ok(None) => break,
                Err(_) => {
                    stats.recv_errors += 1;
                    break;
                }
            }
        }
        master.set_wall_us(woke - start_us);
        master.poll(now);
        while let Some(f) = master.pop_tx() {
            match bus.send(&f) {
                Ok(()) => {
                    stats.frames_sent += 1;
                    stats.syncs_sent += u64::from(f.id == 0x080);
                }
                Err(_) => stats.send_refused += 1,
            }
        }
        stats.cycles += 1;
        deadline += period_us;
        // After a stall, resume at the next period rather than firing a burst of SYNCs.
        if woke > deadline + period_us {
            deadline = woke - (woke - deadline) % period_us + period_us;
        }
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::inproc::InProcBus;
    use crate::master::{MasterConfig, Step};
    use crate::time::VirtualClock;

    #[test]
    fn an_unanswered_master_fails_on_time_and_the_loop_ends() {
        let mut eps = InProcBus::endpoints(2, 64);
        let mut bus = eps.pop().unwrap();
        let cfg = MasterConfig {
            step_timeout_us: 50_000,
            ..Default::default()
        };
        let mut m = Master::new(cfg, vec![Step::Dwell { duration_s: 1.0 }]);
        let stop = AtomicBool::new(false);
        let stats = run_on_bus(
            &mut m,
            &mut bus,
            &mut VirtualClock::new(),
            10_000_000,
            &stop,
        );
        assert!(m.error().unwrap().contains("boot-up"), "{:?}", m.error());
        // The reset went out, then ~50 cycles of waiting.
        assert_eq!(stats.frames_sent, 1);
        assert!((50..60).contains(&stats.cycles), "{}", stats.cycles);
        let reset = eps[0].recv().unwrap().unwrap();
        assert_eq!((reset.id, reset.data[0], reset.data[1]), (0, 0x82, 5));
    }
}
