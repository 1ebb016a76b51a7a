//! SDO server: expedited, segmented and (in `block.rs`) block transfer, upload and download,
//! with the stalled-transfer timeout. Sans-IO: request bytes and a time go in, response bytes
//! come out through a callback. The transfer buffer is allocated when the node is built, as
//! large as the longest value of its dictionary (at least [`MIN_BUF`] bytes), so transfers
//! never allocate.

pub mod block;

pub use crate::event::{SdoDirection, SdoTransfer};

use crate::wire::sdo::{
    self as wire, BlockSegment, Initiate, Mux, SdoRequest, SdoResponse, Segment,
};

/// Smallest transfer buffer (the standard objects' longest value).
pub const MIN_BUF: usize = 64;
/// Default timeout of a stalled segmented / block transfer.
pub const DEFAULT_TIMEOUT_US: u64 = 1_000_000;

pub use crate::wire::sdo::abort;

/// What the server needs from the object dictionary. Errors are abort codes.
pub trait ObjectAccess {
    /// Read the value of (index, sub) into `buf`; returns its length.
    fn read(&mut self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, u32>;
    /// Check, before any data moves, that (index, sub) exists and is writable and that a
    /// value of `size` bytes (if known) can fit.
    fn check_write(&mut self, index: u16, sub: u8, size: Option<usize>) -> Result<(), u32>;
    /// Write the complete value.
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), u32>;
}

#[derive(Clone, Copy, Debug)]
pub(crate) enum State {
    Idle,
    SegDownload { toggle: bool, size: Option<usize> },
    SegUpload { toggle: bool, pos: usize },
    BlockDownload(block::DownState),
    BlockUpload(block::UpState),
}

/// The SDO server of one node.
#[derive(Clone, Debug)]
pub struct SdoServer {
    pub(crate) state: State,
    pub(crate) index: u16,
    pub(crate) sub: u8,
    pub(crate) buf: Box<[u8]>,
    pub(crate) len: usize,
    pub(crate) last_us: u64,
    /// The transfer in progress (or last) is an upload.
    upload: bool,
    /// The transfer that just finished, for the node's event queue.
    finished: Option<SdoTransfer>,
    /// Timeout of a stalled transfer (abort 0x05040000).
    pub timeout_us: u64,
}

impl Default for SdoServer {
    fn default() -> Self {
        SdoServer::with_capacity(MIN_BUF)
    }
}

impl SdoServer {
    /// A server whose transfers hold values of up to `bytes` (at least [`MIN_BUF`]).
    pub fn with_capacity(bytes: usize) -> SdoServer {
        SdoServer {
            state: State::Idle,
            index: 0,
            sub: 0,
            buf: vec![0; bytes.max(MIN_BUF)].into_boxed_slice(),
            len: 0,
            last_us: 0,
            upload: false,
            finished: None,
            timeout_us: DEFAULT_TIMEOUT_US,
        }
    }

    /// Segments per block of a block download (at most 127; the buffer holds a block).
    pub(crate) fn down_blksize(&self) -> u8 {
        (self.buf.len() / 7).clamp(1, 127) as u8
    }

    /// Hand the whole received value to `od` (the buffer lent out without a copy).
    pub(crate) fn write_received(
        &mut self,
        od: &mut impl ObjectAccess,
        len: usize,
    ) -> Result<(), u32> {
        let data = core::mem::take(&mut self.buf);
        let r = od.write(self.index, self.sub, &data[..len]);
        self.buf = data;
        r
    }

    /// Read the object into the buffer; its length.
    pub(crate) fn read_into_buf(&mut self, od: &mut impl ObjectAccess) -> Result<usize, u32> {
        od.read(self.index, self.sub, &mut self.buf)
    }
}

/// An abort frame.
pub fn abort_frame(index: u16, sub: u8, code: u32) -> [u8; 8] {
    wire::abort(Mux::new(index, sub), code)
}

impl SdoServer {
    /// Whether a transfer is in progress.
    pub fn busy(&self) -> bool {
        !matches!(self.state, State::Idle)
    }

