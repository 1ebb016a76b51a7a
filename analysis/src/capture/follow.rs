//! Following the bus: the PDO mapping in force for node N (defaults, confirmed SDO remaps, NMT
//! resets), the set-points and parameters written over SDO, and one [`BusSample`] per SYNC
//! with the latest PDO values.

use super::candump::{parse_line, FrameKind, LogFrame};
use anyhow::{bail, Context, Result};
use drive_protocol::wire::{Initiate, Mux, NmtCommand, NmtFrame, SdoRequest, SdoResponse};
use drive_protocol::{CanFrame, Node};
use std::collections::BTreeMap;

/// Default COB-ID of SYNC.
pub const SYNC_COB_ID: u32 = 0x080;
/// A SYNC interval longer than this many periods counts as a gap.
const GAP_PERIODS: f64 = 1.5;
/// 0x1006 is used unless the measured SYNC interval differs from it by more than this.
const PERIOD_AGREEMENT: f64 = 0.10;
/// An answer is taken for a SYNC at most this many SYNCs back.
const MAX_BEHIND: usize = 32;
/// After this many answers in a row that came exactly one SYNC late, the drive is taken to have
/// lost an answer (every later one then stays one behind), not to be behind: a drive working
/// through a backlog answers late by a count that changes from one answer to the next (a
/// stall, then a burst of answers catching up), or stays further behind. Giving up a SYNC
/// that was answered late costs its row and doubles the next, so only the lost answer's
/// signature does it; a lost answer not recognised costs a shift of one period.
const RESYNC_AFTER: usize = 8;

/// Put an actual value decoded from a TPDO into a row.
fn set_actual(r: &mut BusSample, o: Object, v: i64) {
    match o {
        Object::Statusword => r.statusword = v as u16,
        Object::ModeDisplay => {
            r.mode_display = v as i8;
            r.mode = Some(v as i8);
        }
        Object::Position => r.position_uu = v as i32,
        Object::Velocity => r.velocity_uu_s = v as i32,
        Object::Torque => r.torque_permille = v as i16,
        Object::Current => r.current_permille = v as i16,
        Object::DirectPosition => r.direct_position_uu = v as i32,
        Object::FollowingError => r.following_error_uu = v as i32,
        Object::VelocityDemand => r.velocity_demand_uu_s = v as i32,
        Object::TargetPosition | Object::TargetVelocity => {}
    }
}

// ------------------------------------------------------------------------------------------
// PDO configuration

/// One PDO: its COB-ID entry (sub 1 of 0x14xx / 0x18xx; bit 31 = not valid) and mapping
/// (0x16xx / 0x1Axx: count and entries 0xIIIISSLL, LL = length in bits).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PdoMapping {
    pub cob_id: u32,
    pub count: u8,
    pub entries: [u32; 8],
    /// Transmission type (sub 2): 1..=240 synchronous (a TPDO answers every n-th SYNC).
    pub transmission: u8,
}

impl PdoMapping {
    pub fn valid(&self) -> bool {
        self.cob_id & 0x8000_0000 == 0
    }
    /// The 11-bit identifier.
    pub fn cob(&self) -> u32 {
        self.cob_id & 0x7FF
    }
    /// Sent in answer to SYNC (transmission type 1..=240).
    pub fn synchronous(&self) -> bool {
        (1..=240).contains(&self.transmission)
    }
    pub fn mapped(&self) -> &[u32] {
        self.entries
            .get(..usize::from(self.count.min(8)))
            .unwrap_or(&[])
    }
}

/// The PDO configuration of one node, as far as decoding needs it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdoConfig {
    pub rpdo: [PdoMapping; 4],
    pub tpdo: [PdoMapping; 4],
    /// 0x1006 communication cycle period, us (0 = not set).
    pub cycle_period_us: u32,
    /// 0x60C2 interpolation time period: value (sub 1) and index (sub 2, the power of ten of
    /// seconds), as written.
    pub ip_value: u32,
    pub ip_index: i8,
}

impl PdoConfig {
    /// The configuration stored in a node's object dictionary (its defaults, for a fresh node).
    pub fn from_node(node: &Node) -> Result<Self> {
        let get = |index: u16, sub: u8| {
            node.object_raw(index, sub)
                .with_context(|| format!("the drive has no object {index:04X}sub{sub}"))
        };
        let read = |comm: u16, map: u16| -> Result<PdoMapping> {
            let mut m = PdoMapping {
                cob_id: get(comm, 1)?,
                count: u8::try_from(get(map, 0)?).unwrap_or(0).min(8),
                entries: [0; 8],
                transmission: u8::try_from(get(comm, 2)?).unwrap_or(0),
            };
            for (s, e) in m.entries.iter_mut().enumerate() {
                *e = get(map, s as u8 + 1)?;
            }
            Ok(m)
        };
        let mut rpdo = [PdoMapping::default(); 4];
        let mut tpdo = [PdoMapping::default(); 4];
        for p in 0..4u16 {
            rpdo[usize::from(p)] = read(0x1400 + p, 0x1600 + p)?;
            tpdo[usize::from(p)] = read(0x1800 + p, 0x1A00 + p)?;
        }
        Ok(Self {
            rpdo,
            tpdo,
            cycle_period_us: node.object_raw(0x1006, 0).unwrap_or(0),
            ip_value: node.object_raw(0x60C2, 1).unwrap_or(0),
            ip_index: node.object_raw(0x60C2, 2).map_or(0, |v| v as u8 as i8),
        })
    }

