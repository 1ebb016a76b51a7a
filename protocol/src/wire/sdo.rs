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
        Ok(match Body::parse(frame, &REQUEST_LAYOUTS)? {
            Body::Segment(s) => SdoRequest::DownloadSegment(s),
            Body::Initiate { mux, data } => SdoRequest::InitiateDownload { mux, data },
            Body::Mux(mux) => SdoRequest::InitiateUpload { mux },
            Body::Toggle(toggle) => SdoRequest::UploadSegment { toggle },
            Body::Abort { mux, code } => SdoRequest::Abort { mux, code },
            Body::BlockInitiate {
                mux,
                crc,
                blksize,
                pst,
            } => SdoRequest::BlockUploadInitiate {
                mux,
                crc,
                blksize,
                pst,
            },
            Body::BlockCommand { sub: BLOCK_END, .. } => SdoRequest::BlockUploadEnd,
            Body::BlockCommand {
                sub: BLOCK_ACK,
                ackseq,
                blksize,
            } => SdoRequest::BlockUploadAck { ackseq, blksize },
            Body::BlockCommand { .. } => SdoRequest::BlockUploadStart,
            Body::BlockSizedInitiate { mux, crc, size } => {
                SdoRequest::BlockDownloadInitiate { mux, crc, size }
            }
            Body::BlockEnd { unused, crc } => SdoRequest::BlockDownloadEnd { unused, crc },
        })
    }

    /// The frame.
    pub fn emit(&self) -> [u8; 8] {
        let body = match *self {
            SdoRequest::DownloadSegment(s) => Body::Segment(s),
            SdoRequest::InitiateDownload { mux, data } => Body::Initiate { mux, data },
            SdoRequest::InitiateUpload { mux } => Body::Mux(mux),
            SdoRequest::UploadSegment { toggle } => Body::Toggle(toggle),
            SdoRequest::Abort { mux, code } => Body::Abort { mux, code },
            SdoRequest::BlockUploadInitiate {
                mux,
                crc,
                blksize,
                pst,
            } => Body::BlockInitiate {
                mux,
                crc,
                blksize,
                pst,
            },
            SdoRequest::BlockUploadStart => Body::block_command(BLOCK_START),
            SdoRequest::BlockUploadAck { ackseq, blksize } => Body::BlockCommand {
                sub: BLOCK_ACK,
                ackseq,
                blksize,
            },
            SdoRequest::BlockUploadEnd => Body::block_command(BLOCK_END),
            SdoRequest::BlockDownloadInitiate { mux, crc, size } => {
                Body::BlockSizedInitiate { mux, crc, size }
            }
            SdoRequest::BlockDownloadEnd { unused, crc } => Body::BlockEnd { unused, crc },
        };
        body.emit(&REQUEST_LAYOUTS)
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
        Ok(match Body::parse(frame, &RESPONSE_LAYOUTS)? {
            Body::Segment(s) => SdoResponse::UploadSegment(s),
            Body::Toggle(toggle) => SdoResponse::DownloadSegment { toggle },
            Body::Initiate { mux, data } => SdoResponse::InitiateUpload { mux, data },
            Body::Mux(mux) => SdoResponse::InitiateDownload { mux },
            Body::Abort { mux, code } => SdoResponse::Abort { mux, code },
            Body::BlockInitiate {
                mux, crc, blksize, ..
            } => SdoResponse::BlockDownloadInitiate { mux, crc, blksize },
            Body::BlockCommand { sub: BLOCK_END, .. } => SdoResponse::BlockDownloadEnd,
            Body::BlockCommand {
                ackseq, blksize, ..
            } => SdoResponse::BlockDownloadAck { ackseq, blksize },
            Body::BlockSizedInitiate { mux, crc, size } => {
                SdoResponse::BlockUploadInitiate { mux, crc, size }
            }
            Body::BlockEnd { unused, crc } => SdoResponse::BlockUploadEnd { unused, crc },
        })
    }

    /// The frame.
    pub fn emit(&self) -> [u8; 8] {
        let body = match *self {
            SdoResponse::UploadSegment(s) => Body::Segment(s),
            SdoResponse::DownloadSegment { toggle } => Body::Toggle(toggle),
            SdoResponse::InitiateUpload { mux, data } => Body::Initiate { mux, data },
            SdoResponse::InitiateDownload { mux } => Body::Mux(mux),
            SdoResponse::Abort { mux, code } => Body::Abort { mux, code },
            SdoResponse::BlockDownloadInitiate { mux, crc, blksize } => Body::BlockInitiate {
                mux,
                crc,
                blksize,
                pst: 0,
            },
            SdoResponse::BlockDownloadAck { ackseq, blksize } => Body::BlockCommand {
                sub: BLOCK_ACK,
                ackseq,
                blksize,
            },
            SdoResponse::BlockDownloadEnd => Body::block_command(BLOCK_END),
            SdoResponse::BlockUploadInitiate { mux, crc, size } => {
                Body::BlockSizedInitiate { mux, crc, size }
            }
            SdoResponse::BlockUploadEnd { unused, crc } => Body::BlockEnd { unused, crc },
        };
        body.emit(&RESPONSE_LAYOUTS)
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
    Body::Abort { mux, code }.emit(&REQUEST_LAYOUTS)
}

