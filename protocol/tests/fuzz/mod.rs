//! A stable fuzz / property harness for a [`Node`] and the drive behind it, shared by
//! `protocol/tests/fuzz_node.rs` (a simple drive model) and `emulator/tests/fuzz_node.rs`
//! (the real `AxisDrive`, which includes this file with `#[path]`).
//!
//! A case is a sequence of [`Op`]s: raw frames of any shape, structured SDO exchanges that
//! reach deep states (segmented and block transfers with toggles, sequence numbers, CRCs and
//! announced sizes right or wrong, stopped half way), writes of any object in the table, PDO
//! remaps, RPDOs, RTRs, SYNCs, NMT commands, the master's heartbeat, CiA 402 enables, and time
//! that advances, jumps by hours or goes backwards. After every step the harness checks what
//! a master relies on:
//! - nothing panics; every frame the node sends is a valid standard data frame;
//! - the transmit queue never overflows although it is drained after every call (no step
//!   produces more than the queue holds, so nothing grows without bound);
//! - NMT: stopped sends only heartbeats; pre-operational sends no PDOs;
//! - CiA 402: the statusword shows the state the node is in (0x6041 too), the mode display
//!   is a supported mode (0x6061 too), and a drive in FAULT has 0x1001 and 0x603F set;
//! - SDO: after a client abort the server answers a fresh request, whatever state the
//!   sequence left it in; at the end of each case, a stalled transfer has timed out and the
//!   server answers again.
#![allow(dead_code)]

use drive_protocol::cia402::mode::Mode;
use drive_protocol::cia402::statusword::decode_state;
use drive_protocol::cia402::State;
use drive_protocol::od::{Access, DataType, ObjectDictionary};
use drive_protocol::{CanFrame, Drive, NmtState, Node, NodeConfig, TX_QUEUE};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// One object the generator may pick (a row: its position in the dictionary's order).
#[derive(Clone, Copy, Debug)]
pub struct Obj {
    pub index: u16,
    pub sub: u8,
    pub dtype: DataType,
    pub access: Access,
    pub pdo: bool,
}

/// The objects of a dictionary, in its order: what the generator picks rows from.
#[derive(Clone, Debug)]
pub struct Objects(pub Vec<Obj>);

impl Objects {
    pub fn of(od: &ObjectDictionary) -> Objects {
        Objects(
            od.iter()
                .map(|(_, e)| Obj {
                    index: e.index,
                    sub: e.sub,
                    dtype: e.dtype,
                    access: e.access,
                    pdo: e.pdo,
                })
                .collect(),
        )
    }

    fn rows(&self) -> usize {
        self.0.len()
    }

    /// Rows mappable into an RPDO (`tx = false`) or a TPDO.
    fn mappable(&self, tx: bool) -> Vec<usize> {
        self.0
            .iter()
            .enumerate()
            .filter(|(_, o)| {
                o.pdo
                    && o.dtype.size() > 0
                    && if tx {
                        o.access.readable()
                    } else {
                        o.access.writable()
                    }
            })
            .map(|(i, _)| i)
            .collect()
    }

    fn row_of(&self, index: u16, sub: u8) -> Option<usize> {
        self.0.iter().position(|o| o.index == index && o.sub == sub)
    }
}

/// How time moves before a poll.
#[derive(Clone, Debug)]
pub enum Time {
    /// Forward by a few ms (the normal tick, or a late one).
    Advance(u32),
    /// Forward by up to hours at once (a stalled loop, a suspended process).
    Jump(u64),
    /// Backwards (a clock that is not monotonic).
    Back(u32),
}