    /// The interpolation time period 0x60C2 (value x 10^index s) in us, when it is set and
    /// is a whole number of us (None: not set).
    pub fn interpolation_period_us(&self) -> Option<u32> {
        if self.ip_value == 0 || !(-6..=0).contains(&self.ip_index) {
            return None;
        }
        10u32
            .checked_pow(u32::from((self.ip_index + 6) as u8))
            .and_then(|scale| self.ip_value.checked_mul(scale))
    }

    /// Apply a confirmed write; false if the object is not part of the PDO configuration.
    fn write(&mut self, index: u16, sub: u8, value: u32) -> bool {
        let slot = |base: u16| usize::from(index.wrapping_sub(base));
        match (index, sub) {
            (0x1006, 0) => self.cycle_period_us = value,
            (0x60C2, 1) => self.ip_value = value & 0xFF,
            (0x60C2, 2) => self.ip_index = value as u8 as i8,
            (0x1400..=0x1403, 1) => self.rpdo[slot(0x1400)].cob_id = value,
            (0x1800..=0x1803, 1) => self.tpdo[slot(0x1800)].cob_id = value,
            (0x1400..=0x1403, 2) => self.rpdo[slot(0x1400)].transmission = value as u8,
            (0x1800..=0x1803, 2) => self.tpdo[slot(0x1800)].transmission = value as u8,
            (0x1600..=0x1603, _) | (0x1A00..=0x1A03, _) => {
                let m = if index >= 0x1A00 {
                    &mut self.tpdo[slot(0x1A00)]
                } else {
                    &mut self.rpdo[slot(0x1600)]
                };
                match sub {
                    // The drive refuses more than 8; so do we.
                    0 if value <= 8 => m.count = value as u8,
                    1..=8 => m.entries[usize::from(sub - 1)] = value,
                    _ => return false,
                }
            }
            _ => return false,
        }
        true
    }
}

// ------------------------------------------------------------------------------------------
// Decoded objects

/// The objects decoded from PDOs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Object {
    Statusword,
    ModeDisplay,
    Position,
    Velocity,
    Torque,
    Current,
    DirectPosition,
    FollowingError,
    VelocityDemand,
    TargetPosition,
    TargetVelocity,
}

const N_OBJECTS: usize = 11;

impl Object {
    pub const ALL: [Object; N_OBJECTS] = [
        Object::Statusword,
        Object::ModeDisplay,
        Object::Position,
        Object::Velocity,
        Object::Torque,
        Object::Current,
        Object::DirectPosition,
        Object::FollowingError,
        Object::VelocityDemand,
        Object::TargetPosition,
        Object::TargetVelocity,
    ];

    pub fn of(index: u16, sub: u8) -> Option<Object> {
        Some(match (index, sub) {
            (0x6041, 0) => Object::Statusword,
            (0x6061, 0) => Object::ModeDisplay,
            (0x6064, 0) => Object::Position,
            (0x606C, 0) => Object::Velocity,
            (0x6077, 0) => Object::Torque,
            (0x6078, 0) => Object::Current,
            (0x60E4, 1) => Object::DirectPosition,
            (0x60F4, 0) => Object::FollowingError,
            (0x606B, 0) => Object::VelocityDemand,
            (0x607A, 0) => Object::TargetPosition,
            (0x60FF, 0) => Object::TargetVelocity,
            _ => return None,
        })
    }

    /// Index, sub and name, e.g. "0x606C velocity actual value".
    pub fn name(self) -> &'static str {
        match self {
            Object::Statusword => "0x6041 statusword",
            Object::ModeDisplay => "0x6061 modes of operation display",
            Object::Position => "0x6064 position actual value",
            Object::Velocity => "0x606C velocity actual value",
            Object::Torque => "0x6077 torque actual value",
            Object::Current => "0x6078 current actual value",
            Object::DirectPosition => "0x60E4 sub 1 direct-encoder position",
            Object::FollowingError => "0x60F4 following error actual value",
            Object::VelocityDemand => "0x606B velocity demand value",
            Object::TargetPosition => "0x607A target position",
            Object::TargetVelocity => "0x60FF target velocity",
        }
    }

    pub(super) fn slot(self) -> usize {
        self as usize
    }

    fn signed(self) -> bool {
        self != Object::Statusword
    }
}

