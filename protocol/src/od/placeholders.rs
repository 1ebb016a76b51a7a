//! Placeholders and gaps of a vendor's file that its own device fills in (issue 33): what a
//! real drive serves where its EDS/DCF gives a value no device runs with, or none at all.
//! `from_eds.rs` asks here, object by object; each answer comes with the reason the build
//! report gives.
//!
//! Classes (each with a minimal file of its own in tests/eds/minimal):
//! - a PDO mapping record whose sub-indices have no value (neither DefaultValue nor
//!   ParameterValue: the Elmo Gold DCFs leave entries 2..8, and some counts, empty): an
//!   entry without a value is an unused entry (0), a count without a value counts the
//!   leading entries the file gives, as the device ships its map
//!   (`minimal/pdo-map-gaps.dcf`);
//! - an encoder resolution 0x608F below 4 increments per motor revolution (the Elmo files'
//!   1 increment per revolution: no servo encoder is that coarse; the device serves its
//!   encoder's count there): the simulated motor encoder's increments per revolution are
//!   served; where the rest of the factor group is all ones too (gear 0x6091 1:1 or absent,
//!   feed constant 0x6092 1 per 1 shaft revolution), the vendor's user unit is one encoder
//!   increment (the file's windows and limits are in increments: Elmo's 0x6067 = 100,
//!   0x607D = +-9e8), so 0x6092:1 is served as the increments per shaft revolution and
//!   1 uu = 1 increment (`minimal/encoder-one-per-rev.eds`). The same rule holds for a
//!   value a master writes: the Whistle Gold DCF's ParameterValues 0x608F:1 = 1 and
//!   0x6092:1 = 1 come back through `load_configuration()`; the master reads back what it
//!   wrote, the drive runs with its encoder's count ([`running_factor_group`], each tick in
//!   `cia402`), so 1 uu stays 1 increment and the motor's top speed 0x6080 stays what it is.
//!   A real Elmo does the same with its own numbers: its factor group only relates user
//!   units to its internal counts (Elmo's DSP 402 implementation guide: 0x6093 position
//!   factor, default 1/1), the encoder's counts per revolution being set in Elmo's own tool,
//!   so 0x608F:1 = 1 with 0x6092:1 = 1 leaves 1 uu = 1 count (`minimal/encoder-one-per-rev.eds`
//!   written back: `protocol/tests/eds_vendor_placeholders.rs`);
//! - a PDO COB-ID the file marks read-only (a scanned file: Vector CANeds wrote `ro` for
//!   every COB-ID of the Elmo SimplIQ): its CAN-ID is fixed, but a master still switches the
//!   PDO off and on through bit 31 (python canopen's `load_configuration()` writes the
//!   COB-ID with bit 31 set, then clear, for every PDO): served writable, and any write that
//!   changes anything but bit 31 is refused with 0x06010002, the abort the file's `ro`
//!   promises (`minimal/ro-pdo-cob-id.dcf`).

use super::eds_parse::{EdsFile, EdsSub};
use super::{decode, Access, DataType, DefaultValue};
use crate::drive::DriveInfo;

/// Increments per motor revolution below which 0x608F is a placeholder.
pub const MIN_INCREMENTS_PER_REV: u64 = 4;

/// Whether (index, sub) is a PDO mapping entry or count.
fn is_mapping(index: u16) -> bool {
    matches!(index, 0x1600..=0x17FF | 0x1A00..=0x1BFF)
}

/// Whether the file gives `s` a value (DefaultValue or ParameterValue).
fn has_value(s: &EdsSub) -> bool {
    s.default.is_some() || s.parameter_value.is_some()
}

/// The number a sub of the file gives (DefaultValue, else ParameterValue), if it is one.
fn value_of(s: &EdsSub) -> Option<u64> {
    let v = s.default.as_ref().or(s.parameter_value.as_ref())?;
    let b = v.resolve(s.data_type, Some(1)).ok()?;
    s.data_type.integer().then(|| decode(s.data_type, &b))
}

fn file_value(file: &EdsFile, index: u16, sub: u8) -> Option<u64> {
    value_of(file.sub(index, sub)?)
}

