//! SDO block transfer (CiA 301 7.2.4.3.9 ff.), server side, with CRC (the CRC function is
//! canopen-rs's `sdo::block::crc16`).

use super::{abort, download_size, ObjectAccess, SdoServer, State};
use crate::wire::sdo::{BlockSegment, SdoRequest, SdoResponse};
use canopen_rs::sdo::block::crc16;

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
        req: &SdoRequest,
        od: &mut impl ObjectAccess,
        out: &mut impl FnMut([u8; 8]),
    ) {
        match (self.state, *req) {
            (State::Idle, SdoRequest::BlockDownloadInitiate { mux, crc, size }) => {
                self.start(mux, false);
                let size = match download_size(od, self.index, self.sub, size, self.buf.len()) {
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
                out(SdoResponse::BlockDownloadInitiate {
                    mux,
                    crc: true,
                    blksize: self.down_blksize(),
                }
                .emit());
            }
            (State::BlockDownload(st), SdoRequest::BlockDownloadEnd { unused, crc })
                if st.waiting_end =>
            {
                let total = self.len.saturating_sub(unused as usize);
                if st.crc && crc16(&self.buf[..total]) != crc {
                    return self.fail(abort::CRC, out);
                }
                if st.size.is_some_and(|s| s != total) {
                    return self.fail(abort::LENGTH_MISMATCH, out);
                }
                match self.write_received(od, total) {
                    Ok(()) => {
                        out(SdoResponse::BlockDownloadEnd.emit());
                        self.done(None);
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
        seg: &BlockSegment,
        out: &mut impl FnMut([u8; 8]),
    ) {
        let seq = seg.seqno;
        let blksize = self.down_blksize();
        let ack = |ackseq| SdoResponse::BlockDownloadAck { ackseq, blksize }.emit();
        if seq == 0 || seq > blksize {
            return self.fail(abort::SEQUENCE, out);
        }
        if seq == st.expected {
            if self.len + 7 > self.buf.len() {
                return self.fail(abort::OUT_OF_MEMORY, out);
            }
            self.buf[self.len..self.len + 7].copy_from_slice(&seg.data);
            self.len += 7;
            st.expected += 1;
            if seg.last || seq == blksize {
                out(ack(seq));
                st.expected = 1;
                st.waiting_end = seg.last;
            }
        } else if seq == blksize || seg.last {
            // a segment was lost: acknowledge the last good one, the client repeats the rest
            out(ack(st.expected - 1));
            st.expected = 1;
        }
        self.state = State::BlockDownload(st);
    }

    pub(super) fn block_upload(
        &mut self,
        req: &SdoRequest,
        od: &mut impl ObjectAccess,
        out: &mut impl FnMut([u8; 8]),
    ) {
        match (self.state, *req) {
            (
                State::Idle,
                SdoRequest::BlockUploadInitiate {
                    mux, crc, blksize, ..
                },
            ) => {
                self.start(mux, true);
                if blksize == 0 || blksize > 127 {
                    return self.fail(abort::BLOCK_SIZE, out);
                }
                match self.read_into_buf(od) {
                    Err(c) => self.fail(c, out),
                    Ok(n) => {
                        self.len = n;
                        out(SdoResponse::BlockUploadInitiate {
                            mux,
                            crc: true,
                            size: Some(n as u32),
                        }
                        .emit());
                        self.state = State::BlockUpload(UpState {
                            blksize,
                            crc,
                            acked: 0,
                            started: false,
                            ending: false,
                        });
                    }
                }
            }
            (State::BlockUpload(mut st), SdoRequest::BlockUploadStart) if !st.started => {
                st.started = true;
                self.state = State::BlockUpload(st);
                self.send_sub_block(st, out);
            }
            (State::BlockUpload(mut st), SdoRequest::BlockUploadAck { ackseq, blksize })
                if st.started && !st.ending =>
            {
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
                    out(SdoResponse::BlockUploadEnd { unused, crc }.emit());
                    self.state = State::BlockUpload(st);
                } else {
                    self.state = State::BlockUpload(st);
                    self.send_sub_block(st, out);
                }
            }
            (State::BlockUpload(st), SdoRequest::BlockUploadEnd) if st.ending => {
                self.done(None);
            }
            _ => self.fail(abort::COMMAND, out),
        }
    }

    fn send_sub_block(&mut self, st: UpState, out: &mut impl FnMut([u8; 8])) {
        let mut pos = st.acked;
        for seq in 1..=st.blksize {
            let n = (self.len - pos).min(7);
            let last = pos + n >= self.len;
            out(BlockSegment::new(seq, &self.buf[pos..pos + n], last).emit());
            pos += n;
            if last {
                break;
            }
        }
    }
}
