//! SDO frames (CiA 301 7.2.4.3): parse and emit of every command, client requests and server
//! responses, expedited, segmented and block. A frame is its 8 data bytes.
//!
//! Block sub-block segments carry no command specifier: which side sent them and whether a
//! block transfer is running decides that a frame is a [`BlockSegment`], so they have their
//! own type and the state machines (or a capture decoder following the transfer) pick it.

/// SDO abort codes (CiA 301 7.2.4.3.17) the server sends and the master reads: the 32-bit
/// value of bytes 4..8 of an abort frame.
pub mod abort {
    /// 0x0503_0000: toggle bit not alternated.
    pub const TOGGLE: u32 = 0x0503_0000;
    /// 0x0504_0000: SDO protocol timed out.
    pub const TIMEOUT: u32 = 0x0504_0000;
    /// 0x0504_0001: client/server command specifier not valid or unknown.
    pub const COMMAND: u32 = 0x0504_0001;
    /// 0x0504_0002: invalid block size (block mode).
    pub const BLOCK_SIZE: u32 = 0x0504_0002;
    /// 0x0504_0003: invalid sequence number (block mode).
    pub const SEQUENCE: u32 = 0x0504_0003;
    /// 0x0504_0004: CRC error (block mode).
    pub const CRC: u32 = 0x0504_0004;
    /// 0x0504_0005: out of memory (value larger than the transfer buffer).
    pub const OUT_OF_MEMORY: u32 = 0x0504_0005;
    /// 0x0601_0000: unsupported access to an object.
    pub const UNSUPPORTED_ACCESS: u32 = 0x0601_0000;
    /// 0x0601_0001: attempt to read a write-only object.
    pub const WRITE_ONLY: u32 = 0x0601_0001;
    /// 0x0601_0002: attempt to write a read-only object.
    pub const READ_ONLY: u32 = 0x0601_0002;
    /// 0x0602_0000: object does not exist in the object dictionary.
    pub const NO_OBJECT: u32 = 0x0602_0000;
    /// 0x0604_0041: object cannot be mapped to the PDO.
    pub const NOT_MAPPABLE: u32 = 0x0604_0041;
    /// 0x0604_0042: the mapped objects would exceed the PDO length (8 bytes).
    pub const PDO_LENGTH: u32 = 0x0604_0042;
    /// 0x0604_0043: general parameter incompatibility.
    pub const PARAM_INCOMPATIBLE: u32 = 0x0604_0043;
    /// 0x0606_0000: access failed due to a hardware error.
    pub const HARDWARE: u32 = 0x0606_0000;
    /// 0x0607_0010: data type does not match, length of service parameter does not match.
    pub const LENGTH_MISMATCH: u32 = 0x0607_0010;
    /// 0x0607_0012: data type does not match, length of service parameter too high.
    pub const TOO_LONG: u32 = 0x0607_0012;
    /// 0x0607_0013: data type does not match, length of service parameter too low.
    pub const TOO_SHORT: u32 = 0x0607_0013;
    /// 0x0609_0011: sub-index does not exist.
    pub const NO_SUB: u32 = 0x0609_0011;
    /// 0x0609_0030: value range of parameter exceeded (write access only).
    pub const VALUE_RANGE: u32 = 0x0609_0030;
    /// 0x0609_0031: value of parameter written too high.
    pub const VALUE_HIGH: u32 = 0x0609_0031;
    /// 0x0609_0032: value of parameter written too low.
    pub const VALUE_LOW: u32 = 0x0609_0032;
    /// 0x0609_0036: maximum value is less than minimum value.
    pub const MAX_LT_MIN: u32 = 0x0609_0036;
    /// 0x0800_0000: general error.
    pub const GENERAL: u32 = 0x0800_0000;
    /// 0x0800_0020: data cannot be transferred or stored to the application.
    pub const CANNOT_STORE: u32 = 0x0800_0020;
    /// 0x0800_0022: data cannot be transferred or stored because of the present device state.
    pub const DEVICE_STATE: u32 = 0x0800_0022;
}