/// What node N reported (and was commanded) at one SYNC: the latest PDO values. Values not yet
/// received are 0 (targets: None), as in the reference master's `Sample`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct BusSample {
    pub statusword: u16,
    pub mode_display: i8,
    /// The mode: mode display if mapped and received, else the last 0x6060 written over SDO.
    pub mode: Option<i8>,
    pub position_uu: i32,
    pub direct_position_uu: i32,
    pub velocity_uu_s: i32,
    pub velocity_demand_uu_s: i32,
    pub torque_permille: i16,
    pub current_permille: i16,
    pub following_error_uu: i32,
    pub target_position_uu: Option<i32>,
    pub target_velocity_uu_s: Option<i32>,
}

/// Counters of a decoded log.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct DecodeStats {
    pub lines: usize,
    /// Standard-ID data frames.
    pub frames: usize,
    pub syncs: usize,
    /// Frames of node N: its PDOs (current mapping or predefined COB-IDs), SDO, EMCY, heartbeat.
    pub node_frames: usize,
    pub nmt_frames: usize,
    /// Frames of other COB-IDs (other nodes, the master's heartbeat, ...).
    pub unknown_frames: usize,
    pub remote_frames: usize,
    pub error_frames: usize,
    pub extended_frames: usize,
    pub fd_frames: usize,
    pub pdos_decoded: usize,
    /// PDO frames shorter than their mapping (not decoded).
    pub pdo_length_errors: usize,
    pub sdo_writes_confirmed: usize,
    pub sdo_writes_aborted: usize,
    /// Confirmed writes that changed the PDO configuration (0x14xx-0x1Axx, 0x1006).
    pub pdo_config_writes: usize,
    /// Confirmed SDO writes of a set-point (0x607A, 0x60FF).
    pub sdo_setpoint_writes: usize,
    /// RPDOs carrying a set-point (0x607A, 0x60FF).
    pub pdo_setpoints: usize,
    /// Segmented or block SDO downloads (not followed).
    pub sdo_not_expedited: usize,
    pub nmt_resets: usize,
    /// SYNC intervals longer than 1.5 periods.
    pub sync_gaps: usize,
    /// Frames whose timestamp is earlier than the previous frame's.
    pub timestamps_backwards: usize,
    /// Answers (the synchronous TPDOs of one SYNC) that came after a later SYNC: the drive
    /// was behind, and they are taken for the older SYNC they answer.
    pub answers_late: usize,
    /// SYNCs the drive's synchronous TPDOs never answered in the capture.
    pub syncs_unanswered: usize,
}

/// Where the sample period came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PeriodSource {
    CommandLine,
    Object1006,
    MedianSyncInterval,
}

impl PeriodSource {
    pub fn as_str(self) -> &'static str {
        match self {
            PeriodSource::CommandLine => "--sync-period-us",
            PeriodSource::Object1006 => "0x1006 written in the log",
            PeriodSource::MedianSyncInterval => "median SYNC interval",
        }
    }
}

/// How to decode a log.
#[derive(Debug, Clone)]
pub struct DecodeOptions {
    pub node_id: u8,
    /// The drive's PDO configuration after reset.
    pub defaults: PdoConfig,
    /// Sample period, us; None: 0x1006 or the median SYNC interval.
    pub sync_period_us: Option<u32>,
}

/// A decoded candump log of one node.
#[derive(Debug, Clone)]
pub struct BusLog {
    /// File name (for messages).
    pub source: String,
    pub node_id: u8,
    /// One per SYNC: the latest values when SYNC k was received.
    pub samples: Vec<BusSample>,
    /// The time stamp of each sample's SYNC in the capture (the kernel time of the frame), us.
    pub sync_t_us: Vec<i64>,
    /// One row per SYNC: the set-points in force at it (sent before it) and the values of the
    /// synchronous TPDOs that answered it, in order (the first answer after SYNC k answers the
    /// oldest SYNC not yet answered: a drive that falls behind answers late but in order);
    /// values not answered are held from the row before.
    pub rows: Vec<BusSample>,
    /// Whether row k got an answer.
    pub answered: Vec<bool>,
    pub period_us: u32,
    pub period_source: PeriodSource,
    /// The simulated time a drive clocked by SYNC (`run --lockstep`) advances per SYNC, us,
    /// and what says so, as the drive takes it: `--sync-period-us`, else 0x1006 as written,
    /// else 0x60C2 as written (the drive's own rule: CiA 402 makes the interpolation period
    /// the time between set-points, one per SYNC), else [`BusLog::period_us`]. Not checked
    /// against the bus: such a drive takes it however slowly the SYNCs come.
    pub lockstep_period_us: u32,
    pub lockstep_period_source: &'static str,
    /// Median SYNC interval of the timestamps, us (None with fewer than two SYNCs).
    pub measured_period_us: Option<u32>,
    pub stats: DecodeStats,
    /// The last k_v written to 0x2007 (kv_per_s) over SDO and confirmed, 1/s.
    pub kv_written: Option<f64>,
    /// Warnings: missing objects replaced, gaps, ignored transfers.
    pub notes: Vec<String>,
    pub(super) seen: [bool; N_OBJECTS],
    /// COB-IDs not of node N, with their frame counts.
    pub other_ids: BTreeMap<u32, usize>,
}

