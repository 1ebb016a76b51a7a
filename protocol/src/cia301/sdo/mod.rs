//! SDO server: expedited, segmented and (in `block.rs`) block transfer, upload and download,
//! with the stalled-transfer timeout. Sans-IO: request bytes and a time go in, response bytes
//! come out through a callback. Values are at most [`BUF`] bytes (our largest object is a
//! short string), so transfers never allocate.

pub mod block;

/// Largest value the server moves in one transfer.
pub const BUF: usize = 64;
/// Default timeout of a stalled segmented / block transfer.
pub const DEFAULT_TIMEOUT_US: u64 = 1_000_000;

/// SDO abort codes (CiA 301 7.2.4.3.17).
pub mod abort {
    pub const TOGGLE: u32 = 0x0503_0000;
    pub const TIMEOUT: u32 = 0x0504_0000;
    pub const COMMAND: u32 = 0x0504_0001;
    pub const BLOCK_SIZE: u32 = 0x0504_0002;
    pub const SEQUENCE: u32 = 0x0504_0003;
    pub const CRC: u32 = 0x0504_0004;
    pub const OUT_OF_MEMORY: u32 = 0x0504_0005;
    pub const UNSUPPORTED_ACCESS: u32 = 0x0601_0000;
    pub const WRITE_ONLY: u32 = 0x0601_0001;
    pub const READ_ONLY: u32 = 0x0601_0002;
    pub const NO_OBJECT: u32 = 0x0602_0000;
    pub const NOT_MAPPABLE: u32 = 0x0604_0041;
    pub const PDO_LENGTH: u32 = 0x0604_0042;
    pub const PARAM_INCOMPATIBLE: u32 = 0x0604_0043;
    pub const HARDWARE: u32 = 0x0606_0000;
    pub const LENGTH_MISMATCH: u32 = 0x0607_0010;
    pub const TOO_LONG: u32 = 0x0607_0012;
    pub const TOO_SHORT: u32 = 0x0607_0013;
    pub const NO_SUB: u32 = 0x0609_0011;
    pub const VALUE_RANGE: u32 = 0x0609_0030;
    pub const VALUE_HIGH: u32 = 0x0609_0031;
    pub const VALUE_LOW: u32 = 0x0609_0032;
    pub const MAX_LT_MIN: u32 = 0x0609_0036;
    pub const GENERAL: u32 = 0x0800_0000;
    pub const CANNOT_STORE: u32 = 0x0800_0020;
    pub const DEVICE_STATE: u32 = 0x0800_0022;
}

/// What the server needs from the object dictionary. Errors are abort codes.
pub trait ObjectAccess {
    /// Read the value of (index, sub) into `buf`; returns its length.
    fn read(&mut self, index: u16, sub: u8, buf: &mut [u8; BUF]) -> Result<usize, u32>;
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
    pub(crate) buf: [u8; BUF],
    pub(crate) len: usize,
    pub(crate) last_us: u64,
    /// Timeout of a stalled transfer (abort 0x05040000).
    pub timeout_us: u64,
}

impl Default for SdoServer {
    fn default() -> Self {
        SdoServer {
            state: State::Idle,
            index: 0,
            sub: 0,
            buf: [0; BUF],
            len: 0,
            last_us: 0,
            timeout_us: DEFAULT_TIMEOUT_US,
        }
    }
}

/// An abort frame.
pub fn abort_frame(index: u16, sub: u8, code: u32) -> [u8; 8] {
    let i = index.to_le_bytes();
    let c = code.to_le_bytes();
    [0x80, i[0], i[1], sub, c[0], c[1], c[2], c[3]]
}

pub(crate) fn mux(cs: u8, index: u16, sub: u8) -> [u8; 8] {
    let i = index.to_le_bytes();
    [cs, i[0], i[1], sub, 0, 0, 0, 0]
}

impl SdoServer {
    /// Whether a transfer is in progress.
    pub fn busy(&self) -> bool {
        !matches!(self.state, State::Idle)
    }

    /// Reset to idle without sending anything (NMT reset).
    pub fn reset(&mut self) {
        self.state = State::Idle;
    }

