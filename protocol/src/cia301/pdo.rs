//! PDOs: 4 RPDOs and 4 TPDOs. Mapping validation (CiA 301 dynamic mapping), packing and
//! unpacking, and the transmission-type state of each PDO. The node decides *when* (SYNC,
//! event, inhibit and event timers); this file holds the per-PDO state and the rules.
//!
//! Transmission types: TPDO 0 (acyclic synchronous: at SYNC if the data changed), 1-240
//! (every n-th SYNC), 252 (sampled at SYNC, sent on RTR), 253 (sent on RTR), 254/255 (on
//! change, limited by the inhibit time 0x18xx sub 3, and periodically by the event timer
//! sub 5). RPDO 0-240 are applied at the next SYNC, 254/255 at once.
//!
//! RPDO length (as CANopenNode): a frame longer than the mapping is used (its mapped bytes)
//! and reported with EMCY 0x8220, a shorter one is ignored and reported with EMCY 0x8210;
//! the error stays active until that RPDO arrives with the right length (or an NMT reset).

use crate::cia301::sdo::abort;
use crate::od::{self, Lookup, Store, OBJECTS};

/// One mapped object: its row in the table and its size.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Mapped {
    pub row: u16,
    pub bytes: u8,
}

/// Runtime state of one PDO.
#[derive(Clone, Copy, Debug, Default)]
pub struct Pdo {
    pub valid: bool,
    pub cob: u32,
    pub ttype: u8,
    pub map: [Mapped; 8],
    pub n: u8,
    pub len: u8,
    // TPDO
    pub last: [u8; 8],
    pub has_last: bool,
    pub sync_count: u8,
    pub last_tx_us: Option<u64>,
    pub sampled: [u8; 8],
    // RPDO
    pub rx: [u8; 8],
    pub rx_pending: bool,
    /// EMCY code of the length error this RPDO currently holds (0 = none).
    pub len_error: u16,
    /// The last RPDO carried a value the drive refused (EMCY held until a valid one).
    pub value_error: bool,
}

/// Check one mapping entry (index << 16 | sub << 8 | bits) for a TPDO (`tx`) or RPDO.
pub fn check_entry(entry: u32, tx: bool) -> Result<Mapped, u32> {
    let index = (entry >> 16) as u16;
    let sub = (entry >> 8) as u8;
    let bits = entry as u8;
    let Lookup::Found(row) = od::find(index, sub) else {
        return Err(abort::NOT_MAPPABLE);
    };
    let o = &OBJECTS[row];
    let access_ok = if tx {
        o.access.readable()
    } else {
        o.access.writable()
    };
    if !o.pdo || !access_ok || o.dtype.size() == 0 || bits as usize != o.dtype.size() * 8 {
        return Err(abort::NOT_MAPPABLE);
    }
    Ok(Mapped {
        row: row as u16,
        bytes: bits / 8,
    })
}

/// Build a PDO's mapping from the store (`count` entries starting at row `map_row + 1`).
/// Fails with 0x06040041 / 0x06040042.
pub fn compile(
    store: &Store,
    map_row: usize,
    count: usize,
    tx: bool,
) -> Result<([Mapped; 8], u8, u8), u32> {
    let mut map = [Mapped::default(); 8];
    let mut len = 0usize;
    let count = count.min(8);
    for (k, m) in map.iter_mut().enumerate().take(count) {
        let e = store.u32(map_row + 1 + k);
        *m = check_entry(e, tx)?;
        len += m.bytes as usize;
    }
    if len > 8 {
        return Err(abort::PDO_LENGTH);
    }
    Ok((map, count as u8, len as u8))
}

impl Pdo {
    /// Pack the mapped values into `out`; returns the length.
    pub fn pack(&self, store: &Store, out: &mut [u8; 8]) -> usize {
        let mut pos = 0;
        for m in &self.map[..self.n as usize] {
            let b = store.u32(m.row as usize).to_le_bytes();
            let n = m.bytes as usize;
            out[pos..pos + n].copy_from_slice(&b[..n]);
            pos += n;
        }
        pos
    }

    /// Write received data (the mapped bytes; a longer frame's extra bytes are not looked
    /// at) to the mapped objects. Each value must pass `accept(store, row, raw)` (the checks
    /// an SDO write makes); a refused value is not written and the object keeps its value,
    /// the others are written (as CANopenNode does). Returns false if any value was refused.
    pub fn unpack(
        &self,
        store: &mut Store,
        data: &[u8],
        accept: impl Fn(&Store, usize, u32) -> bool,
    ) -> bool {
        let mut pos = 0;
        let mut all = true;
        for m in &self.map[..self.n as usize] {
            let n = m.bytes as usize;
            let row = m.row as usize;
            let Some(bytes) = data.get(pos..pos + n) else {
                return false;
            };
            let raw = OBJECTS[row].decode(bytes);
            if accept(store, row, raw) {
                store.set(row, raw);
            } else {
                all = false;
            }
            pos += n;
        }
        all
    }

    pub fn is_sync_rx(&self) -> bool {
        self.ttype <= 240
    }
}

/// Allowed transmission types.
pub fn valid_ttype(t: u32, tx: bool) -> bool {
    match t {
        0..=240 | 254 | 255 => true,
        252 | 253 => tx,
        _ => false,
    }
}
