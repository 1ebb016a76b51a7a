//! RPDO reception: match the COB-ID, check the length, apply at once (event-driven types)
//! or hold until the next SYNC (synchronous types 0..=240).

use super::PdoEngine;
use crate::frame::CanFrame;
use crate::od::Store;

/// What a received frame did to the RPDOs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RxOutcome {
    /// No valid RPDO has this identifier.
    NotRpdo,
    /// Applied, or held for SYNC.
    Accepted,
    /// RPDO `number` (1..=4) got `len` bytes instead of `expected`, reported for the first
    /// time since its last good frame (the node raises EMCY 0x8210).
    WrongLength {
        /// RPDO number 1..=4.
        number: u8,
        /// Received length.
        len: u8,
        /// Mapped length.
        expected: u8,
    },
    /// Wrong length again: ignored, already reported.
    WrongLengthRepeated,
}

impl PdoEngine {
    /// A data frame received in operational.
    pub fn receive(&mut self, store: &mut Store, frame: &CanFrame) -> RxOutcome {
        if frame.rtr {
            return RxOutcome::NotRpdo;
        }
        for k in 0..4 {
            let p = &mut self.rpdo[k];
            if !p.valid || p.id() != frame.id {
                continue;
            }
            if frame.len != p.len {
                if p.len_error {
                    return RxOutcome::WrongLengthRepeated;
                }
                p.len_error = true;
                return RxOutcome::WrongLength {
                    number: k as u8 + 1,
                    len: frame.len,
                    expected: p.len,
                };
            }
            p.len_error = false;
            if p.ttype.is_sync() {
                p.rx = frame.data;
                p.rx_pending = true;
            } else {
                p.unpack(store, frame.payload());
            }
            return RxOutcome::Accepted;
        }
        RxOutcome::NotRpdo
    }

    /// At SYNC: apply the synchronous RPDOs received since the last one.
    pub fn apply_sync_rpdos(&mut self, store: &mut Store) {
        for p in self.rpdo.iter_mut() {
            if p.valid && p.rx_pending && p.ttype.is_sync() {
                p.rx_pending = false;
                let data = p.rx;
                p.unpack(store, &data[..p.len as usize]);
            }
        }
    }
}
