//! The SDO write rules of the PDO parameters (CiA 301 7.5.2.35 ff.), in one place. Types and
//! limits of the object dictionary are checked before; what is here is what depends on the
//! PDO's state. Each rule returns the abort code CiA 301 names. A vendor profile changes three
//! of them ([`PdoRules`], docs/quirks.md 3.9, 3.10, 3.15).

use super::layout::{self, Param};
use super::{check_entry, compile, Direction, Pdo, TransmissionType, COB_EXTENDED, COB_INVALID};
use crate::cia301::sdo::abort;
use crate::od::{ObjectDictionary, Store};
use crate::quirks::PdoRules;

/// Whether the PDO is valid (COB-ID bit 31 clear) as stored.
pub fn is_valid(store: &Store, pdo: &Pdo) -> bool {
    pdo.comm_value(store, layout::COB_ID) & COB_INVALID == 0
}

/// Check a write of `raw` to sub `sub` of one of `pdo`'s records (a mapping of at most
/// `max_len` bytes); `Ok` means store it.
#[allow(clippy::too_many_arguments)]
pub fn check_write(
    od: &ObjectDictionary,
    store: &Store,
    pdo: &Pdo,
    param: Param,
    sub: u8,
    raw: u64,
    rules: &PdoRules,
    max_len: usize,
) -> Result<(), u32> {
    if param.mapping {
        check_mapping_write(od, store, pdo, param, sub, raw, rules, max_len)
    } else {
        check_comm_write(od, store, pdo, param, sub, raw, rules)
    }
}

/// Mapping record: only while the PDO is invalid; entries only while sub 0 is 0 (CiA 301
/// 7.5.2.36; with `lenient_remap` also while it is not, if the mapping with the new entry
/// still fits); sub 0 only to a count whose entries map (0x06040041) and fit in `max_len`
/// bytes (0x06040042; 8 on CAN). An entry naming an object of `unmappable` is refused
/// (0x06040041).
#[allow(clippy::too_many_arguments)]
fn check_mapping_write(
    od: &ObjectDictionary,
    store: &Store,
    pdo: &Pdo,
    param: Param,
    sub: u8,
    raw: u64,
    rules: &PdoRules,
    max_len: usize,
) -> Result<(), u32> {
    let tx = param.dir == Direction::Tx;
    if is_valid(store, pdo) {
        return Err(abort::UNSUPPORTED_ACCESS);
    }
    if sub == 0 {
        compile(od, store, &pdo.slots, raw as usize, tx, max_len)?;
        return Ok(());
    }
    let count = pdo
        .slots
        .count
        .map_or(0, |s| store.u32(s as usize) as usize);
    if count != 0 && !rules.lenient_remap {
        if keeps_fixed_entry(od, store, pdo, param, sub, raw) {
            return Ok(());
        }
        return Err(abort::UNSUPPORTED_ACCESS);
    }
    if raw != 0 {
        let entry = raw as u32;
        if rules
            .unmappable
            .contains((entry >> 16) as u16, (entry >> 8) as u8)
        {
            return Err(abort::NOT_MAPPABLE);
        }
        check_entry(od, entry, tx)?;
    }
    if count != 0 && usize::from(sub) <= count {
        // lenient: the mapping in force, with this entry in place, must still compile
        mapped_length_with(od, store, pdo, count, tx, sub, raw as u32, max_len)?;
    }
    Ok(())
}

/// A fixed mapping (its file makes the count `const` or `ro` and the entries `rw`: AMD's
/// Kria KD240 `foc-mc.eds`): the count can never be 0, so CiA 301 would refuse every entry
/// write; a write that leaves entry `sub` as it stands is taken (nothing changes), as a
/// master that loads the file's own map (python canopen's `load_configuration()`) writes it.
/// Any other value is still refused (0x06010000). Our reading of such a file, not checked on
/// the device.
fn keeps_fixed_entry(
    od: &ObjectDictionary,
    store: &Store,
    pdo: &Pdo,
    param: Param,
    sub: u8,
    raw: u64,
) -> bool {
    let map_index = comm_index(param) + 0x200;
    let fixed = od
        .get(map_index, 0)
        .is_some_and(|(_, e)| !e.access.writable());
    let current = usize::from(sub)
        .checked_sub(1)
        .and_then(|k| pdo.slots.entries.get(k).copied().flatten())
        .map(|slot| store.u32(slot as usize));
    fixed && current == Some(raw as u32) && raw <= u64::from(u32::MAX)
}

/// The length in bytes of `pdo`'s first `count` entries with entry `sub` replaced by `entry`
/// (their bits rounded up to whole bytes).
#[allow(clippy::too_many_arguments)]
fn mapped_length_with(
    od: &ObjectDictionary,
    store: &Store,
    pdo: &Pdo,
    count: usize,
    tx: bool,
    sub: u8,
    entry: u32,
    max_len: usize,
) -> Result<usize, u32> {
    let mut bits = 0;
    for k in 0..count {
        let value = if k + 1 == usize::from(sub) {
            entry
        } else {
            let slot = pdo.slots.entries[k].ok_or(abort::NOT_MAPPABLE)?;
            store.u32(slot as usize)
        };
        bits += check_entry(od, value, tx)?.bits();
    }
    let len = bits.div_ceil(8);
    if len > max_len {
        return Err(abort::PDO_LENGTH);
    }
    Ok(len)
}

/// Communication record. A COB-ID its file marks read-only keeps its CAN-ID
/// (`DeviceDescription::fixed_pdo_can_ids`): only bit 31 may change, else 0x06010002.
fn check_comm_write(
    od: &ObjectDictionary,
    store: &Store,
    pdo: &Pdo,
    param: Param,
    sub: u8,
    raw: u64,
    rules: &PdoRules,
) -> Result<(), u32> {
    let valid = is_valid(store, pdo);
    match sub {
        // a drive without RTR keeps bit 30 in a TPDO's COB-ID (docs/quirks.md 3.10)
        1 if param.dir == Direction::Tx
            && raw as u32 & super::COB_NO_RTR == 0
            && rules.no_rtr_abort.is_some() =>
        {
            Err(rules.no_rtr_abort.unwrap_or(abort::VALUE_RANGE))
        }
        1 if od.device.fixed_pdo_can_ids.contains(&comm_index(param))
            && !crate::od::placeholders::keeps_fixed_can_id(
                pdo.comm_value(store, layout::COB_ID),
                raw as u32,
            ) =>
        {
            Err(abort::READ_ONLY)
        }
        // a CAN-ID the device's own file gives this PDO (default or a DCF's ParameterValue),
        // restricted or not, is the device's own (`DeviceDescription::shipped_pdo_can_ids`)
        1 if od
            .device
            .shipped_pdo_can_ids
            .contains(&(comm_index(param), raw as u32 & 0x7FF))
            && raw as u32 & COB_EXTENDED == 0
            && !(valid
                && raw as u32 & COB_INVALID == 0
                && (raw as u32 ^ pdo.comm_value(store, layout::COB_ID)) & 0x7FF != 0) =>
        {
            Ok(())
        }
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

/// The index of the communication record of `param`'s PDO.
fn comm_index(param: Param) -> u16 {
    let base = match param.dir {
        Direction::Rx => 0x1400,
        Direction::Tx => 0x1800,
    };
    base + param.number
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
