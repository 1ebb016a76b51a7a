//! The SII EEPROM image (ETG.1000.6 table 16, ETG.2010): generated from the drive's identity
//! (0x1018) and the slave's mailbox and process-data layout, so what a master reads from the
//! EEPROM and over CoE agree. Word addresses: 0x0008 vendor, 0x000A product, 0x000C
//! revision, 0x000E serial, 0x0018-0x001B standard mailbox offsets and sizes, 0x001C
//! mailbox protocols, then from 0x0040 the categories: strings (10), general (30), FMMU
//! (40), SyncM (41), TxPDO (50), RxPDO (51), end (0xFFFF).

/// Category codes.
pub mod category {
    /// Strings.
    pub const STRINGS: u16 = 10;
    /// General.
    pub const GENERAL: u16 = 30;
    /// FMMU usage.
    pub const FMMU: u16 = 40;
    /// Sync managers.
    pub const SYNCM: u16 = 41;
    /// TxPDOs (inputs of the master).
    pub const TXPDO: u16 = 50;
    /// RxPDOs (outputs of the master).
    pub const RXPDO: u16 = 51;
    /// End.
    pub const END: u16 = 0xFFFF;
}

/// Word address of the vendor ID.
pub const VENDOR: usize = 0x0008;
/// Word address of the product code.
pub const PRODUCT: usize = 0x000A;
/// Word address of the revision.
pub const REVISION: usize = 0x000C;
/// Word address of the serial number.
pub const SERIAL: usize = 0x000E;
/// Word address of the receive (master to slave) mailbox offset.
pub const RX_MAILBOX: usize = 0x0018;
/// Word address of the send (slave to master) mailbox offset.
pub const TX_MAILBOX: usize = 0x001A;
/// Word address of the mailbox protocols.
pub const MAILBOX_PROTOCOLS: usize = 0x001C;
/// Word where the categories start.
pub const CATEGORIES: usize = 0x0040;
/// Mailbox protocol bit: CoE.
pub const PROTO_COE: u16 = 0x0004;
/// CoE details of the general category: SDO, SDO information, PDO assign, PDO
/// configuration, complete access.
pub const COE_DETAILS: u8 = 0x01 | 0x02 | 0x04 | 0x08 | 0x20;

/// The identity (0x1018).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Identity {
    /// Vendor ID (0x1018:1).
    pub vendor: u32,
    /// Product code (0x1018:2).
    pub product: u32,
    /// Revision (0x1018:3).
    pub revision: u32,
    /// Serial number (0x1018:4).
    pub serial: u32,
}

/// A sync manager entry of the SyncM category.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SmEntry {
    /// Physical start.
    pub start: u16,
    /// Length.
    pub len: u16,
    /// Control byte.
    pub control: u8,
    /// Enable byte.
    pub enable: u8,
    /// Type: 1 mailbox out, 2 mailbox in, 3 outputs, 4 inputs.
    pub kind: u8,
}

/// One mapped entry of a PDO category.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PdoEntry {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// CoE data type code.
    pub data_type: u8,
    /// Bits.
    pub bits: u8,
}

/// One PDO of a PDO category.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pdo {
    /// Mapping index (0x1600.. / 0x1A00..).
    pub index: u16,
    /// Sync manager it is assigned to.
    pub sm: u8,
    /// Mapped entries.
    pub entries: Vec<PdoEntry>,
}

/// What the image is generated from.
#[derive(Clone, Debug, Default)]
pub struct SiiConfig {
    /// Identity.
    pub identity: Identity,
    /// Device name (string 1), group (string 2), order code (string 3).
    pub name: String,
    /// Group name.
    pub group: String,
    /// Order code.
    pub order: String,
    /// Sync managers 0..3.
    pub sms: Vec<SmEntry>,
    /// RxPDOs (outputs).
    pub rx_pdos: Vec<Pdo>,
    /// TxPDOs (inputs).
    pub tx_pdos: Vec<Pdo>,
}

