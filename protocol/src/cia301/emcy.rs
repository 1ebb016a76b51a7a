//! EMCY producer: 0x1001 error register, 0x1003 pre-defined error field (history, newest in
//! sub 1), 0x1014 COB-ID, 0x1015 inhibit time. Frames are encoded by [`crate::wire::emcy`].
//!
//! An active error is held by one or more causes ([`Cause`]): a supervised condition that
//! is still present (heartbeat or SYNC lost, a wrong RPDO), or the CiA 402 FAULT state that the error put the
//! drive in. It stays active, in 0x1001 and without EMCY 0x0000, until every cause is gone:
//! a heartbeat that comes back while the drive is still in FAULT clears nothing; the fault
//! reset does (CiA 301: the error register reflects the errors that are active).

use crate::cia301::cob_id;
use crate::cia301::sdo::abort;
use crate::node::writes::{ObjectWrite, Verdict, WriteHooks};
use crate::node::DriveCore;
use crate::od::{idx, Store};
use crate::wire::emcy::EmcyFrame;
use heapless::{Deque, Vec};

const R_1001: usize = idx(0x1001, 0);
const R_1003: usize = idx(0x1003, 0);
/// "Error reset / no error".
const RESET: EmcyFrame = EmcyFrame {
    code: 0,
    register: 0,
    info: [0; 5],
};

/// What keeps an error active.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cause {
    /// A condition the node supervises that is still present (heartbeat or SYNC lost, RPDOs
    /// of the wrong length or with refused values).
    Condition = 0x01,
    /// The CiA 402 fault the error led to, until the fault reset.
    Fault = 0x02,
    /// A one-off event (wrong RPDO or SYNC length): reported, not kept.
    Event = 0x04,
}

#[derive(Clone, Copy, Debug)]
struct Active {
    code: u16,
    /// Bit set of [`Cause`]s.
    causes: u8,
    /// Its 0x1003 entry (code | manufacturer info << 16).
    entry: u32,
}

/// Active errors and the frames waiting for the inhibit time.
#[derive(Clone, Debug, Default)]
pub struct Emcy {
    queue: Deque<[u8; 8], 16>,
    /// Oldest first.
    active: Vec<Active, 8>,
    last_tx_us: Option<u64>,
    /// EMCYs dropped because the queue was full.
    pub dropped: u32,
    /// Entries the 0x1003 history has (its sub-indices 1.. in the dictionary, at most 8; 0
    /// until the node sets it: then sub 0 never counts past what a master can read).
    history_len: usize,
}

/// Most entries the 0x1003 history keeps.
pub const MAX_HISTORY: usize = 8;

/// Error register bits for an error code (bit 0 generic is added whenever any error is active).
fn register_bits(code: u16) -> u8 {
    match code >> 12 {
        0x2 => 0x02,
        0x3 => 0x04,
        0x4 => 0x08,
        0x8 if code & 0xFF00 == 0x8100 || code & 0xFF00 == 0x8200 => 0x10,
        0x8 | 0x7 => 0x20,
        0xF | 0xFF => 0x80,
        _ => 0,
    }
}

impl Emcy {
    /// An EMCY producer whose 0x1003 history has `len` entries (capped at [`MAX_HISTORY`]).
    pub fn with_history(len: usize) -> Emcy {
        Emcy {
            history_len: len.min(MAX_HISTORY),
            ..Emcy::default()
        }
    }

    /// Forget every error (reset node: the application restarts).
    pub fn reset(&mut self, store: &mut Store) {
        self.queue.clear();
        self.active.clear();
        self.last_tx_us = None;
        store.set_u32(R_1001, 0);
    }

    /// Reset communication: the supervisions restart and the PDOs are configured anew, so
    /// the errors their conditions held go (silently: the node boots again); errors the drive is still in FAULT for stay, in
    /// 0x1001 and at the top of the (re-initialised) 0x1003 history.
    pub fn reset_communication(&mut self, store: &mut Store) {
        self.queue.clear();
        self.last_tx_us = None;
        self.active.retain_mut(|a| {
            a.causes &= Cause::Fault as u8;
            a.causes != 0
        });
        for s in 0..=MAX_HISTORY {
            store.set_u32(R_1003 + s, 0);
        }
        for (n, a) in self.active.iter().rev().take(self.history_len).enumerate() {
            store.set_u32(R_1003 + 1 + n, a.entry);
        }
        store.set_u32(R_1003, self.active.len().min(self.history_len) as u32);
        self.update_register(store);
    }

    /// The error register as the active errors make it.
    pub fn register(&self) -> u8 {
        let mut r = 0;
        for a in self.active.iter() {
            r |= 0x01 | register_bits(a.code);
        }
        r
    }

    fn update_register(&self, store: &mut Store) {
        store.set_u32(R_1001, self.register() as u32);
    }

    pub fn is_active(&self, code: u16) -> bool {
        self.active.iter().any(|a| a.code == code)
    }

