//! candump logs: read a CAN bus recording (can-utils `candump -L`, or `candump -ta`) and decode
//! what one CiA 402 drive reported in its PDOs, with the drive's PDO mapping, into one sample
//! per SYNC: the trace the backlash detector needs, as the reference master would have seen it.
//!
//! Accepted lines (empty lines and `#` comments are skipped):
//! - `candump -L`: `(1700000000.123456) vcan0 185#0102030405060708` (`185#R` remote frame,
//!   8-digit IDs extended or error frames, `##` CAN FD);
//! - `candump -ta` (and can-utils `log2long`): ` (1700000000.123456)  vcan0  185   [8]  01 02 03
//!   04 05 06 07 08`, with an optional `-a` ASCII column, `remote request`, `ERRORFRAME` (its
//!   `-e` detail lines, which start with a tab, are skipped) and CAN FD lengths `[02]`..`[64]`.
//!
//! Remote, error, extended-ID and CAN FD frames are counted and skipped; any other malformed line
//! is an error `file:line: reason`.
//!
//! The PDO mapping of node N starts from the drive's defaults, read from our own object
//! dictionary ([`PdoConfig::from_node`]): COB-IDs 0x1400..0x1403 / 0x1800..0x1803 sub 1,
//! mappings 0x1600..0x1603 / 0x1A00..0x1A03. Expedited SDO downloads to those objects (request
//! on 0x600+N, confirmed by 0x580+N with command 0x60 and the same index and sub) change it; an
//! abort (0x80) leaves the old value; NMT reset node or reset communication (to N or to all)
//! returns it to the defaults. Segmented and block downloads are not followed (counted), and a
//! mapping saved with 0x1010 and restored at reset is not modelled: the defaults come back.
//! The SYNC COB-ID is taken as 0x080.
//!
//! Decoded: TPDO (drive to master) 0x6041 statusword, 0x6061 mode display, 0x6064 position,
//! 0x606C velocity, 0x6077 torque, 0x6078 current, 0x60E4 sub 1 direct encoder, 0x60F4
//! following error, 0x606B velocity demand; RPDO (master to drive) 0x607A target position and
//! 0x60FF target velocity. At every SYNC the latest values form one [`BusSample`].
//!
//! Time base: bus timestamps jitter (much inside user-mode Linux) and the spectrum needs uniform
//! sampling, so sample k is at `t = k * period`. The period is `--sync-period-us` if given, else
//! a confirmed SDO write to 0x1006 (unless the bus disagrees by more than 10 %), else the median
//! SYNC interval of the timestamps. Lost SYNCs are counted, not inserted.
//!
//! Set velocity (for the constant-velocity windows): in CSP (mode 8) from the 0x607A targets
//! ([`super::windows::set_velocity_from_demand`]: a PLC's targets are whole units, so a speed
//! of 16.7 units per cycle comes as steps of 16 and 17); in CSV and PV (modes 9, 3) 0x60FF;
//! otherwise 0 (no window). Not 0x606B: in our drive, as in many, the velocity demand is the
//! position controller's output, which carries the limit cycle itself. The mode is the mode
//! display 0x6061, else the last confirmed SDO write to 0x6060.

use super::detector::AxisTrace;
use anyhow::{bail, Context, Result};
use drive_protocol::{CanFrame, Drive, Node};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// Default COB-ID of SYNC.
pub const SYNC_COB_ID: u32 = 0x080;
/// A SYNC interval longer than this many periods counts as a gap.
const GAP_PERIODS: f64 = 1.5;
/// 0x1006 is used unless the measured SYNC interval differs from it by more than this.
const PERIOD_AGREEMENT: f64 = 0.10;

// ------------------------------------------------------------------------------------------
// Line parser

/// What a log line holds, besides a standard data frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameKind {
    /// A standard-ID (11-bit) data frame: the CANopen traffic we decode.
    Data(CanFrame),
    /// A remote (RTR) frame.
    Remote { id: u32 },
    /// An error frame (CAN_ERR_FLAG set in the ID).
    Error,
    /// A 29-bit identifier.
    Extended { id: u32 },
    /// A CAN FD frame.
    Fd { id: u32 },
}

/// One frame of the log, timestamp in microseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LogFrame {
    pub t_us: i64,
    pub kind: FrameKind,
}

/// True when the first line that is neither empty nor a `#` comment starts with `(`: a candump
/// log with timestamps rather than a CSV trace.
pub fn looks_like_candump(text: &str) -> bool {
    text.lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .is_some_and(|l| l.starts_with('('))
}