/// The object an SDO transfer addresses: index and sub-index (bytes 1..4 of an initiate
/// frame or an abort).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Mux {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
}

impl Mux {
    /// A multiplexer.
    pub const fn new(index: u16, sub: u8) -> Mux {
        Mux { index, sub }
    }

    /// The multiplexer bytes of a frame (meaningful for initiate and abort frames only).
    pub fn of(frame: &[u8; 8]) -> Mux {
        Mux {
            index: u16::from_le_bytes([frame[1], frame[2]]),
            sub: frame[3],
        }
    }

    fn put(self, frame: &mut [u8; 8]) {
        let i = self.index.to_le_bytes();
        frame[1] = i[0];
        frame[2] = i[1];
        frame[3] = self.sub;
    }
}

/// The data of an initiate frame (download request, upload response): expedited bytes or the
/// size of a segmented transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Initiate {
    /// Expedited: the value is in the frame. `size` is `Some(1..=4)` when the frame says how
    /// many of the four bytes are valid, `None` when it does not (the object's size applies).
    Expedited {
        /// Bytes 4..8 of the frame.
        data: [u8; 4],
        /// Valid bytes, if indicated.
        size: Option<u8>,
    },
    /// Segmented: the value follows in segments; its size in bytes, if indicated.
    Segmented {
        /// Announced size.
        size: Option<u32>,
    },
}

impl Initiate {
    /// Expedited data of 1..=4 bytes (more are cut to 4), with its size indicated.
    pub fn expedited(bytes: &[u8]) -> Initiate {
        let n = bytes.len().clamp(1, 4);
        let mut data = [0u8; 4];
        let k = bytes.len().min(4);
        data[..k].copy_from_slice(&bytes[..k]);
        Initiate::Expedited {
            data,
            size: Some(n as u8),
        }
    }

    /// The valid expedited bytes (all four when the size is not indicated); empty for a
    /// segmented initiate.
    pub fn bytes(&self) -> &[u8] {
        match self {
            Initiate::Expedited { data, size } => &data[..size.unwrap_or(4).clamp(1, 4) as usize],
            Initiate::Segmented { .. } => &[],
        }
    }

    fn parse(b0: u8, frame: &[u8; 8]) -> Initiate {
        let e = b0 & 0x02 != 0;
        let s = b0 & 0x01 != 0;
        if e {
            Initiate::Expedited {
                data: [frame[4], frame[5], frame[6], frame[7]],
                size: s.then(|| 4 - ((b0 >> 2) & 3)),
            }
        } else {
            Initiate::Segmented {
                size: s.then(|| u32::from_le_bytes([frame[4], frame[5], frame[6], frame[7]])),
            }
        }
    }

    /// Bits 0..4 of the command byte and bytes 4..8.
    fn put(self, frame: &mut [u8; 8]) {
        match self {
            Initiate::Expedited { data, size } => {
                frame[0] |= 0x02;
                if let Some(n) = size {
                    frame[0] |= 0x01 | ((4 - n.clamp(1, 4)) << 2);
                }
                frame[4..8].copy_from_slice(&data);
            }
            Initiate::Segmented { size } => {
                if let Some(n) = size {
                    frame[0] |= 0x01;
                    frame[4..8].copy_from_slice(&n.to_le_bytes());
                }
            }
        }
    }
}

/// One segment of a segmented transfer (download request or upload response): up to 7 bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Segment {
    /// Toggle bit.
    pub toggle: bool,
    /// Bytes 1..8 of the frame.
    pub data: [u8; 7],
    /// Valid bytes (0..=7).
    pub len: u8,
    /// No more segments follow.
    pub last: bool,
}

impl Segment {
    /// A segment carrying `bytes` (at most 7; more are cut).
    pub fn new(toggle: bool, bytes: &[u8], last: bool) -> Segment {
        let n = bytes.len().min(7);
        let mut data = [0u8; 7];
        data[..n].copy_from_slice(&bytes[..n]);
        Segment {
            toggle,
            data,
            len: n as u8,
            last,
        }
    }

