//! The slave's side of LSS fastscan (cs 0x51): which requests it answers and when it is
//! found.
//!
//! A master finds the lowest LSS address among the non-configured slaves in waiting state,
//! 32 bits at a time, without knowing any of them. The order python canopen's
//! `LssMaster.fast_scan()` (canopen 2.4.1) and CANopenNode's `CO_LSSmaster_IdentifyFastscan`
//! send it in:
//!
//! 1. `(IDNumber 0, BitChecked 0x80, LSSSub 0, LSSNext 0)`: every eligible slave answers
//!    0x4F and restarts its scan at the vendor-ID. No answer: nobody to find.
//! 2. For each part `sub` = 0 (vendor-ID), 1, 2, 3 (serial number): for `bit` = 31 down to
//!    0, `(found, bit, sub, sub)`, where `found` holds the bits found so far and 0 at `bit`.
//!    A slave answers when bits 31..=`bit` of its part equal those of `found`; no answer at
//!    all means the bit is 1, and the master sets it.
//! 3. `(found, 0, sub, next)` with `next` = `sub + 1` (0 after the serial number, python
//!    canopen's `(sub + 1) & 3`): the slave whose part equals `found` answers and compares the
//!    part `next` from now on; a slave whose part differs drops out of this scan.
//! 4. When LSSNext < LSSSub on that last, full comparison (after the serial number), the
//!    slave that answered is the one found: it enters LSS configuration state.
//!
//! At each bit the slaves with a 0 there answer, so the master keeps the 0 whenever any slave
//! has one: the scan finds the smallest address, vendor-ID first, then product code,
//! revision, serial number. Answers of several slaves are identical frames, one on the bus.
//!
//! Rules where the sources differ, and what this slave does:
//! - Who takes part. CANopenNode answers only when both its active and its pending node-ID
//!   are 0xFF; Lely (`co_lss_fastscan`) answers in waiting state whatever its node-ID; CiA
//!   305 defines fastscan for non-configured slaves, and python canopen's documentation
//!   ("Before you run fastscan, you have to make sure the devices are in non-configured or
//!   unconfigured state", PR 290; issue 226) expects that. This slave takes part only while
//!   non-configured (active and pending node-ID 0xFF) and in waiting state (the caller,
//!   [`super::LssSlave`], checks both).
//! - Completion. CANopenNode and Lely enter configuration on `BitChecked 0 && LSSNext <
//!   LSSSub`, which also lets a master that skips the last parts (CANopenNode's
//!   `CO_LSSmaster_FS_SKIP`) finish early; CANopenNode PR 647 (open) would require LSSSub 3 and
//!   LSSNext 0. This slave keeps the released rule; python canopen's scan meets both.
//! - Invalid values (BitChecked 32..=0x7F or above 0x80, LSSSub or LSSNext above 3) are not
//!   a fastscan request at all: the codec refuses them and the slave stays silent, as
//!   CANopenNode does.

use crate::wire::lss::{BitChecked, Fastscan, IdentityPart};

use super::LssIdentity;

/// What the slave does with a fastscan request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Reply {
    /// Not for this slave (bits differ, or it compares another part).
    Silent,
    /// Answer 0x4F.
    Answer,
    /// Answer 0x4F: its whole address has matched; enter LSS configuration state.
    AnswerSelected,
}

/// Where a slave is in a scan: the address part it compares next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct FastscanState {
    pos: IdentityPart,
}

impl Default for FastscanState {
    fn default() -> Self {
        FastscanState {
            pos: IdentityPart::VendorId,
        }
    }
}

impl FastscanState {
    /// Start again at the vendor-ID (a reset request, a change of LSS state, an NMT reset).
    pub(crate) fn restart(&mut self) {
        self.pos = IdentityPart::VendorId;
    }

    /// The part this slave compares next.
    #[cfg(test)]
    pub(crate) fn position(&self) -> IdentityPart {
        self.pos
    }

    /// One request, for a slave that takes part (non-configured, waiting).
    pub(crate) fn request(&mut self, identity: &LssIdentity, req: &Fastscan) -> Reply {
        let bit = match req.bit_checked {
            BitChecked::Reset => {
                self.restart();
                return Reply::Answer;
            }
            BitChecked::Bits(b) => b,
        };
        if req.sub != self.pos {
            return Reply::Silent;
        }
        let mask = u32::MAX << bit;
        if (identity.part(req.sub) ^ req.id_number) & mask != 0 {
            return Reply::Silent;
        }
        self.pos = req.next;
        if bit == 0 && req.next < req.sub {
            Reply::AnswerSelected
        } else {
            Reply::Answer
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ID: LssIdentity = LssIdentity {
        vendor_id: 0x0000_0009,
        product_code: 0x402,
        revision_number: 0x0001_0000,
        serial_number: 0x8000_0001,
    };

    fn req(id_number: u32, bit: u8, sub: u8, next: u8) -> Fastscan {
        Fastscan {
            id_number,
            bit_checked: BitChecked::Bits(bit),
            sub: IdentityPart::from_index(sub).unwrap(),
            next: IdentityPart::from_index(next).unwrap(),
        }
    }

    #[test]
    fn compares_only_the_checked_bits_of_its_current_part() {
        let mut s = FastscanState::default();
        // bit 3 of the vendor-ID (9 = 0b1001) is 1: a guess of 0 there is silent
        assert_eq!(s.request(&ID, &req(0, 3, 0, 0)), Reply::Silent);
        // bits 31..=4 are 0: a guess of 0 matches them
        assert_eq!(s.request(&ID, &req(0, 4, 0, 0)), Reply::Answer);
        // lower bits do not count: 8 matches 9 at bits 31..=1
        assert_eq!(s.request(&ID, &req(8, 1, 0, 0)), Reply::Answer);
        assert_eq!(s.request(&ID, &req(8, 0, 0, 0)), Reply::Silent);
        // the product code is not compared before the vendor-ID is confirmed
        assert_eq!(s.request(&ID, &req(0x402, 0, 1, 2)), Reply::Silent);
        assert_eq!(s.request(&ID, &req(9, 0, 0, 1)), Reply::Answer);
        assert_eq!(s.position(), IdentityPart::ProductCode);
        assert_eq!(s.request(&ID, &req(9, 0, 0, 1)), Reply::Silent);
        assert_eq!(s.request(&ID, &req(0x402, 0, 1, 2)), Reply::Answer);
        assert_eq!(s.request(&ID, &req(0x0001_0000, 0, 2, 3)), Reply::Answer);
        // the serial number's high bit
        assert_eq!(s.request(&ID, &req(0, 31, 3, 3)), Reply::Silent);
        assert_eq!(
            s.request(&ID, &req(0x8000_0001, 0, 3, 0)),
            Reply::AnswerSelected
        );
    }

    #[test]
    fn reset_answers_from_anywhere_and_restarts() {
        let mut s = FastscanState::default();
        assert_eq!(s.request(&ID, &req(9, 0, 0, 1)), Reply::Answer);
        assert_eq!(s.position(), IdentityPart::ProductCode);
        let reset = Fastscan {
            id_number: 0xDEAD_BEEF,
            bit_checked: BitChecked::Reset,
            sub: IdentityPart::SerialNumber,
            next: IdentityPart::RevisionNumber,
        };
        assert_eq!(s.request(&ID, &reset), Reply::Answer);
        assert_eq!(s.position(), IdentityPart::VendorId);
    }
}
