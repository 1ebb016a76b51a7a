//! A tiny EtherCAT master written for the tests (sans-IO: it hands frames to the segment and
//! reads them back), walking what SOEM's config_init and CoE client do, and a simple drive.
#![allow(dead_code)]

use drive_ethercat::frame::{self, Returned};
use drive_ethercat::slave::{INPUTS_START, MBX_IN_START, MBX_OUT_START, OUTPUTS_START};
use drive_ethercat::{Segment, Slave};
use drive_protocol::od::{Access, DataType, DefaultValue, Entry, ObjectDictionary};
use drive_protocol::{Clocks, Drive, DriveCommand, DriveInfo, Feedback, NodeConfig, Setpoint};

pub const MBX: usize = 128;
/// Station addresses as SOEM gives them (slave k, 1-based: 0x1000 + k).
pub const NODE_OFFSET: u16 = 0x1000;
/// A long string of the test dictionary (segmented transfers).
pub const LONG_INDEX: u16 = 0x2300;

pub fn info() -> DriveInfo {
    DriveInfo {
        encoder_increments_per_rev: 65536,
        gear_motor_revs: 1,
        gear_shaft_revs: 1,
        feed_user_units: 10_000,
        feed_shaft_revs: 1,
        rated_torque_mnm: 5000,
        rated_current_ma: 8000,
        max_motor_speed_rpm: 3000,
        rotary: false,
    }
}

/// An ideal axis: follows the position demand with a first-order lag.
#[derive(Clone, Debug, Default)]
pub struct TestDrive {
    pub pos: f64,
    pub fault: Option<u16>,
    pub commands: u64,
}

impl Drive for TestDrive {
    fn info(&self) -> DriveInfo {
        info()
    }
    fn feedback(&self) -> Feedback {
        Feedback {
            motor_position_inc: self.pos.round() as i64,
            direct_position_inc: self.pos.round() as i64,
            drive_fault: self.fault,
            ..Feedback::default()
        }
    }
    fn command(&mut self, c: &DriveCommand) {
        self.commands += 1;
        if let Setpoint::Position { position_inc, .. } = c.setpoint {
            self.pos += (position_inc - self.pos) * 0.5;
        }
    }
    fn reset_fault(&mut self) -> bool {
        self.fault = None;
        true
    }
}

pub fn od() -> ObjectDictionary {
    let mut od = ObjectDictionary::standard(&info());
    let text: Vec<u8> = (0..300u32).map(|k| b'a' + (k % 26) as u8).collect();
    od.insert(
        Entry::var(LONG_INDEX, "Long text", DataType::VisibleString, Access::Rw)
            .with_capacity(400)
            .with_default(DefaultValue::Bytes(text)),
    )
    .unwrap();
    od
}

pub fn slave(node_id: u8, drive: &mut TestDrive) -> Slave {
    let mut cfg = NodeConfig::new(node_id, info()).with_od(od());
    cfg.lss = None;
    Slave::new(cfg, drive).unwrap()
}

pub struct Master {
    pub seg: Segment,
    pub drives: Vec<TestDrive>,
    pub now_ns: u64,
    pub counter: u8,
    /// The counter of the last request to each slave (a slave ignores a repeat of it).
    pub last_counter: Vec<u8>,
    /// Frames that came back (the others were dropped by the segment).
    pub returned: u64,
}

#[derive(Debug, PartialEq, Eq)]
pub enum SdoError {
    Abort(u32),
    Mailbox(u16),
    NoAnswer,
    Unexpected(Vec<u8>),
}

impl Master {
    pub fn new(n: usize) -> Master {
        let mut drives = vec![TestDrive::default(); n];
        let slaves = drives
            .iter_mut()
            .enumerate()
            .map(|(k, d)| slave(k as u8 + 1, d))
            .collect();
        Master {
            seg: Segment::new(slaves),
            drives,
            now_ns: 0,
            counter: 0,
            last_counter: vec![0; n],
            returned: 0,
        }
    }