/// Parse one line of `candump -L` or `candump -ta` output. `Ok(None)` for an empty line or a
/// `#` comment; the error is the reason, without file and line.
pub fn parse_line(line: &str) -> Result<Option<LogFrame>, String> {
    let s = line.trim();
    if s.is_empty() || s.starts_with('#') {
        return Ok(None);
    }
    let rest = s
        .strip_prefix('(')
        .ok_or("expected `(timestamp)` at the start of the line (candump -L or -ta)")?;
    let (ts, rest) = rest
        .split_once(')')
        .ok_or("timestamp without closing `)`")?;
    let t_us = parse_timestamp(ts)?;
    let mut tokens = rest.split_whitespace();
    let _iface = tokens
        .next()
        .ok_or("no interface name after the timestamp")?;
    let frame = tokens
        .next()
        .ok_or("no CAN frame after the interface name")?;
    let kind = match frame.split_once('#') {
        Some((id, data)) => {
            // candump -L; newer can-utils may append a direction flag.
            match (tokens.next(), tokens.next()) {
                (None, _) | (Some("T" | "R"), None) => {}
                (Some(t), _) => return Err(format!("unexpected `{t}` after the frame")),
            }
            parse_compact(id, data)?
        }
        None => parse_columns(frame, &mut tokens)?,
    };
    Ok(Some(LogFrame { t_us, kind }))
}

/// `1700000000.123456` -> microseconds. More than 6 decimals are truncated.
fn parse_timestamp(ts: &str) -> Result<i64, String> {
    let bad = || format!("bad timestamp `({ts})`: seconds.microseconds expected (candump -t a)");
    let (secs, frac) = ts.split_once('.').ok_or_else(bad)?;
    let digits = |s: &str, max: usize| {
        !s.is_empty() && s.len() <= max && s.bytes().all(|b| b.is_ascii_digit())
    };
    if !digits(secs, 12) || !digits(frac, 9) {
        return Err(bad());
    }
    let secs: i64 = secs.parse().map_err(|_| bad())?;
    let mut us: i64 = 0;
    for k in 0..6 {
        let d = frac.as_bytes().get(k).map_or(0, |b| i64::from(b - b'0'));
        us = us * 10 + d;
    }
    secs.checked_mul(1_000_000)
        .and_then(|s| s.checked_add(us))
        .ok_or_else(bad)
}

fn is_hex(s: &str) -> bool {
    !s.is_empty() && s.bytes().all(|b| b.is_ascii_hexdigit())
}

enum IdKind {
    Standard(u32),
    Extended(u32),
    Error,
}

/// 3 hex digits: standard; 8: extended, or an error frame when CAN_ERR_FLAG is set.
fn parse_id(s: &str) -> Result<IdKind, String> {
    let bad = || format!("bad CAN ID `{s}`: 3 hex digits (11-bit) or 8 (29-bit) expected");
    if !is_hex(s) {
        return Err(bad());
    }
    let v = u32::from_str_radix(s, 16).map_err(|_| bad())?;
    match s.len() {
        3 if v <= 0x7FF => Ok(IdKind::Standard(v)),
        3 => Err(format!("CAN ID `{s}` above 0x7FF")),
        8 if v & 0x2000_0000 != 0 => Ok(IdKind::Error),
        8 if v <= 0x1FFF_FFFF => Ok(IdKind::Extended(v)),
        _ => Err(bad()),
    }
}

fn hex_byte(s: &str) -> Result<u8, String> {
    if s.len() != 2 || !is_hex(s) {
        return Err(format!("bad data byte `{s}`: two hex digits expected"));
    }
    u8::from_str_radix(s, 16).map_err(|_| format!("bad data byte `{s}`"))
}