    /// The next request is a block download segment (which carries no command specifier).
    pub(crate) fn expects_block_segment(&self) -> bool {
        matches!(self.state, State::BlockDownload(st) if st.receiving())
    }

    /// Reset to idle without sending anything (NMT reset).
    pub fn reset(&mut self) {
        self.state = State::Idle;
    }

    pub(crate) fn mux(&self) -> Mux {
        Mux::new(self.index, self.sub)
    }

    fn start(&mut self, mux: Mux, upload: bool) {
        self.index = mux.index;
        self.sub = mux.sub;
        self.upload = upload;
    }

    fn fail(&mut self, code: u32, out: &mut impl FnMut([u8; 8])) {
        out(abort_frame(self.index, self.sub, code));
        self.done(Some(code));
    }

    /// The transfer ended (completed, or aborted with `abort`): back to idle, remember it.
    fn done(&mut self, abort: Option<u32>) {
        self.state = State::Idle;
        self.finished = Some(SdoTransfer {
            index: self.index,
            sub: self.sub,
            direction: if self.upload {
                SdoDirection::Upload
            } else {
                SdoDirection::Download
            },
            abort,
        });
    }

    /// The transfer that finished since the last call, if any.
    pub fn take_finished(&mut self) -> Option<SdoTransfer> {
        self.finished.take()
    }

    /// When [`SdoServer::poll`] will abort the transfer in progress (us), if one is (never
    /// when that is beyond the end of the clock's range).
    pub fn deadline_us(&self) -> Option<u64> {
        if !self.busy() {
            return None;
        }
        self.last_us.checked_add(self.timeout_us)?.checked_add(1)
    }

    /// Abort a stalled transfer.
    pub fn poll(&mut self, now_us: u64, out: &mut impl FnMut([u8; 8])) {
        if self.busy() && now_us.saturating_sub(self.last_us) > self.timeout_us {
            self.fail(abort::TIMEOUT, out);
        }
    }

    /// Handle one request frame (8 data bytes; shorter frames are ignored by the caller).
    pub fn handle(
        &mut self,
        req: &[u8; 8],
        now_us: u64,
        od: &mut impl ObjectAccess,
        out: &mut impl FnMut([u8; 8]),
    ) {
        self.last_us = now_us;
        // Block download sub-block segments carry no command specifier.
        if let State::BlockDownload(st) = self.state {
            if st.receiving() && req[0] != 0x80 {
                return self.block_download_segment(st, &BlockSegment::parse(req), out);
            }
        }
        let request = match SdoRequest::parse(req) {
            Ok(r) => r,
            Err(_) => {
                if !self.busy() {
                    self.start(Mux::of(req), false);
                }
                return self.fail(abort::COMMAND, out);
            }
        };
        match request {
            // abort from the client: no answer
            SdoRequest::Abort { code, .. } => {
                if self.busy() {
                    self.done(Some(code));
                }
            }
            SdoRequest::InitiateDownload { mux, data } => {
                self.start(mux, false);
                self.download_initiate(data, od, out)
            }
            SdoRequest::InitiateUpload { mux } => {
                self.start(mux, true);
                self.upload_initiate(od, out)
            }
            SdoRequest::DownloadSegment(seg) => self.download_segment(&seg, od, out),
            SdoRequest::UploadSegment { toggle } => self.upload_segment(toggle, out),
            SdoRequest::BlockUploadInitiate { .. }
            | SdoRequest::BlockUploadStart
            | SdoRequest::BlockUploadAck { .. }
            | SdoRequest::BlockUploadEnd => self.block_upload(&request, od, out),
            SdoRequest::BlockDownloadInitiate { .. } | SdoRequest::BlockDownloadEnd { .. } => {
                self.block_download(&request, od, out)
            }
        }
    }