#[derive(Debug, Clone, Copy)]
struct PendingWrite {
    index: u16,
    sub: u8,
    value: u32,
}

struct Decoder<'a> {
    node: u32,
    defaults: &'a PdoConfig,
    cfg: PdoConfig,
    pending: Option<PendingWrite>,
    mode_written: Option<i8>,
    kv_written: Option<f64>,
    latest: [i64; N_OBJECTS],
    seen: [bool; N_OBJECTS],
    stats: DecodeStats,
    sync_t_us: Vec<i64>,
    samples: Vec<BusSample>,
    rows: Vec<BusSample>,
    answered: Vec<bool>,
    /// The answer being filled: its row and the TPDOs (bits 0..3) already in it.
    answer: Option<(usize, u8)>,
    /// A SYNC came after the answer being filled began: only a TPDO numbered above every one
    /// it holds still belongs to it (a drive sends its answer in TPDO order; a master that
    /// sends the next SYNC on the first part of the answer logs the rest after it).
    answer_past_sync: bool,
    /// The oldest SYNC not answered yet.
    next_unanswered: usize,
    /// Answers in a row that came the same number of SYNCs late, and that number.
    behind_in_a_row: usize,
    behind_by: usize,
    last_t_us: Option<i64>,
    other_ids: BTreeMap<u32, usize>,
}

fn sign_extend(v: u64, bits: u32) -> i64 {
    if bits == 0 || bits >= 64 {
        v as i64
    } else {
        let shift = 64 - bits;
        ((v << shift) as i64) >> shift
    }
}

impl<'a> Decoder<'a> {
    fn new(node_id: u8, defaults: &'a PdoConfig) -> Self {
        Self {
            node: u32::from(node_id),
            defaults,
            cfg: defaults.clone(),
            pending: None,
            mode_written: None,
            kv_written: None,
            latest: [0; N_OBJECTS],
            seen: [false; N_OBJECTS],
            stats: DecodeStats::default(),
            sync_t_us: Vec::new(),
            samples: Vec::new(),
            rows: Vec::new(),
            answered: Vec::new(),
            answer: None,
            answer_past_sync: false,
            next_unanswered: 0,
            behind_in_a_row: 0,
            behind_by: 0,
            last_t_us: None,
            other_ids: BTreeMap::new(),
        }
    }

    fn record(&mut self, f: &LogFrame) {
        match f.kind {
            FrameKind::Data(frame) => self.frame(f.t_us, &frame),
            FrameKind::Remote { .. } => self.stats.remote_frames += 1,
            FrameKind::Error => self.stats.error_frames += 1,
            FrameKind::Extended { .. } => self.stats.extended_frames += 1,
            FrameKind::Fd { .. } => self.stats.fd_frames += 1,
        }
    }

    /// The node's predefined COB-IDs (EMCY, the eight PDO IDs, SDO, heartbeat).
    fn predefined(&self, id: u32) -> bool {
        let n = self.node;
        id == 0x80 + n
            || (1..=8).any(|k| id == 0x100 + 0x80 * k + n)
            || id == 0x580 + n
            || id == 0x600 + n
            || id == 0x700 + n
    }

    fn frame(&mut self, t_us: i64, f: &CanFrame) {
        self.stats.frames += 1;
        if self.last_t_us.is_some_and(|t| t_us < t) {
            self.stats.timestamps_backwards += 1;
        }
        self.last_t_us = Some(t_us);
        let d = f.payload();
        let n = self.node;
        if f.id == 0x000 {
            self.stats.nmt_frames += 1;
            if let Some(nmt) = NmtFrame::parse(d) {
                let reset_node = matches!(nmt.command, NmtCommand::ResetNode);
                let reset = reset_node || matches!(nmt.command, NmtCommand::ResetCommunication);
                if reset && nmt.addresses(n as u8) {
                    self.reset(reset_node);
                }
            }
            return;
        }
        if f.id == SYNC_COB_ID && d.len() <= 1 {
            self.sync(t_us);
            return;
        }
        let tpdo = (0..4).find(|&k| self.cfg.tpdo[k].valid() && self.cfg.tpdo[k].cob() == f.id);
        let pdo = self
            .cfg
            .tpdo
            .iter()
            .chain(self.cfg.rpdo.iter())
            .find(|p| p.valid() && p.cob() == f.id)
            .copied();
        if let Some(p) = pdo {
            self.stats.node_frames += 1;
            let row = match tpdo {
                Some(k) if p.synchronous() => self.answer_row(k),
                _ => None,
            };
            self.decode_pdo(&p, f, row);
        } else if f.id == 0x600 + n {
            self.stats.node_frames += 1;
            self.sdo_request(d);
        } else if f.id == 0x580 + n {
            self.stats.node_frames += 1;
            self.sdo_response(d);
        } else if self.predefined(f.id) {
            self.stats.node_frames += 1;
        } else {
            self.stats.unknown_frames += 1;
            *self.other_ids.entry(f.id).or_insert(0) += 1;
        }
    }