/// A PDO mapping sub without a value in the file: the value the device ships there, and why.
/// Entries: 0 (unused); the count: the leading entries 1.. the file gives a non-zero value.
pub fn empty_pdo_mapping(file: &EdsFile, index: u16, s: &EdsSub) -> Option<(DefaultValue, String)> {
    if !is_mapping(index) || has_value(s) || !s.data_type.integer() {
        return None;
    }
    if s.sub >= 1 {
        return Some((
            DefaultValue::Value(0),
            "no value in the file: an unused mapping entry (0), as the device ships it".into(),
        ));
    }
    let count = (1..=64u8)
        .take_while(|&k| file_value(file, index, k).is_some_and(|v| v != 0))
        .count();
    Some((
        DefaultValue::Value(count as u64),
        format!(
            "no value in the file: the count of the mapping entries it gives ({count}), as \
             the device ships its map"
        ),
    ))
}

/// The factor group terms `[0x608F:1, 0x608F:2, 0x6091:1, 0x6091:2, 0x6092:1, 0x6092:2]`.
pub type FactorTerms = [u32; 6];

/// Whether an encoder resolution of `enc` increments per `enc_revs` motor revolutions is a
/// placeholder: below [`MIN_INCREMENTS_PER_REV`] per revolution (0 terms are no factor).
fn encoder_placeholder(enc: u64, enc_revs: u64) -> bool {
    enc != 0 && enc_revs != 0 && enc < MIN_INCREMENTS_PER_REV * enc_revs
}

/// Whether a factor group with a placeholder encoder resolution is all ones: 0x608F n/n,
/// gear 1:1, feed 1 per 1 shaft revolution; the user unit is then one encoder increment.
fn all_ones(enc: u64, enc_revs: u64, gear_one: bool, feed: u64, feed_revs: u64) -> bool {
    enc == enc_revs && gear_one && feed == 1 && feed_revs == 1
}

/// The factor group a drive runs with, from the terms it holds now (a master may have
/// written a placeholder 0x608F back: Elmo's DCFs set 0x608F:1 = 1 and 0x6092:1 = 1 through
/// python canopen's `load_configuration()`), `drive_inc_per_rev` being the increments its own
/// motor encoder counts. The rule of a file's default ([`factor_group`]), applied to a
/// written value: a placeholder encoder resolution is replaced by the encoder's count; where
/// the group is all ones too, the feed by the increments per shaft revolution (1 uu = 1
/// increment). What the master wrote stays readable; the drive runs with this. Called each
/// tick: no allocation.
pub fn running_factor_group(t: FactorTerms, drive_inc_per_rev: u32) -> FactorTerms {
    let [enc, enc_revs, gm, gs, feed, feed_revs] = t.map(u64::from);
    if drive_inc_per_rev == 0 || !encoder_placeholder(enc, enc_revs) {
        return t;
    }
    let Some(served_enc) = u64::from(drive_inc_per_rev)
        .checked_mul(enc_revs)
        .and_then(|x| u32::try_from(x).ok())
    else {
        return t;
    };
    let gear_one = gm == gs && gm != 0;
    let served_feed = if all_ones(enc, enc_revs, gear_one, feed, feed_revs) {
        drive_inc_per_rev
    } else {
        t[4]
    };
    [served_enc, t[1], t[2], t[3], served_feed, t[5]]
}

/// The factor group the drive serves where the file's is a placeholder: 0x608F:1 and, for an
/// all-ones factor group, 0x6092:1 (see the module doc). `None`: the file's value stands.
pub fn factor_group(
    file: &EdsFile,
    info: &DriveInfo,
    index: u16,
    sub: u8,
) -> Option<(u32, String)> {
    let enc = file_value(file, 0x608F, 1)?;
    let enc_revs = file_value(file, 0x608F, 2).unwrap_or(1);
    if !encoder_placeholder(enc, enc_revs) {
        return None;
    }
    let axis_enc = u64::from(info.encoder_increments_per_rev);
    let served_enc = u32::try_from(axis_enc.checked_mul(enc_revs)?).ok()?;
    match (index, sub) {
        (0x608F, 1) => Some((
            served_enc,
            format!(
                "the file's {enc} increment(s) per {enc_revs} motor revolution(s) is a \
                 placeholder (no servo encoder is that coarse; the device serves its encoder's \
                 count): {served_enc}, the simulated motor encoder's, is served"
            ),
        )),
        (0x6092, 1) => {
            let gear_one = match (file_value(file, 0x6091, 1), file_value(file, 0x6091, 2)) {
                (None, None) => true,
                (Some(m), Some(s)) => m == s && m != 0,
                _ => false,
            };
            let feed = file_value(file, 0x6092, 1)?;
            let feed_revs = file_value(file, 0x6092, 2).unwrap_or(1);
            if !all_ones(enc, enc_revs, gear_one, feed, feed_revs) {
                return None;
            }
            let feed = u32::try_from(axis_enc).ok()?;
            Some((
                feed,
                format!(
                    "the file's factor group is all ones (0x608F {enc}/{enc_revs}, 0x6091 1:1, \
                     0x6092 1 per shaft revolution): the vendor's user unit is one encoder \
                     increment (its windows and limits are in increments); {feed} user units \
                     per shaft revolution are served, 1 uu = 1 increment of the simulated \
                     motor encoder"
                ),
            ))
        }
        _ => None,
    }
}