/// The frame layouts of the SDO commands. Client and server frames share them; the two
/// directions differ only in which command specifier (bits 5..8 of byte 0) selects which
/// layout, as [`REQUEST_LAYOUTS`] and [`RESPONSE_LAYOUTS`] say. Each layout's bytes are read
/// once, in [`Body::parse`], and written once, in [`Body::emit`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Layout {
    /// Data segment: toggle, unused-byte count and last flag in byte 0, data in bytes 1..8.
    Segment,
    /// Initiate with a value or a size: e, s and n bits, multiplexer, bytes 4..8.
    Initiate,
    /// Initiate without data (upload request, download confirmation): multiplexer only.
    Mux,
    /// Segment request or confirmation: the toggle bit only.
    Toggle,
    /// Abort: multiplexer and the 32-bit abort code.
    Abort,
    /// Block command specifier 5 (upload requests, download answers): sub-command in bits 0..2.
    Block5,
    /// Block command specifier 6 (download requests, upload answers): initiate or end in bit 0.
    Block6,
}

/// Client command specifier (ccs 0..=6) to layout: download segment, initiate download,
/// initiate upload, upload segment, abort, block upload, block download.
const REQUEST_LAYOUTS: [Layout; 7] = [
    Layout::Segment,
    Layout::Initiate,
    Layout::Mux,
    Layout::Toggle,
    Layout::Abort,
    Layout::Block5,
    Layout::Block6,
];

/// Server command specifier (scs 0..=6) to layout: upload segment, download segment
/// confirmed, initiate upload, initiate download confirmed, abort, block download, block
/// upload.
const RESPONSE_LAYOUTS: [Layout; 7] = [
    Layout::Segment,
    Layout::Toggle,
    Layout::Initiate,
    Layout::Mux,
    Layout::Abort,
    Layout::Block5,
    Layout::Block6,
];

/// Block sub-commands of command specifier 5 (bits 0..2 of byte 0); 0 is the initiate.
const BLOCK_END: u8 = 1;
/// Sub-block acknowledgement: bytes 1 and 2 carry ackseq and the next block size.
const BLOCK_ACK: u8 = 2;
/// Block upload start (client); a server frame with this sub-command reads as an ack.
const BLOCK_START: u8 = 3;

/// A frame read by its layout, before a direction gives it a meaning.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Body {
    Segment(Segment),
    Initiate {
        mux: Mux,
        data: Initiate,
    },
    Mux(Mux),
    Toggle(bool),
    Abort {
        mux: Mux,
        code: u32,
    },
    /// Command specifier 5, sub 0: CRC flag (bit 2), block size (byte 4), protocol switch
    /// threshold (byte 5; client only, 0 from the server).
    BlockInitiate {
        mux: Mux,
        crc: bool,
        blksize: u8,
        pst: u8,
    },
    /// Command specifier 5, sub 1..=3: bytes 1 and 2 are ackseq and blksize (zero but in an
    /// acknowledgement).
    BlockCommand {
        sub: u8,
        ackseq: u8,
        blksize: u8,
    },
    /// Command specifier 6, bit 0 clear: CRC flag (bit 2), size indicated (bit 1), size.
    BlockSizedInitiate {
        mux: Mux,
        crc: bool,
        size: Option<u32>,
    },
    /// Command specifier 6, bit 0 set: unused bytes of the last segment (bits 2..5), CRC.
    BlockEnd {
        unused: u8,
        crc: u16,
    },
}

impl Body {
    /// A block command without acknowledgement fields.
    const fn block_command(sub: u8) -> Body {
        Body::BlockCommand {
            sub,
            ackseq: 0,
            blksize: 0,
        }
    }