/// One step of a case.
#[derive(Clone, Debug)]
pub enum Op {
    /// Any frame on any ID (extended, RTR, any DLC).
    Raw(CanFrame),
    /// Any 8 bytes to the SDO server.
    Sdo([u8; 8]),
    /// Expedited download of `value` to a row of the object table (its own size).
    Write { row: usize, value: u32 },
    /// Segmented download; `flip` flips the toggle at that segment, `stop` leaves the
    /// transfer half way.
    SegDownload {
        row: usize,
        data: Vec<u8>,
        announce: Option<u32>,
        flip: Option<usize>,
        stop: Option<usize>,
    },
    /// Segmented upload of `steps` segments (toggle flipped at `flip`).
    SegUpload {
        row: usize,
        steps: u8,
        flip: Option<u8>,
    },
    /// Block download: initiate, segments (sequence numbers right unless `bad_seq`), end
    /// with the right CRC unless `bad_crc`; `stop` leaves it before the end.
    BlockDownload {
        row: usize,
        data: Vec<u8>,
        announce: bool,
        crc: bool,
        bad_seq: Option<(usize, u8)>,
        bad_crc: bool,
        stop: Option<usize>,
    },
    /// Block upload: initiate with `blksize`, start, then the client's acknowledges
    /// (ackseq, blksize), then the end confirmation if `end`.
    BlockUpload {
        row: usize,
        blksize: u8,
        crc: bool,
        acks: Vec<(u8, u8)>,
        end: bool,
    },
    /// The client aborts whatever is going on; the server must then answer a fresh request.
    AbortThenRead,
    /// Remap PDO `k` (invalidate, clear, entries, count, transmission type, validate).
    Remap {
        tx: bool,
        k: u8,
        entries: Vec<usize>,
        ttype: u8,
    },
    /// An RPDO on the COB-ID RPDO `k` is configured with.
    Rpdo { k: u8, len: u8, data: [u8; 8] },
    /// A remote request for TPDO `k`.
    Rtr { k: u8 },
    /// A SYNC (with a counter byte or not) on the configured COB-ID.
    Sync(Option<u8>),
    /// NMT command specifier to this node or to all.
    Nmt { cs: u8, all: bool },
    /// A heartbeat from `node` with a state byte.
    Heartbeat { node: u8, state: u8 },
    /// Shutdown, switch on, enable operation in a mode, one tick apart.
    Enable { mode: i8 },
    /// 0x2101: inject a drive fault with this code (0 = stop injecting), then fault reset.
    InjectFault { code: u16, reset: bool },
    /// Time moves, then a poll.
    Poll(Time),
    /// `n` regular ticks of 1 ms.
    Ticks(u8),
}

fn time_strategy() -> impl Strategy<Value = Time> {
    prop_oneof![
        6 => (0u32..20_000).prop_map(Time::Advance),
        1 => (1_000_000u64..20_000_000_000).prop_map(Time::Jump),
        1 => (1u32..2_000_000).prop_map(Time::Back),
    ]
}

/// Values worth writing: anything, small numbers, COB-ID shapes, REAL32 numbers.
fn value_strategy() -> impl Strategy<Value = u32> {
    prop_oneof![
        any::<u32>(),
        0u32..16,
        (0u32..0x800).prop_map(|c| c | 0x8000_0000),
        (0u32..0x800).prop_map(|c| c | 0x4000_0000),
        0u32..0x800,
        (-1e4f32..1e4).prop_map(f32::to_bits),
        any::<f32>().prop_map(f32::to_bits),
        prop_oneof![
            Just(0x06u32),
            Just(0x07),
            Just(0x0F),
            Just(0x80),
            Just(0x02),
            Just(0x11F)
        ],
    ]
}

fn frame_strategy(id: u8) -> impl Strategy<Value = CanFrame> {
    let n = id as u32;
    let ids = prop_oneof![
        Just(0u32),
        Just(0x80),
        Just(0x80 + n),
        Just(0x600 + n),
        Just(0x200 + n),
        Just(0x300 + n),
        Just(0x180 + n),
        Just(0x700 + n),
        Just(0x77F),
        0u32..0x800,
        any::<u32>(),
    ];
    (ids, any::<bool>(), any::<bool>(), 0u8..=8, any::<[u8; 8]>()).prop_map(
        |(id, ext, rtr, len, data)| CanFrame {
            id,
            extended: ext && id % 7 == 0,
            rtr: rtr && id % 5 == 0,
            len,
            data,
        },
    )
}

