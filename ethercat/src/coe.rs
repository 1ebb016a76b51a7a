//! CANopen over EtherCAT (ETG.1000.6 5.6.2, ETG.6010): the CoE header (PDO number, service:
//! 1 emergency, 2 SDO request, 3 SDO response, 8 SDO information), the SDO server (upload
//! and download: expedited, normal and segmented; complete access, bit 4 of the command,
//! sub-index 0 carried as 16 bits), SDO information (object list, object description, entry
//! description, fragmented to the mailbox size) and the emergency message. Every object
//! access goes through the drive core's own rules ([`DriveCore::read_object`] /
//! [`DriveCore::write_object`]): the same dictionary and the same abort codes as on CAN.

use drive_protocol::od::{Access, Backing, ObjType};
use drive_protocol::wire::sdo::abort;
use drive_protocol::{Drive, DriveCore};

use crate::al::AlState;
use crate::mailbox::{Mailbox, Message, HEADER, SIZE, TYPE_COE};

/// CoE services.
pub mod service {
    /// Emergency.
    pub const EMERGENCY: u8 = 1;
    /// SDO request.
    pub const SDO_REQUEST: u8 = 2;
    /// SDO response.
    pub const SDO_RESPONSE: u8 = 3;
    /// SDO information.
    pub const SDO_INFO: u8 = 8;
}

/// SDO information op-codes.
pub mod info {
    /// Get OD list request.
    pub const LIST_REQ: u8 = 1;
    /// Get OD list response.
    pub const LIST_RESP: u8 = 2;
    /// Get object description request.
    pub const OBJ_REQ: u8 = 3;
    /// Get object description response.
    pub const OBJ_RESP: u8 = 4;
    /// Get entry description request.
    pub const ENTRY_REQ: u8 = 5;
    /// Get entry description response.
    pub const ENTRY_RESP: u8 = 6;
    /// Error.
    pub const ERROR: u8 = 7;
}

/// Bytes of SDO data in a normal upload or download initiate (mailbox, CoE, command,
/// index, sub, size).
const INITIATE_DATA: usize = SIZE - HEADER - 2 - 8;
/// Bytes of data in a segment (mailbox, CoE, command).
const SEGMENT_DATA: usize = SIZE - HEADER - 3;
/// Bytes of payload in an SDO information fragment (mailbox, CoE, info header).
const INFO_DATA: usize = SIZE - HEADER - 2 - 4;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Transfer {
    Idle,
    Upload {
        pos: usize,
        len: usize,
        toggle: bool,
    },
    Download {
        index: u16,
        sub: u8,
        complete: bool,
        size: usize,
        pos: usize,
        toggle: bool,
    },
}

/// An object list being sent in fragments.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct ListPending {
    list_type: u16,
    /// Next entry of the list to send.
    next: usize,
    total: usize,
    fragments_left: u16,
}

/// The CoE server of one slave.
#[derive(Clone, Debug)]
pub struct Coe {
    buf: Vec<u8>,
    /// The values a complete-access write replaces, to put back when it is refused.
    undo: Vec<u8>,
    transfer: Transfer,
    list: Option<ListPending>,
}

/// Whether an object's configuration may be written only in PRE-OP (PDO assignment and
/// mapping, as ETG.1000.6 requires).
pub fn preop_only(index: u16) -> bool {
    matches!(index, 0x1600..=0x17FF | 0x1A00..=0x1BFF | 0x1C12 | 0x1C13)
}

fn coe_header(m: &mut Message, svc: u8) {
    m.push(&(u16::from(svc) << 12).to_le_bytes());
}

/// An SDO abort: CoE carries it with the service "SDO request" (ETG.1000.6 5.6.2.7.1), as
/// SOEM expects it.
fn sdo_abort(mbx: &mut Mailbox, index: u16, sub: u8, code: u32) {
    let mut m = Message::new();
    coe_header(&mut m, service::SDO_REQUEST);
    m.push(&[0x80]);
    m.push(&index.to_le_bytes());
    m.push(&[sub]);
    m.push(&code.to_le_bytes());
    mbx.send(m, TYPE_COE, 0);
}

