//! RPDO reception: match the COB-ID, check the length, apply at once (event-driven types)
//! or hold until the next SYNC (synchronous types 0..=240).
//!
//! Length (as CANopenNode): a frame longer than the mapping is used (its mapped bytes) and
//! reported with EMCY 0x8220, a shorter one is ignored and reported with EMCY 0x8210. The
//! node applies the data ([`super::mapping::unpack`] through its write path, so each value
//! passes the rules of an SDO write) and holds the EMCYs while the condition lasts.

use super::PdoEngine;
use crate::frame::CanFrame;

/// EMCY code for an RPDO shorter than its mapping (ignored).
pub const EMCY_PDO_LENGTH: u16 = 0x8210;
/// EMCY code for an RPDO longer than its mapping (its mapped bytes are used).
pub const EMCY_PDO_LENGTH_EXCEEDED: u16 = 0x8220;

/// What a received frame did to the RPDOs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RxOutcome {
    /// No valid RPDO has this identifier.
    NotRpdo,
    /// RPDO `k` (0..4) received `len` bytes.
    Received {
        /// RPDO index 0..4.
        k: usize,
        /// Received length.
        len: u8,
        /// Length error EMCY code (0: the mapped length).
        length_code: u16,
        /// The frame's data is to be applied now (an event-driven RPDO of the right length
        /// or longer); false when it is too short or held for SYNC.
        apply: bool,
    },
}

impl PdoEngine {
    /// A data frame received in operational.
    pub fn receive(&mut self, frame: &CanFrame) -> RxOutcome {
        if frame.rtr {
            return RxOutcome::NotRpdo;
        }
        for k in 0..self.rpdo.len() {
            let p = &mut self.rpdo[k];
            if !p.valid || p.id() != frame.id {
                continue;
            }
            let length_code = match frame.len.cmp(&p.len) {
                core::cmp::Ordering::Less => EMCY_PDO_LENGTH,
                core::cmp::Ordering::Equal => 0,
                core::cmp::Ordering::Greater => EMCY_PDO_LENGTH_EXCEEDED,
            };
            let mut apply = false;
            if length_code != EMCY_PDO_LENGTH {
                if p.ttype.is_sync() {
                    p.rx = frame.data;
                    p.rx_pending = true;
                } else {
                    apply = true;
                }
            }
            return RxOutcome::Received {
                k,
                len: frame.len,
                length_code,
                apply,
            };
        }
        RxOutcome::NotRpdo
    }

    /// At SYNC: the data synchronous RPDO `k` received since the last SYNC, to apply now
    /// (`None`: nothing to apply).
    pub fn take_sync_rpdo(&mut self, k: usize) -> Option<[u8; 8]> {
        let p = &mut self.rpdo[k];
        if p.valid && p.rx_pending && p.ttype.is_sync() {
            p.rx_pending = false;
            return Some(p.rx);
        }
        None
    }
}