/// CRC-8 of the configuration area (words 0..7, polynomial 0x07, initial 0xFF).
pub fn crc8(bytes: &[u8]) -> u8 {
    let mut crc: u8 = 0xFF;
    for &b in bytes {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}

fn push_category(words: &mut Vec<u16>, code: u16, bytes: &[u8]) {
    let mut b = bytes.to_vec();
    if b.len() % 2 == 1 {
        b.push(0);
    }
    words.push(code);
    words.push((b.len() / 2) as u16);
    words.extend(b.chunks(2).map(|c| u16::from_le_bytes([c[0], c[1]])));
}

fn pdo_category(pdos: &[Pdo]) -> Vec<u8> {
    let mut b = Vec::new();
    for p in pdos {
        b.extend_from_slice(&p.index.to_le_bytes());
        b.push(p.entries.len() as u8);
        b.push(p.sm);
        b.push(0); // synchronisation
        b.push(0); // name index
        b.extend_from_slice(&0u16.to_le_bytes()); // flags
        for e in &p.entries {
            b.extend_from_slice(&e.index.to_le_bytes());
            b.push(e.sub);
            b.push(0); // name index
            b.push(e.data_type);
            b.push(e.bits);
            b.extend_from_slice(&0u16.to_le_bytes());
        }
    }
    b
}

/// The EEPROM image, in 16-bit words.
pub fn image(cfg: &SiiConfig) -> Vec<u16> {
    let mut w = vec![0u16; CATEGORIES];
    w[0] = 0x0005; // PDI control: the drive's processor
    let id = &cfg.identity;
    for (at, v) in [
        (VENDOR, id.vendor),
        (PRODUCT, id.product),
        (REVISION, id.revision),
        (SERIAL, id.serial),
    ] {
        w[at] = v as u16;
        w[at + 1] = (v >> 16) as u16;
    }
    let (rx, tx) = (cfg.sms.first(), cfg.sms.get(1));
    if let (Some(rx), Some(tx)) = (rx, tx) {
        w[RX_MAILBOX] = rx.start;
        w[RX_MAILBOX + 1] = rx.len;
        w[TX_MAILBOX] = tx.start;
        w[TX_MAILBOX + 1] = tx.len;
        w[MAILBOX_PROTOCOLS] = PROTO_COE;
    }
    w[0x3F] = 1; // version
                 // strings
    let mut s = vec![3u8];
    for t in [&cfg.name, &cfg.group, &cfg.order] {
        let t = &t.as_bytes()[..t.len().min(255)];
        s.push(t.len() as u8);
        s.extend_from_slice(t);
    }
    push_category(&mut w, category::STRINGS, &s);
    let mut g = [0u8; 32];
    g[0] = 2; // group: string 2
    g[2] = 3; // order: string 3
    g[3] = 1; // name: string 1
    g[5] = COE_DETAILS;
    g[9] = 1; // DS402 channels
    g[14] = 2;
    g[16..18].copy_from_slice(&0x0011u16.to_le_bytes()); // ports 0, 1: MII
    push_category(&mut w, category::GENERAL, &g);
    push_category(&mut w, category::FMMU, &[1, 2, 3, 0xFF]);
    let mut sm = Vec::new();
    for e in &cfg.sms {
        sm.extend_from_slice(&e.start.to_le_bytes());
        sm.extend_from_slice(&e.len.to_le_bytes());
        sm.extend_from_slice(&[e.control, 0, e.enable, e.kind]);
    }
    push_category(&mut w, category::SYNCM, &sm);
    push_category(&mut w, category::TXPDO, &pdo_category(&cfg.tx_pdos));
    push_category(&mut w, category::RXPDO, &pdo_category(&cfg.rx_pdos));
    w.push(category::END);
    // EEPROM size (KiBit - 1 in word 0x3E)
    let kbit = (w.len() * 16).div_ceil(1024).max(1);
    w[0x3E] = (kbit - 1) as u16;
    let bytes: Vec<u8> = w[..7].iter().flat_map(|x| x.to_le_bytes()).collect();
    w[7] = u16::from(crc8(&bytes));
    w
}

/// A word of the image (0xFFFF past its end, as an erased EEPROM reads).
pub fn word(image: &[u16], at: usize) -> u16 {
    image.get(at).copied().unwrap_or(0xFFFF)
}

/// Find a category: the word address of its data and its length in words (for a master).
pub fn find(image: &[u16], code: u16) -> Option<(usize, usize)> {
    let mut at = CATEGORIES;
    loop {
        let c = word(image, at);
        if c == category::END {
            return None;
        }
        let len = word(image, at + 1) as usize;
        if c == code {
            return Some((at + 2, len));
        }
        at += 2 + len;
    }
}
