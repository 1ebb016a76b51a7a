//! The pre-defined connection set (CiA 301 7.3.5): COB-ID bases and what an 11-bit
//! identifier carries by default.

use super::lss::LSS_REQUEST;
use crate::frame::CanFrame;

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

/// What a received frame is for one node: the service it goes to, told apart by the COB-IDs
/// the node is configured with ([`RxTable`]), not by the pre-defined set alone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rx {
    /// NMT module control (COB-ID 0).
    Nmt,
    /// SYNC (the COB-ID of 0x1005), a data frame.
    Sync,
    /// SDO request to this node's server (0x600 + node ID).
    Sdo,
    /// A heartbeat or boot-up of node 1..=127 (0x701..=0x77F, a data frame of at least one
    /// byte): the heartbeat consumer's.
    Heartbeat(u8),
    /// LSS request (0x7E5) while the node serves LSS.
    Lss,
    /// Any other data frame: an RPDO if one is configured on its COB-ID (the PDO engine, which
    /// holds the RPDOs' COB-IDs, finds which).
    Rpdo,
    /// Any other remote frame: a request for a TPDO configured on its COB-ID (the PDO engine
    /// finds which, and whether it may answer).
    Rtr,
    /// Not an 11-bit base frame (29-bit, or an identifier above 0x7FF): nobody's.
    Other,
}

/// The COB-IDs a node receives on, as configured now; [`RxTable::classify`] tells a frame's
/// service. Copied out of the dictionary per frame: no allocation, no lock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RxTable {
    /// SYNC COB-ID (0x1005, 11 bits).
    pub sync: u32,
    /// SDO server's request COB-ID (0x600 + node ID).
    pub sdo_rx: u32,
    /// LSS requests are served (an LSS slave, booted).
    pub lss: bool,
}

impl RxTable {
    /// The service `frame` goes to. Where two configured COB-IDs coincide, the first in this
    /// order wins: LSS, NMT, SYNC, SDO, heartbeat, then the PDOs.
    pub fn classify(&self, frame: &CanFrame) -> Rx {
        let id = frame.id;
        if frame.extended || id > 0x7FF {
            Rx::Other
        } else if self.lss && id == LSS_REQUEST {
            Rx::Lss
        } else if id == NMT {
            Rx::Nmt
        } else if id == self.sync && !frame.rtr {
            Rx::Sync
        } else if id == self.sdo_rx {
            Rx::Sdo
        } else if (HEARTBEAT + 1..=HEARTBEAT + 0x7F).contains(&id) && !frame.rtr && frame.len >= 1 {
            Rx::Heartbeat(id as u8)
        } else if frame.rtr {
            Rx::Rtr
        } else {
            Rx::Rpdo
        }
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

    #[test]
    fn rx_table_classifies_by_the_configured_cob_ids() {
        let t = RxTable {
            sync: 0x0A0,
            sdo_rx: 0x605,
            lss: true,
        };
        let data = |id, len| CanFrame::new(id, &[0u8; 8][..len]);
        let remote = |id| CanFrame {
            rtr: true,
            ..CanFrame::new(id, &[])
        };
        assert_eq!(t.classify(&data(0, 2)), Rx::Nmt);
        assert_eq!(t.classify(&data(0x0A0, 0)), Rx::Sync);
        assert_eq!(
            t.classify(&data(0x080, 0)),
            Rx::Rpdo,
            "0x80 is not SYNC here"
        );
        assert_eq!(t.classify(&remote(0x0A0)), Rx::Rtr);
        assert_eq!(t.classify(&data(0x605, 8)), Rx::Sdo);
        assert_eq!(t.classify(&data(0x606, 8)), Rx::Rpdo, "another node's SDO");
        assert_eq!(t.classify(&data(0x701, 1)), Rx::Heartbeat(1));
        assert_eq!(t.classify(&data(0x77F, 1)), Rx::Heartbeat(0x7F));
        assert_eq!(t.classify(&data(0x705, 0)), Rx::Rpdo, "no state byte");
        assert_eq!(t.classify(&remote(0x705)), Rx::Rtr);
        assert_eq!(t.classify(&data(0x7E5, 8)), Rx::Lss);
        let no_lss = RxTable { lss: false, ..t };
        assert_eq!(no_lss.classify(&data(0x7E5, 8)), Rx::Rpdo);
        assert_eq!(t.classify(&data(0x205, 8)), Rx::Rpdo);
        assert_eq!(t.classify(&remote(0x185)), Rx::Rtr);
        let ext = CanFrame {
            extended: true,
            ..data(0, 2)
        };
        assert_eq!(t.classify(&ext), Rx::Other);
        assert_eq!(t.classify(&data(0x800, 1)), Rx::Other);
        // SYNC configured on the SDO's COB-ID: SYNC first
        let clash = RxTable { sync: 0x605, ..t };
        assert_eq!(clash.classify(&data(0x605, 8)), Rx::Sync);
        assert_eq!(clash.classify(&remote(0x605)), Rx::Sdo);
    }
}