    fn layout(&self) -> Layout {
        match self {
            Body::Segment(_) => Layout::Segment,
            Body::Initiate { .. } => Layout::Initiate,
            Body::Mux(_) => Layout::Mux,
            Body::Toggle(_) => Layout::Toggle,
            Body::Abort { .. } => Layout::Abort,
            Body::BlockInitiate { .. } | Body::BlockCommand { .. } => Layout::Block5,
            Body::BlockSizedInitiate { .. } | Body::BlockEnd { .. } => Layout::Block6,
        }
    }

    /// Read a frame with the layout its command specifier selects in `layouts`.
    fn parse(frame: &[u8; 8], layouts: &[Layout; 7]) -> Result<Body, UnknownCommand> {
        let b0 = frame[0];
        let Some(&layout) = layouts.get(usize::from(b0 >> 5)) else {
            return Err(UnknownCommand { command: b0 });
        };
        let mux = Mux::of(frame);
        let crc = b0 & 0x04 != 0;
        Ok(match layout {
            Layout::Segment => Body::Segment(Segment::parse(frame)),
            Layout::Initiate => Body::Initiate {
                mux,
                data: Initiate::parse(b0, frame),
            },
            Layout::Mux => Body::Mux(mux),
            Layout::Toggle => Body::Toggle(b0 & 0x10 != 0),
            Layout::Abort => Body::Abort {
                mux,
                code: u32_at(frame),
            },
            Layout::Block5 => match b0 & 0x03 {
                0 => Body::BlockInitiate {
                    mux,
                    crc,
                    blksize: frame[4],
                    pst: frame[5],
                },
                sub => Body::BlockCommand {
                    sub,
                    ackseq: frame[1],
                    blksize: frame[2],
                },
            },
            Layout::Block6 if b0 & 0x01 == 0 => Body::BlockSizedInitiate {
                mux,
                crc,
                size: (b0 & 0x02 != 0).then(|| u32_at(frame)),
            },
            Layout::Block6 => Body::BlockEnd {
                unused: (b0 >> 2) & 7,
                crc: u16::from_le_bytes([frame[1], frame[2]]),
            },
        })
    }

    /// The frame, with the command specifier `layouts` gives this layout.
    fn emit(&self, layouts: &[Layout; 7]) -> [u8; 8] {
        let layout = self.layout();
        // Every layout is in both tables (a test checks it), so the fallback is never used.
        let cs = layouts.iter().position(|&l| l == layout).unwrap_or(0) as u8;
        let mut f = [0u8; 8];
        f[0] = cs << 5;
        match *self {
            Body::Segment(s) => return s.emit(cs),
            Body::Initiate { mux, data } => {
                mux.put(&mut f);
                data.put(&mut f);
            }
            Body::Mux(mux) => mux.put(&mut f),
            Body::Toggle(toggle) => f[0] |= u8::from(toggle) << 4,
            Body::Abort { mux, code } => {
                mux.put(&mut f);
                f[4..8].copy_from_slice(&code.to_le_bytes());
            }
            Body::BlockInitiate {
                mux,
                crc,
                blksize,
                pst,
            } => {
                f[0] |= u8::from(crc) << 2;
                mux.put(&mut f);
                f[4] = blksize;
                f[5] = pst;
            }
            Body::BlockCommand {
                sub,
                ackseq,
                blksize,
            } => {
                f[0] |= sub & 0x03;
                f[1] = ackseq;
                f[2] = blksize;
            }
            Body::BlockSizedInitiate { mux, crc, size } => {
                f[0] |= u8::from(crc) << 2;
                mux.put(&mut f);
                if let Some(n) = size {
                    f[0] |= 0x02;
                    f[4..8].copy_from_slice(&n.to_le_bytes());
                }
            }
            Body::BlockEnd { unused, crc } => {
                f[0] |= 0x01 | ((unused & 7) << 2);
                f[1..3].copy_from_slice(&crc.to_le_bytes());
            }
        }
        f
    }
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

    #[test]
    fn every_layout_has_a_command_specifier_in_both_directions() {
        for l in REQUEST_LAYOUTS.iter().chain(&RESPONSE_LAYOUTS) {
            assert_eq!(REQUEST_LAYOUTS.iter().filter(|&x| x == l).count(), 1);
            assert_eq!(RESPONSE_LAYOUTS.iter().filter(|&x| x == l).count(), 1);
        }
    }

    mod roundtrip {
        use super::super::*;
        use proptest::prelude::*;

        fn mux() -> impl Strategy<Value = Mux> {
            (any::<u16>(), any::<u8>()).prop_map(|(i, s)| Mux::new(i, s))
        }