    /// The valid bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.data[..self.len.min(7) as usize]
    }

    fn parse(frame: &[u8; 8]) -> Segment {
        let mut data = [0u8; 7];
        data.copy_from_slice(&frame[1..8]);
        Segment {
            toggle: frame[0] & 0x10 != 0,
            data,
            len: 7 - ((frame[0] >> 1) & 7),
            last: frame[0] & 0x01 != 0,
        }
    }

    fn emit(&self, cs: u8) -> [u8; 8] {
        let mut f = [0u8; 8];
        f[0] = (cs << 5)
            | if self.toggle { 0x10 } else { 0 }
            | ((7 - self.len.min(7)) << 1)
            | self.last as u8;
        f[1..8].copy_from_slice(&self.data);
        f
    }
}

/// A block sub-block segment (either direction): sequence number 1..=127, 7 data bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockSegment {
    /// Sequence number within the sub-block (1..=127 on a valid frame).
    pub seqno: u8,
    /// Last segment of the transfer.
    pub last: bool,
    /// Bytes 1..8 (the last segment's unused bytes are given in the end frame).
    pub data: [u8; 7],
}

impl BlockSegment {
    /// A segment carrying `bytes` (at most 7, zero-padded).
    pub fn new(seqno: u8, bytes: &[u8], last: bool) -> BlockSegment {
        let n = bytes.len().min(7);
        let mut data = [0u8; 7];
        data[..n].copy_from_slice(&bytes[..n]);
        BlockSegment {
            seqno: seqno & 0x7F,
            last,
            data,
        }
    }

    /// Read a frame as a sub-block segment.
    pub fn parse(frame: &[u8; 8]) -> BlockSegment {
        let mut data = [0u8; 7];
        data.copy_from_slice(&frame[1..8]);
        BlockSegment {
            seqno: frame[0] & 0x7F,
            last: frame[0] & 0x80 != 0,
            data,
        }
    }

    /// The frame.
    pub fn emit(&self) -> [u8; 8] {
        let mut f = [0u8; 8];
        f[0] = (self.seqno & 0x7F) | if self.last { 0x80 } else { 0 };
        f[1..8].copy_from_slice(&self.data);
        f
    }
}

/// A frame with a command specifier this codec does not know (ccs / scs 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnknownCommand {
    /// The command byte.
    pub command: u8,
}

impl core::fmt::Display for UnknownCommand {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "unknown SDO command specifier in byte 0x{:02X}",
            self.command
        )
    }
}

impl std::error::Error for UnknownCommand {}

/// A request from the SDO client (COB-ID 0x600 + node), every command but the block
/// sub-block segments ([`BlockSegment`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoRequest {
    /// Initiate download (ccs 1): expedited value or announced size.
    InitiateDownload {
        /// Object.
        mux: Mux,
        /// Expedited data or segmented size.
        data: Initiate,
    },
    /// Download segment (ccs 0).
    DownloadSegment(Segment),
    /// Initiate upload (ccs 2).
    InitiateUpload {
        /// Object.
        mux: Mux,
    },
    /// Upload segment request (ccs 3).
    UploadSegment {
        /// Toggle bit.
        toggle: bool,
    },
    /// Abort (ccs 4).
    Abort {
        /// Object.
        mux: Mux,
        /// Abort code.
        code: u32,
    },
    /// Block upload initiate (ccs 5, cs 0).
    BlockUploadInitiate {
        /// Object.
        mux: Mux,
        /// The client supports CRC.
        crc: bool,
        /// Segments per sub-block the client accepts.
        blksize: u8,
        /// Protocol switch threshold (0: no switch).
        pst: u8,
    },
    /// Block upload: start sending (ccs 5, cs 3).
    BlockUploadStart,
    /// Block upload: sub-block acknowledged (ccs 5, cs 2).
    BlockUploadAck {
        /// Last segment received in sequence.
        ackseq: u8,
        /// Segments per next sub-block.
        blksize: u8,
    },
    /// Block upload: end confirmed (ccs 5, cs 1).
    BlockUploadEnd,
    /// Block download initiate (ccs 6, cs 0).
    BlockDownloadInitiate {
        /// Object.
        mux: Mux,
        /// The client supports CRC.
        crc: bool,
        /// Announced size.
        size: Option<u32>,
    },
    /// Block download end (ccs 6, cs 1).
    BlockDownloadEnd {
        /// Bytes of the last segment without data (0..=7).
        unused: u8,
        /// CRC of the whole value (0 when CRC is not used).
        crc: u16,
    },
}