fn sdo_response(mbx: &mut Mailbox, cmd: u8, index: u16, sub: u8, data: &[u8]) {
    let mut m = Message::new();
    coe_header(&mut m, service::SDO_RESPONSE);
    m.push(&[cmd]);
    m.push(&index.to_le_bytes());
    m.push(&[sub]);
    m.push(data);
    mbx.send(m, TYPE_COE, 0);
}

/// CoE object access bits of an entry (ETG.1000.6 table 48).
fn access_bits(a: Access, pdo: bool) -> u16 {
    let mut v = 0;
    if a.readable() {
        v |= 0x07;
    }
    if a.writable() {
        v |= 0x38;
    }
    if pdo && a.writable() {
        v |= 0x40;
    }
    if pdo && a.readable() {
        v |= 0x80;
    }
    v
}

impl Coe {
    /// A server whose transfers hold values of up to `bytes`.
    pub fn new(bytes: usize) -> Coe {
        Coe {
            buf: vec![0; bytes.max(SIZE)],
            undo: vec![0; bytes.max(SIZE)],
            transfer: Transfer::Idle,
            list: None,
        }
    }

    /// Forget a transfer in progress (a state change to INIT).
    pub fn reset(&mut self) {
        self.transfer = Transfer::Idle;
        self.list = None;
    }

    /// A CoE message (`body`: after the mailbox header).
    pub fn handle(
        &mut self,
        body: &[u8],
        node: &mut DriveCore,
        drive: &mut impl Drive,
        state: AlState,
        mbx: &mut Mailbox,
    ) {
        if body.len() < 2 {
            mbx.error(crate::mailbox::error::SIZE_TOO_SHORT);
            return;
        }
        let svc = (u16::from_le_bytes([body[0], body[1]]) >> 12) as u8;
        let rest = &body[2..];
        match svc {
            service::SDO_REQUEST => self.sdo(rest, node, drive, state, mbx),
            service::SDO_INFO => self.info(rest, node, mbx),
            _ => mbx.error(crate::mailbox::error::SERVICE_NOT_SUPPORTED),
        }
    }

    fn sdo(
        &mut self,
        req: &[u8],
        node: &mut DriveCore,
        drive: &mut impl Drive,
        state: AlState,
        mbx: &mut Mailbox,
    ) {
        if req.is_empty() {
            mbx.error(crate::mailbox::error::SIZE_TOO_SHORT);
            return;
        }
        let cmd = req[0];
        let ccs = cmd >> 5;
        if ccs == 4 {
            // the master aborts the transfer in progress: no answer
            self.transfer = Transfer::Idle;
            return;
        }
        // segments carry no index: they belong to the transfer in progress
        if ccs == 0 || ccs == 3 {
            return self.segment(req, node, drive, mbx);
        }
        if req.len() < 8 {
            mbx.error(crate::mailbox::error::SIZE_TOO_SHORT);
            return;
        }
        let index = u16::from_le_bytes([req[1], req[2]]);
        let sub = req[3];
        let complete = cmd & 0x10 != 0;
        self.transfer = Transfer::Idle;
        match ccs {
            2 => self.upload(index, sub, complete, node, drive, mbx),
            1 => {
                if preop_only(index) && state != AlState::PreOp {
                    return sdo_abort(mbx, index, sub, abort::DEVICE_STATE);
                }
                let expedited = cmd & 0x02 != 0;
                let sized = cmd & 0x01 != 0;
                if expedited {
                    let n = if sized {
                        4 - ((cmd >> 2) & 3) as usize
                    } else {
                        node.od()
                            .get(index, sub)
                            .map_or(4, |(_, e)| e.dtype.size().clamp(1, 4))
                    };
                    let data = &req[4..4 + n];
                    let r = if complete {
                        self.write_complete_or_undo(index, sub, data, node, drive)
                    } else {
                        node.write_object(index, sub, data, drive)
                    };
                    match r {
                        Ok(()) => sdo_response(mbx, 0x60, index, sub, &[0; 4]),
                        Err(code) => sdo_abort(mbx, index, sub, code),
                    }
                    return;
                }
                let size = u32::from_le_bytes([req[4], req[5], req[6], req[7]]) as usize;
                let data = &req[8..];
                if !complete {
                    if let Err(code) = node.check_write_object(index, sub, Some(size), drive) {
                        return sdo_abort(mbx, index, sub, code);
                    }
                }
                if size > self.buf.len() {
                    return sdo_abort(mbx, index, sub, abort::OUT_OF_MEMORY);
                }
                let n = data.len().min(size);
                self.buf[..n].copy_from_slice(&data[..n]);
                if n == size {
                    let r = self.finish_download(index, sub, complete, size, node, drive);
                    match r {
                        Ok(()) => sdo_response(mbx, 0x60, index, sub, &[0; 4]),
                        Err(code) => sdo_abort(mbx, index, sub, code),
                    }
                } else {
                    self.transfer = Transfer::Download {
                        index,
                        sub,
                        complete,
                        size,
                        pos: n,
                        toggle: false,
                    };
                    sdo_response(mbx, 0x60, index, sub, &[0; 4]);
                }
            }
            _ => sdo_abort(mbx, index, sub, abort::COMMAND),
        }
    }

