//! The pre-defined connection set (CiA 301 7.3.5): COB-ID bases and what an 11-bit
//! identifier carries by default.

/// NMT commands.
pub const NMT: u32 = 0x000;
/// SYNC (default COB-ID).
pub const SYNC: u32 = 0x080;
/// EMCY base (+ node ID).
pub const EMCY: u32 = 0x080;
/// TPDO1 base (+ node ID); TPDO2..4 at +0x100 each.
pub const TPDO1: u32 = 0x180;
/// RPDO1 base (+ node ID); RPDO2..4 at +0x100 each.
pub const RPDO1: u32 = 0x200;
/// SDO server -> client base (+ node ID).
pub const SDO_TX: u32 = 0x580;
/// SDO client -> server base (+ node ID).
pub const SDO_RX: u32 = 0x600;
/// Heartbeat / boot-up base (+ node ID).
pub const HEARTBEAT: u32 = 0x700;

/// What a COB-ID carries in the pre-defined connection set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CobFunction {
    /// NMT command.
    Nmt,
    /// SYNC.
    Sync,
    /// Emergency.
    Emcy,
    /// Transmit PDO 1..=4 (from the node).
    Tpdo(u8),
    /// Receive PDO 1..=4 (to the node).
    Rpdo(u8),
    /// SDO response (server -> client).
    SdoTx,
    /// SDO request (client -> server).
    SdoRx,
    /// Heartbeat or boot-up.
    Heartbeat,
    /// Not in the pre-defined set (TIME, LSS, node ID 0, ...).
    Other,
}

/// A COB-ID split into function and node ID.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cob {
    /// Function.
    pub function: CobFunction,
    /// Node ID (0 for NMT, SYNC and `Other`).
    pub node: u8,
}

impl Cob {
    /// Classify an 11-bit identifier by the pre-defined connection set.
    pub fn classify(id: u32) -> Cob {
        let node = (id & 0x7F) as u8;
        let base = id & 0x780;
        let function = match (id, base) {
            (0, _) => CobFunction::Nmt,
            (0x080, _) => CobFunction::Sync,
            _ if id > 0x7FF || node == 0 => CobFunction::Other,
            (_, 0x080) => CobFunction::Emcy,
            (_, 0x180) => CobFunction::Tpdo(1),
            (_, 0x280) => CobFunction::Tpdo(2),
            (_, 0x380) => CobFunction::Tpdo(3),
            (_, 0x480) => CobFunction::Tpdo(4),
            (_, 0x200) => CobFunction::Rpdo(1),
            (_, 0x300) => CobFunction::Rpdo(2),
            (_, 0x400) => CobFunction::Rpdo(3),
            (_, 0x500) => CobFunction::Rpdo(4),
            (_, 0x580) => CobFunction::SdoTx,
            (_, 0x600) => CobFunction::SdoRx,
            (_, 0x700) => CobFunction::Heartbeat,
            _ => CobFunction::Other,
        };
        let node = match function {
            CobFunction::Nmt | CobFunction::Sync | CobFunction::Other => 0,
            _ => node,
        };
        Cob { function, node }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classify_covers_the_predefined_set() {
        assert_eq!(Cob::classify(0).function, CobFunction::Nmt);
        assert_eq!(Cob::classify(0x80).function, CobFunction::Sync);
        assert_eq!(
            Cob::classify(0x85),
            Cob {
                function: CobFunction::Emcy,
                node: 5
            }
        );
        assert_eq!(Cob::classify(0x385).function, CobFunction::Tpdo(3));
        assert_eq!(Cob::classify(0x505).function, CobFunction::Rpdo(4));
        assert_eq!(Cob::classify(0x585).function, CobFunction::SdoTx);
        assert_eq!(Cob::classify(0x605).function, CobFunction::SdoRx);
        assert_eq!(Cob::classify(0x77F).function, CobFunction::Heartbeat);
        assert_eq!(Cob::classify(0x100).function, CobFunction::Other);
        assert_eq!(Cob::classify(0x700).function, CobFunction::Other);
    }
}
