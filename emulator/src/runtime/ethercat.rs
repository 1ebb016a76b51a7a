//! The loop of `drive-emu run --ethercat IFACE`: the run's axes as EtherCAT slaves in line
//! order ([`drive_ethercat::Segment`]) on a raw packet socket. A frame is processed and sent
//! back the moment it arrives; between frames, each drive's cycle runs at the fixed tick rate
//! as the CAN runtime steps it (the node's cycle with the simulated time, then the axis
//! advances one period). Frames carry the wall clock (DC, watchdog); the drive's cycle the
//! simulated time. With `lockstep`, the drives' time advances by one period per frame that
//! carries process data (the master's cycle, as per SYNC on CAN) instead of by the tick: the
//! drive then sees exactly one cycle per master cycle however busy the machine is. Nothing
//! allocates in the loop.

use std::sync::atomic::{AtomicBool, Ordering};

use drive_ethercat::Segment;
use drive_protocol::Clocks;

use super::SimulatedDrive;
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
    let mut next_us = clock.now_us() + period_us;
    while !stop.load(Ordering::Relaxed) {
        // every frame waiting, each answered at once
        loop {
            match sock.recv(&mut buf) {
                Ok(Some(n)) if n <= buf.len() => {
                    let now_us = clock.now_us();
                    let now_ns = now_us.saturating_mul(1000);
                    let frame = &mut buf[..n];
                    if !faults.admit(frame, now_us) {
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
                            // the master's cycle: the drives' one period, after the answer
                            let t = sim_us;
                            step(seg, drives, &mut sim_us, now_ns / 1000, period_us);
                            after_cycle(seg, drives, faults, t);
                            stats.cycles += 1;
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
        if now_us >= next_us {
            let t = sim_us;
            step(seg, drives, &mut sim_us, now_us, period_us);
            after_cycle(seg, drives, faults, t);
            stats.cycles += 1;
            next_us += period_us;
            if now_us > next_us + period_us {
                stats.late_cycles += (now_us - next_us) / period_us;
                next_us = now_us + period_us;
            }
            continue;
        }
        clock.wait_until_or_readable(next_us.min(held_due), Some(sock.fd()));
    }
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