/// A PDO COB-ID (0x1400..=0x15FF, 0x1800..=0x19FF sub 1) the file marks read-only: served
/// writable for bit 31 (valid) only, and why. The caller records the record's index as one
/// whose CAN-ID is fixed.
pub fn read_only_pdo_cob_id(index: u16, s: &EdsSub) -> Option<(Access, String)> {
    let comm = matches!(index, 0x1400..=0x15FF | 0x1800..=0x19FF);
    if !comm || s.sub != 1 || s.data_type != DataType::U32 {
        return None;
    }
    if !matches!(s.access, Access::Ro | Access::Const) {
        return None;
    }
    Some((
        Access::Rw,
        "the file marks the COB-ID read-only: its CAN-ID is fixed (a write changing more \
         than bit 31 is refused with 0x06010002), bit 31 switches the PDO off and on as a master \
         (python canopen's load_configuration) does before remapping"
            .into(),
    ))
}

/// Whether a write of `new` to the COB-ID of a PDO whose CAN-ID is fixed keeps it: only bit
/// 31 (valid) may differ from `current`.
pub fn keeps_fixed_can_id(current: u32, new: u32) -> bool {
    (current ^ new) & 0x7FFF_FFFF == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fixed_can_id_may_only_toggle_the_valid_bit() {
        assert!(keeps_fixed_can_id(0x4000_0185, 0xC000_0185));
        assert!(keeps_fixed_can_id(0x0000_0205, 0x8000_0205));
        assert!(!keeps_fixed_can_id(0x4000_0185, 0x0000_0185));
        assert!(!keeps_fixed_can_id(0x4000_0185, 0x4000_0186));
        assert!(!keeps_fixed_can_id(0x0000_0185, 0x2000_0185));
    }

    #[test]
    fn a_written_placeholder_encoder_resolution_runs_with_the_encoder_count() {
        let enc = 1 << 20;
        // Elmo's DCF writes 1/1, gear 1:1, feed 1/1: 1 uu = 1 increment
        assert_eq!(
            running_factor_group([1, 1, 1, 1, 1, 1], enc),
            [enc, 1, 1, 1, enc, 1]
        );
        // 1 increment per revolution with a feed of its own: only the encoder is replaced
        assert_eq!(
            running_factor_group([1, 1, 1, 1, 3600, 1], enc),
            [enc, 1, 1, 1, 3600, 1]
        );
        // 3 per 1 revolution is a placeholder; 2 per 2 too; a gear of 2:1 is no all-ones group
        assert_eq!(
            running_factor_group([3, 1, 2, 1, 1, 1], enc)[..],
            [enc, 1, 2, 1, 1, 1]
        );
        assert_eq!(running_factor_group([2, 2, 1, 1, 1, 1], enc)[4], enc);
        // a real resolution, or a zero term, stands
        for t in [
            [4, 1, 1, 1, 1, 1],
            [2000, 1, 1, 1, 2000, 1],
            [0, 1, 1, 1, 1, 1],
            [1, 0, 1, 1, 1, 1],
        ] {
            assert_eq!(running_factor_group(t, enc), t, "{t:?}");
        }
        // no encoder count known: the terms stand
        assert_eq!(
            running_factor_group([1, 1, 1, 1, 1, 1], 0),
            [1, 1, 1, 1, 1, 1]
        );
    }
}
