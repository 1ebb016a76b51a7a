//! COB-ID rules shared by the SYNC (0x1005), EMCY (0x1014) and PDO (0x14xx / 0x18xx sub 1)
//! COB-ID objects.

/// CiA 301 restricted CAN-IDs: never valid for a PDO, SYNC, TIME or EMCY COB-ID (NMT,
/// reserved, the node-specific SDO, heartbeat / boot-up and LSS ranges).
pub fn restricted(can_id: u32) -> bool {
    matches!(
        can_id,
        0x000
            | 0x001..=0x07F
            | 0x101..=0x180
            | 0x581..=0x5FF
            | 0x601..=0x67F
            | 0x6E0..=0x6FF
            | 0x701..=0x77F
            | 0x780..=0x7FF
    )
}

/// Bit 29: 29-bit identifier (CAN extended frame), not supported by this device.
pub const FRAME_29BIT: u32 = 0x2000_0000;
/// Bits 11-28: the rest of a 29-bit identifier; zero for an 11-bit one.
pub const ID_HIGH_BITS: u32 = 0x1FFF_F800;

/// Whether a COB-ID value is acceptable: 11-bit frame format, and when `checked` (the object
/// is, or is made, valid) a CAN-ID outside the restricted ranges.
pub fn acceptable(cob_id: u32, checked: bool) -> bool {
    cob_id & (FRAME_29BIT | ID_HIGH_BITS) == 0 && !(checked && restricted(cob_id & 0x7FF))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_restricted_ranges_and_their_neighbours() {
        for id in [
            0x000, 0x001, 0x07F, 0x101, 0x180, 0x581, 0x5FF, 0x601, 0x67F, 0x6E0, 0x6FF,
        ] {
            assert!(restricted(id), "{id:#x}");
        }
        for id in [0x701, 0x77F, 0x780, 0x7FF] {
            assert!(restricted(id), "{id:#x}");
        }
        for id in [
            0x080, 0x081, 0x0FF, 0x100, 0x181, 0x200, 0x57F, 0x580, 0x600, 0x680, 0x6DF,
        ] {
            assert!(!restricted(id), "{id:#x}");
        }
        assert!(!restricted(0x700), "0x700 is not in a restricted range");
    }
}