/// One step; `id` is the node's ID, `objects` its dictionary's.
pub fn op_strategy(id: u8, objects: &Objects) -> impl Strategy<Value = Op> {
    let row = 0..objects.rows();
    let rx_map = objects.mappable(false);
    let tx_map = objects.mappable(true);
    let remap = (
        any::<bool>(),
        0u8..4,
        proptest::collection::vec(0usize..64, 0..5),
        0u8..=255,
    )
        .prop_map(move |(tx, k, e, ttype)| {
            let m = if tx { &tx_map } else { &rx_map };
            Op::Remap {
                tx,
                k,
                entries: e.into_iter().map(|i| m[i % m.len()]).collect(),
                ttype: match ttype % 5 {
                    0 => 1,
                    1 => 255,
                    2 => 0,
                    _ => ttype,
                },
            }
        });
    prop_oneof![
        4 => frame_strategy(id).prop_map(Op::Raw),
        2 => any::<[u8; 8]>().prop_map(Op::Sdo),
        8 => (row.clone(), value_strategy()).prop_map(|(row, value)| Op::Write { row, value }),
        2 => (
            row.clone(),
            proptest::collection::vec(any::<u8>(), 0..80),
            proptest::option::of(0u32..100),
            proptest::option::of(0usize..12),
            proptest::option::of(0usize..12),
        )
            .prop_map(|(row, data, announce, flip, stop)| Op::SegDownload {
                row,
                data,
                announce,
                flip,
                stop
            }),
        1 => (row.clone(), 0u8..12, proptest::option::of(0u8..12))
            .prop_map(|(row, steps, flip)| Op::SegUpload { row, steps, flip }),
        3 => (
            row.clone(),
            proptest::collection::vec(any::<u8>(), 0..80),
            any::<bool>(),
            any::<bool>(),
            proptest::option::of((0usize..12, any::<u8>())),
            proptest::bool::weighted(0.2),
            proptest::option::of(0usize..12),
        )
            .prop_map(|(row, data, announce, crc, bad_seq, bad_crc, stop)| {
                Op::BlockDownload {
                    row,
                    data,
                    announce,
                    crc,
                    bad_seq,
                    bad_crc,
                    stop,
                }
            }),
        2 => (
            row.clone(),
            prop_oneof![1u8..=127, any::<u8>()],
            any::<bool>(),
            proptest::collection::vec((0u8..12, prop_oneof![1u8..=127, any::<u8>()]), 0..4),
            any::<bool>(),
        )
            .prop_map(|(row, blksize, crc, acks, end)| Op::BlockUpload {
                row,
                blksize,
                crc,
                acks,
                end
            }),
        2 => Just(Op::AbortThenRead),
        2 => remap,
        4 => (0u8..4, 0u8..=8, any::<[u8; 8]>()).prop_map(|(k, len, data)| Op::Rpdo { k, len, data }),
        1 => (0u8..4).prop_map(|k| Op::Rtr { k }),
        3 => proptest::option::of(any::<u8>()).prop_map(Op::Sync),
        2 => (prop_oneof![Just(1u8), Just(2), Just(0x80), Just(0x81), Just(0x82), any::<u8>()], any::<bool>())
            .prop_map(|(cs, all)| Op::Nmt { cs, all }),
        2 => (prop_oneof![Just(0x7Fu8), 1u8..128], prop_oneof![Just(5u8), Just(0x7F), Just(0), any::<u8>()])
            .prop_map(|(node, state)| Op::Heartbeat { node, state }),
        2 => prop_oneof![Just(1i8), Just(3), Just(6), Just(8), Just(9), Just(10), any::<i8>()]
            .prop_map(|mode| Op::Enable { mode }),
        1 => (prop_oneof![Just(0u16), Just(0x7300), Just(0x4310), any::<u16>()], any::<bool>())
            .prop_map(|(code, reset)| Op::InjectFault { code, reset }),
        6 => time_strategy().prop_map(Op::Poll),
        3 => (1u8..40).prop_map(Op::Ticks),
    ]
}

/// A case: the node starts operational or not, then the steps.
pub fn case_strategy(
    id: u8,
    objects: &Objects,
    max_ops: usize,
) -> impl Strategy<Value = (bool, Vec<Op>)> {
    (
        proptest::bool::weighted(0.8),
        proptest::collection::vec(op_strategy(id, objects), 1..max_ops),
    )
}

