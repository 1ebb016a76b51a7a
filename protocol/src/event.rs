//! What the node reports through [`crate::Node::poll_event`]: state changes, EMCYs, SYNC,
//! finished SDO transfers. The events wait in a bounded queue ([`EVENT_QUEUE`]); when it is
//! full the newest event is dropped and counted ([`crate::Node::events_dropped`]), so a caller
//! that never drains it costs nothing but the count.

use crate::cia301::nmt::NmtState;
use crate::cia402::State;

/// Capacity of the event queue.
pub const EVENT_QUEUE: usize = 32;

/// Direction of an SDO transfer, seen from the client.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoDirection {
    /// The client wrote (download).
    Download,
    /// The client read (upload).
    Upload,
}

/// A finished SDO transfer of the node's server.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoTransfer {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Direction.
    pub direction: SdoDirection,
    /// `None` when the transfer completed, else the abort code (sent by us or by the client,
    /// including the 0x05040000 timeout).
    pub abort: Option<u32>,
}

/// Something that happened in the node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeEvent {
    /// The CiA 402 state changed.
    Cia402State {
        /// Before.
        from: State,
        /// After.
        to: State,
    },
    /// The NMT state changed (a reset shows as the change to pre-operational after boot).
    NmtState {
        /// Before.
        from: NmtState,
        /// After.
        to: NmtState,
    },
    /// An error became active and its EMCY was queued (also when the EMCY producer is
    /// disabled: the event is the error, not the frame).
    EmcyRaised {
        /// Emergency error code.
        code: u16,
    },
    /// An active error went away.
    EmcyCleared {
        /// Emergency error code.
        code: u16,
    },
    /// A SYNC was received.
    Sync {
        /// Its counter, if it carries one.
        counter: Option<u8>,
    },
    /// An SDO transfer finished.
    SdoTransfer(SdoTransfer),
}
