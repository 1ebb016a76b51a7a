//! SYNC consumer: counter (0x1019) and supervision of the communication cycle period
//! (0x1006). A SYNC missing for more than 1.5 periods is reported once as SYNC loss.
//!
//! SYNC producer (CiA 301 7.2.5, 0x1005 bit 30 "gen"): with bit 30 set and 0x1006 > 0 the
//! node sends SYNC on 0x1005's CAN-ID every 0x1006 us of the communication clock, in
//! pre-operational and operational, with a counter byte 1..=0x1019 (then 1 again) when 0x1019
//! is 2..=240. A deadline in the node's timer table ([`SyncProducer::deadline_us`]); the node
//! acts on its own SYNC as on a received one (its synchronous PDOs).

use crate::cia301::cob_id;
use crate::cia301::sdo::abort;
use crate::node::writes::{ObjectWrite, Verdict, WriteHooks};
use crate::node::DriveCore;
use crate::od::idx;

/// Manufacturer-chosen EMCY code for SYNC loss: 0x8100 "communication, generic" (CiA 301
/// defines none; CANopenNode uses the same). 0x8240 = unexpected SYNC data length.
pub const EMCY_SYNC_LOSS: u16 = 0x8100;
pub const EMCY_SYNC_LENGTH: u16 = 0x8240;

#[derive(Clone, Copy, Debug, Default)]
pub struct SyncConsumer {
    pub last_us: Option<u64>,
    /// Interval between the last two SYNCs, us.
    pub interval_us: u64,
    pub lost: bool,
    pub bad_length: bool,
}

/// Result of a SYNC frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SyncIn {
    pub counter: Option<u8>,
    /// The frame's length did not match 0x1019 (report EMCY 0x8240 once).
    pub length_error: bool,
    /// SYNC came back after a loss.
    pub recovered: bool,
}

impl SyncConsumer {
    pub fn on_sync(&mut self, now_us: u64, len: u8, byte0: u8, overflow: u8) -> SyncIn {
        let expected = if overflow > 1 { 1 } else { 0 };
        let bad = len != expected;
        let length_error = bad && !self.bad_length;
        self.bad_length = bad;
        if let Some(l) = self.last_us {
            self.interval_us = now_us.saturating_sub(l);
        }
        self.last_us = Some(now_us);
        let recovered = self.lost;
        self.lost = false;
        SyncIn {
            counter: if len >= 1 { Some(byte0) } else { None },
            length_error,
            recovered,
        }
    }

    /// When [`SyncConsumer::poll`] reports SYNC loss if no SYNC comes first (us).
    pub fn deadline_us(&self, period_us: u32) -> Option<u64> {
        if period_us == 0 || self.lost {
            return None;
        }
        // poll fires at the first `now` with now - last > 1.5 periods; never when that is
        // beyond the end of the clock's range
        self.last_us
            .and_then(|l| l.checked_add(loss_after_us(period_us) + 1))
    }

    /// True once when SYNC has been missing for more than 1.5 x `period_us` (0 = off).
    pub fn poll(&mut self, now_us: u64, period_us: u32) -> bool {
        if period_us == 0 || self.lost {
            return false;
        }
        if let Some(l) = self.last_us {
            if now_us.saturating_sub(l) > loss_after_us(period_us) {
                self.lost = true;
                return true;
            }
        }
        false
    }
}

/// The SYNC producer's state: when the next SYNC is due and what the last one counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SyncProducer {
    /// The next SYNC's time (us, communication clock; `None` beyond the clock's range: never)
    /// and the period it was armed with; `None`: not running (armed at the first poll that
    /// finds the producer configured).
    armed: Option<(Option<u64>, u32)>,
    /// The counter of the last SYNC sent (0: none since the producer started).
    counter: u8,
}

/// Whether 0x1005 and 0x1006 make the node the SYNC producer: bit 30 set, a period.
pub fn produces(cob_id: u32, period_us: u32) -> bool {
    cob_id & GEN_BIT != 0 && period_us > 0
}

