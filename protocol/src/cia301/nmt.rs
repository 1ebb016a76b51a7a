//! NMT slave: the node's communication state and the commands of the NMT master (COB-ID 0).
//! Frame decoding is [`crate::wire::nmt`].

use crate::frame::CanFrame;
pub use crate::wire::nmt::NmtCommand;
use crate::wire::nmt::NmtFrame;

/// NMT state; the discriminant is the heartbeat state byte.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NmtState {
    /// Initialising: after power-on or reset, until the boot-up message (heartbeat state 0x00).
    Initialising = 0x00,
    /// Stopped: only NMT and heartbeat are served (heartbeat state 0x04).
    Stopped = 0x04,
    /// Operational: SDO, PDO, SYNC and EMCY all active (heartbeat state 0x05).
    Operational = 0x05,
    /// Pre-operational: SDO, SYNC and EMCY, no PDOs (heartbeat state 0x7F).
    PreOperational = 0x7F,
}

/// Decode an NMT frame (COB-ID 0) addressed to `node_id` or to all nodes (0).
pub fn decode(frame: &CanFrame, node_id: u8) -> Option<NmtCommand> {
    // CiA 301: NMT module control is exactly 2 bytes; anything else is not a command (a
    // flood of odd-length frames must not reset the node)
    if frame.id != 0 || frame.rtr || frame.len != 2 {
        return None;
    }
    let f = NmtFrame::parse(frame.payload())?;
    f.addresses(node_id).then_some(f.command)
}

/// The state a command leads to (resets return `Initialising`; the node then boots again).
pub fn next_state(cmd: NmtCommand) -> NmtState {
    match cmd {
        NmtCommand::StartRemoteNode => NmtState::Operational,
        NmtCommand::StopRemoteNode => NmtState::Stopped,
        NmtCommand::EnterPreOperational => NmtState::PreOperational,
        NmtCommand::ResetNode | NmtCommand::ResetCommunication => NmtState::Initialising,
    }
}
