//! PDO mapping (CiA 301 7.5.2.36): validation of mapping entries and of a whole mapping,
//! packing and unpacking of the mapped values.

use super::layout::{PdoSlots, MAX_ENTRIES};
use super::Pdo;
use crate::cia301::sdo::abort;
use crate::od::{self, Backing, DataType, Lookup, ObjectDictionary, Store};

/// One mapped object: its slot (none for a dummy entry) and type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mapped {
    /// Slot in the store; `None` for a dummy entry (an RPDO skips those bits).
    pub slot: Option<u32>,
    /// Type of the value.
    pub dtype: DataType,
    /// An RPDO writes the received value (false: a read-only object the device ships in a
    /// default mapping; its bits are skipped).
    pub write: bool,
    /// Bits in the PDO: the type's size, or fewer for an entry the device ships mapping the
    /// low bits of a longer object (`DeviceDescription::shipped_short_entries`), or a BOOLEAN
    /// of 1 bit on a device of granularity 1.
    pub bits: u8,
}

impl Default for Mapped {
    fn default() -> Self {
        Mapped {
            slot: None,
            dtype: DataType::U8,
            write: true,
            bits: 8,
        }
    }
}

impl Mapped {
    /// Size in the PDO, whole bytes (an entry of whole bytes; see [`Mapped::bits`]).
    #[inline]
    pub fn bytes(&self) -> usize {
        usize::from(self.bits) / 8
    }

    /// Size in the PDO, bits.
    #[inline]
    pub fn bits(&self) -> usize {
        usize::from(self.bits)
    }
}

/// Check one mapping entry (index << 16 | sub << 8 | bits) for a TPDO (`tx`) or RPDO: a
/// visible, PDO-mappable, stored object of a fixed size whose bits are its size, readable
/// (TPDO) or writable (RPDO); or, in an RPDO, a dummy entry (a data type index 0x0001..=0x0007
/// that `[DummyUsage]` allows); or, where the device has them, a padding entry (index 0, sub 0,
/// whole bytes) in either. Fewer bits than the object has: an entry of the device's own
/// default maps (`DeviceDescription::shipped_short_entries`, the low bits), or a BOOLEAN of
/// 1 bit on a device of granularity 1 (CiA 301 encodes a BOOLEAN in 1 bit).
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
            bits: bits as u8,
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
            bits: bits as u8,
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
    // the device's own default map may take the low bits of a longer object
    let short = bits > 0 && bits < size * 8 && od.device.shipped_short_entries.contains(&entry);
    // a device of granularity 1 maps a BOOLEAN as CiA 301 encodes it, in 1 bit
    let bit_bool = bits == 1 && e.dtype == DataType::Boolean && od.device.granularity == 1;
    if !e.pdo
        || !access_ok
        || e.backing != Backing::Stored
        || size == 0
        || size > 8
        || (bits != size * 8 && !short && !bit_bool)
    {
        return Err(abort::NOT_MAPPABLE);
    }
    Ok(Mapped {
        slot: Some(slot.get() as u32),
        dtype: e.dtype,
        write: tx || e.access.writable(),
        bits: bits as u8,
    })
}

/// Bytes a PDO carries on CAN (one frame): the PDO engine's default limit.
pub const CAN_MAX_LEN: usize = 8;

/// A PDO's mapping as built by [`compile`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Compiled {
    /// The entries (the first `n`).
    pub map: [Mapped; MAX_ENTRIES],
    /// Mapped entries.
    pub n: u8,
    /// Bytes of the PDO: the entries' bits, rounded up to whole bytes.
    pub len: u8,
    /// Some entry is not whole bytes: the values sit at bit positions ([`pack`] and
    /// [`unpack`] take the bit path; whole bytes, the byte path).
    pub bitwise: bool,
}

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
) -> Result<Compiled, u32> {
    let mut map = [Mapped::default(); MAX_ENTRIES];
    if count > MAX_ENTRIES {
        return Err(abort::PDO_LENGTH);
    }
    let mut bits = 0usize;
    let mut bitwise = false;
    for (k, m) in map.iter_mut().enumerate().take(count) {
        let Some(s) = slots.entries[k] else {
            return Err(abort::NOT_MAPPABLE);
        };
        *m = check_entry(od, store.u32(s as usize), tx)?;
        bits += m.bits();
        bitwise |= !m.bits().is_multiple_of(8);
    }
    let len = bits.div_ceil(8);
    if len > max_len.min(usize::from(u8::MAX)) {
        return Err(abort::PDO_LENGTH);
    }
    Ok(Compiled {
        map,
        n: count as u8,
        len: len as u8,
        bitwise,
    })
}

