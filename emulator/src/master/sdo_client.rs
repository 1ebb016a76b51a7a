//! A minimal SDO client for the reference master: expedited download and upload (up to
//! 4 bytes), one transfer at a time, with a timeout. Segmented transfers are not needed for
//! configuring a drive.

use crate::bus::CanFrame;

/// One finished transfer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SdoResult {
    Written,
    Read(u32),
    Aborted(u32),
    TimedOut,
}

#[derive(Debug, Clone, Copy)]
struct Pending {
    index: u16,
    sub: u8,
    upload: bool,
    deadline_us: u64,
}

#[derive(Debug)]
pub struct SdoClient {
    node_id: u8,
    timeout_us: u64,
    pending: Option<Pending>,
    done: Option<SdoResult>,
}

impl SdoClient {
    pub fn new(node_id: u8, timeout_us: u64) -> Self {
        Self {
            node_id,
            timeout_us,
            pending: None,
            done: None,
        }
    }

    pub fn busy(&self) -> bool {
        self.pending.is_some()
    }

    /// Expedited download of `len` (1-4) bytes of `value`, little endian.
    pub fn write(&mut self, now_us: u64, index: u16, sub: u8, value: u32, len: u8) -> CanFrame {
        let n = 4 - len.clamp(1, 4);
        let cmd = 0x23 | (n << 2);
        let [i0, i1] = index.to_le_bytes();
        let v = value.to_le_bytes();
        self.start(now_us, index, sub, false);
        CanFrame::new(
            0x600 + u32::from(self.node_id),
            &[cmd, i0, i1, sub, v[0], v[1], v[2], v[3]],
        )
    }

    /// Upload request.
    pub fn read(&mut self, now_us: u64, index: u16, sub: u8) -> CanFrame {
        let [i0, i1] = index.to_le_bytes();
        self.start(now_us, index, sub, true);
        CanFrame::new(
            0x600 + u32::from(self.node_id),
            &[0x40, i0, i1, sub, 0, 0, 0, 0],
        )
    }

    fn start(&mut self, now_us: u64, index: u16, sub: u8, upload: bool) {
        self.done = None;
        self.pending = Some(Pending {
            index,
            sub,
            upload,
            deadline_us: now_us + self.timeout_us,
        });
    }

    /// Feed a received frame; returns true if it was this client's SDO response.
    pub fn handle(&mut self, frame: &CanFrame) -> bool {
        if frame.extended || frame.id != 0x580 + u32::from(self.node_id) || frame.len != 8 {
            return false;
        }
        let Some(p) = self.pending else {
            return true;
        };
        let d = frame.data;
        let index = u16::from_le_bytes([d[1], d[2]]);
        if index != p.index || d[3] != p.sub {
            return true;
        }
        let value = u32::from_le_bytes([d[4], d[5], d[6], d[7]]);
        let result = match d[0] {
            0x80 => SdoResult::Aborted(value),
            0x60 if !p.upload => SdoResult::Written,
            c if p.upload && c & 0xE0 == 0x40 && c & 0x02 != 0 => {
                let unused = if c & 0x01 != 0 { (c >> 2) & 0x3 } else { 0 };
                let bytes = 4 - unused as u32;
                let mask = if bytes == 4 {
                    u32::MAX
                } else {
                    (1u32 << (8 * bytes)) - 1
                };
                SdoResult::Read(value & mask)
            }
            // A segmented upload answer: more than 4 bytes, which this client does not read.
            _ => SdoResult::Aborted(0x0504_0001),
        };
        self.pending = None;
        self.done = Some(result);
        true
    }

    /// Check the timeout; returns the finished result once.
    pub fn poll(&mut self, now_us: u64) -> Option<SdoResult> {
        if let Some(p) = self.pending {
            if now_us >= p.deadline_us {
                self.pending = None;
                return Some(SdoResult::TimedOut);
            }
        }
        self.done.take()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reply(node: u8, d: [u8; 8]) -> CanFrame {
        CanFrame::new(0x580 + u32::from(node), &d)
    }

    #[test]
    fn expedited_download_encodes_size_and_completes_on_ack() {
        let mut c = SdoClient::new(5, 1000);
        let f = c.write(0, 0x6060, 0, 8, 1);
        assert_eq!(f.id, 0x605);
        assert_eq!(&f.data[..5], &[0x2F, 0x60, 0x60, 0x00, 0x08]);
        assert!(c.handle(&reply(5, [0x60, 0x60, 0x60, 0, 0, 0, 0, 0])));
        assert_eq!(c.poll(1), Some(SdoResult::Written));
        assert!(!c.busy());
    }

    #[test]
    fn upload_masks_unused_bytes_and_abort_and_timeout_are_reported() {
        let mut c = SdoClient::new(5, 1000);
        c.read(0, 0x6041, 0);
        c.handle(&reply(5, [0x4B, 0x41, 0x60, 0, 0x37, 0x02, 0xFF, 0xFF]));
        assert_eq!(c.poll(1), Some(SdoResult::Read(0x0237)));
        c.read(0, 0x1234, 0);
        c.handle(&reply(5, [0x80, 0x34, 0x12, 0, 0, 0, 0x02, 0x06]));
        assert_eq!(c.poll(1), Some(SdoResult::Aborted(0x0602_0000)));
        c.read(0, 0x1000, 0);
        assert_eq!(c.poll(999), None);
        assert_eq!(c.poll(1000), Some(SdoResult::TimedOut));
    }
}
