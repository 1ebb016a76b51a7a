//! The CAN frame as the node sees it: classic CAN, 11-bit or 29-bit identifier, 0..=8 bytes.

/// One classic CAN frame. `len` is the DLC (0..=8); bytes beyond `len` are ignored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CanFrame {
    /// Identifier: 11 bits (COB-ID) or 29 bits when `extended`.
    pub id: u32,
    /// 29-bit (CAN 2.0B) identifier.
    pub extended: bool,
    /// Remote transmission request (no data; asks for an RTR-capable TPDO).
    pub rtr: bool,
    /// Data length code, 0..=8.
    pub len: u8,
    /// Data bytes; those past `len` are zero and ignored.
    pub data: [u8; 8],
}

impl CanFrame {
    /// A standard-ID data frame; `data` longer than 8 bytes is truncated.
    pub fn new(id: u32, data: &[u8]) -> CanFrame {
        let len = data.len().min(8);
        let mut d = [0u8; 8];
        d[..len].copy_from_slice(&data[..len]);
        CanFrame {
            id,
            extended: false,
            rtr: false,
            len: len as u8,
            data: d,
        }
    }

    /// A standard-ID remote (RTR) frame.
    pub fn remote(id: u32, len: u8) -> CanFrame {
        CanFrame {
            id,
            extended: false,
            rtr: true,
            len: len.min(8),
            data: [0; 8],
        }
    }

    /// The valid payload bytes (`len` clamped to 8).
    pub fn payload(&self) -> &[u8] {
        &self.data[..(self.len as usize).min(8)]
    }
}