    fn finish_download(
        &mut self,
        index: u16,
        sub: u8,
        complete: bool,
        size: usize,
        node: &mut DriveCore,
        drive: &mut impl Drive,
    ) -> Result<(), u32> {
        let data = core::mem::take(&mut self.buf);
        let r = if complete {
            self.write_complete_or_undo(index, sub, &data[..size], node, drive)
        } else {
            node.write_object(index, sub, &data[..size], drive)
        };
        self.buf = data;
        r
    }

    /// A complete-access write that changes nothing when it is refused: the object's
    /// values before it are put back (sub 0 last).
    fn write_complete_or_undo(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
        node: &mut DriveCore,
        drive: &mut impl Drive,
    ) -> Result<(), u32> {
        // snapshot: sub 0 and every readable sub-index, each at its place in `undo`
        let mut pos = 0;
        let mut saved: heapless::Vec<(u8, u16, u16), 64> = heapless::Vec::new();
        for s in 0..=u8::MAX {
            if node.od().get(index, s).is_none() {
                continue;
            }
            if let Ok(n) = node.read_object(index, s, &mut self.undo[pos..], drive) {
                if saved.push((s, pos as u16, n as u16)).is_err() {
                    break;
                }
                pos += n;
            }
        }
        let r = self.write_complete(index, sub, data, node, drive);
        if r.is_err() {
            for &(s, at, n) in saved.iter().rev() {
                let (at, n) = (at as usize, n as usize);
                let _ = node.write_object(index, s, &self.undo[at..at + n], drive);
            }
            // the count goes back last, once its entries are back
            if let Some(&(0, at, n)) = saved.first() {
                let (at, n) = (at as usize, n as usize);
                let _ = node.write_object(index, 0, &self.undo[at..at + n], drive);
            }
        }
        r
    }

    /// Complete access write: sub 0 (as 16 bits, when `sub` is 0) then every sub-index in
    /// order, each with its own rules; a writable sub 0 is set to 0 first and to its value
    /// last (the PDO assignment procedure).
    fn write_complete(
        &self,
        index: u16,
        sub: u8,
        data: &[u8],
        node: &mut DriveCore,
        drive: &mut impl Drive,
    ) -> Result<(), u32> {
        if sub > 1 {
            return Err(abort::UNSUPPORTED_ACCESS);
        }
        let od = node.od();
        if !od.has_index(index) {
            return Err(abort::NO_OBJECT);
        }
        let sub0 = od.get(index, 0).map(|(_, e)| e.access.writable());
        let mut pos = 0;
        let mut count = None;
        if sub == 0 {
            if data.len() < 2 {
                return Err(abort::TOO_SHORT);
            }
            count = Some(data[0]);
            pos = 2;
            if sub0 == Some(true) {
                node.write_object(index, 0, &[0], drive)?;
            }
        }
        let last = count.unwrap_or(u8::MAX);
        let mut s = 1u8;
        while s <= last && pos < data.len() {
            let Some((_, e)) = node.od().get(index, s) else {
                if count.is_some() {
                    return Err(abort::NO_SUB);
                }
                break;
            };
            let n = e.dtype.size();
            if n == 0 || pos + n > data.len() {
                return Err(abort::LENGTH_MISMATCH);
            }
            node.write_object(index, s, &data[pos..pos + n], drive)?;
            pos += n;
            s = s.wrapping_add(1);
            if s == 0 {
                break;
            }
        }
        if let (Some(c), Some(true)) = (count, sub0) {
            node.write_object(index, 0, &[c], drive)?;
        }
        Ok(())
    }