/// `ID#DATA` (candump -L).
fn parse_compact(id: &str, data: &str) -> Result<FrameKind, String> {
    let id = parse_id(id)?;
    if let Some(fd) = data.strip_prefix('#') {
        // CAN FD: a flags nibble, then up to 64 bytes.
        let body = fd.get(1..).unwrap_or("");
        let flags_ok = fd.get(..1).is_some_and(is_hex);
        if !flags_ok
            || !body.len().is_multiple_of(2)
            || body.len() > 128
            || !body.bytes().all(|b| b.is_ascii_hexdigit())
        {
            return Err(format!("bad CAN FD frame data `##{fd}`"));
        }
        return Ok(match id {
            IdKind::Standard(i) | IdKind::Extended(i) => FrameKind::Fd { id: i },
            IdKind::Error => FrameKind::Error,
        });
    }
    if let Some(r) = data.strip_prefix(['R', 'r']) {
        if !(r.is_empty() || (r.len() == 1 && r.bytes().all(|b| (b'0'..=b'8').contains(&b)))) {
            return Err(format!(
                "bad remote frame `#{data}`: `R` or `R0`..`R8` expected"
            ));
        }
        return Ok(match id {
            IdKind::Standard(i) | IdKind::Extended(i) => FrameKind::Remote { id: i },
            IdKind::Error => FrameKind::Error,
        });
    }
    // Optional `_X`: the raw DLC 9..F of an 8-byte classic frame (len8_dlc).
    let (hex, raw_dlc) = match data.split_once('_') {
        Some((h, d)) => (h, Some(d)),
        None => (data, None),
    };
    let hex: String = hex.chars().filter(|&c| c != '.').collect();
    if !hex.len().is_multiple_of(2) {
        return Err(format!("odd number of hex digits in data `{data}`"));
    }
    if hex.len() > 16 {
        return Err(format!(
            "{} data bytes in `{data}`: a classic CAN frame has at most 8",
            hex.len() / 2
        ));
    }
    let mut bytes = [0u8; 8];
    for (k, b) in bytes.iter_mut().enumerate().take(hex.len() / 2) {
        *b = hex_byte(hex.get(2 * k..2 * k + 2).unwrap_or(""))?;
    }
    let len = hex.len() / 2;
    if let Some(d) = raw_dlc {
        let ok = d.len() == 1
            && u8::from_str_radix(d, 16).is_ok_and(|v| (9..=15).contains(&v))
            && len == 8;
        if !ok {
            return Err(format!("bad raw DLC suffix `_{d}` in `{data}`"));
        }
    }
    let payload = bytes.get(..len).unwrap_or(&[]);
    Ok(match id {
        IdKind::Standard(i) => FrameKind::Data(CanFrame::new(i, payload)),
        IdKind::Extended(i) => FrameKind::Extended { id: i },
        IdKind::Error => FrameKind::Error,
    })
}

/// `ID [n] B0 B1 ...` (candump default columns, with -ta).
fn parse_columns<'a>(
    id: &str,
    tokens: &mut impl Iterator<Item = &'a str>,
) -> Result<FrameKind, String> {
    let id = parse_id(id)?;
    let dlc_tok = tokens.next().ok_or("no `[len]` after the CAN ID")?;
    let dlc_str = dlc_tok
        .strip_prefix('[')
        .and_then(|d| d.strip_suffix(']'))
        .filter(|d| !d.is_empty() && d.len() <= 2 && d.bytes().all(|b| b.is_ascii_digit()))
        .ok_or_else(|| format!("bad length `{dlc_tok}`: `[0]`..`[8]` expected"))?;
    let dlc: usize = dlc_str
        .parse()
        .map_err(|_| format!("bad length `{dlc_tok}`"))?;
    if dlc_str.len() == 2 {
        // candump prints a CAN FD frame's length with two digits (`[02]`, `[64]`).
        if dlc > 64 {
            return Err(format!("CAN FD length {dlc} > 64"));
        }
        for _ in 0..dlc {
            hex_byte(
                tokens
                    .next()
                    .ok_or("CAN FD frame shorter than its length")?,
            )?;
        }
        return Ok(match id {
            IdKind::Standard(i) | IdKind::Extended(i) => FrameKind::Fd { id: i },
            IdKind::Error => FrameKind::Error,
        });
    }
    if dlc > 8 {
        return Err(format!(
            "length {dlc} > 8: a classic CAN frame has at most 8 bytes"
        ));
    }
    let mut bytes = [0u8; 8];
    let mut rest: Vec<&str> = Vec::new();
    let mut n = 0;
    for t in tokens.by_ref() {
        if n < dlc && t != "remote" {
            bytes[n] = hex_byte(t)?;
            n += 1;
        } else {
            rest.push(t);
            break;
        }
    }
    let remote = rest.first() == Some(&"remote");
    if remote {
        if tokens.next() != Some("request") {
            return Err("`remote` without `request`".into());
        }
    } else if n < dlc {
        return Err(format!("{n} data bytes, length says {dlc}"));
    }
    // What may follow: the -a ASCII column, or ERRORFRAME.
    let tail = if remote {
        tokens.next()
    } else {
        rest.first().copied()
    };
    let error_word = tail == Some("ERRORFRAME");
    if let Some(t) = tail {
        if !(t.starts_with('\'') || error_word) {
            return Err(format!("unexpected `{t}` after {dlc} data bytes"));
        }
    }
    Ok(match id {
        IdKind::Error => FrameKind::Error,
        IdKind::Standard(i) | IdKind::Extended(i) if remote => FrameKind::Remote { id: i },
        IdKind::Standard(_) if error_word => FrameKind::Error,
        IdKind::Standard(i) => FrameKind::Data(CanFrame::new(i, bytes.get(..dlc).unwrap_or(&[]))),
        IdKind::Extended(i) => FrameKind::Extended { id: i },
    })
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
}