impl SdoRequest {
    /// Parse a request frame. Every command specifier but 7 has a meaning; reserved bits are
    /// ignored.
    pub fn parse(frame: &[u8; 8]) -> Result<SdoRequest, UnknownCommand> {
        let b0 = frame[0];
        let mux = Mux::of(frame);
        Ok(match b0 >> 5 {
            0 => SdoRequest::DownloadSegment(Segment::parse(frame)),
            1 => SdoRequest::InitiateDownload {
                mux,
                data: Initiate::parse(b0, frame),
            },
            2 => SdoRequest::InitiateUpload { mux },
            3 => SdoRequest::UploadSegment {
                toggle: b0 & 0x10 != 0,
            },
            4 => SdoRequest::Abort {
                mux,
                code: u32_at(frame),
            },
            5 => match b0 & 0x03 {
                0 => SdoRequest::BlockUploadInitiate {
                    mux,
                    crc: b0 & 0x04 != 0,
                    blksize: frame[4],
                    pst: frame[5],
                },
                1 => SdoRequest::BlockUploadEnd,
                2 => SdoRequest::BlockUploadAck {
                    ackseq: frame[1],
                    blksize: frame[2],
                },
                _ => SdoRequest::BlockUploadStart,
            },
            6 => {
                if b0 & 0x01 == 0 {
                    SdoRequest::BlockDownloadInitiate {
                        mux,
                        crc: b0 & 0x04 != 0,
                        size: (b0 & 0x02 != 0).then(|| u32_at(frame)),
                    }
                } else {
                    SdoRequest::BlockDownloadEnd {
                        unused: (b0 >> 2) & 7,
                        crc: u16::from_le_bytes([frame[1], frame[2]]),
                    }
                }
            }
            _ => return Err(UnknownCommand { command: b0 }),
        })
    }

    /// The frame.
    pub fn emit(&self) -> [u8; 8] {
        let mut f = [0u8; 8];
        match *self {
            SdoRequest::DownloadSegment(s) => return s.emit(0),
            SdoRequest::InitiateDownload { mux, data } => {
                f[0] = 0x20;
                mux.put(&mut f);
                data.put(&mut f);
            }
            SdoRequest::InitiateUpload { mux } => {
                f[0] = 0x40;
                mux.put(&mut f);
            }
            SdoRequest::UploadSegment { toggle } => f[0] = 0x60 | if toggle { 0x10 } else { 0 },
            SdoRequest::Abort { mux, code } => return abort(mux, code),
            SdoRequest::BlockUploadInitiate {
                mux,
                crc,
                blksize,
                pst,
            } => {
                f[0] = 0xA0 | if crc { 0x04 } else { 0 };
                mux.put(&mut f);
                f[4] = blksize;
                f[5] = pst;
            }
            SdoRequest::BlockUploadStart => f[0] = 0xA3,
            SdoRequest::BlockUploadAck { ackseq, blksize } => {
                f[0] = 0xA2;
                f[1] = ackseq;
                f[2] = blksize;
            }
            SdoRequest::BlockUploadEnd => f[0] = 0xA1,
            SdoRequest::BlockDownloadInitiate { mux, crc, size } => {
                f[0] = 0xC0 | if crc { 0x04 } else { 0 };
                mux.put(&mut f);
                if let Some(n) = size {
                    f[0] |= 0x02;
                    f[4..8].copy_from_slice(&n.to_le_bytes());
                }
            }
            SdoRequest::BlockDownloadEnd { unused, crc } => {
                f[0] = 0xC1 | ((unused & 7) << 2);
                f[1..3].copy_from_slice(&crc.to_le_bytes());
            }
        }
        f
    }