    /// Read a value (or the whole object) into the transfer buffer.
    fn read_value(
        &mut self,
        index: u16,
        sub: u8,
        complete: bool,
        node: &mut DriveCore,
        drive: &mut impl Drive,
    ) -> Result<usize, u32> {
        if !complete {
            return node.read_object(index, sub, &mut self.buf, drive);
        }
        if sub > 1 {
            return Err(abort::UNSUPPORTED_ACCESS);
        }
        if !node.od().has_index(index) {
            return Err(abort::NO_OBJECT);
        }
        let mut pos = 0;
        let mut last = u8::MAX;
        if sub == 0 {
            let mut b = [0u8; 1];
            node.read_object(index, 0, &mut b, drive)?;
            self.buf[0] = b[0];
            self.buf[1] = 0;
            pos = 2;
            last = b[0];
        }
        let mut s = 1u8;
        while s <= last {
            if node.od().get(index, s).is_some() {
                let n = node.read_object(index, s, &mut self.buf[pos..], drive)?;
                pos += n;
            } else if node.od().object(index).all(|(_, e)| e.sub < s) {
                break;
            }
            if s == u8::MAX {
                break;
            }
            s += 1;
        }
        Ok(pos)
    }

    fn upload(
        &mut self,
        index: u16,
        sub: u8,
        complete: bool,
        node: &mut DriveCore,
        drive: &mut impl Drive,
        mbx: &mut Mailbox,
    ) {
        let len = match self.read_value(index, sub, complete, node, drive) {
            Ok(n) => n,
            Err(code) => return sdo_abort(mbx, index, sub, code),
        };
        let ca = if complete { 0x10 } else { 0 };
        if len <= 4 && !complete {
            let mut d = [0u8; 4];
            d[..len].copy_from_slice(&self.buf[..len]);
            let cmd = 0x43 | (((4 - len) as u8) << 2);
            return sdo_response(mbx, cmd, index, sub, &d);
        }
        let n = len.min(INITIATE_DATA);
        let mut m = Message::new();
        coe_header(&mut m, service::SDO_RESPONSE);
        m.push(&[0x41 | ca]);
        m.push(&index.to_le_bytes());
        m.push(&[sub]);
        m.push(&(len as u32).to_le_bytes());
        m.push(&self.buf[..n]);
        mbx.send(m, TYPE_COE, 0);
        if n < len {
            self.transfer = Transfer::Upload {
                pos: n,
                len,
                toggle: false,
            };
        }
    }