    fn reset(&mut self, node: bool) {
        self.stats.nmt_resets += 1;
        self.cfg = self.defaults.clone();
        self.pending = None;
        if node {
            self.mode_written = None;
        }
    }

    fn sync(&mut self, t_us: i64) {
        self.stats.syncs += 1;
        self.sync_t_us.push(t_us);
        let v = |o: Object| self.latest[o.slot()];
        let seen = |o: Object| self.seen[o.slot()];
        let mode_display = v(Object::ModeDisplay) as i8;
        let sample = BusSample {
            statusword: v(Object::Statusword) as u16,
            mode_display,
            mode: if seen(Object::ModeDisplay) {
                Some(mode_display)
            } else {
                self.mode_written
            },
            position_uu: v(Object::Position) as i32,
            direct_position_uu: v(Object::DirectPosition) as i32,
            velocity_uu_s: v(Object::Velocity) as i32,
            velocity_demand_uu_s: v(Object::VelocityDemand) as i32,
            torque_permille: v(Object::Torque) as i16,
            current_permille: v(Object::Current) as i16,
            following_error_uu: v(Object::FollowingError) as i32,
            target_position_uu: seen(Object::TargetPosition)
                .then(|| v(Object::TargetPosition) as i32),
            target_velocity_uu_s: seen(Object::TargetVelocity)
                .then(|| v(Object::TargetVelocity) as i32),
        };
        self.samples.push(sample);
        // The row of this SYNC: its set-points now; its actual values held from the row before
        // until its answer comes.
        let mut row = match self.rows.last() {
            Some(prev) => BusSample {
                target_position_uu: sample.target_position_uu,
                target_velocity_uu_s: sample.target_velocity_uu_s,
                ..*prev
            },
            None => sample,
        };
        row.mode = sample.mode;
        self.rows.push(row);
        self.answered.push(false);
        // A new SYNC: the answer being filled takes only its later TPDOs from now on.
        self.answer_past_sync = true;
    }

    /// The row a frame of synchronous TPDO `k` answers: the row of the answer being filled if
    /// it does not hold TPDO `k` yet, else a new answer for the oldest SYNC not answered (at
    /// most [`MAX_BEHIND`] SYNCs back). A drive that lost an answer would leave every later
    /// one a SYNC behind: after [`RESYNC_AFTER`] answers in a row that came exactly one SYNC
    /// late, the oldest unanswered SYNC is given up.
    fn answer_row(&mut self, k: usize) -> Option<usize> {
        let latest = self.rows.len().checked_sub(1)?;
        let bit = 1u8 << k;
        if let Some((j, mask)) = self.answer {
            let highest = 1u32 << (31 - u32::from(mask).leading_zeros());
            let later = u32::from(bit) > highest;
            if mask & bit == 0 && (!self.answer_past_sync || later) {
                self.answer = Some((j, mask | bit));
                return Some(j);
            }
        }
        self.answer_past_sync = false;
        let mut j = self
            .next_unanswered
            .max(latest.saturating_sub(MAX_BEHIND))
            .min(latest);
        if j < latest {
            let by = latest - j;
            if by == self.behind_by {
                self.behind_in_a_row += 1;
            } else {
                self.behind_in_a_row = 1;
                self.behind_by = by;
            }
            if by == 1 && self.behind_in_a_row > RESYNC_AFTER {
                j = latest;
                self.behind_in_a_row = 0;
            } else {
                self.stats.answers_late += 1;
            }
        } else {
            self.behind_in_a_row = 0;
            self.behind_by = 0;
        }
        self.next_unanswered = j + 1;
        self.answer = Some((j, bit));
        self.answered[j] = true;
        Some(j)
    }

    /// Decode a PDO into the latest values and, for a synchronous TPDO, into the row of the
    /// SYNC it answers (`row`; later rows that hold older values get them too).
    fn decode_pdo(&mut self, p: &PdoMapping, f: &CanFrame, row: Option<usize>) {
        let total_bits: u32 = p.mapped().iter().map(|e| e & 0xFF).sum();
        if total_bits > 64 || u32::from(f.len) * 8 < total_bits {
            self.stats.pdo_length_errors += 1;
            return;
        }
        self.stats.pdos_decoded += 1;
        let raw = u64::from_le_bytes(f.data);
        let mut offset = 0u32;
        for &e in p.mapped() {
            let bits = e & 0xFF;
            if bits == 0 {
                continue;
            }
            let mask = if bits >= 64 {
                u64::MAX
            } else {
                (1u64 << bits) - 1
            };
            let v = raw.checked_shr(offset).unwrap_or(0) & mask;
            offset += bits;
            if let Some(o) = Object::of((e >> 16) as u16, (e >> 8) as u8) {
                if matches!(o, Object::TargetPosition | Object::TargetVelocity) {
                    self.stats.pdo_setpoints += 1;
                }
                let value = if o.signed() {
                    sign_extend(v, bits)
                } else {
                    v as i64
                };
                self.latest[o.slot()] = value;
                self.seen[o.slot()] = true;
                match row {
                    Some(j) => {
                        for r in j..self.rows.len() {
                            if r == j || !self.answered[r] {
                                set_actual(&mut self.rows[r], o, value);
                            }
                        }
                    }
                    // An event-driven TPDO (statusword, mode) holds from now on.
                    None if !matches!(o, Object::TargetPosition | Object::TargetVelocity) => {
                        if let Some(r) = self.rows.last_mut() {
                            set_actual(r, o, value);
                        }
                    }
                    None => {}
                }
            }
        }
    }

