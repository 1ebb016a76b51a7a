//! The wire layer: parse and emit of the CiA 301 frames the node, the reference master, the
//! capture decoder and the end-to-end tests exchange, apart from any state machine (as
//! smoltcp keeps its `wire` module apart from its sockets).
//!
//! - [`sdo`]: every SDO command, client request ([`SdoRequest`]) and server response
//!   ([`SdoResponse`]), plus block sub-block segments ([`BlockSegment`]);
//! - [`nmt`]: NMT commands (COB-ID 0);
//! - [`emcy`]: emergency messages;
//! - [`heartbeat`]: heartbeat and boot-up;
//! - [`sync`]: SYNC with or without its counter;
//! - [`cob`]: the pre-defined connection set (which function a COB-ID carries);
//! - [`lss`]: LSS (CiA 305) requests and responses (COB-IDs 0x7E5 / 0x7E4).
//!
//! Parsing never panics: every byte pattern is either a value or an error.

pub mod cob;
pub mod emcy;
pub mod heartbeat;
pub mod lss;
pub mod nmt;
pub mod sdo;
pub mod sync;

pub use cob::{Cob, CobFunction};
pub use emcy::EmcyFrame;
pub use heartbeat::Heartbeat;
pub use lss::{LssParseError, LssRequest, LssResponse};
pub use nmt::{NmtCommand, NmtFrame};
pub use sdo::{BlockSegment, Initiate, Mux, SdoRequest, SdoResponse, Segment, UnknownCommand};
pub use sync::SyncFrame;