    /// The object this request names, for the commands that carry one.
    pub fn mux(&self) -> Option<Mux> {
        match *self {
            SdoRequest::InitiateDownload { mux, .. }
            | SdoRequest::InitiateUpload { mux }
            | SdoRequest::Abort { mux, .. }
            | SdoRequest::BlockUploadInitiate { mux, .. }
            | SdoRequest::BlockDownloadInitiate { mux, .. } => Some(mux),
            _ => None,
        }
    }
}

/// A response from the SDO server (COB-ID 0x580 + node), every command but the block
/// sub-block segments ([`BlockSegment`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoResponse {
    /// Initiate download confirmed (scs 3).
    InitiateDownload {
        /// Object.
        mux: Mux,
    },
    /// Download segment confirmed (scs 1).
    DownloadSegment {
        /// Toggle bit of the segment confirmed.
        toggle: bool,
    },
    /// Initiate upload answer (scs 2): the value (expedited) or its size (segmented).
    InitiateUpload {
        /// Object.
        mux: Mux,
        /// Expedited data or segmented size.
        data: Initiate,
    },
    /// Upload segment (scs 0).
    UploadSegment(Segment),
    /// Abort (scs 4).
    Abort {
        /// Object.
        mux: Mux,
        /// Abort code.
        code: u32,
    },
    /// Block download initiate answer (scs 5, ss 0).
    BlockDownloadInitiate {
        /// Object.
        mux: Mux,
        /// The server supports CRC.
        crc: bool,
        /// Segments per sub-block the server accepts.
        blksize: u8,
    },
    /// Block download sub-block acknowledged (scs 5, ss 2).
    BlockDownloadAck {
        /// Last segment received in sequence.
        ackseq: u8,
        /// Segments per next sub-block.
        blksize: u8,
    },
    /// Block download end confirmed (scs 5, ss 1).
    BlockDownloadEnd,
    /// Block upload initiate answer (scs 6, ss 0).
    BlockUploadInitiate {
        /// Object.
        mux: Mux,
        /// The server uses CRC.
        crc: bool,
        /// Size of the value, if indicated.
        size: Option<u32>,
    },
    /// Block upload end (scs 6, ss 1).
    BlockUploadEnd {
        /// Bytes of the last segment without data (0..=7).
        unused: u8,
        /// CRC of the whole value (0 when CRC is not used).
        crc: u16,
    },
}

impl SdoResponse {
    /// Parse a response frame. Every server command specifier but 7 has a meaning; reserved
    /// bits are ignored (scs 5 with ss 3 reads as an acknowledgement).
    pub fn parse(frame: &[u8; 8]) -> Result<SdoResponse, UnknownCommand> {
        let b0 = frame[0];
        let mux = Mux::of(frame);
        Ok(match b0 >> 5 {
            0 => SdoResponse::UploadSegment(Segment::parse(frame)),
            1 => SdoResponse::DownloadSegment {
                toggle: b0 & 0x10 != 0,
            },
            2 => SdoResponse::InitiateUpload {
                mux,
                data: Initiate::parse(b0, frame),
            },
            3 => SdoResponse::InitiateDownload { mux },
            4 => SdoResponse::Abort {
                mux,
                code: u32_at(frame),
            },
            5 => match b0 & 0x03 {
                0 => SdoResponse::BlockDownloadInitiate {
                    mux,
                    crc: b0 & 0x04 != 0,
                    blksize: frame[4],
                },
                1 => SdoResponse::BlockDownloadEnd,
                _ => SdoResponse::BlockDownloadAck {
                    ackseq: frame[1],
                    blksize: frame[2],
                },
            },
            6 => {
                if b0 & 0x01 == 0 {
                    SdoResponse::BlockUploadInitiate {
                        mux,
                        crc: b0 & 0x04 != 0,
                        size: (b0 & 0x02 != 0).then(|| u32_at(frame)),
                    }
                } else {
                    SdoResponse::BlockUploadEnd {
                        unused: (b0 >> 2) & 7,
                        crc: u16::from_le_bytes([frame[1], frame[2]]),
                    }
                }
            }
            _ => return Err(UnknownCommand { command: b0 }),
        })
    }