    /// Send one frame of datagrams, get them back.
    pub fn frame(&mut self, dgs: &[(u8, u32, &[u8])]) -> Vec<Returned> {
        let list: Vec<(u8, u8, u32, &[u8])> = dgs
            .iter()
            .enumerate()
            .map(|(k, (c, a, d))| (*c, k as u8, *a, *d))
            .collect();
        let mut f = frame::build([0x01; 6], &list);
        self.now_ns += 10_000;
        self.seg
            .process(&mut f, self.now_ns, &mut self.drives)
            .expect("a well-formed frame comes back");
        assert_eq!(
            f[6] & frame::SOURCE_MAC_RETURNED,
            frame::SOURCE_MAC_RETURNED
        );
        self.returned += 1;
        frame::read_back(&f).unwrap()
    }

    pub fn one(&mut self, cmd: u8, addr: u32, data: &[u8]) -> (Vec<u8>, u16) {
        let r = self.frame(&[(cmd, addr, data)]).remove(0);
        (r.data, r.wkc)
    }

    pub fn addr(adp: u16, ado: u16) -> u32 {
        u32::from(adp) | u32::from(ado) << 16
    }

    pub fn brd(&mut self, ado: u16, len: usize) -> (Vec<u8>, u16) {
        self.one(7, Self::addr(0, ado), &vec![0; len])
    }
    pub fn bwr(&mut self, ado: u16, data: &[u8]) -> u16 {
        self.one(8, Self::addr(0, ado), data).1
    }
    pub fn aprd(&mut self, pos: u16, ado: u16, len: usize) -> (Vec<u8>, u16) {
        self.one(1, Self::addr(0u16.wrapping_sub(pos), ado), &vec![0; len])
    }
    pub fn apwr(&mut self, pos: u16, ado: u16, data: &[u8]) -> u16 {
        self.one(2, Self::addr(0u16.wrapping_sub(pos), ado), data).1
    }
    pub fn fprd(&mut self, station: u16, ado: u16, len: usize) -> (Vec<u8>, u16) {
        self.one(4, Self::addr(station, ado), &vec![0; len])
    }
    pub fn fpwr(&mut self, station: u16, ado: u16, data: &[u8]) -> u16 {
        self.one(5, Self::addr(station, ado), data).1
    }
    pub fn fprd16(&mut self, station: u16, ado: u16) -> u16 {
        let (d, w) = self.fprd(station, ado, 2);
        assert_eq!(w, 1, "FPRD 0x{ado:04X} of 0x{station:04X}");
        u16::from_le_bytes([d[0], d[1]])
    }

    /// SII read of 8 bytes at word `addr`, as SOEM's readeeprom1/2 (FPWR control +
    /// address, FPRD status until not busy, FPRD data).
    pub fn eeprom(&mut self, station: u16, addr: u16) -> [u8; 8] {
        let a = addr.to_le_bytes();
        assert_eq!(
            self.fpwr(station, 0x0502, &[0x00, 0x01, a[0], a[1], 0, 0]),
            1
        );
        let st = self.fprd16(station, 0x0502);
        assert_eq!(st & 0x8000, 0, "busy");
        assert_eq!(st & 0x0040, 0x0040, "8-byte reads");
        let (d, w) = self.fprd(station, 0x0508, 8);
        assert_eq!(w, 1);
        d.try_into().unwrap()
    }
    pub fn eeprom32(&mut self, station: u16, addr: u16) -> u32 {
        let d = self.eeprom(station, addr);
        u32::from_le_bytes([d[0], d[1], d[2], d[3]])
    }

    /// config_init as SOEM walks it: returns the number of slaves found.
    pub fn config_init(&mut self) -> usize {
        self.bwr(0x0012, &[0, 0]);
        self.bwr(0x0120, &[0x11, 0]);
        let (_, n) = self.brd(0x0000, 2);
        let n = n as usize;
        self.bwr(0x0101, &[0]);
        self.bwr(0x0200, &[4, 0]);
        self.bwr(0x0300, &[0; 8]);
        self.bwr(0x0600, &[0; 48]);
        self.bwr(0x0800, &[0; 32]);
        self.bwr(0x0981, &[0]);
        self.bwr(0x0910, &[0; 4]);
        // DC speed counter start and filter depths: resets the time control loop
        self.bwr(0x0930, &0x1000u16.to_le_bytes());
        self.bwr(0x0934, &0x0C00u16.to_le_bytes());
        self.bwr(0x0500, &[2]);
        self.bwr(0x0500, &[0]);
        for k in 1..=n as u16 {
            let pos = k - 1;
            self.aprd(pos, 0x0140, 2);
            assert_eq!(self.apwr(pos, 0x0010, &(NODE_OFFSET + k).to_le_bytes()), 1);
            let (d, w) = self.aprd(pos, 0x0010, 2);
            assert_eq!((u16::from_le_bytes([d[0], d[1]]), w), (NODE_OFFSET + k, 1));
        }
        n
    }

