//! A single-writer, many-reader ring of fixed-size records: a seqlock per slot.
//!
//! The writer (the loop thread) never waits: it overwrites the oldest slot. Each reader keeps
//! its own [`Cursor`] and reads without taking anything away from the others; a reader that
//! falls more than the ring's capacity behind skips to the oldest record still there and counts
//! what it missed. Every word of a slot is an atomic, so a read that races a write is not a
//! data race: it is detected by the slot's sequence number (odd while written, `2n + 2` once
//! record `n` is complete) and the record is counted as lost (H.-J. Boehm, "Can seqlocks get
//! along with programming language memory models?", MSPC 2012: relaxed data accesses between a
//! release fence on the writer's side and an acquire fence on the reader's).

use std::sync::atomic::{fence, AtomicU64, Ordering};
use std::sync::Arc;

struct Slot<const W: usize> {
    /// `2n + 1` while record `n` is written, `2n + 2` once it is complete; 0: never written.
    seq: AtomicU64,
    words: [AtomicU64; W],
}

/// The shared ring: readers hold it in an `Arc`; its one writer is the [`RingWriter`].
pub struct SeqRing<const W: usize> {
    slots: Box<[Slot<W>]>,
    /// Records written so far (the next record's number).
    head: AtomicU64,
}

/// The ring's only writer (not `Clone`): whoever owns it may push.
pub struct RingWriter<const W: usize> {
    ring: Arc<SeqRing<W>>,
    next: u64,
}

/// Why a record could not be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReadError {
    /// Not written yet.
    NotYet,
    /// Overwritten by a newer record (or being overwritten while read).
    Overwritten,
}

impl<const W: usize> SeqRing<W> {
    /// A ring of `capacity` records (at least 2), allocated here once, and its writer.
    pub fn new(capacity: usize) -> (RingWriter<W>, Arc<SeqRing<W>>) {
        assert!(capacity >= 2, "a ring needs at least two slots");
        let slots = (0..capacity)
            .map(|_| Slot {
                seq: AtomicU64::new(0),
                words: std::array::from_fn(|_| AtomicU64::new(0)),
            })
            .collect();
        let ring = Arc::new(SeqRing {
            slots,
            head: AtomicU64::new(0),
        });
        (
            RingWriter {
                ring: Arc::clone(&ring),
                next: 0,
            },
            ring,
        )
    }

    pub fn capacity(&self) -> usize {
        self.slots.len()
    }

    /// Records written so far.
    pub fn written(&self) -> u64 {
        self.head.load(Ordering::Acquire)
    }

    /// Read record `n` into `out`.
    pub fn read(&self, n: u64, out: &mut [u64; W]) -> Result<(), ReadError> {
        let slot = &self.slots[(n % self.slots.len() as u64) as usize];
        let want = 2 * n + 2;
        let s1 = slot.seq.load(Ordering::Acquire);
        if s1 != want {
            return Err(if s1 < want {
                ReadError::NotYet
            } else {
                ReadError::Overwritten
            });
        }
        for (o, w) in out.iter_mut().zip(&slot.words) {
            *o = w.load(Ordering::Relaxed);
        }
        fence(Ordering::Acquire);
        if slot.seq.load(Ordering::Relaxed) != want {
            return Err(ReadError::Overwritten);
        }
        Ok(())
    }
}

impl<const W: usize> RingWriter<W> {
    /// Write the next record over the oldest one. Wait-free: a fixed number of atomic stores,
    /// no allocation, no lock.
    #[inline]
    pub fn push(&mut self, words: &[u64; W]) {
        let r = &*self.ring;
        let n = self.next;
        let slot = &r.slots[(n % r.slots.len() as u64) as usize];
        slot.seq.store(2 * n + 1, Ordering::Relaxed);
        fence(Ordering::Release);
        for (w, v) in slot.words.iter().zip(words) {
            w.store(*v, Ordering::Relaxed);
        }
        slot.seq.store(2 * n + 2, Ordering::Release);
        self.next = n + 1;
        r.head.store(n + 1, Ordering::Release);
    }

    /// The ring this writer fills.
    pub fn ring(&self) -> &Arc<SeqRing<W>> {
        &self.ring
    }
}

/// One reader's place in a ring.
#[derive(Debug, Clone, Default)]
pub struct Cursor {
    next: u64,
    /// Records this reader missed (it fell behind by more than the capacity, or a record was
    /// overwritten while it read it).
    pub lost: u64,
}

impl Cursor {
    /// A cursor at the ring's next record: it reads what is written from now on.
    pub fn at_end<const W: usize>(ring: &SeqRing<W>) -> Self {
        Cursor {
            next: ring.written(),
            lost: 0,
        }
    }

