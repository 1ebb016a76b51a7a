//! Store and restore parameters (CiA 301 7.5.2.13 / 7.5.2.14, objects 0x1010 and 0x1011):
//! the signature "save" in 0x1010:1 keeps a copy of every value (the node's second store,
//! allocated with the node), which an NMT reset then restores; "load" in 0x1011:1 makes the
//! next reset restore the defaults again.

use crate::cia301::sdo::abort;
use crate::node::writes::{ObjectWrite, Verdict, WriteHooks};
use crate::node::DriveCore;

/// "save" as the UNSIGNED32 a master writes (ASCII, little-endian).
pub const SAVE: u64 = 0x6576_6173;
/// "load" as the UNSIGNED32 a master writes.
pub const LOAD: u64 = 0x6461_6F6C;

/// 0x1010 and 0x1011, sub 1 (all parameters); the other sub-indices are stored as written.
pub(crate) fn register_writes(t: &mut WriteHooks) {
    t.register(0x1010, 0x1011, write_store_restore);
}

fn write_store_restore(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    match (w.index, w.sub) {
        (0x1010, 1) => {
            if w.raw != SAVE {
                return Err(abort::CANNOT_STORE);
            }
            c.saved.copy_from(&c.store);
            c.has_saved = true;
            Ok(Verdict::Applied)
        }
        (0x1011, 1) => {
            if w.raw != LOAD {
                return Err(abort::CANNOT_STORE);
            }
            c.has_saved = false;
            Ok(Verdict::Applied)
        }
        _ => Ok(Verdict::Store),
    }
}
