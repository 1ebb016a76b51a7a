//! PDO mapping (CiA 301 7.5.2.36): validation of mapping entries and of a whole mapping,
//! packing and unpacking of the mapped values.

use super::layout::{PdoSlots, MAX_ENTRIES};
use super::Pdo;
use crate::cia301::sdo::abort;
use crate::od::{self, Backing, DataType, Lookup, ObjectDictionary, Store};

/// One mapped object: its slot (none for a dummy entry) and type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mapped {
    /// Slot in the store; `None` for a dummy entry (an RPDO skips those bytes).
    pub slot: Option<u32>,
    /// Type of the value.
    pub dtype: DataType,
    /// An RPDO writes the received value (false: a read-only object the device ships in a
    /// default mapping; its bytes are skipped).
    pub write: bool,
    /// Bytes in the PDO: the type's size, or fewer for an entry the device ships mapping
    /// the low bytes of a longer object (`DeviceDescription::shipped_short_entries`).
    pub len: u8,
}

impl Default for Mapped {
    fn default() -> Self {
        Mapped {
            slot: None,
            dtype: DataType::U8,
            write: true,
            len: 1,
        }
    }
}

impl Mapped {
    /// Size in the PDO, bytes.
    pub fn bytes(&self) -> usize {
        self.len as usize
    }
}

/// Check one mapping entry (index << 16 | sub << 8 | bits) for a TPDO (`tx`) or RPDO: a
/// visible, PDO-mappable, stored object of a fixed size whose bits are its size, readable
/// (TPDO) or writable (RPDO); or, in an RPDO, a dummy entry (a data type index 0x0001..=0x0007
/// that `[DummyUsage]` allows); or, where the device has them, a padding entry (index 0, sub 0,
/// whole bytes) in either.
pub fn check_entry(od: &ObjectDictionary, entry: u32, tx: bool) -> Result<Mapped, u32> {
    let index = (entry >> 16) as u16;
    let sub = (entry >> 8) as u8;
    let bits = entry as u8 as usize;
    if index == 0 && sub == 0 && od.device.padding_entries {
        // a gap of whole bytes (EtherCAT padding)
        if bits == 0 || !bits.is_multiple_of(8) {
            return Err(abort::NOT_MAPPABLE);
        }
        return Ok(Mapped {
            slot: None,
            dtype: DataType::U8,
            write: false,
            len: (bits / 8) as u8,
        });
    }
    if (1..=7).contains(&index) {
        let dtype = DataType::from_code(index).ok_or(abort::NOT_MAPPABLE)?;
        if tx || !od.device.dummy_usage[index as usize] || bits != dtype.size() * 8 {
            return Err(abort::NOT_MAPPABLE);
        }
        return Ok(Mapped {
            slot: None,
            dtype,
            write: false,
            len: dtype.size() as u8,
        });
    }
    let Lookup::Found(slot) = od.find(index, sub) else {
        return Err(abort::NOT_MAPPABLE);
    };
    let e = od.entry(slot);
    let shipped =
        !tx && e.access.readable() && od.device.shipped_read_only_rpdo_entries.contains(&entry);
    let access_ok = if tx {
        e.access.readable()
    } else {
        e.access.writable() || shipped
    };
    let size = e.dtype.size();
    // the device's own default map may take the low bytes of a longer object
    let short = bits.is_multiple_of(8)
        && bits > 0
        && bits < size * 8
        && od.device.shipped_short_entries.contains(&entry);
    if !e.pdo
        || !access_ok
        || e.backing != Backing::Stored
        || size == 0
        || size > 8
        || (bits != size * 8 && !short)
    {
        return Err(abort::NOT_MAPPABLE);
    }
    Ok(Mapped {
        slot: Some(slot.get() as u32),
        dtype: e.dtype,
        write: tx || e.access.writable(),
        len: (bits / 8) as u8,
    })
}

/// Bytes a PDO carries on CAN (one frame): the PDO engine's default limit.
pub const CAN_MAX_LEN: usize = 8;

/// Build a PDO's mapping from the store (`count` entries of `slots`), at most `max_len`
/// bytes (the front end's limit: [`CAN_MAX_LEN`] on CAN, more where a PDO is not one CAN
/// frame). Fails with 0x06040041 / 0x06040042.
pub fn compile(
    od: &ObjectDictionary,
    store: &Store,
    slots: &PdoSlots,
    count: usize,
    tx: bool,
    max_len: usize,
) -> Result<([Mapped; MAX_ENTRIES], u8, u8), u32> {
    let mut map = [Mapped::default(); MAX_ENTRIES];
    if count > MAX_ENTRIES {
        return Err(abort::PDO_LENGTH);
    }
    let mut len = 0usize;
    for (k, m) in map.iter_mut().enumerate().take(count) {
        let Some(s) = slots.entries[k] else {
            return Err(abort::NOT_MAPPABLE);
        };
        *m = check_entry(od, store.u32(s as usize), tx)?;
        len += m.bytes();
    }
    if len > max_len.min(usize::from(u8::MAX)) {
        return Err(abort::PDO_LENGTH);
    }
    Ok((map, count as u8, len as u8))
}

/// Pack the mapped values of `p` into `out`; returns the length (the values that fit: a
/// mapping longer than `out` is cut at the last whole value).
pub fn pack(p: &Pdo, store: &Store, out: &mut [u8]) -> usize {
    let mut pos = 0;
    for m in &p.map[..p.n as usize] {
        let n = m.bytes();
        let Some(dst) = out.get_mut(pos..pos + n) else {
            break;
        };
        match m.slot {
            Some(s) => {
                store.read_bytes(s as usize, n, dst);
            }
            None => dst.fill(0),
        }
        pos += n;
    }
    pos
}

/// Hand the values of received `data` to the objects `map` maps, in order, through
/// `write(slot, raw)`: the node's write path, which checks each value as an SDO write is
/// checked (type limits, then the rule of the service that owns the object) and stores it or
/// refuses it (false). A refused value is not written and the object keeps its value, the
/// others are written (as CANopenNode does). Dummy entries and read-only entries a device
/// ships in its default mapping are skipped. Returns false if any value was refused.
pub fn unpack(map: &[Mapped], data: &[u8], mut write: impl FnMut(usize, u64) -> bool) -> bool {
    let mut pos = 0;
    let mut all = true;
    for m in map {
        let n = m.bytes();
        let Some(bytes) = data.get(pos..pos + n) else {
            return false;
        };
        if let (Some(s), true) = (m.slot, m.write) {
            // a short entry: the low bytes, zero-extended to the type's size
            let mut full = [0u8; 8];
            full[..n].copy_from_slice(bytes);
            let raw = od::decode(m.dtype, &full[..m.dtype.size().max(n)]);
            all &= write(s as usize, raw);
        }
        pos += n;
    }
    all
}