    fn download_initiate(
        &mut self,
        data: Initiate,
        od: &mut impl ObjectAccess,
        out: &mut impl FnMut([u8; 8]),
    ) {
        match data {
            Initiate::Expedited { data, size } => {
                let res = od.check_write(self.index, self.sub, size.map(usize::from));
                let res = res.and_then(|_| {
                    // without a size, the object's own size (<= 4) is taken
                    let n = match size {
                        Some(n) => n as usize,
                        None => {
                            let mut probe = [0u8; 8];
                            od.read(self.index, self.sub, &mut probe)
                                .map(|l| l.clamp(1, 4))
                                .unwrap_or(4)
                        }
                    };
                    od.write(self.index, self.sub, &data[..n])
                });
                match res {
                    Ok(()) => {
                        out(SdoResponse::InitiateDownload { mux: self.mux() }.emit());
                        self.done(None);
                    }
                    Err(c) => self.fail(c, out),
                }
            }
            Initiate::Segmented { size } => {
                let size = match download_size(od, self.index, self.sub, size, self.buf.len()) {
                    Ok(size) => size,
                    Err(c) => return self.fail(c, out),
                };
                self.len = 0;
                self.state = State::SegDownload {
                    toggle: false,
                    size,
                };
                out(SdoResponse::InitiateDownload { mux: self.mux() }.emit());
            }
        }
    }

    fn download_segment(
        &mut self,
        seg: &Segment,
        od: &mut impl ObjectAccess,
        out: &mut impl FnMut([u8; 8]),
    ) {
        let State::SegDownload { toggle, size } = self.state else {
            return self.fail(abort::COMMAND, out);
        };
        if seg.toggle != toggle {
            return self.fail(abort::TOGGLE, out);
        }
        let n = seg.bytes().len();
        if self.len + n > self.buf.len() {
            return self.fail(abort::OUT_OF_MEMORY, out);
        }
        self.buf[self.len..self.len + n].copy_from_slice(seg.bytes());
        self.len += n;
        let ack = SdoResponse::DownloadSegment { toggle: seg.toggle }.emit();
        if seg.last {
            if size.is_some_and(|s| s != self.len) {
                return self.fail(abort::LENGTH_MISMATCH, out);
            }
            match self.write_received(od, self.len) {
                Ok(()) => {
                    out(ack);
                    self.done(None);
                }
                Err(c) => self.fail(c, out),
            }
        } else {
            out(ack);
            self.state = State::SegDownload {
                toggle: !toggle,
                size,
            };
        }
    }

    fn upload_initiate(&mut self, od: &mut impl ObjectAccess, out: &mut impl FnMut([u8; 8])) {
        match self.read_into_buf(od) {
            Err(c) => self.fail(c, out),
            Ok(n) if n <= 4 && n > 0 => {
                let data = Initiate::expedited(&self.buf[..n]);
                out(SdoResponse::InitiateUpload {
                    mux: self.mux(),
                    data,
                }
                .emit());
                self.done(None);
            }
            Ok(n) => {
                self.len = n;
                let data = Initiate::Segmented {
                    size: Some(n as u32),
                };
                out(SdoResponse::InitiateUpload {
                    mux: self.mux(),
                    data,
                }
                .emit());
                self.state = State::SegUpload {
                    toggle: false,
                    pos: 0,
                };
            }
        }
    }

    fn upload_segment(&mut self, t: bool, out: &mut impl FnMut([u8; 8])) {
        let State::SegUpload { toggle, pos } = self.state else {
            return self.fail(abort::COMMAND, out);
        };
        if t != toggle {
            return self.fail(abort::TOGGLE, out);
        }
        let n = (self.len - pos).min(7);
        let last = pos + n >= self.len;
        out(SdoResponse::UploadSegment(Segment::new(t, &self.buf[pos..pos + n], last)).emit());
        if last {
            self.done(None);
        } else {
            self.state = State::SegUpload {
                toggle: !toggle,
                pos: pos + n,
            };
        }
    }
}

/// The size a segmented or block download announces, checked against the object (access,
/// length) and against our buffer of `cap` bytes.
fn download_size(
    od: &mut impl ObjectAccess,
    index: u16,
    sub: u8,
    announced: Option<u32>,
    cap: usize,
) -> Result<Option<usize>, u32> {
    let size = announced.map(|n| n as usize);
    od.check_write(index, sub, size)?;
    if size.is_some_and(|n| n > cap) {
        return Err(abort::OUT_OF_MEMORY);
    }
    Ok(size)
}