    /// Raise an error held by `cause`: update 0x1001 and 0x1003, queue the EMCY frame.
    /// Returns false when the error was already active (only the cause is added).
    pub fn raise(&mut self, store: &mut Store, code: u16, info: [u8; 5], cause: Cause) -> bool {
        // An error that is already active is not a new event: one EMCY, one history entry,
        // until it is cleared (e.g. heartbeat loss followed by its 0x6007 fault reaction).
        if let Some(a) = self.active.iter_mut().find(|a| a.code == code) {
            a.causes |= cause as u8;
            return false;
        }
        let entry = code as u32 | (u16::from_le_bytes([info[0], info[1]]) as u32) << 16;
        let a = Active {
            code,
            causes: cause as u8,
            entry,
        };
        if self.active.push(a).is_err() {
            // table full: keep the older errors, still report this one
        }
        let reg = self.register() | 0x01 | register_bits(code);
        store.set_u32(R_1001, reg as u32);
        // history: shift down, newest in sub 1
        let n = (store.u32(R_1003) as usize).min(self.history_len);
        for s in (1..MAX_HISTORY).rev() {
            let v = store.u32(R_1003 + s);
            store.set_u32(R_1003 + s + 1, v);
        }
        store.set_u32(R_1003 + 1, entry);
        store.set_u32(R_1003, (n + 1).min(self.history_len) as u32);
        let msg = EmcyFrame {
            code,
            register: reg,
            info,
        };
        self.push(msg.emit());
        true
    }

    /// `cause` no longer holds error `code`; when no error is left, send "error reset / no
    /// error" (EMCY 0x0000). Returns true when the error went inactive.
    pub fn clear(&mut self, store: &mut Store, code: u16, cause: Cause) -> bool {
        let Some(p) = self.active.iter().position(|a| a.code == code) else {
            return false;
        };
        self.active[p].causes &= !(cause as u8);
        if self.active[p].causes != 0 {
            return false;
        }
        self.active.remove(p);
        self.update_register(store);
        if self.active.is_empty() {
            self.push(RESET.emit());
        }
        true
    }

    /// `cause` holds no error any more (CiA 402 fault reset: [`Cause::Fault`]). Returns the
    /// codes that went inactive.
    pub fn clear_cause(&mut self, store: &mut Store, cause: Cause) -> Vec<u16, 8> {
        let mut gone = Vec::new();
        self.active.retain_mut(|a| {
            a.causes &= !(cause as u8);
            if a.causes == 0 {
                let _ = gone.push(a.code);
            }
            a.causes != 0
        });
        if !gone.is_empty() {
            self.update_register(store);
            if self.active.is_empty() {
                self.push(RESET.emit());
            }
        }
        gone
    }

    /// The active error codes, oldest first.
    pub fn active_codes(&self) -> Vec<u16, 8> {
        self.active.iter().map(|a| a.code).collect()
    }

    /// Report an event without keeping it active (history + EMCY frame, and EMCY 0x0000 when
    /// no other error is active). Returns whether it was raised (not already active).
    pub fn report(&mut self, store: &mut Store, code: u16, info: [u8; 5]) -> bool {
        let raised = self.raise(store, code, info, Cause::Event);
        self.clear(store, code, Cause::Event);
        raised
    }

    fn push(&mut self, f: [u8; 8]) {
        if self.queue.push_back(f).is_err() {
            self.dropped = self.dropped.wrapping_add(1);
        }
    }

    /// When the next queued frame may go (us): `None` with an empty queue.
    pub fn next_at_us(&self, inhibit_100us: u16) -> Option<u64> {
        if self.queue.is_empty() {
            return None;
        }
        Some(
            self.last_tx_us
                .map_or(0, |l| l.saturating_add(inhibit_100us as u64 * 100)),
        )
    }

    /// The next frame allowed by the inhibit time (100 us units), if any.
    pub fn next(&mut self, now_us: u64, inhibit_100us: u16) -> Option<[u8; 8]> {
        if self.queue.is_empty() {
            return None;
        }
        if let Some(l) = self.last_tx_us {
            if now_us < l.saturating_add(inhibit_100us as u64 * 100) && now_us >= l {
                return None;
            }
        }
        self.last_tx_us = Some(now_us);
        self.queue.pop_front()
    }
}

/// The EMCY objects whose writes the producer rules: 0x1003 (0 clears the history) and 0x1014
/// (the COB-ID).
pub(crate) fn register_writes(t: &mut WriteHooks) {
    t.register(0x1003, 0x1003, write_history);
    t.register(0x1014, 0x1014, write_cob_id);
}

/// 0x1003 sub 0: writing 0 clears the history (sub 0 and every entry); any other value is
/// refused (CiA 301 7.5.2.5).
fn write_history(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    if w.sub != 0 {
        return Ok(Verdict::Store);
    }
    if w.raw != 0 {
        return Err(abort::VALUE_RANGE);
    }
    for s in 0..=MAX_HISTORY {
        c.store.set(w.row + s, 0);
    }
    Ok(Verdict::Applied)
}

/// 0x1014: bit 31 set (EMCY not valid) takes any CAN-ID; bit 30 is reserved; a valid COB-ID
/// must be an 11-bit CAN-ID outside the restricted ranges. 0 on a device whose own file has
/// it (`DeviceDescription::emcy_cob_id_zero_predefined`: EMCY on $NODEID + 0x80) is its own
/// value written back.
fn write_cob_id(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    if w.raw == 0 && c.od.device.emcy_cob_id_zero_predefined {
        return Ok(Verdict::Store);
    }
    let valid = w.raw & 0x8000_0000 == 0;
    if w.raw & 0x4000_0000 != 0 || !cob_id::acceptable(w.raw as u32, valid) {
        return Err(abort::VALUE_RANGE);
    }
    Ok(Verdict::Store)
}
