//! When the node next needs a poll (docs/decisions/0003): the earliest of the services'
//! deadlines, on the application and the communication clock.

use super::*;

impl Node {
    /// The next time (us, on the clock given to `handle` / `poll`) at which [`Node::poll`]
    /// has a communication deadline: an SDO transfer timeout, the heartbeat producer, a
    /// heartbeat consumer timeout, SYNC supervision (1.5 periods), a TPDO event timer or the
    /// end of a TPDO or EMCY inhibit time holding back a frame. A SYNC received and not yet
    /// processed makes it the time of that SYNC (poll now). `None`: no deadline; the node
    /// then needs `poll` only for its CiA 402 cycle, which the caller runs at its own rate.
    ///
    /// **Contract:** right after `poll(now)`, `poll_at()` is `None` or `> now`: `poll` does
    /// everything due at `now` (every heartbeat consumer that timed out, every EMCY the
    /// inhibit time lets go, every event-driven TPDO due), so a loop that sleeps until
    /// `poll_at()` never spins. With two clocks the same holds for the communication clock:
    /// right after `poll_comm(comm)` or `poll_with(clocks)`, [`Node::poll_at_comm`] is `None`
    /// or `> comm`. A frame that finds the transmit queue full is dropped and counted
    /// ([`Node::tx_overflows`]), never held for a later poll. `handle` may bring the deadline
    /// to `now` or before it (a SYNC to process, a TPDO whose data a received frame changed):
    /// poll then. Checked after every poll by the property tests over the fuzz harness
    /// (`protocol/tests/fuzz/`) and by the `cargo fuzz` target.
    ///
    /// **The clock** is the caller's, in u64 microseconds (584 542 years), and is not assumed
    /// to be monotonic (a clock that goes back delays the timers that started later). It does
    /// not wrap: a period or timeout whose end would lie beyond `u64::MAX` never ends (the
    /// heartbeat producer stops, a stalled SDO transfer is not aborted, a heartbeat, SYNC or
    /// TPDO timer does not expire); the boot-up after a reset and the end of an EMCY inhibit
    /// time are clamped to `u64::MAX`. Nothing overflows, in an overflow-checked build too.
    pub fn poll_at(&self) -> Option<u64> {
        earliest(self.can.sdo.deadline_us(), self.core.poll_at())
    }

    /// The communication deadlines of [`Node::poll_at`] alone (on the communication clock):
    /// when [`Node::poll_comm`] has something to do. Right after `poll_comm(comm)` or
    /// `poll_with(clocks)` it is `None` or later than the communication time (the contract
    /// of [`Node::poll_at`]).
    pub fn poll_at_comm(&self) -> Option<u64> {
        earliest(self.can.sdo.deadline_us(), self.core.poll_at_comm())
    }
}

/// The earlier of two deadlines.
fn earliest(a: Option<u64>, b: Option<u64>) -> Option<u64> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, None) => a,
        (None, b) => b,
    }
}

impl DriveCore {
    /// [`Node::poll_at`] for the drive core alone (no SDO server): when
    /// [`DriveCore::poll`] has something to do.
    pub fn poll_at(&self) -> Option<u64> {
        let c = self;
        let mut at = self.poll_at_comm();
        let mut take = |t: Option<u64>| {
            if let Some(t) = t {
                at = Some(at.map_or(t, |a| a.min(t)));
            }
        };
        if c.nmt == NmtState::Initialising {
            return at;
        }
        take(c.pending_sync);
        if c.nmt == NmtState::Operational {
            take(c.sync.deadline_us(c.store.u32(R_1006)));
        }
        take(c.qs.watchdog_deadline(&c.quirks, c.watchdog_period().0));
        at
    }

    /// [`Node::poll_at_comm`] for the drive core alone (no SDO server).
    pub fn poll_at_comm(&self) -> Option<u64> {
        let c = self;
        let mut at = None;
        let mut take = |t: Option<u64>| {
            if let Some(t) = t {
                at = Some(at.map_or(t, |a: u64| a.min(t)));
            }
        };
        if c.nmt == NmtState::Initialising {
            take(c.boot_due_us); // the boot-up after the boot delay
            return at;
        }
        take(c.qs.deadline_comm()); // the vendor switches' heartbeats, delayed SDO answers
        take(c.hb.deadline_us(c.store.u32(R_1017) as u16));
        take(c.hbc.deadline_us());
        if c.nmt == NmtState::Operational {
            for k in 0..c.pdo.tpdo.len() {
                take(c.pdo.deadline_us(&c.store, k, c.comm_us));
            }
        }
        if c.emcy_allowed() {
            take(c.emcy.next_at_us(c.store.u32(R_1015) as u16));
        }
        at
    }
}
