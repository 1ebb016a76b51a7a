//! The SDO write rules of the PDO parameters (CiA 301 7.5.2.35 ff.), in one place. Types and
//! limits of the object dictionary are checked before; what is here is what depends on the
//! PDO's state. Each rule returns the abort code CiA 301 names.

use super::layout::{self, Param};
use super::{check_entry, compile, Direction, Pdo, TransmissionType, COB_EXTENDED, COB_INVALID};
use crate::cia301::sdo::abort;
use crate::od::{ObjectDictionary, Store};

/// Whether the PDO is valid (COB-ID bit 31 clear) as stored.
pub fn is_valid(store: &Store, pdo: &Pdo) -> bool {
    pdo.comm_value(store, layout::COB_ID) & COB_INVALID == 0
}

/// Check a write of `raw` to sub `sub` of one of `pdo`'s records; `Ok` means store it.
pub fn check_write(
    od: &ObjectDictionary,
    store: &Store,
    pdo: &Pdo,
    param: Param,
    sub: u8,
    raw: u64,
) -> Result<(), u32> {
    if param.mapping {
        check_mapping_write(od, store, pdo, param, sub, raw)
    } else {
        check_comm_write(store, pdo, param, sub, raw)
    }
}

/// Mapping record: only while the PDO is invalid; entries only while sub 0 is 0; sub 0 only
/// to a count whose entries map (0x06040041) and fit in 8 bytes (0x06040042).
fn check_mapping_write(
    od: &ObjectDictionary,
    store: &Store,
    pdo: &Pdo,
    param: Param,
    sub: u8,
    raw: u64,
) -> Result<(), u32> {
    let tx = param.dir == Direction::Tx;
    if is_valid(store, pdo) {
        return Err(abort::UNSUPPORTED_ACCESS);
    }
    if sub == 0 {
        compile(od, store, &pdo.slots, raw as usize, tx)?;
    } else {
        if pdo.slots.count.is_some_and(|s| store.u32(s as usize) != 0) {
            return Err(abort::UNSUPPORTED_ACCESS);
        }
        if raw != 0 {
            check_entry(od, raw as u32, tx)?;
        }
    }
    Ok(())
}

/// Communication record.
fn check_comm_write(store: &Store, pdo: &Pdo, param: Param, sub: u8, raw: u64) -> Result<(), u32> {
    let valid = is_valid(store, pdo);
    match sub {
        1 => check_cob_id(store, pdo, valid, raw),
        2 => {
            if raw > 0xFF || !TransmissionType::from_u8(raw as u8).allowed(param.dir) {
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
fn check_cob_id(store: &Store, pdo: &Pdo, valid: bool, raw: u64) -> Result<(), u32> {
    let raw = raw as u32;
    let cur = pdo.comm_value(store, layout::COB_ID);
    let new_valid = raw & COB_INVALID == 0;
    // 11-bit frames only; a valid PDO never on a CiA 301 restricted CAN-ID
    if raw & COB_EXTENDED != 0 || !crate::cia301::cob_id::acceptable(raw, new_valid) {
        return Err(abort::VALUE_RANGE);
    }
    if valid && new_valid && (raw & 0x7FF) != (cur & 0x7FF) {
        return Err(abort::VALUE_RANGE);
    }
    Ok(())
}
