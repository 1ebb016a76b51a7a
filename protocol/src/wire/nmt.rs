//! NMT command frames (COB-ID 0, two bytes: command specifier, node ID or 0 for all).
//! The command byte values are canopen-rs's `NmtCommand`.

pub use canopen_rs::NmtCommand;

/// An NMT command frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NmtFrame {
    /// The command.
    pub command: NmtCommand,
    /// Addressed node (0: all nodes).
    pub node: u8,
}

/// The command byte of an NMT command.
pub fn command_byte(c: NmtCommand) -> u8 {
    match c {
        NmtCommand::StartRemoteNode => 0x01,
        NmtCommand::StopRemoteNode => 0x02,
        NmtCommand::EnterPreOperational => 0x80,
        NmtCommand::ResetNode => 0x81,
        NmtCommand::ResetCommunication => 0x82,
    }
}

impl NmtFrame {
    /// Parse the payload of a COB-ID 0 frame; `None` when shorter than 2 bytes or an unknown
    /// command.
    pub fn parse(payload: &[u8]) -> Option<NmtFrame> {
        if payload.len() < 2 {
            return None;
        }
        let command = NmtCommand::from_byte(payload[0]).ok()?;
        Some(NmtFrame {
            command,
            node: payload[1],
        })
    }

    /// The two payload bytes.
    pub fn emit(&self) -> [u8; 2] {
        [command_byte(self.command), self.node]
    }

    /// Whether the command is for `node_id` (addressed to it or to all).
    pub fn addresses(&self, node_id: u8) -> bool {
        self.node == 0 || self.node == node_id
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_rejects() {
        for b in [0x01, 0x02, 0x80, 0x81, 0x82] {
            let f = NmtFrame::parse(&[b, 5]).unwrap();
            assert_eq!(f.emit(), [b, 5]);
            assert!(f.addresses(5) && !f.addresses(6));
        }
        assert!(NmtFrame::parse(&[0x03, 5]).is_none());
        assert!(NmtFrame::parse(&[0x01]).is_none());
        assert!(NmtFrame::parse(&[0x01, 0]).unwrap().addresses(9));
    }
}
