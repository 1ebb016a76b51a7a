//! When the node next needs a poll (docs/decisions/0003): the earliest of the services'
//! deadlines, on the application and the communication clock, from one fixed-size table
//! ([`Timers`]) with a slot per service.

use super::*;

/// A service with a deadline: one slot of [`Timers`]. The first eight run on the
/// communication clock, the last three on the application clock ([`Clocks`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Timer {
    /// The SDO server's transfer time-out (the CAN front end's).
    Sdo,
    /// The boot-up after the boot delay (initialising).
    Boot,
    /// The vendor switches' extra heartbeats and delayed SDO answers.
    Vendor,
    /// The heartbeat producer (0x1017).
    HeartbeatProducer,
    /// The heartbeat consumer's earliest time-out (0x1016).
    HeartbeatConsumer,
    /// The earliest TPDO event timer or inhibit time holding back a frame (operational).
    Tpdo,
    /// The end of the EMCY inhibit time (0x1015) holding back an EMCY.
    Emcy,
    /// The SYNC producer's next SYNC (0x1005 bit 30, 0x1006; pre-operational and
    /// operational).
    SyncProducer,
    /// A SYNC received and not yet processed (poll now).
    PendingSync,
    /// SYNC supervision: 1.5 communication cycles (0x1006) without a SYNC (operational).
    SyncSupervision,
    /// The vendor's SYNC watchdog (docs/quirks.md 3.13).
    Watchdog,
}

/// Slots in [`Timers`].
const TIMERS: usize = 11;

impl Timer {
    /// Every timer, in slot order.
    pub const ALL: [Timer; TIMERS] = [
        Timer::Sdo,
        Timer::Boot,
        Timer::Vendor,
        Timer::HeartbeatProducer,
        Timer::HeartbeatConsumer,
        Timer::Tpdo,
        Timer::Emcy,
        Timer::SyncProducer,
        Timer::PendingSync,
        Timer::SyncSupervision,
        Timer::Watchdog,
    ];

    /// Whether it runs on the communication clock (else the application clock).
    pub const fn comm(self) -> bool {
        !matches!(
            self,
            Timer::PendingSync | Timer::SyncSupervision | Timer::Watchdog
        )
    }
}

/// The services' next deadlines, one slot per [`Timer`] (`None`: not armed), us on the
/// slot's clock. Fixed size, no allocation; [`Node::timers`] / [`DriveCore::timers`] fill
/// it from the services' state, [`Node::poll_at`] is its earliest slot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Timers {
    at: [Option<u64>; TIMERS],
}

impl Timers {
    /// The deadline of `t`, if armed.
    pub fn get(&self, t: Timer) -> Option<u64> {
        self.at[t as usize]
    }

    fn set(&mut self, t: Timer, at: Option<u64>) {
        self.at[t as usize] = at;
    }

    /// The earliest armed slot and its deadline (on either clock); the first slot in
    /// [`Timer::ALL`] order on a tie.
    pub fn earliest(&self) -> Option<(Timer, u64)> {
        self.earliest_of(|_| true)
    }

    fn earliest_of(&self, which: impl Fn(Timer) -> bool) -> Option<(Timer, u64)> {
        let mut best: Option<(Timer, u64)> = None;
        for t in Timer::ALL {
            if let (true, Some(at)) = (which(t), self.get(t)) {
                if best.is_none_or(|(_, b)| at < b) {
                    best = Some((t, at));
                }
            }
        }
        best
    }

    /// The earliest deadline on either clock ([`Node::poll_at`]).
    pub fn next(&self) -> Option<u64> {
        self.earliest().map(|(_, at)| at)
    }

    /// The earliest deadline on the communication clock ([`Node::poll_at_comm`]).
    pub fn next_comm(&self) -> Option<u64> {
        self.earliest_of(Timer::comm).map(|(_, at)| at)
    }
}

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
        self.timers().next()
    }

    /// The communication deadlines of [`Node::poll_at`] alone (on the communication clock):
    /// when [`Node::poll_comm`] has something to do. Right after `poll_comm(comm)` or
    /// `poll_with(clocks)` it is `None` or later than the communication time (the contract
    /// of [`Node::poll_at`]).
    pub fn poll_at_comm(&self) -> Option<u64> {
        self.timers().next_comm()
    }

    /// The services' deadlines now, the SDO server's among them ([`Timers`]).
    pub fn timers(&self) -> Timers {
        let mut t = self.core.timers();
        t.set(Timer::Sdo, self.can.sdo.deadline_us());
        t
    }
}

impl DriveCore {
    /// [`Node::poll_at`] for the drive core alone (no SDO server): when
    /// [`DriveCore::poll`] has something to do.
    pub fn poll_at(&self) -> Option<u64> {
        self.timers().next()
    }

    /// [`Node::poll_at_comm`] for the drive core alone (no SDO server).
    pub fn poll_at_comm(&self) -> Option<u64> {
        self.timers().next_comm()
    }

    /// The services' deadlines now ([`Timers`]; the SDO slot is the CAN front end's and
    /// empty here). While initialising only the boot-up is armed; TPDOs and SYNC
    /// supervision only in operational; an EMCY only while EMCYs may be sent.
    pub fn timers(&self) -> Timers {
        let c = self;
        let mut t = Timers::default();
        if c.nmt == NmtState::Initialising {
            t.set(Timer::Boot, c.boot_due_us);
            return t;
        }
        t.set(Timer::Vendor, c.qs.deadline_comm());
        t.set(
            Timer::HeartbeatProducer,
            c.hb.deadline_us(c.store.u32(R_1017) as u16),
        );
        t.set(Timer::HeartbeatConsumer, c.hbc.deadline_us());
        if c.nmt == NmtState::Operational {
            let tpdo = (0..c.pdo.tpdo.len())
                .filter_map(|k| c.pdo.deadline_us(&c.store, k, c.comm_us))
                .min();
            t.set(Timer::Tpdo, tpdo);
            t.set(
                Timer::SyncSupervision,
                c.sync.deadline_us(c.store.u32(R_1006)),
            );
        }
        if c.emcy_allowed() {
            t.set(Timer::Emcy, c.emcy.next_at_us(c.store.u32(R_1015) as u16));
        }
        t.set(
            Timer::SyncProducer,
            c.sync_producer
                .deadline_us(c.sync_producing(), c.store.u32(R_1006), c.comm_us),
        );
        t.set(Timer::PendingSync, c.pending_sync);
        t.set(
            Timer::Watchdog,
            c.qs.watchdog_deadline(&c.quirks, c.watchdog_period().0),
        );
        t
    }
}