    fn sdo_request(&mut self, d: &[u8]) {
        self.pending = None;
        let Ok(frame) = <[u8; 8]>::try_from(d) else {
            return;
        };
        match SdoRequest::parse(&frame) {
            Ok(SdoRequest::InitiateDownload {
                mux,
                data: data @ Initiate::Expedited { .. },
            }) => {
                let mut v = [0u8; 4];
                let bytes = data.bytes();
                v[..bytes.len().min(4)].copy_from_slice(&bytes[..bytes.len().min(4)]);
                self.pending = Some(PendingWrite {
                    index: mux.index,
                    sub: mux.sub,
                    value: u32::from_le_bytes(v),
                });
            }
            Ok(SdoRequest::InitiateDownload { .. } | SdoRequest::BlockDownloadInitiate { .. }) => {
                self.stats.sdo_not_expedited += 1
            }
            _ => {}
        }
    }

    fn sdo_response(&mut self, d: &[u8]) {
        let Ok(frame) = <[u8; 8]>::try_from(d) else {
            return;
        };
        let Some(p) = self.pending else {
            return;
        };
        let ours = |mux: Mux| mux.index == p.index && mux.sub == p.sub;
        match SdoResponse::parse(&frame) {
            Ok(SdoResponse::InitiateDownload { mux }) if ours(mux) => {
                self.pending = None;
                self.stats.sdo_writes_confirmed += 1;
                self.confirmed(p);
            }
            Ok(SdoResponse::Abort { mux, .. }) if ours(mux) => {
                self.pending = None;
                self.stats.sdo_writes_aborted += 1;
            }
            _ => {}
        }
    }

    /// A confirmed SDO write: the PDO configuration, the mode, k_v, or a set-point.
    fn confirmed(&mut self, p: PendingWrite) {
        if self.cfg.write(p.index, p.sub, p.value) {
            self.stats.pdo_config_writes += 1;
        } else if (p.index, p.sub) == (0x6060, 0) {
            self.mode_written = Some(p.value as u8 as i8);
        } else if (p.index, p.sub) == (0x2007, 0) {
            // kv_per_s, REAL32
            self.kv_written = Some(f64::from(f32::from_bits(p.value)));
        } else if let Some(o @ (Object::TargetPosition | Object::TargetVelocity)) =
            Object::of(p.index, p.sub)
        {
            // A set-point written over SDO (`node.sdo['Target velocity'].raw = v`): in force
            // from now on, as one received in an RPDO.
            self.latest[o.slot()] = sign_extend(u64::from(p.value), 32);
            self.seen[o.slot()] = true;
            self.stats.sdo_setpoint_writes += 1;
        }
    }
}

fn median_u32(v: &mut [i64]) -> Option<u32> {
    if v.is_empty() {
        return None;
    }
    v.sort_unstable();
    let n = v.len();
    let m = if !n.is_multiple_of(2) {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2] + 1) / 2
    };
    u32::try_from(m).ok()
}

/// A candump log's lines, one at a time: the text held in memory ([`TextLines`]) or a file
/// streamed (`samples::csv::TraceLines`: the log is never held whole).
pub trait LogLines {
    /// The next line without its newline (nor a `\r` before it), and whether a newline ended
    /// it (the last line of a log whose writer was stopped has none); `None` at the end.
    fn next_log_line<'b>(&mut self, buf: &'b mut Vec<u8>) -> Result<Option<(&'b str, bool)>>;
}

/// The lines of a log held as text.
pub struct TextLines<'a> {
    rest: &'a str,
}

impl<'a> TextLines<'a> {
    pub fn new(text: &'a str) -> Self {
        TextLines { rest: text }
    }
}

impl LogLines for TextLines<'_> {
    fn next_log_line<'b>(&mut self, buf: &'b mut Vec<u8>) -> Result<Option<(&'b str, bool)>> {
        if self.rest.is_empty() {
            return Ok(None);
        }
        let (line, newline) = match self.rest.split_once('\n') {
            Some((l, r)) => {
                self.rest = r;
                (l, true)
            }
            None => (std::mem::take(&mut self.rest), false),
        };
        let line = line.strip_suffix('\r').unwrap_or(line);
        buf.clear();
        buf.extend_from_slice(line.as_bytes());
        Ok(Some((
            std::str::from_utf8(buf).expect("a str's bytes"),
            newline,
        )))
    }
}

