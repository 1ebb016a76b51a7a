//! A minimal SDO client for the reference master: expedited download and upload (up to
//! 4 bytes), one transfer at a time, with a timeout. Segmented transfers are not needed for
//! configuring a drive.

use crate::bus::CanFrame;
use drive_protocol::wire::{cob, Initiate, Mux, SdoRequest, SdoResponse};

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
        let n = usize::from(len.clamp(1, 4));
        let req = SdoRequest::InitiateDownload {
            mux: Mux::new(index, sub),
            data: Initiate::expedited(&value.to_le_bytes()[..n]),
        };
        self.start(now_us, index, sub, false);
        CanFrame::new(cob::SDO_RX + u32::from(self.node_id), &req.emit())
    }

    /// Upload request.
    pub fn read(&mut self, now_us: u64, index: u16, sub: u8) -> CanFrame {
        let req = SdoRequest::InitiateUpload {
            mux: Mux::new(index, sub),
        };
        self.start(now_us, index, sub, true);
        CanFrame::new(cob::SDO_RX + u32::from(self.node_id), &req.emit())
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
        if frame.extended || frame.id != cob::SDO_TX + u32::from(self.node_id) || frame.len != 8 {
            return false;
        }
        let Some(p) = self.pending else {
            return true;
        };
        let response = SdoResponse::parse(&frame.data);
        // Only answers naming the pending object (segment answers name none) are ours.
        let mux = Mux::new(p.index, p.sub);
        if response
            .ok()
            .and_then(|r| r.mux())
            .unwrap_or(Mux::of(&frame.data))
            != mux
        {
            return true;
        }
        let result = match response {
            Ok(SdoResponse::Abort { code, .. }) => SdoResult::Aborted(code),
            Ok(SdoResponse::InitiateDownload { .. }) if !p.upload => SdoResult::Written,
            Ok(SdoResponse::InitiateUpload {
                data: data @ Initiate::Expedited { .. },
                ..
            }) if p.upload => {
                let mut v = [0u8; 4];
                let b = data.bytes();
                v[..b.len()].copy_from_slice(b);
                SdoResult::Read(u32::from_le_bytes(v))
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
