//! The EtherCAT frame on the wire: an Ethernet II header of EtherType 0x88A4, the 2-byte
//! EtherCAT header (11-bit length, type 1 = datagrams), then datagrams: command, index,
//! 32-bit address, 11-bit length with the "more follows" flag, IRQ, data, 16-bit working
//! counter (ETG.1000.4). Parsing is bounds-checked: a malformed frame is an error, never a
//! panic. Slaves work on the frame in place ([`Datagrams`] hands out each datagram's fields
//! as offsets into the frame).

/// EtherType of EtherCAT.
pub const ETHERTYPE: u16 = 0x88A4;
/// Ethernet II header length.
pub const ETH_HEADER: usize = 14;
/// EtherCAT header length.
pub const ECAT_HEADER: usize = 2;
/// Datagram header length (before the data).
pub const DATAGRAM_HEADER: usize = 10;
/// Working counter length (after the data).
pub const WKC_LEN: usize = 2;
/// Type field of an EtherCAT header carrying datagrams.
pub const TYPE_DATAGRAMS: u8 = 1;
/// Largest datagram data length (11 bits).
pub const MAX_DATA: usize = 0x7FF;
/// Bit of the Ethernet source address a slave sets on the frames it returns (the U/L bit of
/// the first byte, as an ESC's port 0 does), so a master can tell its own frame from a reply.
pub const SOURCE_MAC_RETURNED: u8 = 0x02;

/// Why a frame is not an EtherCAT frame a slave can process.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// Shorter than the Ethernet and EtherCAT headers.
    TooShort,
    /// Not EtherType 0x88A4 (the value found).
    NotEtherCat(u16),
    /// EtherCAT header type other than 1 (datagrams).
    UnsupportedType(u8),
    /// The EtherCAT length runs past the end of the frame.
    LengthBeyondFrame,
    /// A datagram runs past the EtherCAT length (at this byte offset of the frame).
    DatagramBeyondLength(usize),
    /// The EtherCAT length has bytes after the last datagram (no "more follows").
    TrailingBytes,
    /// No datagram at all.
    Empty,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::TooShort => write!(f, "frame shorter than the Ethernet + EtherCAT headers"),
            FrameError::NotEtherCat(t) => write!(f, "EtherType 0x{t:04X} is not EtherCAT"),
            FrameError::UnsupportedType(t) => write!(f, "EtherCAT header type {t} (only 1)"),
            FrameError::LengthBeyondFrame => write!(f, "EtherCAT length past the frame's end"),
            FrameError::DatagramBeyondLength(at) => {
                write!(f, "datagram at byte {at} runs past the EtherCAT length")
            }
            FrameError::TrailingBytes => write!(f, "bytes after the last datagram"),
            FrameError::Empty => write!(f, "no datagram"),
        }
    }
}

impl std::error::Error for FrameError {}

/// One datagram's place in a frame: header fields and where its data and working counter are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DatagramAt {
    /// Command byte.
    pub cmd: u8,
    /// Offset of the datagram header in the frame.
    pub header: usize,
    /// Offset of its data.
    pub data: usize,
    /// Data length.
    pub len: usize,
}

impl DatagramAt {
    /// Offset of the working counter.
    pub fn wkc(&self) -> usize {
        self.data + self.len
    }
    /// Offset of the 32-bit address (ADP at +0, ADO at +2).
    pub fn address(&self) -> usize {
        self.header + 2
    }
}

/// The datagrams of a frame, checked once ([`Datagrams::parse`]); at most `N` of them.
#[derive(Clone, Debug)]
pub struct Datagrams<const N: usize> {
    /// The datagrams in frame order.
    pub list: heapless::Vec<DatagramAt, N>,
}

/// Most datagrams a frame may carry here (a 1500-byte frame holds at most 124 empty ones).
pub const MAX_DATAGRAMS: usize = 128;

