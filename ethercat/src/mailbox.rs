//! The mailbox (ETG.1000.6 5.6): SM0 carries the master's requests to the slave, SM1 the
//! slave's messages to the master. Each message starts with a 6-byte header: length of the
//! data after it, address, channel / priority, type (bits 0-3; 3 = CoE) and counter (bits
//! 4-6). The slave's outgoing messages wait in a bounded queue; one sits in SM1 until the
//! master has read it. A message the slave cannot parse is answered with a mailbox error
//! (type 0), never dropped silently.

/// Mailbox size of this slave (SM0 and SM1), bytes.
pub const SIZE: usize = 128;
/// Mailbox header length.
pub const HEADER: usize = 6;
/// Mailbox type: error.
pub const TYPE_ERROR: u8 = 0;
/// Mailbox type: CoE.
pub const TYPE_COE: u8 = 3;
/// Messages that may wait to be read.
pub const QUEUE: usize = 8;

/// Mailbox error details (ETG.1000.6 table 30).
pub mod error {
    /// Syntax of the 6-octet header is wrong.
    pub const SYNTAX: u16 = 0x0001;
    /// The mailbox protocol is not supported.
    pub const UNSUPPORTED_PROTOCOL: u16 = 0x0002;
    /// The service is not supported.
    pub const SERVICE_NOT_SUPPORTED: u16 = 0x0004;
    /// The mailbox header is invalid (length).
    pub const INVALID_HEADER: u16 = 0x0005;
    /// The length of the received data is too short.
    pub const SIZE_TOO_SHORT: u16 = 0x0006;
    /// No more memory (queue full).
    pub const NO_MORE_MEMORY: u16 = 0x0007;
}

/// A parsed mailbox header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Header {
    /// Length of the data after the header.
    pub len: usize,
    /// Address (station address of the source or destination).
    pub address: u16,
    /// Type (bits 0-3 of byte 5).
    pub kind: u8,
    /// Counter (bits 4-6 of byte 5).
    pub counter: u8,
}

impl Header {
    /// Parse a message (`buf` is the whole mailbox buffer).
    pub fn parse(buf: &[u8]) -> Result<Header, u16> {
        if buf.len() < HEADER {
            return Err(error::SYNTAX);
        }
        let len = u16::from_le_bytes([buf[0], buf[1]]) as usize;
        if HEADER + len > buf.len() {
            return Err(error::INVALID_HEADER);
        }
        Ok(Header {
            len,
            address: u16::from_le_bytes([buf[2], buf[3]]),
            kind: buf[5] & 0x0F,
            counter: (buf[5] >> 4) & 0x07,
        })
    }

    /// Write the header into `buf[..6]`.
    pub fn emit(&self, buf: &mut [u8]) {
        buf[0..2].copy_from_slice(&(self.len as u16).to_le_bytes());
        buf[2..4].copy_from_slice(&self.address.to_le_bytes());
        buf[4] = 0;
        buf[5] = (self.kind & 0x0F) | (self.counter & 0x07) << 4;
    }
}

/// One outgoing message.
#[derive(Clone, Copy, Debug)]
pub struct Message {
    /// Bytes (header included).
    pub buf: [u8; SIZE],
    /// Valid length.
    pub len: usize,
}

impl Message {
    /// An empty message of `kind` whose body the caller fills from byte 6; `finish` sets
    /// the header.
    pub fn new() -> Message {
        Message {
            buf: [0; SIZE],
            len: HEADER,
        }
    }
    /// Append bytes to the body (cut at the mailbox size).
    pub fn push(&mut self, b: &[u8]) {
        let n = b.len().min(SIZE - self.len);
        self.buf[self.len..self.len + n].copy_from_slice(&b[..n]);
        self.len += n;
    }
    /// Room left, bytes.
    pub fn room(&self) -> usize {
        SIZE - self.len
    }
}

impl Default for Message {
    fn default() -> Self {
        Message::new()
    }
}

/// The slave's side of the two mailboxes.
#[derive(Clone, Debug, Default)]
pub struct Mailbox {
    /// Messages waiting for SM1.
    pub out: heapless::Deque<Message, QUEUE>,
    /// Counter of the slave's last message (1..=7).
    pub counter: u8,
    /// Counter of the master's last request (to drop a repeated one).
    pub last_in: Option<u8>,
    /// Messages dropped because the queue was full.
    pub dropped: u32,
}

impl Mailbox {
    /// Queue a message of `kind` (the header is filled in here).
    pub fn send(&mut self, mut m: Message, kind: u8, address: u16) {
        self.counter = if self.counter >= 7 {
            1
        } else {
            self.counter + 1
        };
        Header {
            len: m.len - HEADER,
            address,
            kind,
            counter: self.counter,
        }
        .emit(&mut m.buf);
        if self.out.push_back(m).is_err() {
            self.dropped = self.dropped.wrapping_add(1);
        }
    }

    /// Queue a mailbox error with `detail`.
    pub fn error(&mut self, detail: u16) {
        let mut m = Message::new();
        m.push(&1u16.to_le_bytes());
        m.push(&detail.to_le_bytes());
        self.send(m, TYPE_ERROR, 0);
    }

    /// Forget everything (a state change below PRE-OP).
    pub fn reset(&mut self) {
        self.out.clear();
        self.last_in = None;
    }
}
