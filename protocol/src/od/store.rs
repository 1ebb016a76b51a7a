//! The values of one node's objects. Every slot of the dictionary (visible or hidden) has a
//! 64-bit value (raw bits, signed types sign-extended, REAL as IEEE bits); a string or DOMAIN
//! slot also has a span of a byte arena, sized by its capacity when the node is built.
//! Nothing here allocates after [`Store::new`] ([`Store::copy_from`] included).

use super::{DefaultValue, ObjectDictionary};

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Span {
    off: u32,
    cap: u32,
    len: u32,
}

/// The values of one node's objects.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Store {
    vals: Vec<u64>,
    spans: Vec<Span>,
    bytes: Vec<u8>,
}

impl Store {
    /// A store for `od` with every value at its default for `node_id`.
    pub fn new(od: &ObjectDictionary, node_id: u8) -> Store {
        let mut spans = Vec::with_capacity(od.slot_count());
        let mut off = 0u32;
        for e in od.all_slots() {
            let cap = if e.dtype.variable() {
                e.capacity as u32
            } else {
                0
            };
            spans.push(Span { off, cap, len: 0 });
            off += cap;
        }
        let mut s = Store {
            vals: vec![0; od.slot_count()],
            spans,
            bytes: vec![0; off as usize],
        };
        s.reset_range(od, 0x0000, 0xFFFF, node_id);
        s
    }

    /// Reset the slots with index in `lo..=hi` to their defaults.
    pub fn reset_range(&mut self, od: &ObjectDictionary, lo: u16, hi: u16, node_id: u8) {
        for (i, e) in od.all_slots().enumerate() {
            if e.index < lo || e.index > hi {
                continue;
            }
            match &e.default {
                DefaultValue::Bytes(b) => {
                    let sp = &mut self.spans[i];
                    let n = b.len().min(sp.cap as usize);
                    let off = sp.off as usize;
                    self.bytes[off..off + n].copy_from_slice(&b[..n]);
                    sp.len = n as u32;
                    self.vals[i] = 0;
                }
                _ => self.vals[i] = e.default_raw(node_id),
            }
        }
    }

    /// Copy the slots with index in `lo..=hi` from `from` (restore of saved parameters,
    /// 0x1011); `from` is a store of the same dictionary.
    pub fn copy_range(&mut self, from: &Store, od: &ObjectDictionary, lo: u16, hi: u16) {
        for (i, e) in od.all_slots().enumerate() {
            if e.index >= lo && e.index <= hi {
                self.vals[i] = from.vals[i];
                let sp = self.spans[i];
                let (o, n) = (sp.off as usize, sp.cap as usize);
                self.bytes[o..o + n].copy_from_slice(&from.bytes[o..o + n]);
                self.spans[i].len = from.spans[i].len;
            }
        }
    }

    /// Become a copy of `from` (a store of the same dictionary) without allocating.
    pub fn copy_from(&mut self, from: &Store) {
        self.vals.copy_from_slice(&from.vals);
        self.spans.copy_from_slice(&from.spans);
        self.bytes.copy_from_slice(&from.bytes);
    }

    #[inline]
    pub fn u32(&self, i: usize) -> u32 {
        self.vals[i] as u32
    }
    #[inline]
    pub fn i32(&self, i: usize) -> i32 {
        self.vals[i] as i32
    }
    #[inline]
    pub fn raw(&self, i: usize) -> u64 {
        self.vals[i]
    }
    /// Set a value (raw form; a signed value sign-extended).
    #[inline]
    pub fn set(&mut self, i: usize, v: u64) {
        self.vals[i] = v;
    }
    /// Set a value of a 32-bit (or smaller) unsigned object.
    #[inline]
    pub fn set_u32(&mut self, i: usize, v: u32) {
        self.vals[i] = v as u64;
    }
    /// Set a value of a signed object.
    #[inline]
    pub fn set_i32(&mut self, i: usize, v: i32) {
        self.vals[i] = v as i64 as u64;
    }

    /// Little-endian wire bytes of slot `i` (`size` bytes of its type; 0 for variable types)
    /// into `out`; returns the length.
    pub fn read_bytes(&self, i: usize, size: usize, out: &mut [u8]) -> usize {
        if size == 0 {
            let sp = self.spans[i];
            let n = (sp.len as usize).min(out.len());
            out[..n].copy_from_slice(&self.bytes[sp.off as usize..sp.off as usize + n]);
            return n;
        }
        let n = size.min(out.len()).min(8);
        out[..n].copy_from_slice(&self.vals[i].to_le_bytes()[..n]);
        n
    }

    /// Length of the variable-length value of slot `i` as stored (0 for fixed-size types).
    pub(crate) fn stored_len(&self, i: usize) -> usize {
        self.spans.get(i).map_or(0, |s| s.len as usize)
    }

    /// Store the bytes of a variable-length value; false if they exceed the capacity.
    pub fn write_bytes(&mut self, i: usize, data: &[u8]) -> bool {
        let sp = &mut self.spans[i];
        if data.len() > sp.cap as usize {
            return false;
        }
        let off = sp.off as usize;
        self.bytes[off..off + data.len()].copy_from_slice(data);
        sp.len = data.len() as u32;
        true
    }

    /// The largest capacity of any slot (the SDO server's buffer).
    pub fn max_capacity(&self) -> usize {
        self.spans.iter().map(|s| s.cap as usize).max().unwrap_or(0)
    }
}