    /// A cursor at the oldest record the ring still holds.
    pub fn at_oldest<const W: usize>(ring: &SeqRing<W>) -> Self {
        let head = ring.written();
        Cursor {
            next: head.saturating_sub(ring.capacity() as u64),
            lost: 0,
        }
    }

    /// The number of the next record this cursor reads.
    pub fn position(&self) -> u64 {
        self.next
    }

    /// The next record, if one was written since; skips (and counts) what was overwritten.
    pub fn next<const W: usize>(&mut self, ring: &SeqRing<W>, out: &mut [u64; W]) -> bool {
        loop {
            let head = ring.written();
            if self.next >= head {
                return false;
            }
            let cap = ring.capacity() as u64;
            if head - self.next > cap {
                // Skip to the oldest record still there, leaving one slot of margin for the
                // one the writer may be overwriting right now.
                let to = head - cap + 1;
                self.lost += to - self.next;
                self.next = to;
            }
            match ring.read(self.next, out) {
                Ok(()) => {
                    self.next += 1;
                    return true;
                }
                Err(ReadError::Overwritten) => {
                    self.lost += 1;
                    self.next += 1;
                }
                Err(ReadError::NotYet) => return false,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A record whose words all derive from one number: a torn read shows as words that
    /// disagree.
    fn record(n: u64) -> [u64; 8] {
        std::array::from_fn(|i| n.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (i as u64) << 56)
    }

    fn consistent(w: &[u64; 8]) -> Option<u64> {
        let n = w[0].wrapping_mul(0xF1DE_83E1_9937_733D); // the odd factor's inverse mod 2^64
        (*w == record(n)).then_some(n)
    }

    #[test]
    fn the_inverse_factor_is_right() {
        for n in [0u64, 1, 7, 123_456_789, u64::MAX / 3] {
            assert_eq!(consistent(&record(n)), Some(n));
        }
    }

    #[test]
    fn a_reader_gets_every_record_in_order_when_it_keeps_up() {
        let (mut w, ring) = SeqRing::<8>::new(16);
        let mut c = Cursor::at_end(&ring);
        let mut out = [0; 8];
        assert!(!c.next(&ring, &mut out), "nothing written yet");
        let mut seen = Vec::new();
        for n in 0..100u64 {
            w.push(&record(n));
            if n % 10 == 9 {
                while c.next(&ring, &mut out) {
                    seen.push(consistent(&out).unwrap());
                }
            }
        }
        assert_eq!(seen, (0..100).collect::<Vec<_>>());
        assert_eq!(c.lost, 0);
    }

    #[test]
    fn a_reader_that_stops_loses_the_oldest_records_and_counts_them() {
        let (mut w, ring) = SeqRing::<8>::new(16);
        let mut slow = Cursor::at_end(&ring);
        let mut fast = Cursor::at_end(&ring);
        let mut out = [0; 8];
        for n in 0..1000u64 {
            w.push(&record(n));
            assert!(fast.next(&ring, &mut out));
            assert_eq!(consistent(&out), Some(n));
        }
        // The slow reader comes back: it gets the newest records the ring holds, in order, and
        // the count of what it missed; the two add up to what was written.
        let mut got = Vec::new();
        while slow.next(&ring, &mut out) {
            got.push(consistent(&out).unwrap());
        }
        assert!(!got.is_empty() && got.len() <= 16, "{}", got.len());
        assert_eq!(*got.last().unwrap(), 999);
        assert!(got.windows(2).all(|p| p[1] == p[0] + 1), "{got:?}");
        assert_eq!(slow.lost + got.len() as u64, 1000);
        assert_eq!(fast.lost, 0);
    }

    #[test]
    fn concurrent_readers_never_see_a_torn_record() {
        let (mut w, ring) = SeqRing::<8>::new(64);
        const N: u64 = 300_000;
        let start = Arc::new(std::sync::Barrier::new(4));
        let readers: Vec<_> = (0..3)
            .map(|_| {
                let (ring, start) = (Arc::clone(&ring), Arc::clone(&start));
                std::thread::spawn(move || {
                    let mut c = Cursor::default();
                    let mut out = [0; 8];
                    let (mut read, mut last) = (0u64, None::<u64>);
                    start.wait();
                    while c.position() < N {
                        if c.next(&ring, &mut out) {
                            let n = consistent(&out).expect("a torn record");
                            assert!(last.is_none_or(|l| n > l), "out of order");
                            assert_eq!(n + 1, c.position(), "the record the cursor was at");
                            last = Some(n);
                            read += 1;
                        }
                    }
                    (read, c.lost)
                })
            })
            .collect();
        start.wait();
        for n in 0..N {
            w.push(&record(n));
        }
        for r in readers {
            let (read, lost) = r.join().unwrap();
            // Every record is either read whole or counted lost.
            assert_eq!(read + lost, N, "read {read} lost {lost}");
            assert!(read > 0);
        }
    }
}