/// 0x1005 bit 30: the node generates SYNC.
pub const GEN_BIT: u32 = 0x4000_0000;

impl SyncProducer {
    /// When the producer next needs a poll: its next SYNC, `now_us` when it is configured but
    /// not armed yet (a write just made it the producer or changed its period), `None` when
    /// `active` is false.
    pub fn deadline_us(&self, active: bool, period_us: u32, now_us: u64) -> Option<u64> {
        if !active {
            return None;
        }
        match self.armed {
            Some((at, p)) if p == period_us => at,
            _ => Some(now_us),
        }
    }

    /// At `now_us`: `Some(counter)` when a SYNC is due (the counter byte it carries, `None`
    /// with `overflow` 0). Not `active`: stopped, the counter back to its start. A period
    /// changed while running re-arms from now (the first SYNC of the new period one period
    /// later); a SYNC more than a period late is not caught up (no burst).
    pub fn poll(
        &mut self,
        active: bool,
        now_us: u64,
        period_us: u32,
        overflow: u8,
    ) -> Option<Option<u8>> {
        if !active {
            *self = SyncProducer::default();
            return None;
        }
        let p = u64::from(period_us);
        let at = match self.armed {
            Some((at, armed_p)) if armed_p == period_us => at,
            _ => {
                self.armed = Some((now_us.checked_add(p), period_us));
                return None;
            }
        };
        // a SYNC whose time lies beyond the clock's range never comes
        let at = at.filter(|&at| now_us >= at)?;
        let next = at
            .checked_add(p)
            .filter(|&t| t > now_us)
            .or_else(|| now_us.checked_add(p));
        self.armed = Some((next, period_us));
        if overflow < 2 {
            return Some(None);
        }
        self.counter = if self.counter == 0 || self.counter >= overflow {
            1
        } else {
            self.counter + 1
        };
        Some(Some(self.counter))
    }
}

/// SYNC is lost once it has been missing for more than this, us: 1.5 periods (rounded down;
/// for whole microseconds "more than floor(1.5 p)" is "more than 1.5 p").
fn loss_after_us(period_us: u32) -> u64 {
    period_us as u64 * 3 / 2
}

/// The SYNC objects whose writes the consumer rules: 0x1005 (the COB-ID) and 0x1019 (the
/// counter overflow value).
pub(crate) fn register_writes(t: &mut WriteHooks) {
    t.register(0x1005, 0x1005, write_cob_id);
    t.register(0x1019, 0x1019, write_overflow);
}

/// 0x1005: an 11-bit CAN-ID outside the restricted ranges (bit 31 is "don't care"); bit 30
/// makes this node the SYNC producer. While it produces (bit 30 set), the CAN-ID may not
/// change: CiA 301 7.5.2.5 asks a producer to be stopped (bit 30 cleared) first, refused
/// 0x06090030 as CANopenNode does.
fn write_cob_id(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    let new = w.raw as u32;
    if !cob_id::acceptable(new & !GEN_BIT, true) {
        return Err(abort::VALUE_RANGE);
    }
    let old = c.store.u32(w.row);
    let id_bits = 0x3FFF_FFFF;
    if old & GEN_BIT != 0 && new & GEN_BIT != 0 && (old ^ new) & id_bits != 0 {
        return Err(abort::VALUE_RANGE);
    }
    if (old ^ new) & GEN_BIT != 0 {
        // started or stopped: a new start counts from 1 and waits a period
        c.sync_producer = SyncProducer::default();
    }
    Ok(Verdict::Store)
}

/// 0x1019: only while the communication cycle period 0x1006 is 0 (CiA 301 7.5.2.22); 1 is
/// not an overflow value.
fn write_overflow(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    if c.store.u32(idx(0x1006, 0)) != 0 {
        return Err(abort::DEVICE_STATE);
    }
    if w.raw == 1 {
        return Err(abort::VALUE_RANGE);
    }
    Ok(Verdict::Store)
}
