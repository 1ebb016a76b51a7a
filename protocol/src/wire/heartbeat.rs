//! Heartbeat and boot-up frames (COB-ID 0x700 + node, one byte: the NMT state; boot-up is 0).

/// A heartbeat or boot-up message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Heartbeat {
    /// Producer's NMT state byte (0x00 boot-up, 0x04 stopped, 0x05 operational, 0x7F
    /// pre-operational); other values come from broken peers and are kept as they are.
    pub state: u8,
}

impl Heartbeat {
    /// The boot-up message.
    pub const BOOTUP: Heartbeat = Heartbeat { state: 0 };

    /// Parse a heartbeat payload (at least one byte; further bytes are ignored).
    pub fn parse(payload: &[u8]) -> Option<Heartbeat> {
        payload.first().map(|&state| Heartbeat { state })
    }

    /// The payload byte.
    pub fn emit(&self) -> [u8; 1] {
        [self.state]
    }

    /// Whether this is the boot-up message.
    pub fn is_bootup(&self) -> bool {
        self.state == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        for s in [0u8, 4, 5, 0x7F] {
            assert_eq!(
                Heartbeat::parse(&Heartbeat { state: s }.emit()),
                Some(Heartbeat { state: s })
            );
        }
        assert!(Heartbeat::parse(&[0]).unwrap().is_bootup());
        assert!(Heartbeat::parse(&[]).is_none());
    }
}