/// Pack the mapped values of `p` into `out`; returns the length (the values that fit: a
/// mapping longer than `out` is cut at the last whole value). A mapping of whole bytes copies
/// bytes; one with an entry of fewer (`Pdo::bitwise`) puts each value's low bits at the
/// running bit position, LSB first (CiA 301), the bits after the last value 0.
pub fn pack(p: &Pdo, store: &Store, out: &mut [u8]) -> usize {
    let map = &p.map[..p.n as usize];
    if p.bitwise {
        return pack_bits(map, store, out);
    }
    let mut pos = 0;
    for m in map {
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

/// [`pack`] at bit positions.
fn pack_bits(map: &[Mapped], store: &Store, out: &mut [u8]) -> usize {
    let mut pos = 0;
    let room = out.len() * 8;
    for m in map {
        let n = m.bits();
        if pos + n > room {
            break;
        }
        let value = m.slot.map_or(0, |s| store.raw(s as usize));
        put_bits(out, pos, n, value);
        pos += n;
    }
    let len = pos.div_ceil(8);
    if !pos.is_multiple_of(8) {
        // the bits after the last value
        out[len - 1] &= low_mask(pos % 8) as u8;
    }
    len
}

/// The low `n` bits set (`n` <= 64).
#[inline]
fn low_mask(n: usize) -> u64 {
    if n >= 64 {
        u64::MAX
    } else {
        (1u64 << n) - 1
    }
}

/// Put the low `n` bits of `value` at bit `pos` of `out` (bit 0: the LSB of byte 0), the
/// other bits kept. `out` holds `pos + n` bits.
fn put_bits(out: &mut [u8], mut pos: usize, mut n: usize, mut value: u64) {
    while n > 0 {
        let shift = pos % 8;
        let take = (8 - shift).min(n);
        let mask = (low_mask(take) as u8) << shift;
        let b = &mut out[pos / 8];
        *b = (*b & !mask) | (((value as u8) << shift) & mask);
        value = value.checked_shr(take as u32).unwrap_or(0);
        pos += take;
        n -= take;
    }
}

/// The `n` bits at bit `pos` of `data` (bit 0: the LSB of byte 0), zero-extended. `data`
/// holds `pos + n` bits.
fn get_bits(data: &[u8], mut pos: usize, n: usize) -> u64 {
    let mut value = 0u64;
    let mut got = 0;
    while got < n {
        let shift = pos % 8;
        let take = (8 - shift).min(n - got);
        let part = u64::from(data[pos / 8] >> shift) & low_mask(take);
        value |= part << got;
        pos += take;
        got += take;
    }
    value
}

/// Hand the values of received `data` to the objects `map` maps, in order, through
/// `write(slot, raw)`: the node's write path, which checks each value as an SDO write is
/// checked (type limits, then the rule of the service that owns the object) and stores it or
/// refuses it (false). A refused value is not written and the object keeps its value, the
/// others are written (as CANopenNode does). Dummy entries and read-only entries a device
/// ships in its default mapping are skipped. With `bitwise` (the mapping's
/// [`Compiled::bitwise`]) the values sit at bit positions. Returns false if any value was
/// refused.
pub fn unpack(
    map: &[Mapped],
    bitwise: bool,
    data: &[u8],
    mut write: impl FnMut(usize, u64) -> bool,
) -> bool {
    if bitwise {
        return unpack_bits(map, data, write);
    }
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

/// [`unpack`] at bit positions: each value its entry's bits, zero-extended to its type.
fn unpack_bits(map: &[Mapped], data: &[u8], mut write: impl FnMut(usize, u64) -> bool) -> bool {
    let mut pos = 0;
    let mut all = true;
    for m in map {
        let n = m.bits();
        if pos + n > data.len() * 8 {
            return false;
        }
        if let (Some(s), true) = (m.slot, m.write) {
            let full = get_bits(data, pos, n).to_le_bytes();
            let raw = od::decode(m.dtype, &full[..m.dtype.size().clamp(1, 8)]);
            all &= write(s as usize, raw);
        }
        pos += n;
    }
    all
}

#[cfg(test)]
mod tests {
    use super::{get_bits, low_mask, put_bits};
    use proptest::prelude::*;

    /// Pack `fields` (width in bits, value) one after the other from bit 0, as `pack_bits`
    /// does, into a buffer of `fill` bytes; returns the buffer.
    fn pack_fields(fields: &[(usize, u64)], fill: u8) -> [u8; 16] {
        let mut out = [fill; 16];
        let mut pos = 0;
        for &(n, v) in fields {
            put_bits(&mut out, pos, n, v);
            pos += n;
        }
        out
    }

    #[test]
    fn values_sit_lsb_first_at_continuous_bit_positions() {
        // 1 bit, 1 bit, 16 bits across bytes 0..=2, 3 bits, 1 bit: CiA 301's order
        let out = pack_fields(&[(1, 1), (1, 0), (16, 0xABCD), (3, 0b101), (1, 1)], 0);
        // bits 0..2: 1, 0; bits 2..18: 0xABCD; bits 18..21: 0b101; bit 21: 1
        let want: u32 = 1 | (0xABCD << 2) | (0b101 << 18) | (1 << 21);
        assert_eq!(&out[..3], &want.to_le_bytes()[..3]);
        assert_eq!(out[3], 0);
        assert_eq!(get_bits(&out, 2, 16), 0xABCD);
        assert_eq!(get_bits(&out, 18, 3), 0b101);
        assert_eq!(get_bits(&out, 21, 1), 1);
    }

    #[test]
    fn only_the_low_bits_of_a_value_go_in_and_the_neighbours_are_kept() {
        let mut out = [0xFFu8; 3];
        put_bits(&mut out, 5, 9, 0);
        assert_eq!(out, [0x1F, 0xC0, 0xFF]);
        let mut out = [0u8; 3];
        // a value wider than its entry: its high bits are dropped
        put_bits(&mut out, 3, 4, 0xFFFF_FFFF_FFFF_FFF5);
        assert_eq!(out, [0x5 << 3, 0, 0]);
        let mut out = [0u8; 9];
        put_bits(&mut out, 7, 64, u64::MAX);
        assert_eq!(get_bits(&out, 7, 64), u64::MAX);
        assert_eq!(get_bits(&out, 0, 7), 0);
        assert_eq!(get_bits(&out, 71, 1), 0);
    }

    proptest! {
        /// A sweep of layouts: any widths 1..=64 bits at any positions, up to 128 bits; the
        /// values read back are the values put, cut to their width, whatever the buffer held.
        #[test]
        fn put_then_get_gives_the_values_back(
            fields in prop::collection::vec((1usize..=64, any::<u64>()), 1..12),
            fill in any::<u8>(),
        ) {
            let mut total = 0;
            let fields: Vec<(usize, u64)> = fields
                .into_iter()
                .take_while(|(n, _)| {
                    total += n;
                    total <= 128
                })
                .collect();
            let out = pack_fields(&fields, fill);
            let mut pos = 0;
            for &(n, v) in &fields {
                prop_assert_eq!(get_bits(&out, pos, n), v & low_mask(n), "at bit {}", pos);
                pos += n;
            }
            // the bits after the last value are the buffer's own
            let rest = 128 - pos;
            let tail = get_bits(&out, pos, rest.min(64));
            let fill_bits = (u128::from_le_bytes([fill; 16]) >> (pos % 8)) as u64;
            prop_assert_eq!(tail, fill_bits & low_mask(rest.min(64)));
        }
    }
}
