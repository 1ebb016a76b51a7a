//! The CiA 402 objects whose writes the drive rules, for an SDO download and an RPDO alike:
//! the controlword 0x6040 (its edges latched for the next tick), the mode 0x6060 (one the
//! drive supports, 0x6502), the software position limits 0x607D (min <= max) and the homing
//! method 0x6098 (a method 0 the vendor stores, ignores or refuses, docs/quirks.md 3.4).

use super::mode::Mode;
use super::objects as o;
use crate::cia301::sdo::abort;
use crate::node::writes::{ObjectWrite, Origin, Verdict, WriteHooks};
use crate::node::DriveCore;
use crate::od::idx;
use crate::quirks::HomingMethodZero;

/// 0x6040, 0x6060, 0x607D and 0x6098.
pub(crate) fn register_writes(t: &mut WriteHooks) {
    t.register(0x6040, 0x6040, write_controlword);
    t.register(0x6060, 0x6060, write_mode);
    t.register(0x607D, 0x607D, write_position_limit);
    t.register(0x6098, 0x6098, write_homing_method);
}

/// 0x6040: the rising edges (and, with `controlword_min_hold`, the value that stood long
/// enough) are latched for the next tick. An RPDO that repeats the controlword writes no new
/// value (a cyclic RPDO would otherwise restart the hold time every cycle).
fn write_controlword(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    let old = c.store.u32(w.row) as u16;
    let new = w.raw as u16;
    if w.sub == 0 && !(w.origin == Origin::Rpdo && old == new) {
        let hold = c.quirks.controlword_min_hold;
        c.cw_latch.on_write(old, new, c.comm_us, hold);
    }
    Ok(Verdict::Store)
}

/// 0x6060: a mode the drive supports (0x6502), else 0x06090030.
fn write_mode(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    let supported = c.store.u32(idx(0x6502, 0));
    if !Mode::from_value(w.raw as i8).is_some_and(|m| m.in_mask(supported)) {
        return Err(abort::VALUE_RANGE);
    }
    Ok(Verdict::Store)
}

/// 0x607D: the minimum (sub 1) not above the maximum (sub 2), else 0x06090036.
fn write_position_limit(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    let v = w.raw as i32;
    match w.sub {
        1 if v > c.store.i32(o::SW_LIMIT_MAX) => Err(abort::MAX_LT_MIN),
        2 if v < c.store.i32(o::SW_LIMIT_MIN) => Err(abort::MAX_LT_MIN),
        _ => Ok(Verdict::Store),
    }
}

/// 0x6098 = 0: stored, ignored (confirmed, the method stays) or refused, as the vendor's
/// `homing_method_zero` says.
fn write_homing_method(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    if w.sub != 0 || w.raw as i8 != 0 {
        return Ok(Verdict::Store);
    }
    match c.quirks.homing_method_zero {
        HomingMethodZero::Store => Ok(Verdict::Store),
        HomingMethodZero::Ignore => Ok(Verdict::Applied),
        HomingMethodZero::Refuse => Err(abort::VALUE_RANGE),
    }
}