        fn initiate() -> impl Strategy<Value = Initiate> {
            prop_oneof![
                (any::<[u8; 4]>(), proptest::option::of(1u8..=4))
                    .prop_map(|(data, size)| Initiate::Expedited { data, size }),
                proptest::option::of(any::<u32>()).prop_map(|size| Initiate::Segmented { size }),
            ]
        }

        fn segment() -> impl Strategy<Value = Segment> {
            (any::<bool>(), any::<[u8; 7]>(), 0u8..=7, any::<bool>()).prop_map(
                |(toggle, data, len, last)| Segment {
                    toggle,
                    data,
                    len,
                    last,
                },
            )
        }

        fn request() -> impl Strategy<Value = SdoRequest> {
            prop_oneof![
                (mux(), initiate())
                    .prop_map(|(mux, data)| SdoRequest::InitiateDownload { mux, data }),
                segment().prop_map(SdoRequest::DownloadSegment),
                mux().prop_map(|mux| SdoRequest::InitiateUpload { mux }),
                any::<bool>().prop_map(|toggle| SdoRequest::UploadSegment { toggle }),
                (mux(), any::<u32>()).prop_map(|(mux, code)| SdoRequest::Abort { mux, code }),
                (mux(), any::<bool>(), any::<u8>(), any::<u8>()).prop_map(
                    |(mux, crc, blksize, pst)| SdoRequest::BlockUploadInitiate {
                        mux,
                        crc,
                        blksize,
                        pst
                    }
                ),
                Just(SdoRequest::BlockUploadStart),
                (any::<u8>(), any::<u8>())
                    .prop_map(|(ackseq, blksize)| SdoRequest::BlockUploadAck { ackseq, blksize }),
                Just(SdoRequest::BlockUploadEnd),
                (mux(), any::<bool>(), proptest::option::of(any::<u32>())).prop_map(
                    |(mux, crc, size)| SdoRequest::BlockDownloadInitiate { mux, crc, size }
                ),
                (0u8..=7, any::<u16>())
                    .prop_map(|(unused, crc)| SdoRequest::BlockDownloadEnd { unused, crc }),
            ]
        }

        fn response() -> impl Strategy<Value = SdoResponse> {
            prop_oneof![
                mux().prop_map(|mux| SdoResponse::InitiateDownload { mux }),
                any::<bool>().prop_map(|toggle| SdoResponse::DownloadSegment { toggle }),
                (mux(), initiate())
                    .prop_map(|(mux, data)| SdoResponse::InitiateUpload { mux, data }),
                segment().prop_map(SdoResponse::UploadSegment),
                (mux(), any::<u32>()).prop_map(|(mux, code)| SdoResponse::Abort { mux, code }),
                (mux(), any::<bool>(), any::<u8>()).prop_map(|(mux, crc, blksize)| {
                    SdoResponse::BlockDownloadInitiate { mux, crc, blksize }
                }),
                (any::<u8>(), any::<u8>()).prop_map(|(ackseq, blksize)| {
                    SdoResponse::BlockDownloadAck { ackseq, blksize }
                }),
                Just(SdoResponse::BlockDownloadEnd),
                (mux(), any::<bool>(), proptest::option::of(any::<u32>())).prop_map(
                    |(mux, crc, size)| SdoResponse::BlockUploadInitiate { mux, crc, size }
                ),
                (0u8..=7, any::<u16>())
                    .prop_map(|(unused, crc)| SdoResponse::BlockUploadEnd { unused, crc }),
            ]
        }

        proptest! {
            #![proptest_config(ProptestConfig::with_cases(2000))]

            /// parse(emit(x)) == x for every request variant with any field values.
            #[test]
            fn request_parse_of_emit_is_identity(r in request()) {
                prop_assert_eq!(SdoRequest::parse(&r.emit()), Ok(r));
            }

            /// parse(emit(x)) == x for every response variant with any field values.
            #[test]
            fn response_parse_of_emit_is_identity(r in response()) {
                prop_assert_eq!(SdoResponse::parse(&r.emit()), Ok(r));
            }

            /// Block sub-block segments (sequence numbers 0..=127) survive emit and parse.
            #[test]
            fn block_segment_parse_of_emit_is_identity(
                seqno in 0u8..=127, data in any::<[u8; 7]>(), last in any::<bool>()
            ) {
                let s = BlockSegment { seqno, last, data };
                prop_assert_eq!(BlockSegment::parse(&s.emit()), s);
            }
        }
    }
}
