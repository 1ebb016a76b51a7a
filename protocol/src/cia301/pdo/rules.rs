//! The SDO write rules of the PDO parameters (CiA 301 7.5.2.35 ff.), in one place. Types and
//! limits of the object table are checked before; what is here is what depends on the PDO's
//! state. Each rule returns the abort code CiA 301 names.

use super::layout::{self, Slot};
use super::{check_entry, compile, Direction, TransmissionType, COB_EXTENDED, COB_INVALID};
use crate::cia301::sdo::abort;
use crate::od::Store;

/// Whether PDO `k` is valid (COB-ID bit 31 clear) as stored.
pub fn is_valid(store: &Store, k: usize, dir: Direction) -> bool {
    store.u32(layout::comm_row(k, dir) + layout::COB_ID) & COB_INVALID == 0
}

/// Check a write of `raw` to `slot` sub `sub`; `Ok` means store it.
pub fn check_write(store: &Store, slot: Slot, sub: u8, raw: u32) -> Result<(), u32> {
    if slot.mapping {
        check_mapping_write(store, slot, sub, raw)
    } else {
        check_comm_write(store, slot, sub, raw)
    }
}

/// Mapping record: only while the PDO is invalid; entries only while sub 0 is 0; sub 0 only
/// to a count whose entries map (0x06040041) and fit in 8 bytes (0x06040042).
fn check_mapping_write(store: &Store, slot: Slot, sub: u8, raw: u32) -> Result<(), u32> {
    let tx = slot.dir == Direction::Tx;
    if is_valid(store, slot.number, slot.dir) {
        return Err(abort::UNSUPPORTED_ACCESS);
    }
    let mrow = layout::map_row(slot.number, slot.dir);
    if sub == 0 {
        compile(store, mrow, raw as usize, tx)?;
    } else {
        if store.u32(mrow) != 0 {
            return Err(abort::UNSUPPORTED_ACCESS);
        }
        if raw != 0 {
            check_entry(raw, tx)?;
        }
    }
    Ok(())
}

/// Communication record.
fn check_comm_write(store: &Store, slot: Slot, sub: u8, raw: u32) -> Result<(), u32> {
    let valid = is_valid(store, slot.number, slot.dir);
    match sub {
        1 => check_cob_id(store, slot, valid, raw),
        2 => {
            if !TransmissionType::from_u8(raw as u8).allowed(slot.dir) || raw > 0xFF {
                return Err(abort::VALUE_RANGE);
            }
            Ok(())
        }
        // inhibit time: not while the PDO is valid
        3 => {
            if valid {
                return Err(abort::UNSUPPORTED_ACCESS);
            }
            Ok(())
        }
        _ => Ok(()),
    }
}

/// COB-ID: 11-bit only; while the PDO is valid, the identifier may not change.
fn check_cob_id(store: &Store, slot: Slot, valid: bool, raw: u32) -> Result<(), u32> {
    let row = layout::comm_row(slot.number, slot.dir) + layout::COB_ID;
    let cur = store.u32(row);
    let new_valid = raw & COB_INVALID == 0;
    if raw & COB_EXTENDED != 0 || raw & 0x1FFF_F800 != 0 {
        return Err(abort::VALUE_RANGE);
    }
    if valid && new_valid && (raw & 0x7FF) != (cur & 0x7FF) {
        return Err(abort::VALUE_RANGE);
    }
    Ok(())
}
