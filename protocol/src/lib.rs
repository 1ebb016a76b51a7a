//! Sans-IO CANopen node for a CiA 402 servo drive: frames and a monotonic time go in,
//! frames come out. No threads, sockets or clocks in here.
//!
//! Layout: [`frame`] (the CAN frame), [`od`] (the object table and EDS export), [`cia301`]
//! (NMT, SDO, PDO, SYNC, heartbeat, EMCY), [`cia402`] (state machine, modes, factor group,
//! profiles), [`params`] (manufacturer objects), [`node`] (the glue), [`drive`] (the contract
//! with the drive behind the node).

pub mod cia301;
pub mod cia402;
pub mod drive;
pub mod event;
pub mod frame;
pub mod node;
pub mod od;
pub mod params;
pub mod wire;

pub use cia301::nmt::NmtState;
pub use cia402::State as Cia402State;
pub use drive::{AxisParam, Drive, DriveCommand, DriveInfo, Feedback, ParamError, Setpoint};
pub use event::{NodeEvent, SdoDirection, SdoTransfer, EVENT_QUEUE};
pub use frame::CanFrame;
pub use node::{ConfigError, FrameEvent, Node, RuntimeStats, TX_QUEUE};