/// CRC-16/XMODEM, as SDO block transfer uses.
pub fn crc16(data: &[u8]) -> u16 {
    let mut crc = 0u16;
    for &b in data {
        crc ^= (b as u16) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// The node, its drive, the clock, and a way to move the drive's physics.
pub struct Harness<D: Drive> {
    pub node: Node,
    /// The node's objects, as the generator saw them.
    pub objects: Objects,
    pub drive: D,
    pub now_us: u64,
    /// Advance the drive's physics by this much simulated time (us).
    pub advance: fn(&mut D, u64),
    /// Most physics time one poll may run (a jump of the node's clock does not run hours of
    /// physics).
    pub max_physics_us: u64,
    /// Frames sent so far.
    pub sent: u64,
    /// Expedited reads answered after a client abort.
    pub recoveries: u64,
    /// What the server answered, by kind (to check that cases go deep).
    pub stats: SdoStats,
}

/// Counts of SDO responses by kind.
#[derive(Clone, Copy, Debug, Default)]
pub struct SdoStats {
    pub download_ok: u64,
    pub aborts: u64,
    pub segments: u64,
    pub block_download_done: u64,
    pub block_upload_end: u64,
    pub block_acks: u64,
}

fn fail(msg: String) -> TestCaseError {
    TestCaseError::fail(msg)
}

impl<D: Drive> Harness<D> {
    /// A harness on a node built from `cfg`, its objects [`Objects::of`] its dictionary (the
    /// rows `case_strategy` was given must come from the same dictionary).
    pub fn new(cfg: NodeConfig, drive: D, advance: fn(&mut D, u64)) -> Self {
        let mut node = Node::new(cfg).expect("node");
        node.boot(0);
        let mut h = Harness {
            objects: Objects::of(node.od()),
            node,
            drive,
            now_us: 0,
            advance,
            max_physics_us: 10_000,
            sent: 0,
            recoveries: 0,
            stats: SdoStats::default(),
        };
        while h.node.pop_tx().is_some() {}
        h
    }

    fn id(&self) -> u32 {
        self.node.node_id() as u32
    }

    /// Take every frame the node queued and check each against the NMT state.
    fn drain(&mut self) -> Result<Vec<CanFrame>, TestCaseError> {
        let id = self.id();
        let nmt = self.node.nmt_state();
        let emcy_cob = self.node.object_raw(0x1014, 0).unwrap_or(0) & 0x7FF;
        let mut out = Vec::new();
        while let Some(f) = self.node.pop_tx() {
            if f.extended || f.rtr || f.id > 0x7FF || f.len > 8 {
                return Err(fail(format!("invalid frame sent: {f:?}")));
            }
            // LSS (CiA 305) answers on 0x7E4 in every NMT state
            let allowed = f.id == 0x7E4
                || match nmt {
                    NmtState::Stopped => f.id == 0x700 + id,
                    NmtState::PreOperational | NmtState::Initialising => {
                        f.id == 0x700 + id || f.id == 0x580 + id || f.id == emcy_cob
                    }
                    NmtState::Operational => true,
                };
            if !allowed {
                return Err(fail(format!("{nmt:?}: sent {f:?}")));
            }
            if f.id == 0x580 + id && f.len != 8 {
                return Err(fail(format!("SDO response of {} bytes", f.len)));
            }
            out.push(f);
        }
        if self.node.tx_overflows() != 0 {
            return Err(fail(format!(
                "transmit queue ({TX_QUEUE}) overflowed within one call: {} frames lost",
                self.node.tx_overflows()
            )));
        }
        self.sent += out.len() as u64;
        Ok(out)
    }

    pub fn handle(&mut self, f: &CanFrame) -> Result<Vec<CanFrame>, TestCaseError> {
        let _ = self.node.handle(f, self.now_us, &mut self.drive);
        self.drain()
    }

    /// Move the clock, run the drive's physics for the forward part, poll, check.
    pub fn poll(&mut self, t: &Time) -> Result<(), TestCaseError> {
        match *t {
            Time::Advance(dt) => {
                self.now_us += dt as u64;
                (self.advance)(&mut self.drive, (dt as u64).min(self.max_physics_us));
            }
            Time::Jump(dt) => {
                self.now_us += dt;
                (self.advance)(&mut self.drive, dt.min(self.max_physics_us));
            }
            Time::Back(dt) => self.now_us = self.now_us.saturating_sub(dt as u64),
        }
        self.node.poll(self.now_us, &mut self.drive);
        self.drain()?;
        self.check_state()
    }

    fn tick(&mut self) -> Result<(), TestCaseError> {
        self.poll(&Time::Advance(1000))
    }

    /// CiA 402 invariants, valid after a poll.
    fn check_state(&self) -> Result<(), TestCaseError> {
        let n = &self.node;
        let sw = n.statusword();
        let st = n.cia402_state();
        if decode_state(sw) != Some(st) {
            return Err(fail(format!("statusword {sw:#06x} in state {st:?}")));
        }
        if n.object_raw(0x6041, 0) != Some(sw as u32) {
            return Err(fail(format!(
                "0x6041 {:?} != statusword {sw:#06x}",
                n.object_raw(0x6041, 0)
            )));
        }
        let m = n.mode();
        let supported = n.object_raw(0x6502, 0).unwrap_or(0);
        if !Mode::from_value(m).is_some_and(|x| x.in_mask(supported)) {
            return Err(fail(format!("mode display {m} is not a supported mode")));
        }
        let shown = n.object_raw(0x6061, 0).map(|r| r as i32 as i8);
        if shown != Some(m) {
            return Err(fail(format!("0x6061 {shown:?} != mode display {m}")));
        }
        if matches!(st, State::Fault | State::FaultReactionActive) {
            let reg = n.object_raw(0x1001, 0).unwrap_or(0);
            let code = n.object_raw(0x603F, 0).unwrap_or(0);
            if reg & 1 == 0 || code == 0 {
                return Err(fail(format!(
                    "{st:?} with 0x1001 = {reg:#x}, 0x603F = {code:#x}"
                )));
            }
        }
        Ok(())
    }

    /// Send an SDO request, return the server's responses.
    pub fn sdo(&mut self, req: [u8; 8]) -> Result<Vec<[u8; 8]>, TestCaseError> {
        let id = self.id();
        let out = self.handle(&CanFrame::new(0x600 + id, &req))?;
        let r: Vec<[u8; 8]> = out
            .into_iter()
            .filter(|f| f.id == 0x580 + id)
            .map(|f| f.data)
            .collect();
        let st = &mut self.stats;
        for d in &r {
            match d[0] {
                0x60 => st.download_ok += 1,
                0x80 => st.aborts += 1,
                0x20 | 0x30 => st.segments += 1,
                0xA1 => st.block_download_done += 1,
                0xA2 => st.block_acks += 1,
                c if c & 0xE3 == 0xC1 => st.block_upload_end += 1,
                _ => {}
            }
        }
        Ok(r)
    }

    fn sdo_served(&self) -> bool {
        matches!(
            self.node.nmt_state(),
            NmtState::PreOperational | NmtState::Operational
        )
    }

    /// Client abort, then an expedited read of 0x1000 must be answered.
    pub fn abort_then_read(&mut self) -> Result<(), TestCaseError> {
        self.sdo([0x80, 0, 0, 0, 0, 0, 0, 0x08])?;
        let r = self.sdo([0x40, 0x00, 0x10, 0, 0, 0, 0, 0])?;
        if !self.sdo_served() {
            return if r.is_empty() {
                Ok(())
            } else {
                Err(fail(format!("SDO answered while not served: {r:x?}")))
            };
        }
        let want = [0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00];
        if r.len() != 1 || r[0] != want {
            return Err(fail(format!(
                "after a client abort the server answered {r:x?} to a read of 0x1000"
            )));
        }
        self.recoveries += 1;
        Ok(())
    }

    fn expedited(&mut self, row: usize, value: u32) -> Result<Vec<[u8; 8]>, TestCaseError> {
        let o = self.objects.0[row];
        let n = match o.dtype.size() {
            0 => 4,
            s => s,
        };
        let i = o.index.to_le_bytes();
        let mut req = [0x23 | (((4 - n) as u8) << 2), i[0], i[1], o.sub, 0, 0, 0, 0];
        req[4..4 + n].copy_from_slice(&value.to_le_bytes()[..n]);
        self.sdo(req)
    }

    /// Expedited download of (index, sub) with the object's own size.
    fn write_entry(&mut self, index: u16, sub: u8, value: u32) -> Result<(), TestCaseError> {
        match self.objects.row_of(index, sub) {
            Some(row) => self.expedited(row, value).map(|_| ()),
            None => Err(fail(format!("no object {index:04X}sub{sub}"))),
        }
    }

    pub fn apply(&mut self, op: &Op) -> Result<(), TestCaseError> {
        let id = self.id();
        match op {
            Op::Raw(f) => {
                self.handle(f)?;
            }
            Op::Sdo(req) => {
                self.sdo(*req)?;
            }
            Op::Write { row, value } => {
                self.expedited(*row, *value)?;
            }
            Op::SegDownload {
                row,
                data,
                announce,
                flip,
                stop,
            } => {
                let o = self.objects.0[*row];
                let mut data = data.clone();
                let mut announce = *announce;
                if data.first().is_some_and(|b| b & 1 == 0) && o.dtype.size() > 0 {
                    data.resize(o.dtype.size(), 0);
                    announce = announce.map(|_| data.len() as u32);
                }
                let i = o.index.to_le_bytes();
                let mut req = [
                    0x20 | announce.is_some() as u8,
                    i[0],
                    i[1],
                    o.sub,
                    0,
                    0,
                    0,
                    0,
                ];
                if let Some(s) = announce {
                    req[4..8].copy_from_slice(&s.to_le_bytes());
                }
                self.sdo(req)?;
                let chunks: Vec<&[u8]> = data.chunks(7).collect();
                let mut t = 0u8;
                for (k, c) in chunks.iter().enumerate() {
                    if Some(k) == *stop {
                        break;
                    }
                    let last = k + 1 == chunks.len();
                    let tt = if Some(k) == *flip { t ^ 0x10 } else { t };
                    let mut r = [0u8; 8];
                    r[0] = tt | (((7 - c.len()) as u8) << 1) | last as u8;
                    r[1..1 + c.len()].copy_from_slice(c);
                    self.sdo(r)?;
                    t ^= 0x10;
                }
            }
            Op::SegUpload { row, steps, flip } => {
                let o = self.objects.0[*row];
                let i = o.index.to_le_bytes();
                self.sdo([0x40, i[0], i[1], o.sub, 0, 0, 0, 0])?;
                let mut t = 0u8;
                for k in 0..*steps {
                    let tt = if Some(k) == *flip { t ^ 0x10 } else { t };
                    self.sdo([0x60 | tt, 0, 0, 0, 0, 0, 0, 0])?;
                    t ^= 0x10;
                }
            }
            Op::BlockDownload {
                row,
                data,
                announce,
                crc,
                bad_seq,
                bad_crc,
                stop,
            } => {
                let o = self.objects.0[*row];
                // half the time, a value of the object's own size (so transfers complete)
                let mut data = data.clone();
                if data.first().is_some_and(|b| b & 1 == 0) && o.dtype.size() > 0 {
                    data.resize(o.dtype.size(), 0);
                }
                let data = &data;
                let i = o.index.to_le_bytes();
                let mut req = [
                    0xC0 | (*crc as u8) << 2 | (*announce as u8) << 1,
                    i[0],
                    i[1],
                    o.sub,
                    0,
                    0,
                    0,
                    0,
                ];
                if *announce {
                    req[4..8].copy_from_slice(&(data.len() as u32).to_le_bytes());
                }
                let r = self.sdo(req)?;
                let blksize = r.first().map(|f| f[4]).unwrap_or(1).clamp(1, 127) as usize;
                let chunks: Vec<&[u8]> = data.chunks(7).collect();
                let mut seq = 1usize;
                for (k, c) in chunks.iter().enumerate() {
                    if Some(k) == *stop {
                        return Ok(());
                    }
                    let last = k + 1 == chunks.len();
                    let mut s = seq as u8;
                    if let Some((at, v)) = bad_seq {
                        if *at == k {
                            s = *v & 0x7F;
                        }
                    }
                    let mut f = [0u8; 8];
                    f[0] = s | if last { 0x80 } else { 0 };
                    f[1..1 + c.len()].copy_from_slice(c);
                    self.sdo(f)?;
                    seq = if seq >= blksize { 1 } else { seq + 1 };
                }
                let unused = ((7 - data.len() % 7) % 7) as u8;
                let mut c = crc16(data);
                if *bad_crc {
                    c ^= 0x5A5A;
                }
                let c = c.to_le_bytes();
                self.sdo([0xC1 | (unused << 2), c[0], c[1], 0, 0, 0, 0, 0])?;
            }
            Op::BlockUpload {
                row,
                blksize,
                crc,
                acks,
                end,
            } => {
                let o = self.objects.0[*row];
                let i = o.index.to_le_bytes();
                self.sdo([
                    0xA0 | (*crc as u8) << 2,
                    i[0],
                    i[1],
                    o.sub,
                    *blksize,
                    0,
                    0,
                    0,
                ])?;
                self.sdo([0xA3, 0, 0, 0, 0, 0, 0, 0])?;
                for (ackseq, bs) in acks {
                    self.sdo([0xA2, *ackseq, *bs, 0, 0, 0, 0, 0])?;
                }
                if *end {
                    self.sdo([0xA1, 0, 0, 0, 0, 0, 0, 0])?;
                }
            }
            Op::AbortThenRead => self.abort_then_read()?,
            Op::Remap {
                tx,
                k,
                entries,
                ttype,
            } => {
                let (comm, map) = if *tx {
                    (0x1800 + *k as u16, 0x1A00 + *k as u16)
                } else {
                    (0x1400 + *k as u16, 0x1600 + *k as u16)
                };
                let cob = self.node.object_raw(comm, 1).unwrap_or(0);
                self.write_entry(comm, 1, cob | 0x8000_0000)?;
                self.write_entry(map, 0, 0)?;
                for (s, row) in entries.iter().enumerate() {
                    let o = self.objects.0[*row];
                    let e =
                        (o.index as u32) << 16 | (o.sub as u32) << 8 | (o.dtype.size() as u32 * 8);
                    self.write_entry(map, s as u8 + 1, e)?;
                }
                self.write_entry(map, 0, entries.len() as u32)?;
                self.write_entry(comm, 2, *ttype as u32)?;
                self.write_entry(comm, 1, cob & 0x7FFF_FFFF)?;
            }
            Op::Rpdo { k, len, data } => {
                let cob = self.node.object_raw(0x1400 + *k as u16, 1).unwrap_or(0) & 0x7FF;
                let mut f = CanFrame::new(cob, &data[..*len as usize]);
                f.len = *len;
                self.handle(&f)?;
            }
            Op::Rtr { k } => {
                let p = self.node.object_raw(0x1A00 + *k as u16, 0).unwrap_or(0);
                let cob = self.node.object_raw(0x1800 + *k as u16, 1).unwrap_or(0) & 0x7FF;
                self.handle(&CanFrame::remote(cob, p.min(8) as u8))?;
            }
            Op::Sync(counter) => {
                let cob = self.node.object_raw(0x1005, 0).unwrap_or(0x80) & 0x7FF;
                let f = match counter {
                    Some(c) => CanFrame::new(cob, &[*c]),
                    None => CanFrame::new(cob, &[]),
                };
                self.handle(&f)?;
            }
            Op::Nmt { cs, all } => {
                let target = if *all { 0 } else { id as u8 };
                self.handle(&CanFrame::new(0, &[*cs, target]))?;
            }
            Op::Heartbeat { node, state } => {
                self.handle(&CanFrame::new(0x700 + *node as u32, &[*state]))?;
            }
            Op::Enable { mode } => {
                self.write_entry(0x6060, 0, *mode as u8 as u32)?;
                for cw in [0x06u32, 0x07, 0x0F] {
                    self.write_entry(0x6040, 0, cw)?;
                    self.tick()?;
                }
            }
            Op::InjectFault { code, reset } => {
                self.write_entry(0x2101, 0, *code as u32)?;
                self.tick()?;
                if *reset {
                    self.write_entry(0x6040, 0, 0)?;
                    self.tick()?;
                    self.write_entry(0x6040, 0, 0x80)?;
                    self.tick()?;
                }
            }
            Op::Poll(t) => self.poll(t)?,
            Op::Ticks(n) => {
                for _ in 0..*n {
                    self.tick()?;
                }
            }
        }
        Ok(())
    }

    /// Run a case: start (or not), the steps, then the end checks.
    pub fn run(&mut self, start: bool, ops: &[Op]) -> Result<(), TestCaseError> {
        if start {
            let id = self.id() as u8;
            self.handle(&CanFrame::new(0, &[0x01, id]))?;
        }
        for op in ops {
            self.apply(op)?;
        }
        self.finish()
    }

    /// Whatever the case left behind: a stalled transfer times out, the server answers, and
    /// reset node brings the node back (boot-up, pre-operational).
    pub fn finish(&mut self) -> Result<(), TestCaseError> {
        let id = self.id() as u8;
        self.handle(&CanFrame::new(0, &[0x80, id]))?;
        for _ in 0..3 {
            self.poll(&Time::Jump(1_000_000))?;
        }
        self.abort_then_read()?;
        let out = self.handle(&CanFrame::new(0, &[0x81, id]))?;
        if !out
            .iter()
            .any(|f| f.id == 0x700 + id as u32 && f.data[0] == 0)
        {
            return Err(fail(format!("no boot-up after reset node: {out:?}")));
        }
        if self.node.nmt_state() != NmtState::PreOperational {
            return Err(fail(format!(
                "{:?} after reset node",
                self.node.nmt_state()
            )));
        }
        self.tick()?;
        self.abort_then_read()
    }
}
