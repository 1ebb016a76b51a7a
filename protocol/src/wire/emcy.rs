//! Emergency frames (CiA 301 7.2.7.3.1): error code, error register, five manufacturer bytes.

/// An EMCY frame. Code 0x0000 is "error reset / no error".
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EmcyFrame {
    /// Emergency error code.
    pub code: u16,
    /// Error register (0x1001) at the time of the event.
    pub register: u8,
    /// Manufacturer-specific bytes.
    pub info: [u8; 5],
}

impl EmcyFrame {
    /// Parse an EMCY payload; `None` unless it has 8 bytes.
    pub fn parse(payload: &[u8]) -> Option<EmcyFrame> {
        if payload.len() != 8 {
            return None;
        }
        let mut info = [0u8; 5];
        info.copy_from_slice(&payload[3..8]);
        Some(EmcyFrame {
            code: u16::from_le_bytes([payload[0], payload[1]]),
            register: payload[2],
            info,
        })
    }

    /// The eight payload bytes.
    pub fn emit(&self) -> [u8; 8] {
        let c = self.code.to_le_bytes();
        let i = self.info;
        [c[0], c[1], self.register, i[0], i[1], i[2], i[3], i[4]]
    }

    /// Whether this is the "error reset / no error" message.
    pub fn is_reset(&self) -> bool {
        self.code == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_layout() {
        let e = EmcyFrame {
            code: 0x8611,
            register: 0x21,
            info: [1, 2, 3, 4, 5],
        };
        assert_eq!(e.emit(), [0x11, 0x86, 0x21, 1, 2, 3, 4, 5]);
        assert_eq!(EmcyFrame::parse(&e.emit()), Some(e));
        assert!(EmcyFrame::parse(&[0; 7]).is_none());
    }
}
