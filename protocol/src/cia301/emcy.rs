//! EMCY producer: 0x1001 error register, 0x1003 pre-defined error field (history, newest in
//! sub 1), 0x1014 COB-ID, 0x1015 inhibit time. Frames are encoded by [`crate::wire::emcy`].

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

/// Active errors and the frames waiting for the inhibit time.
#[derive(Clone, Debug, Default)]
pub struct Emcy {
    queue: Deque<[u8; 8], 16>,
    active: Vec<u16, 8>,
    last_tx_us: Option<u64>,
    /// EMCYs dropped because the queue was full.
    pub dropped: u32,
}

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
    pub fn reset(&mut self, store: &mut Store) {
        self.queue.clear();
        self.active.clear();
        self.last_tx_us = None;
        store.set(R_1001, 0);
    }

    fn register(&self) -> u8 {
        let mut r = 0;
        for &c in self.active.iter() {
            r |= 0x01 | register_bits(c);
        }
        r
    }

    pub fn is_active(&self, code: u16) -> bool {
        self.active.contains(&code)
    }

    /// Raise an error: update 0x1001 and 0x1003, queue the EMCY frame. Returns false when
    /// the error was already active (nothing done).
    pub fn raise(&mut self, store: &mut Store, code: u16, info: [u8; 5]) -> bool {
        // An error that is already active is not a new event: one EMCY, one history entry,
        // until it is cleared (e.g. heartbeat loss followed by its 0x6007 fault reaction).
        if self.active.contains(&code) {
            return false;
        }
        if self.active.push(code).is_err() {
            // table full: keep the older errors, still report this one
        }
        let reg = self.register() | 0x01;
        store.set(R_1001, reg as u32);
        // history: shift down, newest in sub 1
        let n = (store.u32(R_1003) as usize).min(8);
        for s in (1..8).rev() {
            let v = store.u32(R_1003 + s);
            store.set(R_1003 + s + 1, v);
        }
        store.set(
            R_1003 + 1,
            code as u32 | (u16::from_le_bytes([info[0], info[1]]) as u32) << 16,
        );
        store.set(R_1003, (n + 1).min(8) as u32);
        let msg = EmcyFrame {
            code,
            register: reg,
            info,
        };
        self.push(msg.emit());
        true
    }

    /// An error went away; when none is left, send "error reset / no error". Returns false
    /// when the error was not active.
    pub fn clear(&mut self, store: &mut Store, code: u16) -> bool {
        let Some(p) = self.active.iter().position(|&c| c == code) else {
            return false;
        };
        self.active.swap_remove(p);
        let reg = self.register();
        store.set(R_1001, reg as u32);
        if self.active.is_empty() {
            self.push(RESET.emit());
        }
        true
    }

    /// The active error codes.
    pub fn active(&self) -> &[u16] {
        &self.active
    }

    /// Clear every active error (CiA 402 fault reset).
    pub fn clear_all(&mut self, store: &mut Store) {
        if !self.active.is_empty() {
            self.active.clear();
            store.set(R_1001, 0);
            self.push(RESET.emit());
        }
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
                .map_or(0, |l| l + inhibit_100us as u64 * 100),
        )
    }

    /// The next frame allowed by the inhibit time (100 us units), if any.
    pub fn next(&mut self, now_us: u64, inhibit_100us: u16) -> Option<[u8; 8]> {
        if self.queue.is_empty() {
            return None;
        }
        if let Some(l) = self.last_tx_us {
            if now_us < l + inhibit_100us as u64 * 100 {
                return None;
            }
        }
        self.last_tx_us = Some(now_us);
        self.queue.pop_front()
    }

    /// Drop queued frames (EMCY not allowed in this NMT state).
    pub fn discard_queue(&mut self) {
        self.queue.clear();
    }
}