    fn segment(
        &mut self,
        req: &[u8],
        node: &mut DriveCore,
        drive: &mut impl Drive,
        mbx: &mut Mailbox,
    ) {
        let cmd = req[0];
        let toggle = cmd & 0x10 != 0;
        match (cmd >> 5, self.transfer) {
            (
                3,
                Transfer::Upload {
                    pos,
                    len,
                    toggle: t,
                },
            ) => {
                if toggle != t {
                    self.transfer = Transfer::Idle;
                    return sdo_abort(mbx, 0, 0, abort::TOGGLE);
                }
                let n = (len - pos).min(SEGMENT_DATA);
                let last = pos + n == len;
                let mut c = if toggle { 0x10 } else { 0 } | u8::from(last);
                if n < 7 {
                    c |= ((7 - n) as u8) << 1;
                }
                let mut m = Message::new();
                coe_header(&mut m, service::SDO_RESPONSE);
                m.push(&[c]);
                m.push(&self.buf[pos..pos + n]);
                for _ in n..7 {
                    m.push(&[0]);
                }
                mbx.send(m, TYPE_COE, 0);
                self.transfer = if last {
                    Transfer::Idle
                } else {
                    Transfer::Upload {
                        pos: pos + n,
                        len,
                        toggle: !t,
                    }
                };
            }
            (
                0,
                Transfer::Download {
                    index,
                    sub,
                    complete,
                    size,
                    pos,
                    toggle: t,
                },
            ) => {
                if toggle != t {
                    self.transfer = Transfer::Idle;
                    return sdo_abort(mbx, index, sub, abort::TOGGLE);
                }
                let last = cmd & 0x01 != 0;
                let mut n = req.len() - 1;
                if n <= 7 {
                    n = 7usize.saturating_sub(((cmd >> 1) & 7) as usize).min(n);
                }
                if pos + n > size {
                    self.transfer = Transfer::Idle;
                    return sdo_abort(mbx, index, sub, abort::TOO_LONG);
                }
                self.buf[pos..pos + n].copy_from_slice(&req[1..1 + n]);
                let pos = pos + n;
                let c = 0x20 | if toggle { 0x10 } else { 0 };
                if last {
                    self.transfer = Transfer::Idle;
                    if pos != size {
                        return sdo_abort(mbx, index, sub, abort::TOO_SHORT);
                    }
                    match self.finish_download(index, sub, complete, size, node, drive) {
                        Ok(()) => {}
                        Err(code) => return sdo_abort(mbx, index, sub, code),
                    }
                } else {
                    self.transfer = Transfer::Download {
                        index,
                        sub,
                        complete,
                        size,
                        pos,
                        toggle: !t,
                    };
                }
                let mut m = Message::new();
                coe_header(&mut m, service::SDO_RESPONSE);
                m.push(&[c]);
                m.push(&[0; 7]);
                mbx.send(m, TYPE_COE, 0);
            }
            _ => {
                self.transfer = Transfer::Idle;
                sdo_abort(mbx, 0, 0, abort::COMMAND);
            }
        }
    }

    fn info_header(m: &mut Message, opcode: u8, incomplete: bool, fragments_left: u16) {
        coe_header(m, service::SDO_INFO);
        m.push(&[opcode | if incomplete { 0x80 } else { 0 }, 0]);
        m.push(&fragments_left.to_le_bytes());
    }

    fn info_error(mbx: &mut Mailbox, code: u32) {
        let mut m = Message::new();
        Self::info_header(&mut m, info::ERROR, false, 0);
        m.push(&code.to_le_bytes());
        mbx.send(m, TYPE_COE, 0);
    }

    /// The indices of list `t` (1 all, 2 RxPDO-mappable, 3 TxPDO-mappable, 4 backup, 5
    /// settings), in order, through `f(position, index)`; returns the count.
    fn list_indices(node: &DriveCore, t: u16, mut f: impl FnMut(usize, u16)) -> usize {
        let od = node.od();
        let mut n = 0;
        let mut last = None;
        for (_, e) in od.iter() {
            if last == Some(e.index) {
                continue;
            }
            let any = |p: &dyn Fn(&drive_protocol::od::Entry) -> bool| {
                od.object(e.index).any(|(_, x)| p(x))
            };
            let take = match t {
                1 => true,
                2 => any(&|x| x.pdo && x.access.writable()),
                3 => any(&|x| x.pdo && x.access.readable()),
                4 | 5 => false,
                _ => false,
            };
            if take {
                last = Some(e.index);
                f(n, e.index);
                n += 1;
            }
        }
        n
    }