    pub fn station(k: usize) -> u16 {
        NODE_OFFSET + k as u16 + 1
    }

    /// Set the mailbox SMs as the SII says (what SOEM does) and go to PRE-OP.
    pub fn go_preop(&mut self, k: usize) -> u16 {
        let st = Self::station(k);
        let rx = self.eeprom(st, 0x0018);
        let mut sm = Vec::new();
        sm.extend_from_slice(&rx[0..4]); // SM0 start, len
        sm.extend_from_slice(&[0x26, 0, 1, 0]);
        sm.extend_from_slice(&rx[4..8]); // SM1 start, len
        sm.extend_from_slice(&[0x22, 0, 1, 0]);
        assert_eq!(self.fpwr(st, 0x0800, &sm), 1);
        self.request(k, 0x12)
    }

    /// Write AL control, read AL status back.
    pub fn request(&mut self, k: usize, state: u16) -> u16 {
        let st = Self::station(k);
        assert_eq!(self.fpwr(st, 0x0120, &state.to_le_bytes()), 1);
        self.fprd16(st, 0x0130)
    }

    pub fn al_code(&mut self, k: usize) -> u16 {
        self.fprd16(Self::station(k), 0x0134)
    }

    /// Send a mailbox message (CoE body) to slave k.
    pub fn mbx_send(&mut self, k: usize, kind: u8, body: &[u8]) {
        let st = Self::station(k);
        let status = self.fprd(st, 0x0805, 1).0[0];
        assert_eq!(status & 0x08, 0, "SM0 mailbox empty before a write");
        let next = |c: u8| if c >= 7 { 1 } else { c + 1 };
        self.counter = next(self.counter);
        if self.counter == self.last_counter[k] {
            self.counter = next(self.counter);
        }
        self.last_counter[k] = self.counter;
        let mut m = vec![0u8; MBX];
        m[0..2].copy_from_slice(&(body.len() as u16).to_le_bytes());
        m[5] = kind | self.counter << 4;
        m[6..6 + body.len()].copy_from_slice(body);
        assert_eq!(self.fpwr(st, MBX_OUT_START, &m), 1, "mailbox write");
    }

    /// Read the next message of slave k (type, body); None when SM1 is empty.
    pub fn mbx_receive(&mut self, k: usize) -> Option<(u8, Vec<u8>)> {
        let st = Self::station(k);
        let status = self.fprd(st, 0x080D, 1).0[0];
        if status & 0x08 == 0 {
            // an empty mailbox refuses the read: no working counter
            assert_eq!(self.fprd(st, MBX_IN_START, MBX).1, 0);
            return None;
        }
        let (d, w) = self.fprd(st, MBX_IN_START, MBX);
        assert_eq!(w, 1);
        let len = u16::from_le_bytes([d[0], d[1]]) as usize;
        Some((d[5] & 0x0F, d[6..6 + len].to_vec()))
    }

    fn coe_sdo(cmd: u8, index: u16, sub: u8, data: &[u8]) -> Vec<u8> {
        let mut b = vec![0x00, 0x20, cmd];
        b.extend_from_slice(&index.to_le_bytes());
        b.push(sub);
        b.extend_from_slice(data);
        b
    }

    fn sdo_answer(&mut self, k: usize) -> Result<Vec<u8>, SdoError> {
        let Some((kind, body)) = self.mbx_receive(k) else {
            return Err(SdoError::NoAnswer);
        };
        if kind == 0 {
            return Err(SdoError::Mailbox(u16::from_le_bytes([body[2], body[3]])));
        }
        if body.len() >= 10 && body[1] >> 4 == 2 && body[2] == 0x80 {
            // an abort comes with the service "SDO request"
            return Err(SdoError::Abort(u32::from_le_bytes([
                body[6], body[7], body[8], body[9],
            ])));
        }
        if body.len() < 3 || body[1] >> 4 != 3 {
            return Err(SdoError::Unexpected(body));
        }
        if body[2] == 0x80 {
            // an abort as an SDO response: not what SOEM takes
            return Err(SdoError::Unexpected(body));
        }
        Ok(body[2..].to_vec())
    }

