//! SDO block transfer (CiA 301 7.2.4.3.9 ff.), server side, with CRC (the CRC function is
//! canopen-rs's `sdo::block::crc16`).

use super::{abort, download_size, mux, ObjectAccess, SdoServer, State, BUF};
use canopen_rs::sdo::block::crc16;

/// Segments per sub-block the server accepts in a block download.
pub const DOWN_BLKSIZE: u8 = (BUF / 7) as u8;

#[derive(Clone, Copy, Debug)]
pub(crate) struct DownState {
    expected: u8,
    crc: bool,
    size: Option<usize>,
    waiting_end: bool,
}

impl DownState {
    pub(crate) fn receiving(&self) -> bool {
        !self.waiting_end
    }
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct UpState {
    blksize: u8,
    crc: bool,
    /// Bytes acknowledged by the client.
    acked: usize,
    started: bool,
    ending: bool,
}

impl SdoServer {
    pub(super) fn block_download(
        &mut self,
        req: &[u8; 8],
        od: &mut impl ObjectAccess,
        out: &mut impl FnMut([u8; 8]),
    ) {
        match self.state {
            State::Idle if req[0] & 0x01 == 0 => {
                self.index = u16::from_le_bytes([req[1], req[2]]);
                self.sub = req[3];
                let crc = req[0] & 0x04 != 0;
                let size = match download_size(od, self.index, self.sub, req[0] & 0x02 != 0, req) {
                    Ok(size) => size,
                    Err(c) => return self.fail(c, out),
                };
                self.len = 0;
                self.state = State::BlockDownload(DownState {
                    expected: 1,
                    crc,
                    size,
                    waiting_end: false,
                });
                let mut f = mux(0xA4, self.index, self.sub);
                f[4] = DOWN_BLKSIZE;
                out(f);
            }
            State::BlockDownload(st) if st.waiting_end && req[0] & 0x01 == 1 => {
                let unused = ((req[0] >> 2) & 7) as usize;
                let total = self.len.saturating_sub(unused);
                let crc = u16::from_le_bytes([req[1], req[2]]);
                if st.crc && crc16(&self.buf[..total]) != crc {
                    return self.fail(abort::CRC, out);
                }
                if st.size.is_some_and(|s| s != total) {
                    return self.fail(abort::LENGTH_MISMATCH, out);
                }
                let data = self.buf;
                match od.write(self.index, self.sub, &data[..total]) {
                    Ok(()) => {
                        out([0xA1, 0, 0, 0, 0, 0, 0, 0]);
                        self.state = State::Idle;
                    }
                    Err(c) => self.fail(c, out),
                }
            }
            _ => self.fail(abort::COMMAND, out),
        }
    }

    pub(super) fn block_download_segment(
        &mut self,
        mut st: DownState,
        req: &[u8; 8],
        _od: &mut impl ObjectAccess,
        out: &mut impl FnMut([u8; 8]),
    ) {
        let seq = req[0] & 0x7F;
        let last = req[0] & 0x80 != 0;
        if seq == 0 || seq > DOWN_BLKSIZE {
            return self.fail(abort::SEQUENCE, out);
        }
        if seq == st.expected {
            if self.len + 7 > BUF {
                return self.fail(abort::OUT_OF_MEMORY, out);
            }
            self.buf[self.len..self.len + 7].copy_from_slice(&req[1..8]);
            self.len += 7;
            st.expected += 1;
            if last || seq == DOWN_BLKSIZE {
                out([0xA2, seq, DOWN_BLKSIZE, 0, 0, 0, 0, 0]);
                st.expected = 1;
                st.waiting_end = last;
            }
        } else if seq == DOWN_BLKSIZE || last {
            // a segment was lost: acknowledge the last good one, the client repeats the rest
            out([0xA2, st.expected - 1, DOWN_BLKSIZE, 0, 0, 0, 0, 0]);
            st.expected = 1;
        }
        self.state = State::BlockDownload(st);
    }

    pub(super) fn block_upload(
        &mut self,
        req: &[u8; 8],
        od: &mut impl ObjectAccess,
        out: &mut impl FnMut([u8; 8]),
    ) {
        let cs = req[0] & 0x03;
        match (self.state, cs) {
            (State::Idle, 0) => {
                self.index = u16::from_le_bytes([req[1], req[2]]);
                self.sub = req[3];
                let blksize = req[4];
                if blksize == 0 || blksize > 127 {
                    return self.fail(abort::BLOCK_SIZE, out);
                }
                let mut buf = [0u8; BUF];
                match od.read(self.index, self.sub, &mut buf) {
                    Err(c) => self.fail(c, out),
                    Ok(n) => {
                        self.buf = buf;
                        self.len = n;
                        let mut f = mux(0xC6, self.index, self.sub);
                        f[4..8].copy_from_slice(&(n as u32).to_le_bytes());
                        out(f);
                        self.state = State::BlockUpload(UpState {
                            blksize,
                            crc: req[0] & 0x04 != 0,
                            acked: 0,
                            started: false,
                            ending: false,
                        });
                    }
                }
            }
            (State::BlockUpload(mut st), 3) if !st.started => {
                st.started = true;
                self.state = State::BlockUpload(st);
                self.send_sub_block(st, out);
            }
            (State::BlockUpload(mut st), 2) if st.started && !st.ending => {
                let ackseq = req[1];
                let blksize = req[2];
                if ackseq > st.blksize {
                    return self.fail(abort::SEQUENCE, out);
                }
                if blksize == 0 || blksize > 127 {
                    return self.fail(abort::BLOCK_SIZE, out);
                }
                st.acked = (st.acked + ackseq as usize * 7).min(self.len);
                st.blksize = blksize;
                if st.acked >= self.len {
                    st.ending = true;
                    let unused = ((7 - self.len % 7) % 7) as u8;
                    let unused = if self.len == 0 { 7 } else { unused };
                    let crc = if st.crc {
                        crc16(&self.buf[..self.len])
                    } else {
                        0
                    };
                    let c = crc.to_le_bytes();
                    out([0xC1 | (unused << 2), c[0], c[1], 0, 0, 0, 0, 0]);
                    self.state = State::BlockUpload(st);
                } else {
                    self.state = State::BlockUpload(st);
                    self.send_sub_block(st, out);
                }
            }
            (State::BlockUpload(st), 1) if st.ending => {
                self.state = State::Idle;
            }
            _ => self.fail(abort::COMMAND, out),
        }
    }

    fn send_sub_block(&mut self, st: UpState, out: &mut impl FnMut([u8; 8])) {
        let mut pos = st.acked;
        for seq in 1..=st.blksize {
            let n = (self.len - pos).min(7);
            let last = pos + n >= self.len;
            let mut f = [0u8; 8];
            f[0] = seq | if last { 0x80 } else { 0 };
            f[1..1 + n].copy_from_slice(&self.buf[pos..pos + n]);
            out(f);
            pos += n;
            if last {
                break;
            }
        }
    }
}