impl LogLines for crate::samples::csv::TraceLines<'_> {
    fn next_log_line<'b>(&mut self, buf: &'b mut Vec<u8>) -> Result<Option<(&'b str, bool)>> {
        let line = self.next_line(buf)?;
        let newline = self.ended_with_newline();
        Ok(line.map(|l| (l, newline)))
    }
}

/// Decode a candump log (`text`, named `source` in messages) for one node.
pub fn decode(text: &str, source: &str, opts: &DecodeOptions) -> Result<BusLog> {
    decode_lines(&mut TextLines::new(text), source, opts)
}

/// [`decode`] of a log read line by line (`analyze` streams a file so: only the decoded
/// samples are kept, never the log's text).
pub fn decode_lines(
    lines: &mut dyn LogLines,
    source: &str,
    opts: &DecodeOptions,
) -> Result<BusLog> {
    if !(1..=127).contains(&opts.node_id) {
        bail!("node {} outside 1..=127", opts.node_id);
    }
    let mut dec = Decoder::new(opts.node_id, &opts.defaults);
    let cut_line = follow_lines(&mut dec, lines, source)?;
    require_node_and_sync(&dec, source, opts.node_id)?;
    let mut notes: Vec<String> = cut_line.into_iter().collect();
    let (period_us, period_source, measured) = sync_period(&dec, opts, source, &mut notes)?;
    let (lockstep_period_us, lockstep_period_source) = lockstep_period(&dec.cfg, opts, period_us);
    let mut stats = dec.stats;
    let gap_us = GAP_PERIODS * f64::from(period_us);
    stats.sync_gaps = dec
        .sync_t_us
        .windows(2)
        .filter(|w| (w[1] - w[0]) as f64 > gap_us)
        .count();
    stats.syncs_unanswered = dec.answered.iter().filter(|a| !**a).count();
    note_decoding_losses(&stats, &mut notes);
    note_unmapped_objects(&dec.seen, &mut notes);
    Ok(BusLog {
        source: source.to_string(),
        node_id: opts.node_id,
        samples: dec.samples,
        sync_t_us: dec.sync_t_us,
        rows: dec.rows,
        answered: dec.answered,
        period_us,
        period_source,
        lockstep_period_us,
        lockstep_period_source,
        measured_period_us: measured,
        stats,
        kv_written: dec.kv_written,
        notes,
        seen: dec.seen,
        other_ids: dec.other_ids,
    })
}

/// Feed every frame of the log to the decoder. Returns the note on a last line cut short
/// (skipped); an unparsable line is an error.
fn follow_lines(
    dec: &mut Decoder,
    lines: &mut dyn LogLines,
    source: &str,
) -> Result<Option<String>> {
    let mut after_error_frame = false;
    let mut cut_line = None;
    let mut buf = Vec::new();
    let mut i = 0usize;
    while let Some((line, newline)) = lines.next_log_line(&mut buf)? {
        i += 1;
        dec.stats.lines += 1;
        // candump -e prints an error frame's explanation on lines starting with a tab.
        if after_error_frame && line.starts_with('\t') {
            continue;
        }
        // The last line of a log whose writer was killed mid-line: no newline at its end. It
        // may even parse (a frame with fewer data bytes), so it is never trusted: skipped and
        // reported.
        if !newline && !line.trim().is_empty() {
            cut_line = Some(format!(
                "{source}:{i}: last line cut short (no newline at the end: the writer was \
                 stopped mid-line): skipped: `{}`",
                crate::quote::text_max(line, 60)
            ));
            continue;
        }
        let parsed = match parse_line(line) {
            Ok(p) => p,
            // The reason repeats the line's text: rendered (control characters escaped).
            Err(e) => bail!(
                "{source}:{i}: {}",
                crate::quote::text_max(&e, crate::quote::MAX_MESSAGE_CHARS)
            ),
        };
        if let Some(f) = parsed {
            after_error_frame = f.kind == FrameKind::Error;
            dec.record(&f);
        }
    }
    Ok(cut_line)
}

/// The log must hold frames of node `n` (else: the most frequent other COB-IDs, a wrong
/// --node?) and SYNCs (samples are taken at SYNC).
fn require_node_and_sync(dec: &Decoder, source: &str, n: u8) -> Result<()> {
    let st = &dec.stats;
    if st.node_frames == 0 {
        let mut by_count: Vec<(u32, usize)> = dec.other_ids.iter().map(|(i, c)| (*i, *c)).collect();
        by_count.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        let others: Vec<String> = by_count
            .iter()
            .take(8)
            .map(|(id, c)| format!("0x{id:03X} ({c})"))
            .collect();
        bail!(
            "{source}: no frame of node {n} in the log ({} frames, {} SYNCs; most frequent other COB-IDs: \
             {}); wrong --node?",
            st.frames,
            st.syncs,
            if others.is_empty() {
                "none".into()
            } else {
                others.join(", ")
            }
        );
    }
    if st.syncs == 0 {
        bail!(
            "{source}: no SYNC (COB-ID 0x080) in the log: samples are taken at SYNC, a log of \
             synchronous PDOs is needed"
        );
    }
    Ok(())
}