    /// SDO upload (complete access with `ca`), expedited, normal or segmented.
    pub fn sdo_read(
        &mut self,
        k: usize,
        index: u16,
        sub: u8,
        ca: bool,
    ) -> Result<Vec<u8>, SdoError> {
        let cmd = 0x40 | if ca { 0x10 } else { 0 };
        self.mbx_send(k, 3, &Self::coe_sdo(cmd, index, sub, &[0; 4]));
        let r = self.sdo_answer(k)?;
        if r[0] & 0x02 != 0 {
            let n = 4 - ((r[0] >> 2) & 3) as usize;
            return Ok(r[4..4 + n].to_vec());
        }
        let size = u32::from_le_bytes([r[4], r[5], r[6], r[7]]) as usize;
        let mut v = r[8..].to_vec();
        v.truncate(size);
        let mut toggle = 0u8;
        while v.len() < size {
            self.mbx_send(k, 3, &[0x00, 0x20, 0x60 | toggle, 0, 0, 0, 0, 0, 0, 0]);
            let s = self.sdo_answer(k)?;
            assert_eq!(s[0] & 0x10, toggle, "toggle");
            let mut n = s.len() - 1;
            if n == 7 {
                n -= ((s[0] >> 1) & 7) as usize;
            }
            v.extend_from_slice(&s[1..1 + n]);
            if s[0] & 1 != 0 {
                break;
            }
            toggle ^= 0x10;
        }
        assert_eq!(v.len(), size);
        Ok(v)
    }

    /// SDO download (complete access with `ca`): expedited up to 4 bytes, else normal and
    /// segmented.
    pub fn sdo_write(
        &mut self,
        k: usize,
        index: u16,
        sub: u8,
        ca: bool,
        data: &[u8],
    ) -> Result<(), SdoError> {
        let caf = if ca { 0x10 } else { 0 };
        if data.len() <= 4 {
            let mut d = [0u8; 4];
            d[..data.len()].copy_from_slice(data);
            let cmd = 0x23 | caf | (((4 - data.len()) as u8) << 2);
            self.mbx_send(k, 3, &Self::coe_sdo(cmd, index, sub, &d));
            let r = self.sdo_answer(k)?;
            assert_eq!(r[0], 0x60);
            return Ok(());
        }
        let first = data.len().min(MBX - 16);
        let mut d = (data.len() as u32).to_le_bytes().to_vec();
        d.extend_from_slice(&data[..first]);
        self.mbx_send(k, 3, &Self::coe_sdo(0x21 | caf, index, sub, &d));
        let r = self.sdo_answer(k)?;
        assert_eq!(r[0], 0x60);
        let mut pos = first;
        let mut toggle = 0u8;
        while pos < data.len() {
            let n = (data.len() - pos).min(MBX - 9);
            let last = pos + n == data.len();
            let mut seg = vec![0x00, 0x20, toggle | u8::from(last)];
            seg.extend_from_slice(&data[pos..pos + n]);
            if n < 7 {
                seg[2] |= ((7 - n) as u8) << 1;
                seg.resize(3 + 7, 0);
            }
            self.mbx_send(k, 3, &seg);
            let r = self.sdo_answer(k)?;
            assert_eq!(r[0], 0x20 | toggle);
            pos += n;
            toggle ^= 0x10;
        }
        Ok(())
    }

    /// SDO information: the object list of `list_type`, reassembled from its fragments.
    pub fn od_list(&mut self, k: usize, list_type: u16) -> Vec<u16> {
        let mut req = vec![0x00, 0x80, 0x01, 0, 0, 0];
        req.extend_from_slice(&list_type.to_le_bytes());
        self.mbx_send(k, 3, &req);
        let mut out = Vec::new();
        let mut first = true;
        loop {
            let (_, b) = self.mbx_receive(k).expect("a fragment");
            assert_eq!(b[1] >> 4, 8);
            assert_eq!(b[2] & 0x7F, 0x02);
            let left = u16::from_le_bytes([b[4], b[5]]);
            let words: Vec<u16> = b[6..]
                .chunks(2)
                .map(|c| u16::from_le_bytes([c[0], c[1]]))
                .collect();
            if first {
                assert_eq!(words[0], list_type);
                out.extend_from_slice(&words[1..]);
            } else {
                out.extend_from_slice(&words);
            }
            first = false;
            if left == 0 {
                assert_eq!(b[2] & 0x80, 0);
                return out;
            }
        }
    }