    fn fail(&mut self, code: u32, out: &mut impl FnMut([u8; 8])) {
        out(abort_frame(self.index, self.sub, code));
        self.state = State::Idle;
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
                return self.block_download_segment(st, req, od, out);
            }
        }
        let ccs = req[0] >> 5;
        let index = u16::from_le_bytes([req[1], req[2]]);
        let sub = req[3];
        match ccs {
            4 => {
                // abort from the client: no answer
                self.state = State::Idle;
            }
            1 => {
                self.index = index;
                self.sub = sub;
                self.download_initiate(req, od, out)
            }
            2 => {
                self.index = index;
                self.sub = sub;
                self.upload_initiate(od, out)
            }
            0 => self.download_segment(req, od, out),
            3 => self.upload_segment(req, out),
            5 => self.block_upload(req, od, out),
            6 => self.block_download(req, od, out),
            _ => {
                if self.busy() {
                    self.fail(abort::COMMAND, out)
                } else {
                    self.index = index;
                    self.sub = sub;
                    self.fail(abort::COMMAND, out)
                }
            }
        }
    }

    fn download_initiate(
        &mut self,
        req: &[u8; 8],
        od: &mut impl ObjectAccess,
        out: &mut impl FnMut([u8; 8]),
    ) {
        let e = req[0] & 0x02 != 0;
        let s = req[0] & 0x01 != 0;
        if e {
            let n = if s {
                4 - ((req[0] >> 2) & 3) as usize
            } else {
                4
            };
            let res = od.check_write(self.index, self.sub, if s { Some(n) } else { None });
            let res = res.and_then(|_| {
                // without a size, the object's own size (<= 4) is taken
                let mut probe = [0u8; BUF];
                let n = if s {
                    n
                } else {
                    od.read(self.index, self.sub, &mut probe)
                        .map(|l| l.clamp(1, 4))
                        .unwrap_or(4)
                };
                od.write(self.index, self.sub, &req[4..4 + n])
            });
            match res {
                Ok(()) => {
                    out(mux(0x60, self.index, self.sub));
                    self.state = State::Idle;
                }
                Err(c) => self.fail(c, out),
            }
        } else {
            let size = match download_size(od, self.index, self.sub, s, req) {
                Ok(size) => size,
                Err(c) => return self.fail(c, out),
            };
            self.len = 0;
            self.state = State::SegDownload {
                toggle: false,
                size,
            };
            out(mux(0x60, self.index, self.sub));
        }
    }

    fn download_segment(
        &mut self,
        req: &[u8; 8],
        od: &mut impl ObjectAccess,
        out: &mut impl FnMut([u8; 8]),
    ) {
        let State::SegDownload { toggle, size } = self.state else {
            return self.fail(abort::COMMAND, out);
        };
        let t = req[0] & 0x10 != 0;
        if t != toggle {
            return self.fail(abort::TOGGLE, out);
        }
        let n = 7 - ((req[0] >> 1) & 7) as usize;
        let last = req[0] & 1 != 0;
        if self.len + n > BUF {
            return self.fail(abort::OUT_OF_MEMORY, out);
        }
        self.buf[self.len..self.len + n].copy_from_slice(&req[1..1 + n]);
        self.len += n;
        if last {
            if size.is_some_and(|s| s != self.len) {
                return self.fail(abort::LENGTH_MISMATCH, out);
            }
            let data = self.buf;
            match od.write(self.index, self.sub, &data[..self.len]) {
                Ok(()) => {
                    out([0x20 | if t { 0x10 } else { 0 }, 0, 0, 0, 0, 0, 0, 0]);
                    self.state = State::Idle;
                }
                Err(c) => self.fail(c, out),
            }
        } else {
            out([0x20 | if t { 0x10 } else { 0 }, 0, 0, 0, 0, 0, 0, 0]);
            self.state = State::SegDownload {
                toggle: !toggle,
                size,
            };
        }
    }

    fn upload_initiate(&mut self, od: &mut impl ObjectAccess, out: &mut impl FnMut([u8; 8])) {
        let mut buf = [0u8; BUF];
        match od.read(self.index, self.sub, &mut buf) {
            Err(c) => self.fail(c, out),
            Ok(n) if n <= 4 && n > 0 => {
                let mut f = mux(0x43 | (((4 - n) as u8) << 2), self.index, self.sub);
                f[4..4 + n].copy_from_slice(&buf[..n]);
                out(f);
                self.state = State::Idle;
            }
            Ok(n) => {
                self.buf = buf;
                self.len = n;
                let mut f = mux(0x41, self.index, self.sub);
                f[4..8].copy_from_slice(&(n as u32).to_le_bytes());
                out(f);
                self.state = State::SegUpload {
                    toggle: false,
                    pos: 0,
                };
            }
        }
    }

    fn upload_segment(&mut self, req: &[u8; 8], out: &mut impl FnMut([u8; 8])) {
        let State::SegUpload { toggle, pos } = self.state else {
            return self.fail(abort::COMMAND, out);
        };
        let t = req[0] & 0x10 != 0;
        if t != toggle {
            return self.fail(abort::TOGGLE, out);
        }
        let n = (self.len - pos).min(7);
        let last = pos + n >= self.len;
        let mut f = [0u8; 8];
        f[0] = (if t { 0x10 } else { 0 }) | (((7 - n) as u8) << 1) | last as u8;
        f[1..1 + n].copy_from_slice(&self.buf[pos..pos + n]);
        out(f);
        self.state = if last {
            State::Idle
        } else {
            State::SegUpload {
                toggle: !toggle,
                pos: pos + n,
            }
        };
    }
}

/// The size a segmented or block download announces (`announced`: the size-indicated bit,
/// size in bytes 4..8), checked against the object (access, length) and against our buffer.
fn download_size(
    od: &mut impl ObjectAccess,
    index: u16,
    sub: u8,
    announced: bool,
    req: &[u8; 8],
) -> Result<Option<usize>, u32> {
    let size = announced.then(|| u32::from_le_bytes([req[4], req[5], req[6], req[7]]) as usize);
    od.check_write(index, sub, size)?;
    if size.is_some_and(|n| n > BUF) {
        return Err(abort::OUT_OF_MEMORY);
    }
    Ok(size)
}