/// The SYNC period, us, and where it came from: the command line, 0x1006 as written (when
/// the SYNCs agree), or the median SYNC interval; also the measured median, if any.
fn sync_period(
    dec: &Decoder,
    opts: &DecodeOptions,
    source: &str,
    notes: &mut Vec<String>,
) -> Result<(u32, PeriodSource, Option<u32>)> {
    let mut intervals: Vec<i64> = dec
        .sync_t_us
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0)
        .collect();
    let measured = median_u32(&mut intervals);
    let from_1006 = (dec.cfg.cycle_period_us > 0).then_some(dec.cfg.cycle_period_us);
    let agrees = |p: u32| {
        measured
            .is_none_or(|m| (f64::from(m) - f64::from(p)).abs() <= PERIOD_AGREEMENT * f64::from(p))
    };
    let (period_us, period_source) = match (opts.sync_period_us, from_1006, measured) {
        (Some(p), _, _) => (p, PeriodSource::CommandLine),
        (None, Some(p), _) if agrees(p) => (p, PeriodSource::Object1006),
        (None, _, Some(m)) => {
            if let Some(p) = from_1006 {
                notes.push(format!(
                    "0x1006 was written as {p} us but SYNC came every {m} us: using {m} us"
                ));
            }
            (m, PeriodSource::MedianSyncInterval)
        }
        (None, _, None) => {
            bail!("{source}: cannot tell the SYNC period from a single SYNC; give --sync-period-us")
        }
    };
    if period_us == 0 {
        bail!("{source}: the SYNC period must be > 0 us");
    }
    Ok((period_us, period_source, measured))
}

/// The time per SYNC of a drive clocked by SYNC ([`BusLog::lockstep_period_us`]).
fn lockstep_period(cfg: &PdoConfig, opts: &DecodeOptions, period_us: u32) -> (u32, &'static str) {
    if let Some(p) = opts.sync_period_us {
        (p, "--sync-period-us")
    } else if cfg.cycle_period_us > 0 {
        (cfg.cycle_period_us, "0x1006 written in the log")
    } else if let Some(p) = cfg.interpolation_period_us().filter(|&p| p > 0) {
        (p, "0x60C2 written in the log")
    } else {
        (period_us, "the median SYNC interval")
    }
}

/// Notes on what the decoder could not follow: SYNC gaps, backward timestamps, short PDOs,
/// segmented SDOs.
fn note_decoding_losses(stats: &DecodeStats, notes: &mut Vec<String>) {
    if stats.sync_gaps > 0 {
        notes.push(format!(
            "{} SYNC intervals longer than {GAP_PERIODS} periods (late or lost SYNCs, or a gap \
             in the log)",
            stats.sync_gaps
        ));
    }
    if stats.answers_late > 0 {
        notes.push(format!(
            "{} answers of the drive (its synchronous TPDOs) came after a later SYNC and are \
             taken for the SYNC they answer",
            stats.answers_late
        ));
    }
    if stats.timestamps_backwards > 0 {
        notes.push(format!(
            "{} frames with a timestamp earlier than the previous frame's (candump -td logs \
             are not read; use -ta or -L)",
            stats.timestamps_backwards
        ));
    }
    if stats.pdo_length_errors > 0 {
        notes.push(format!(
            "{} PDO frames shorter than their mapping were not decoded",
            stats.pdo_length_errors
        ));
    }
    if stats.sdo_not_expedited > 0 {
        notes.push(format!(
            "{} segmented or block SDO downloads were not followed",
            stats.sdo_not_expedited
        ));
    }
}

/// Notes on objects the PDOs did not carry, and what stands in for them.
fn note_unmapped_objects(seen: &[bool; N_OBJECTS], notes: &mut Vec<String>) {
    let has = |o: Object| seen[o.slot()];
    if has(Object::Velocity) && !has(Object::Current) {
        notes.push(format!(
            "{} is not mapped: the current column is 0, the detector judges on speed alone",
            Object::Current.name()
        ));
    }
    for (o, instead) in [
        (Object::Position, Object::DirectPosition),
        (Object::DirectPosition, Object::Position),
    ] {
        if !has(o) {
            notes.push(if has(instead) {
                format!("{} is not mapped: using {}", o.name(), instead.name())
            } else {
                format!("{} is not mapped: position columns are 0", o.name())
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sign_extends_short_fields() {
        assert_eq!(sign_extend(0xFFFF, 16), -1);
        assert_eq!(sign_extend(0x7FFF, 16), 0x7FFF);
        assert_eq!(sign_extend(0x80, 8), -128);
        assert_eq!(sign_extend(0xFFFF_FFFF, 32), -1);
    }
}
