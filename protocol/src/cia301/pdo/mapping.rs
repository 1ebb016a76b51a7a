//! PDO mapping (CiA 301 7.5.2.36): validation of mapping entries and of a whole mapping,
//! packing and unpacking of the mapped values.

use super::Pdo;
use crate::cia301::sdo::abort;
use crate::od::{self, Lookup, Store, OBJECTS};

/// One mapped object: its row in the table and its size.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Mapped {
    /// Row in the object table.
    pub row: u16,
    /// Size in bytes.
    pub bytes: u8,
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

/// Pack the mapped values of `p` into `out`; returns the length.
pub fn pack(p: &Pdo, store: &Store, out: &mut [u8; 8]) -> usize {
    let mut pos = 0;
    for m in &p.map[..p.n as usize] {
        let b = store.u32(m.row as usize).to_le_bytes();
        let n = m.bytes as usize;
        out[pos..pos + n].copy_from_slice(&b[..n]);
        pos += n;
    }
    pos
}

/// Write received data to the objects `p` maps.
pub fn unpack(p: &Pdo, store: &mut Store, data: &[u8]) {
    let mut pos = 0;
    for m in &p.map[..p.n as usize] {
        let n = m.bytes as usize;
        let o = &OBJECTS[m.row as usize];
        store.set(m.row as usize, o.decode(&data[pos..pos + n]));
        pos += n;
    }
}
