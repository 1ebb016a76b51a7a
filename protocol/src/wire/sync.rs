//! SYNC frames: empty, or one counter byte (1..=240) when 0x1019 is above 1.

/// A SYNC frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SyncFrame {
    /// The counter, when the frame carries one.
    pub counter: Option<u8>,
}

impl SyncFrame {
    /// Parse a SYNC payload: the first byte, if any, is the counter.
    pub fn parse(payload: &[u8]) -> SyncFrame {
        SyncFrame {
            counter: payload.first().copied(),
        }
    }

    /// The payload (0 or 1 byte) and its length.
    pub fn emit(&self) -> ([u8; 1], usize) {
        match self.counter {
            Some(c) => ([c], 1),
            None => ([0], 0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        for s in [SyncFrame { counter: None }, SyncFrame { counter: Some(7) }] {
            let (b, n) = s.emit();
            assert_eq!(SyncFrame::parse(&b[..n]), s);
        }
    }
}