    /// The frame.
    pub fn emit(&self) -> [u8; 8] {
        let mut f = [0u8; 8];
        match *self {
            SdoResponse::UploadSegment(s) => return s.emit(0),
            SdoResponse::DownloadSegment { toggle } => {
                f[0] = 0x20 | if toggle { 0x10 } else { 0 };
            }
            SdoResponse::InitiateUpload { mux, data } => {
                f[0] = 0x40;
                mux.put(&mut f);
                data.put(&mut f);
            }
            SdoResponse::InitiateDownload { mux } => {
                f[0] = 0x60;
                mux.put(&mut f);
            }
            SdoResponse::Abort { mux, code } => return abort(mux, code),
            SdoResponse::BlockDownloadInitiate { mux, crc, blksize } => {
                f[0] = 0xA0 | if crc { 0x04 } else { 0 };
                mux.put(&mut f);
                f[4] = blksize;
            }
            SdoResponse::BlockDownloadAck { ackseq, blksize } => {
                f[0] = 0xA2;
                f[1] = ackseq;
                f[2] = blksize;
            }
            SdoResponse::BlockDownloadEnd => f[0] = 0xA1,
            SdoResponse::BlockUploadInitiate { mux, crc, size } => {
                f[0] = 0xC0 | if crc { 0x04 } else { 0 };
                mux.put(&mut f);
                if let Some(n) = size {
                    f[0] |= 0x02;
                    f[4..8].copy_from_slice(&n.to_le_bytes());
                }
            }
            SdoResponse::BlockUploadEnd { unused, crc } => {
                f[0] = 0xC1 | ((unused & 7) << 2);
                f[1..3].copy_from_slice(&crc.to_le_bytes());
            }
        }
        f
    }

    /// The object this response names, for the commands that carry one.
    pub fn mux(&self) -> Option<Mux> {
        match *self {
            SdoResponse::InitiateDownload { mux }
            | SdoResponse::InitiateUpload { mux, .. }
            | SdoResponse::Abort { mux, .. }
            | SdoResponse::BlockDownloadInitiate { mux, .. }
            | SdoResponse::BlockUploadInitiate { mux, .. } => Some(mux),
            _ => None,
        }
    }
}

/// An abort frame (the same layout in both directions).
pub fn abort(mux: Mux, code: u32) -> [u8; 8] {
    let mut f = [0x80, 0, 0, 0, 0, 0, 0, 0];
    mux.put(&mut f);
    f[4..8].copy_from_slice(&code.to_le_bytes());
    f
}

