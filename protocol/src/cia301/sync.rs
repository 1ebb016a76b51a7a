//! SYNC consumer: counter (0x1019) and supervision of the communication cycle period
//! (0x1006). A SYNC missing for more than 1.5 periods is reported once as SYNC loss.

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

/// 0x1005: bit 30 set (this node produces SYNC) is refused, as is a COB-ID that is not an
/// 11-bit CAN-ID outside the restricted ranges; bit 31 is "don't care".
fn write_cob_id(_: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    if w.raw & 0x4000_0000 != 0 || !cob_id::acceptable(w.raw as u32, true) {
        return Err(abort::VALUE_RANGE);
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