    fn info(&mut self, req: &[u8], node: &mut DriveCore, mbx: &mut Mailbox) {
        if req.len() < 4 {
            return Self::info_error(mbx, abort::COMMAND);
        }
        let opcode = req[0] & 0x7F;
        let body = &req[4..];
        match opcode {
            info::LIST_REQ if body.len() >= 2 => {
                let t = u16::from_le_bytes([body[0], body[1]]);
                if t == 0 {
                    let mut m = Message::new();
                    Self::info_header(&mut m, info::LIST_RESP, false, 0);
                    m.push(&0u16.to_le_bytes());
                    for k in 1..=5 {
                        let n = Self::list_indices(node, k, |_, _| {}) as u16;
                        m.push(&n.to_le_bytes());
                    }
                    return mbx.send(m, TYPE_COE, 0);
                }
                if t > 5 {
                    return Self::info_error(mbx, abort::VALUE_RANGE);
                }
                let total = Self::list_indices(node, t, |_, _| {});
                // the first fragment carries the list type too
                let words = total + 1;
                let per = INFO_DATA / 2;
                let fragments = words.div_ceil(per).max(1) as u16;
                self.list = Some(ListPending {
                    list_type: t,
                    next: 0,
                    total,
                    fragments_left: fragments - 1,
                });
                self.pump(node, mbx);
            }
            info::OBJ_REQ if body.len() >= 2 => {
                let index = u16::from_le_bytes([body[0], body[1]]);
                let od = node.od();
                let Some((_, first)) = od.object(index).next() else {
                    return Self::info_error(mbx, abort::NO_OBJECT);
                };
                let max_sub = od.object(index).map(|(_, e)| e.sub).max().unwrap_or(0);
                let dtype = match first.otype {
                    ObjType::Var => first.dtype.code(),
                    ObjType::Array => od
                        .object(index)
                        .find(|(_, e)| e.sub > 0)
                        .map_or(first.dtype.code(), |(_, e)| e.dtype.code()),
                    ObjType::Record => 0x002A,
                };
                let mut m = Message::new();
                Self::info_header(&mut m, info::OBJ_RESP, false, 0);
                m.push(&index.to_le_bytes());
                m.push(&dtype.to_le_bytes());
                m.push(&[max_sub, first.otype.code()]);
                let name = first.parent.as_bytes();
                let room = m.room();
                m.push(&name[..name.len().min(room)]);
                mbx.send(m, TYPE_COE, 0);
            }
            info::ENTRY_REQ if body.len() >= 4 => {
                let index = u16::from_le_bytes([body[0], body[1]]);
                let sub = body[2];
                let od = node.od();
                let e = match od.find(index, sub) {
                    drive_protocol::od::Lookup::Found(slot) => od.entry(slot),
                    drive_protocol::od::Lookup::NoObject => {
                        return Self::info_error(mbx, abort::NO_OBJECT)
                    }
                    drive_protocol::od::Lookup::NoSub => {
                        return Self::info_error(mbx, abort::NO_SUB)
                    }
                };
                let bits = if e.dtype.size() == 0 {
                    (e.capacity * 8).min(0xFFFF) as u16
                } else {
                    (e.dtype.size() * 8) as u16
                };
                let pdo = e.pdo && e.backing == Backing::Stored;
                let mut m = Message::new();
                Self::info_header(&mut m, info::ENTRY_RESP, false, 0);
                m.push(&index.to_le_bytes());
                m.push(&[sub, 0]);
                m.push(&e.dtype.code().to_le_bytes());
                m.push(&bits.to_le_bytes());
                m.push(&access_bits(e.access, pdo).to_le_bytes());
                let name = e.name.as_bytes();
                let room = m.room();
                m.push(&name[..name.len().min(room)]);
                mbx.send(m, TYPE_COE, 0);
            }
            _ => Self::info_error(mbx, abort::COMMAND),
        }
    }

    /// Send the next fragment of an object list in progress when the queue has room.
    pub fn pump(&mut self, node: &DriveCore, mbx: &mut Mailbox) {
        while let Some(mut l) = self.list {
            if mbx.out.is_full() {
                return;
            }
            let mut m = Message::new();
            Self::info_header(
                &mut m,
                info::LIST_RESP,
                l.fragments_left > 0,
                l.fragments_left,
            );
            let mut room = INFO_DATA / 2;
            if l.next == 0 {
                m.push(&l.list_type.to_le_bytes());
                room -= 1;
            }
            let (from, to) = (l.next, (l.next + room).min(l.total));
            Self::list_indices(node, l.list_type, |k, index| {
                if (from..to).contains(&k) {
                    m.push(&index.to_le_bytes());
                }
            });
            l.next = to;
            mbx.send(m, TYPE_COE, 0);
            if l.fragments_left == 0 {
                self.list = None;
            } else {
                l.fragments_left -= 1;
                self.list = Some(l);
            }
        }
    }
}

/// A CoE emergency from a CAN EMCY payload (error code, error register, 5 bytes).
pub fn emergency(mbx: &mut Mailbox, emcy: &[u8]) {
    let mut m = Message::new();
    coe_header(&mut m, service::EMERGENCY);
    let mut d = [0u8; 8];
    let n = emcy.len().min(8);
    d[..n].copy_from_slice(&emcy[..n]);
    m.push(&d);
    mbx.send(m, TYPE_COE, 0);
}