fn u32_at(frame: &[u8; 8]) -> u32 {
    u32::from_le_bytes([frame[4], frame[5], frame[6], frame[7]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_frames_parse_as_cia301_says() {
        // expedited download of one byte (0x2F) to 0x6060:0
        let r = SdoRequest::parse(&[0x2F, 0x60, 0x60, 0, 8, 0, 0, 0]).unwrap();
        assert_eq!(
            r,
            SdoRequest::InitiateDownload {
                mux: Mux::new(0x6060, 0),
                data: Initiate::Expedited {
                    data: [8, 0, 0, 0],
                    size: Some(1)
                }
            }
        );
        // expedited upload answer of two bytes (0x4B)
        let r = SdoResponse::parse(&[0x4B, 0x41, 0x60, 0, 0x37, 0x02, 0xFF, 0xFF]).unwrap();
        let SdoResponse::InitiateUpload { mux, data } = r else {
            panic!("{r:?}")
        };
        assert_eq!(mux, Mux::new(0x6041, 0));
        assert_eq!(data.bytes(), &[0x37, 0x02]);
        // segmented upload answer with size 10 (0x41)
        let r = SdoResponse::parse(&[0x41, 0x08, 0x10, 0, 10, 0, 0, 0]).unwrap();
        assert!(matches!(
            r,
            SdoResponse::InitiateUpload {
                data: Initiate::Segmented { size: Some(10) },
                ..
            }
        ));
        // last upload segment with 3 bytes, toggle 1: 0x10 | (4 << 1) | 1 = 0x19
        let r = SdoResponse::parse(&[0x19, 1, 2, 3, 0, 0, 0, 0]).unwrap();
        let SdoResponse::UploadSegment(s) = r else {
            panic!("{r:?}")
        };
        assert!(s.toggle && s.last);
        assert_eq!(s.bytes(), &[1, 2, 3]);
        assert_eq!(
            SdoRequest::parse(&[0x80, 0x00, 0x10, 0, 0, 0, 0x02, 0x06]).unwrap(),
            SdoRequest::Abort {
                mux: Mux::new(0x1000, 0),
                code: 0x0602_0000
            }
        );
        assert!(SdoRequest::parse(&[0xE0, 0, 0, 0, 0, 0, 0, 0]).is_err());
        assert!(SdoResponse::parse(&[0xFF, 0, 0, 0, 0, 0, 0, 0]).is_err());
    }

    #[test]
    fn emitted_frames_match_the_command_bytes_of_cia301() {
        let m = Mux::new(0x1008, 0);
        assert_eq!(SdoRequest::InitiateUpload { mux: m }.emit()[0], 0x40);
        assert_eq!(SdoResponse::InitiateDownload { mux: m }.emit()[0], 0x60);
        assert_eq!(
            SdoRequest::InitiateDownload {
                mux: m,
                data: Initiate::expedited(&[1, 2])
            }
            .emit()[0],
            0x2B
        );
        assert_eq!(
            SdoResponse::BlockUploadInitiate {
                mux: m,
                crc: true,
                size: Some(9)
            }
            .emit(),
            [0xC6, 0x08, 0x10, 0, 9, 0, 0, 0]
        );
        assert_eq!(
            SdoResponse::BlockDownloadInitiate {
                mux: m,
                crc: true,
                blksize: 9
            }
            .emit(),
            [0xA4, 0x08, 0x10, 0, 9, 0, 0, 0]
        );
        assert_eq!(SdoRequest::UploadSegment { toggle: true }.emit()[0], 0x70);
        assert_eq!(
            SdoResponse::DownloadSegment { toggle: true }.emit()[0],
            0x30
        );
        assert_eq!(
            SdoResponse::BlockUploadEnd {
                unused: 3,
                crc: 0x1234
            }
            .emit(),
            [0xCD, 0x34, 0x12, 0, 0, 0, 0, 0]
        );
        assert_eq!(BlockSegment::new(5, &[1], true).emit()[0], 0x85);
    }

    /// Every frame with a known command parses, and emitting what was parsed gives a frame
    /// that parses to the same value (reserved bits dropped); this over all command bytes
    /// with varied payloads.
    #[test]
    fn parse_emit_parse_is_stable_for_every_command_byte() {
        for b0 in 0..=255u8 {
            for pat in [[0u8; 7], [0xFF; 7], [1, 2, 3, 4, 5, 6, 7]] {
                let mut f = [b0, 0, 0, 0, 0, 0, 0, 0];
                f[1..].copy_from_slice(&pat);
                match SdoRequest::parse(&f) {
                    Ok(r) => assert_eq!(SdoRequest::parse(&r.emit()), Ok(r), "{f:02X?}"),
                    Err(e) => assert_eq!(b0 >> 5, 7, "{e}"),
                }
                match SdoResponse::parse(&f) {
                    Ok(r) => assert_eq!(SdoResponse::parse(&r.emit()), Ok(r), "{f:02X?}"),
                    Err(e) => assert_eq!(b0 >> 5, 7, "{e}"),
                }
                let s = BlockSegment::parse(&f);
                assert_eq!(BlockSegment::parse(&s.emit()), s);
            }
        }
    }
}
