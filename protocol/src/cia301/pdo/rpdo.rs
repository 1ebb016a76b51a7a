//! RPDO reception: match the COB-ID, check the length, apply at once (event-driven types)
//! or hold until the next SYNC (synchronous types 0..=240).
//!
//! Length (as CANopenNode): a frame longer than the mapping is used (its mapped bytes) and
//! reported with EMCY 0x8220, a shorter one is ignored and reported with EMCY 0x8210. Values
//! pass the checks of an SDO write (`accept`); a refused one is not written. The node holds
//! the EMCYs while the condition lasts.

use super::PdoEngine;
use crate::frame::CanFrame;
use crate::od::Store;

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
        /// Whether every value was accepted; `None` when nothing was applied now (too
        /// short, or held for SYNC).
        values_ok: Option<bool>,
    },
}

impl PdoEngine {
    /// A data frame received in operational.
    pub fn receive(
        &mut self,
        store: &mut Store,
        frame: &CanFrame,
        accept: impl Fn(&Store, usize, u64) -> bool,
    ) -> RxOutcome {
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
            let mut values_ok = None;
            if length_code != EMCY_PDO_LENGTH {
                if p.ttype.is_sync() {
                    p.rx = frame.data;
                    p.rx_pending = true;
                } else {
                    let data = frame.data;
                    values_ok = Some(p.unpack(store, &data[..p.len as usize], accept));
                }
            }
            return RxOutcome::Received {
                k,
                len: frame.len,
                length_code,
                values_ok,
            };
        }
        RxOutcome::NotRpdo
    }

    /// At SYNC: apply synchronous RPDO `k` if it received data since the last SYNC.
    /// Whether its values were all accepted (`None`: nothing applied).
    pub fn apply_sync_rpdo(
        &mut self,
        k: usize,
        store: &mut Store,
        accept: impl Fn(&Store, usize, u64) -> bool,
    ) -> Option<bool> {
        let p = &mut self.rpdo[k];
        if p.valid && p.rx_pending && p.ttype.is_sync() {
            p.rx_pending = false;
            let data = p.rx;
            return Some(p.unpack(store, &data[..p.len as usize], accept));
        }
        None
    }
}