impl PdoMapping {
    pub fn valid(&self) -> bool {
        self.cob_id & 0x8000_0000 == 0
    }
    /// The 11-bit identifier.
    pub fn cob(&self) -> u32 {
        self.cob_id & 0x7FF
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
        })
    }

    /// The defaults of our drive for `preset` as node `node_id`; also whether the axis is
    /// rotary (user unit 0.001 deg) or linear (1 um).
    pub fn drive_defaults(node_id: u8, preset: &str) -> Result<(Self, bool)> {
        let cfg = crate::presets::AxisConfig::from_preset(preset)
            .map_err(|e| anyhow::anyhow!("preset {preset}: {e}"))?;
        let drive = crate::runtime::axis_drive::AxisDrive::from_config(&cfg)
            .map_err(|e| anyhow::anyhow!("preset {preset}: {e}"))?;
        let info = drive.info();
        let node = Node::new(node_id, info).map_err(|e| anyhow::anyhow!("node {node_id}: {e}"))?;
        Ok((Self::from_node(&node)?, info.rotary))
    }

    /// Apply a confirmed write; false if the object is not part of the PDO configuration.
    fn write(&mut self, index: u16, sub: u8, value: u32) -> bool {
        let slot = |base: u16| usize::from(index.wrapping_sub(base));
        match (index, sub) {
            (0x1006, 0) => self.cycle_period_us = value,
            (0x1400..=0x1403, 1) => self.rpdo[slot(0x1400)].cob_id = value,
            (0x1800..=0x1803, 1) => self.tpdo[slot(0x1800)].cob_id = value,
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

    fn slot(self) -> usize {
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
    /// Segmented or block SDO downloads (not followed).
    pub sdo_not_expedited: usize,
    pub nmt_resets: usize,
    /// SYNC intervals longer than 1.5 periods.
    pub sync_gaps: usize,
    /// Frames whose timestamp is earlier than the previous frame's.
    pub timestamps_backwards: usize,
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
    /// One per SYNC; sample k is at `k * period_us`.
    pub samples: Vec<BusSample>,
    pub period_us: u32,
    pub period_source: PeriodSource,
    /// Median SYNC interval of the timestamps, us (None with fewer than two SYNCs).
    pub measured_period_us: Option<u32>,
    pub stats: DecodeStats,
    /// Warnings: missing objects replaced, gaps, ignored transfers.
    pub notes: Vec<String>,
    seen: [bool; N_OBJECTS],
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
    latest: [i64; N_OBJECTS],
    seen: [bool; N_OBJECTS],
    stats: DecodeStats,
    sync_t_us: Vec<i64>,
    samples: Vec<BusSample>,
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
            latest: [0; N_OBJECTS],
            seen: [false; N_OBJECTS],
            stats: DecodeStats::default(),
            sync_t_us: Vec::new(),
            samples: Vec::new(),
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
            if let [cmd @ (0x81 | 0x82), target, ..] = *d {
                if target == 0 || u32::from(target) == n {
                    self.reset(cmd == 0x81);
                }
            }
            return;
        }
        if f.id == SYNC_COB_ID && d.len() <= 1 {
            self.sync(t_us);
            return;
        }
        let pdo = self
            .cfg
            .tpdo
            .iter()
            .chain(self.cfg.rpdo.iter())
            .find(|p| p.valid() && p.cob() == f.id)
            .copied();
        if let Some(p) = pdo {
            self.stats.node_frames += 1;
            self.decode_pdo(&p, f);
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
    }

    fn decode_pdo(&mut self, p: &PdoMapping, f: &CanFrame) {
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
                self.latest[o.slot()] = if o.signed() {
                    sign_extend(v, bits)
                } else {
                    v as i64
                };
                self.seen[o.slot()] = true;
            }
        }
    }

    fn sdo_request(&mut self, d: &[u8]) {
        self.pending = None;
        let [cmd, i0, i1, sub, ..] = *d else {
            return;
        };
        match cmd >> 5 {
            // Initiate download.
            1 if cmd & 0x02 != 0 => {
                let unused = if cmd & 0x01 != 0 {
                    usize::from((cmd >> 2) & 0x03)
                } else {
                    0
                };
                let Some(bytes) = d.get(4..8 - unused) else {
                    return;
                };
                let mut v = [0u8; 4];
                for (dst, src) in v.iter_mut().zip(bytes) {
                    *dst = *src;
                }
                self.pending = Some(PendingWrite {
                    index: u16::from_le_bytes([i0, i1]),
                    sub,
                    value: u32::from_le_bytes(v),
                });
            }
            1 | 6 => self.stats.sdo_not_expedited += 1,
            _ => {}
        }
    }

    fn sdo_response(&mut self, d: &[u8]) {
        let [cmd, i0, i1, sub, ..] = *d else {
            return;
        };
        let Some(p) = self.pending else {
            return;
        };
        if p.index != u16::from_le_bytes([i0, i1]) || p.sub != sub {
            return;
        }
        match cmd {
            0x60 => {
                self.pending = None;
                self.stats.sdo_writes_confirmed += 1;
                if self.cfg.write(p.index, p.sub, p.value) {
                    self.stats.pdo_config_writes += 1;
                } else if (p.index, p.sub) == (0x6060, 0) {
                    self.mode_written = Some(p.value as u8 as i8);
                }
            }
            0x80 => {
                self.pending = None;
                self.stats.sdo_writes_aborted += 1;
            }
            _ => {}
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

/// Decode a candump log (`text`, named `source` in messages) for one node.
pub fn decode(text: &str, source: &str, opts: &DecodeOptions) -> Result<BusLog> {
    if !(1..=127).contains(&opts.node_id) {
        bail!("node {} outside 1..=127", opts.node_id);
    }
    let mut dec = Decoder::new(opts.node_id, &opts.defaults);
    let mut after_error_frame = false;
    for (i, line) in text.lines().enumerate() {
        dec.stats.lines += 1;
        // candump -e prints an error frame's explanation on lines starting with a tab.
        if after_error_frame && line.starts_with('\t') {
            continue;
        }
        let parsed = parse_line(line).map_err(|e| anyhow::anyhow!("{source}:{}: {e}", i + 1))?;
        if let Some(f) = parsed {
            after_error_frame = f.kind == FrameKind::Error;
            dec.record(&f);
        }
    }
    let n = opts.node_id;
    let st = dec.stats;
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
    let mut notes = Vec::new();
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
    let gap_us = GAP_PERIODS * f64::from(period_us);
    let mut stats = dec.stats;
    stats.sync_gaps = dec
        .sync_t_us
        .windows(2)
        .filter(|w| (w[1] - w[0]) as f64 > gap_us)
        .count();
    if stats.sync_gaps > 0 {
        notes.push(format!(
            "{} SYNC intervals longer than {GAP_PERIODS} periods (lost SYNCs or a gap in the \
             log); the time base k * period does not show them",
            stats.sync_gaps
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
    let seen = dec.seen;
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
    Ok(BusLog {
        source: source.to_string(),
        node_id: n,
        samples: dec.samples,
        period_us,
        period_source,
        measured_period_us: measured,
        stats,
        notes,
        seen,
        other_ids: dec.other_ids,
    })
}

impl BusLog {
    /// Whether an object was decoded at least once.
    pub fn seen(&self, o: Object) -> bool {
        self.seen[o.slot()]
    }

    /// Time of sample k, s.
    pub fn t_s(&self, k: usize) -> f64 {
        k as f64 * f64::from(self.period_us) * 1e-6
    }

    /// The set velocity per sample, uu/s (see the module doc), or an error naming what the log
    /// lacks when it holds no set-point at all.
    pub fn set_velocity_uu_s(&self) -> Result<Vec<f64>> {
        use crate::master::{MODE_CSP, MODE_CSV, MODE_PV};
        let (mut csp, mut csv) = (0usize, 0usize);
        // The CSP targets as a demand series (holding the last one where a sample has none).
        let mut last = 0.0;
        let targets: Vec<f64> = self
            .samples
            .iter()
            .map(|s| {
                if let Some(t) = s.target_position_uu {
                    last = f64::from(t);
                }
                last
            })
            .collect();
        let t: Vec<f64> = (0..self.samples.len()).map(|k| self.t_s(k)).collect();
        let from_targets =
            super::windows::set_velocity_from_demand(&t, &targets, super::windows::DEMAND_SPAN_S);
        let mut out = Vec::with_capacity(self.samples.len());
        for (s, v_csp) in self.samples.iter().zip(from_targets) {
            let v = match (s.mode, s.target_position_uu, s.target_velocity_uu_s) {
                (Some(MODE_CSP), Some(_), _) => {
                    csp += 1;
                    v_csp
                }
                (Some(MODE_CSV | MODE_PV), _, Some(v)) => {
                    csv += 1;
                    f64::from(v)
                }
                _ => 0.0,
            };
            out.push(v);
        }
        if csp == 0 && csv == 0 {
            let modes: std::collections::BTreeSet<i8> =
                self.samples.iter().filter_map(|s| s.mode).collect();
            let modes = if modes.is_empty() {
                "the mode is unknown (0x6061 not mapped, no SDO write to 0x6060)".to_string()
            } else {
                format!(
                    "modes seen: {}",
                    modes
                        .iter()
                        .map(|m| m.to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            };
            let seen = |o: Object| {
                if self.seen(o) {
                    "seen"
                } else {
                    "never in an RPDO"
                }
            };
            bail!(
                "{}: node {}: no set-point in the log, the constant-velocity windows cannot be \
                 found: needs {} in CSP (mode 8) [{}], or {} in CSV or PV (mode 9, 3) [{}]; \
                 {modes}",
                self.source,
                self.node_id,
                Object::TargetPosition.name(),
                seen(Object::TargetPosition),
                Object::TargetVelocity.name(),
                seen(Object::TargetVelocity),
            );
        }
        Ok(out)
    }

    /// The detector's trace (user units: um or mdeg, velocities in uu/s, current in per mille).
    pub fn to_axis_trace(&self, rotary: bool) -> Result<AxisTrace> {
        if !self.seen(Object::Velocity) {
            let mut missing = vec![Object::Velocity.name()];
            if !self.seen(Object::Current) {
                missing.push(Object::Current.name());
            }
            let decoded: Vec<&str> = Object::ALL
                .iter()
                .filter(|o| self.seen(**o))
                .map(|o| o.name())
                .collect();
            bail!(
                "{}: node {}: {} never in a PDO of the log (decoded: {}); the detector needs the \
                 motor speed (and current): map them into a TPDO",
                self.source,
                self.node_id,
                missing.join(" and "),
                if decoded.is_empty() {
                    "nothing".to_string()
                } else {
                    decoded.join(", ")
                }
            );
        }
        let set_velocity = self.set_velocity_uu_s()?;
        let col = |f: fn(&BusSample) -> f64| self.samples.iter().map(f).collect::<Vec<f64>>();
        let position = col(|s| f64::from(s.position_uu));
        let direct = col(|s| f64::from(s.direct_position_uu));
        let (motor_position, direct_position) = match (
            self.seen(Object::Position),
            self.seen(Object::DirectPosition),
        ) {
            (true, true) | (false, false) => (position, direct),
            (true, false) => (position.clone(), position),
            (false, true) => (direct.clone(), direct),
        };
        let tr = AxisTrace {
            t_s: (0..self.samples.len()).map(|k| self.t_s(k)).collect(),
            set_velocity,
            motor_velocity: col(|s| f64::from(s.velocity_uu_s)),
            current: col(|s| f64::from(s.current_permille)),
            motor_position,
            direct_position,
            position_unit: if rotary { "mdeg" } else { "um" }.into(),
            current_unit: "permille".into(),
        };
        tr.check()
            .map_err(|e| anyhow::anyhow!("{}: {e}", self.source))?;
        Ok(tr)
    }

    /// One paragraph for the terminal: what was in the log and what was decoded.
    pub fn summary(&self) -> String {
        let s = &self.stats;
        let mut out = format!(
            "candump: {} lines, {} frames; node {}: {} frames ({} PDOs decoded, {} PDO \
             configuration writes followed, {} SDO aborts, {} NMT resets); {} SYNCs -> {} \
             samples every {} us ({}); {} frames of other COB-IDs; skipped {} RTR, {} error, {} \
             extended-ID, {} CAN FD frames",
            s.lines,
            s.frames,
            self.node_id,
            s.node_frames,
            s.pdos_decoded,
            s.pdo_config_writes,
            s.sdo_writes_aborted,
            s.nmt_resets,
            s.syncs,
            self.samples.len(),
            self.period_us,
            self.period_source.as_str(),
            s.unknown_frames,
            s.remote_frames,
            s.error_frames,
            s.extended_frames,
            s.fd_frames
        );
        for n in &self.notes {
            let _ = write!(out, "\n  note: {n}");
        }
        out
    }
}

/// Read a candump log and build the detector's trace for node `node_id` of our drive with
/// `preset`. `rotary` forces rotary units; the preset decides otherwise.
pub fn trace_from_candump(
    path: &Path,
    text: &str,
    node_id: u8,
    preset: &str,
    sync_period_us: Option<u32>,
    rotary: bool,
) -> Result<(AxisTrace, BusLog)> {
    let (defaults, preset_rotary) = PdoConfig::drive_defaults(node_id, preset)?;
    let log = decode(
        text,
        &path.display().to_string(),
        &DecodeOptions {
            node_id,
            defaults,
            sync_period_us,
        },
    )?;
    let tr = log.to_axis_trace(rotary || preset_rotary)?;
    Ok((tr, log))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(line: &str) -> CanFrame {
        match parse_line(line).unwrap().unwrap().kind {
            FrameKind::Data(f) => f,
            k => panic!("{k:?}"),
        }
    }

    #[test]
    fn reads_the_log_format() {
        let f = parse_line("(1700000000.123456) vcan0 185#0102030405060708")
            .unwrap()
            .unwrap();
        assert_eq!(f.t_us, 1_700_000_000_123_456);
        assert_eq!(
            f.kind,
            FrameKind::Data(CanFrame::new(0x185, &[1, 2, 3, 4, 5, 6, 7, 8]))
        );
        assert_eq!(data("(0.5) can0 080#").len, 0);
        assert_eq!(
            parse_line("(0.5) can0 080#").unwrap().unwrap().t_us,
            500_000
        );
        assert_eq!(data("(1.000001) can0 7ff#aB").payload(), &[0xAB]);
        assert_eq!(data("(1.0) can0 123#11.22 T").payload(), &[0x11, 0x22]);
        assert_eq!(
            data("(1.0) can0 123#1122334455667788_C").payload(),
            &[0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88]
        );
    }

    #[test]
    fn reads_the_column_format() {
        let f = parse_line(" (1700000000.123456)  vcan0  185   [8]  01 02 03 04 05 06 07 08")
            .unwrap()
            .unwrap();
        assert_eq!(f.t_us, 1_700_000_000_123_456);
        assert_eq!(
            f.kind,
            FrameKind::Data(CanFrame::new(0x185, &[1, 2, 3, 4, 5, 6, 7, 8]))
        );
        assert_eq!(data(" (1.0)  vcan0  080   [0] ").len, 0);
        assert_eq!(
            data(" (1.0)  vcan0  285   [2]  0A FF   '..'").payload(),
            &[0x0A, 0xFF]
        );
    }

    #[test]
    fn reads_what_can_utils_log2long_prints() {
        // `log2long` (can-utils) output for a -L log: the same columns as `candump -ta`.
        let kinds: Vec<FrameKind> = [
            "(1700000000.123456)  vcan0       185   [8]  01 02 03 04 05 06 07 08   '........'",
            "(1700000000.123460)  vcan0       080   [0]                            ''",
            "(1700000000.123470)  vcan0       705   [0]  remote request",
            "(1700000000.123480)  vcan0  12345678   [2]  01 02                     '..'",
            "(1700000000.123490)  vcan0  20000004   [8]  00 04 00 00 00 00 00 00   ERRORFRAME",
            "(1700000000.123500)  vcan0       123  [02]  AA BB                     '..'",
        ]
        .iter()
        .map(|l| parse_line(l).unwrap().unwrap().kind)
        .collect();
        assert_eq!(
            kinds,
            [
                FrameKind::Data(CanFrame::new(0x185, &[1, 2, 3, 4, 5, 6, 7, 8])),
                FrameKind::Data(CanFrame::new(0x080, &[])),
                FrameKind::Remote { id: 0x705 },
                FrameKind::Extended { id: 0x1234_5678 },
                FrameKind::Error,
                FrameKind::Fd { id: 0x123 },
            ]
        );
    }

    #[test]
    fn skips_remote_error_extended_and_fd_frames() {
        let kind = |l: &str| parse_line(l).unwrap().unwrap().kind;
        assert_eq!(kind("(1.0) can0 705#R"), FrameKind::Remote { id: 0x705 });
        assert_eq!(kind("(1.0) can0 705#R1"), FrameKind::Remote { id: 0x705 });
        assert_eq!(
            kind(" (1.0)  can0  705   [1]  remote request"),
            FrameKind::Remote { id: 0x705 }
        );
        assert_eq!(
            kind("(1.0) can0 20000004#0004000000000000"),
            FrameKind::Error
        );
        assert_eq!(
            kind(" (1.0)  can0  20000004   [8]  00 04 00 00 00 00 00 00   ERRORFRAME"),
            FrameKind::Error
        );
        assert_eq!(
            kind("(1.0) can0 12345678#00"),
            FrameKind::Extended { id: 0x1234_5678 }
        );
        assert_eq!(
            kind(" (1.0)  can0  12345678   [1]  00"),
            FrameKind::Extended { id: 0x1234_5678 }
        );
        assert_eq!(kind("(1.0) can0 123##1AABB"), FrameKind::Fd { id: 0x123 });
        assert_eq!(parse_line("   ").unwrap(), None);
        assert_eq!(parse_line("# comment").unwrap(), None);
    }

    #[test]
    fn rejects_malformed_lines_with_a_reason() {
        let err = |l: &str| parse_line(l).unwrap_err();
        assert!(
            err("(1.0) can0 185#0G").contains("0G"),
            "{}",
            err("(1.0) can0 185#0G")
        );
        assert!(err("(1.0) can0 185#012").contains("odd"));
        assert!(err("(1.0) can0 185#010203040506070809").contains("at most 8"));
        assert!(err(" (1.0)  can0  185   [9]  01 02 03 04 05 06 07 08 09").contains("> 8"));
        assert!(err(" (1.0)  can0  185  [65]  01").contains("> 64"));
        assert!(err(" (1.0)  can0  185  [12]  01 02").contains("shorter"));
        assert!(err(" (1.0)  can0  185   [2]  01 XY").contains("XY"));
        assert!(err(" (1.0)  can0  185   [3]  01 02").contains("length says 3"));
        assert!(err(" (1.0)  can0  185   [1]  01 02").contains("unexpected `02`"));
        assert!(err("(1.0) can0 1G5#00").contains("CAN ID"));
        assert!(err("(1.0) can0 85#00").contains("CAN ID"));
        assert!(err("(1.0) can0 885#00").contains("above 0x7FF"));
        assert!(err("(1.0) can0 185#R9").contains("remote"));
        assert!(err("(x.0) can0 185#00").contains("timestamp"));
        assert!(err("(2023-11-14 22:13:20.123456) can0 185#00").contains("timestamp"));
        assert!(err("(1.0 can0 185#00").contains("`)`"));
        assert!(err("185#00").contains("timestamp"));
        assert!(err("(1.0) can0").contains("no CAN frame"));
        assert!(err("(1.0) can0 185#00 extra").contains("extra"));
        // Never panics on odd input.
        for l in [
            "(",
            "()",
            "(.)",
            "(1.)",
            "(1.0) c 1#",
            "(1.0) c ###",
            "(1.0) c 123#_",
            "(1.0) c 123 [",
            "(1.0) c 123 []",
            "(1.0) c 123 [1] é",
        ] {
            assert!(parse_line(l).is_err(), "{l}");
        }
    }

    #[test]
    fn sniffs_the_format_by_content() {
        assert!(looks_like_candump("\n# x\n (1.0)  can0  080   [0]\n"));
        assert!(!looks_like_candump("t_s,velocity_uu_s\n0,1\n"));
        assert!(!looks_like_candump(""));
    }

    fn defaults() -> PdoConfig {
        PdoConfig::drive_defaults(5, "cnc1").unwrap().0
    }

    #[test]
    fn defaults_come_from_the_drive_object_dictionary() {
        let d = defaults();
        assert_eq!(d.tpdo[0].cob_id, 0x185);
        assert_eq!(d.tpdo[1].mapped(), &[0x6041_0010, 0x6064_0020]);
        assert_eq!(d.rpdo[1].cob_id, 0x305);
        assert_eq!(d.rpdo[1].mapped(), &[0x6040_0010, 0x607A_0020]);
    }

    #[test]
    fn follows_confirmed_remaps_ignores_aborted_ones_and_resets() {
        // Remap TPDO2 (0x285) to velocity only; an aborted attempt to map position is ignored.
        let log = "\
(1.000000) can0 605#2F011A0000000000
(1.000100) can0 585#60011A0000000000
(1.000200) can0 605#23011A012000646000
(1.000300) can0 585#80011A0100000906
(1.000400) can0 605#23011A0120006C60
(1.000500) can0 585#60011A0100000000
(1.000600) can0 605#2F011A0001000000
(1.000700) can0 585#60011A0000000000
(1.001000) can0 285#E8030000
(1.001100) can0 080#
(1.002000) can0 000#8205
(1.002100) can0 285#7856341200100000
(1.002200) can0 080#
";
        // Line 3 has 9 data bytes: a strict parser refuses it, with its line number.
        let opts = DecodeOptions {
            node_id: 5,
            defaults: defaults(),
            sync_period_us: None,
        };
        let e = decode(log, "x.log", &opts).unwrap_err().to_string();
        assert!(e.starts_with("x.log:3:"), "{e}");
        let log = log.replace("605#23011A012000646000", "605#23011A0120006460");
        let r = decode(&log, "x.log", &opts).unwrap();
        assert_eq!(r.stats.sdo_writes_aborted, 1);
        assert_eq!(r.stats.pdo_config_writes, 3);
        assert_eq!(r.samples.len(), 2);
        assert_eq!(r.samples[0].velocity_uu_s, 1000);
        assert_eq!(r.samples[0].position_uu, 0);
        // After reset communication TPDO2 is statusword + position again.
        assert_eq!(r.samples[1].statusword, 0x5678);
        assert_eq!(r.samples[1].position_uu, 0x1000_1234);
        assert_eq!(r.samples[1].velocity_uu_s, 1000);
        assert_eq!(r.period_us, 1100);
        assert_eq!(r.period_source, PeriodSource::MedianSyncInterval);
    }

    #[test]
    fn sign_extends_short_fields() {
        assert_eq!(sign_extend(0xFFFF, 16), -1);
        assert_eq!(sign_extend(0x7FFF, 16), 0x7FFF);
        assert_eq!(sign_extend(0x80, 8), -128);
        assert_eq!(sign_extend(0xFFFF_FFFF, 32), -1);
    }
}