impl<const N: usize> Datagrams<N> {
    /// Check a whole frame (Ethernet header included) and find its datagrams. Nothing is
    /// changed; every offset it returns lies inside `frame`.
    pub fn parse(frame: &[u8]) -> Result<Self, FrameError> {
        if frame.len() < ETH_HEADER + ECAT_HEADER {
            return Err(FrameError::TooShort);
        }
        let ethertype = u16::from_be_bytes([frame[12], frame[13]]);
        if ethertype != ETHERTYPE {
            return Err(FrameError::NotEtherCat(ethertype));
        }
        let h = u16::from_le_bytes([frame[14], frame[15]]);
        let ecat_len = (h & 0x07FF) as usize;
        let ftype = (h >> 12) as u8;
        if ftype != TYPE_DATAGRAMS {
            return Err(FrameError::UnsupportedType(ftype));
        }
        let start = ETH_HEADER + ECAT_HEADER;
        let end = start + ecat_len;
        if end > frame.len() {
            return Err(FrameError::LengthBeyondFrame);
        }
        let mut list = heapless::Vec::new();
        let mut at = start;
        loop {
            if at + DATAGRAM_HEADER + WKC_LEN > end {
                return Err(if at == start {
                    FrameError::Empty
                } else {
                    FrameError::DatagramBeyondLength(at)
                });
            }
            let lf = u16::from_le_bytes([frame[at + 6], frame[at + 7]]);
            let len = (lf & 0x07FF) as usize;
            let more = lf & 0x8000 != 0;
            let next = at + DATAGRAM_HEADER + len + WKC_LEN;
            if next > end {
                return Err(FrameError::DatagramBeyondLength(at));
            }
            let d = DatagramAt {
                cmd: frame[at],
                header: at,
                data: at + DATAGRAM_HEADER,
                len,
            };
            if list.push(d).is_err() {
                return Err(FrameError::DatagramBeyondLength(at));
            }
            at = next;
            if !more {
                break;
            }
        }
        if at != end {
            return Err(FrameError::TrailingBytes);
        }
        Ok(Datagrams { list })
    }
}

/// Build a frame (for a master or a test): Ethernet header from `src`, broadcast
/// destination, then the datagrams `(cmd, idx, address, data)`; working counters 0. Padded
/// to the Ethernet minimum of 60 bytes.
pub fn build(src: [u8; 6], datagrams: &[(u8, u8, u32, &[u8])]) -> Vec<u8> {
    let mut f = Vec::with_capacity(64);
    f.extend_from_slice(&[0xFF; 6]);
    f.extend_from_slice(&src);
    f.extend_from_slice(&ETHERTYPE.to_be_bytes());
    f.extend_from_slice(&[0, 0]);
    for (k, (cmd, idx, addr, data)) in datagrams.iter().enumerate() {
        let more = if k + 1 < datagrams.len() { 0x8000 } else { 0 };
        f.push(*cmd);
        f.push(*idx);
        f.extend_from_slice(&addr.to_le_bytes());
        f.extend_from_slice(&((data.len() as u16 & 0x07FF) | more).to_le_bytes());
        f.extend_from_slice(&[0, 0]);
        f.extend_from_slice(data);
        f.extend_from_slice(&[0, 0]);
    }
    let ecat_len = (f.len() - ETH_HEADER - ECAT_HEADER) as u16;
    let h = (ecat_len & 0x07FF) | (u16::from(TYPE_DATAGRAMS) << 12);
    f[14..16].copy_from_slice(&h.to_le_bytes());
    if f.len() < 60 {
        f.resize(60, 0);
    }
    f
}

/// A datagram of a returned frame, read back (for a master or a test).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Returned {
    /// Command.
    pub cmd: u8,
    /// Address as it came back (ADP counted up by auto-increment slaves).
    pub address: u32,
    /// Data.
    pub data: Vec<u8>,
    /// Working counter.
    pub wkc: u16,
}

/// Read back the datagrams of a frame.
pub fn read_back(frame: &[u8]) -> Result<Vec<Returned>, FrameError> {
    let d = Datagrams::<MAX_DATAGRAMS>::parse(frame)?;
    Ok(d.list
        .iter()
        .map(|g| {
            let a = g.address();
            Returned {
                cmd: g.cmd,
                address: u32::from_le_bytes([frame[a], frame[a + 1], frame[a + 2], frame[a + 3]]),
                data: frame[g.data..g.data + g.len].to_vec(),
                wkc: u16::from_le_bytes([frame[g.wkc()], frame[g.wkc() + 1]]),
            }
        })
        .collect())
}