    /// The PDO assignment and mapping over CoE (complete access, as SOEM), then SM2/SM3
    /// and two FMMUs at logical `log_out` / `log_in`. Returns (outputs, inputs) bytes.
    pub fn map_pdos(&mut self, k: usize, log_out: u32, log_in: u32) -> (usize, usize) {
        let st = Self::station(k);
        let mut sizes = [0usize; 2];
        for (n, assign) in [0x1C12u16, 0x1C13].into_iter().enumerate() {
            let v = self.sdo_read(k, assign, 0, true).unwrap();
            let count = v[0] as usize;
            for p in 0..count {
                let m = u16::from_le_bytes([v[2 + 2 * p], v[3 + 2 * p]]);
                let mv = self.sdo_read(k, m, 0, true).unwrap();
                for e in 0..mv[0] as usize {
                    let at = 2 + 4 * e;
                    sizes[n] += mv[at] as usize / 8;
                }
            }
        }
        let (o, i) = (sizes[0] as u16, sizes[1] as u16);
        let mut sm = Vec::new();
        sm.extend_from_slice(&OUTPUTS_START.to_le_bytes());
        sm.extend_from_slice(&o.to_le_bytes());
        sm.extend_from_slice(&[0x64, 0, 1, 0]);
        sm.extend_from_slice(&INPUTS_START.to_le_bytes());
        sm.extend_from_slice(&i.to_le_bytes());
        sm.extend_from_slice(&[0x20, 0, 1, 0]);
        assert_eq!(self.fpwr(st, 0x0810, &sm), 1);
        let fmmu = |log: u32, len: u16, phys: u16, kind: u8| {
            let mut f = Vec::new();
            f.extend_from_slice(&log.to_le_bytes());
            f.extend_from_slice(&len.to_le_bytes());
            f.extend_from_slice(&[0, 7]);
            f.extend_from_slice(&phys.to_le_bytes());
            f.extend_from_slice(&[0, kind, 1, 0, 0, 0]);
            f
        };
        let mut f = fmmu(log_out, o, OUTPUTS_START, 2);
        f.extend(fmmu(log_in, i, INPUTS_START, 1));
        assert_eq!(self.fpwr(st, 0x0600, &f), 1);
        (sizes[0], sizes[1])
    }

    /// One process-data cycle: LRW of the whole image, then each drive's cycle.
    pub fn lrw(&mut self, image: &[u8]) -> (Vec<u8>, u16) {
        let r = self.one(12, 0, image);
        self.cycle();
        r
    }

    pub fn cycle(&mut self) {
        self.now_ns += 1_000_000;
        let us = self.now_ns / 1000;
        self.seg.cycle(Clocks::same(us), &mut self.drives);
    }
}

/// config_init and PRE-OP for `n` slaves.
pub fn preop(n: usize) -> Master {
    let mut m = Master::new(n);
    assert_eq!(m.config_init(), n);
    for k in 0..n {
        assert_eq!(m.go_preop(k), 0x02, "PRE-OP of slave {k}");
    }
    m
}

/// PRE-OP, PDO mapping, SAFE-OP, OP for `n` slaves; returns the master and the image size.
pub fn op(n: usize) -> (Master, usize, usize) {
    let mut m = preop(n);
    let (mut o, mut i) = (0, 0);
    // the default assignment: controlword + target position, statusword + position actual
    let total_out = 6 * n;
    for k in 0..n {
        let (so, si) = m.map_pdos(k, o as u32, (total_out + i) as u32);
        assert_eq!((so, si), (6, 6));
        o += so;
        i += si;
    }
    for k in 0..n {
        assert_eq!(m.request(k, 0x04), 0x04, "SAFE-OP of slave {k}");
    }
    let (_, wkc) = m.lrw(&vec![0; o + i]);
    assert_eq!(wkc as usize, 3 * n);
    for k in 0..n {
        assert_eq!(m.request(k, 0x08), 0x08, "OP of slave {k}");
    }
    (m, o, i)
}

pub fn outputs(cw: u16, pos: i32) -> [u8; 6] {
    let mut v = [0u8; 6];
    v[..2].copy_from_slice(&cw.to_le_bytes());
    v[2..].copy_from_slice(&pos.to_le_bytes());
    v
}
