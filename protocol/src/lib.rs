//! Sans-IO CANopen node for a CiA 402 servo drive: frames and a monotonic time go in,
//! frames come out. No threads, sockets or clocks in here.
//!
//! The surface: [`Node`] (frames in with [`Node::handle`], time in with [`Node::poll`], frames
//! out with [`Node::pop_tx`], events out with [`Node::poll_event`], next deadline from
//! [`Node::poll_at`]); the [`Drive`] contract the emulator implements ([`DriveCommand`] in,
//! [`Feedback`] out); [`CanFrame`]; the states [`NmtState`] and [`Cia402State`]. Four modules
//! are public: [`wire`] (parse and emit of SDO, NMT, EMCY, heartbeat, SYNC and LSS frames, for
//! a master or a capture decoder), [`od`] (the object dictionary, its EDS export and parse),
//! [`cia402`] (modes of operation, controlword and statusword bits), [`cia305`] (the LSS
//! slave) and [`quirks`] (the vendor behaviour switches a node is built with).
//!
//! Inside (private): `cia301` (NMT, SDO server, PDO engine, SYNC, heartbeat, EMCY), the rest
//! of `cia402` (state machine, one file per mode, factor group, profiles), `node` (the glue)
//! and `drive`. The node is built once from a [`NodeConfig`]; its object dictionary
//! ([`od::ObjectDictionary`]) is a value: the standard objects plus the application's, or a
//! vendor's EDS (docs/decisions/0009-object-dictionary.md).

#![warn(missing_docs)]

// The public surface (docs/decisions/0007-protocol-public-surface.md): the node, its drive
// contract and its events at the crate root; `wire` (the codec a master or capture decoder
// needs), `od` (the object table behind the EDS) and `cia402` (state, modes, control and status
// bits) as modules. Everything else is the node's inside.
mod cia301;
pub mod cia305;
pub mod cia402;
mod drive;
mod event;
mod frame;
mod node;
pub mod od;
pub mod quirks;
pub mod quote;
pub mod wire;

pub use cia301::emcy_code::{self, EmcyMeaning};
pub use cia301::nmt::NmtState;
pub use cia402::State as Cia402State;
pub use drive::{Drive, DriveCommand, DriveInfo, Feedback, Setpoint};
pub use event::{NodeEvent, SdoDirection, SdoTransfer, EVENT_QUEUE};
pub use frame::CanFrame;
pub use node::access::EMCY_RPDO_TIMEOUT;
pub use node::deadlines::{Timer, Timers};
pub use node::{
    Clocks, ConfigError, FrameEvent, LssConfig, LssStore, Node, NodeConfig, DEFAULT_LSS_BIT_TIMING,
    TX_QUEUE,
};
pub use node::{CoreOutput, DriveCore};
pub use quirks::Quirks;
