//! Vendor behaviour switches (docs/quirks.md): how a real drive departs from the letter of
//! CiA 301 / CiA 402 in ways that break masters. Every switch is off in [`Quirks::default`]
//! (the strict drive); a profile (the emulator's `profiles/*.toml`) turns some on.
//!
//! This file holds the switches as the node is configured with them ([`Quirks`], in
//! [`crate::NodeConfig::quirks`]) and the little state they need while the node runs
//! ([`QuirkState`], [`ControlwordLatch`]): fixed-size fields and arrays sized when the node is
//! built, so nothing here allocates or locks on the tick. The node calls the hooks of
//! docs/quirks.md section 5 from `node.rs`, the CiA 402 ones from `cia402/mod.rs`.

use heapless::{Deque, Vec as HVec};

pub mod schema;

use schema::{params, Kind, Param, Params, Range, Switch, SwitchField, Word, Written};

use crate::frame::CanFrame;
use crate::od::ObjectDictionary;
use crate::wire::sdo::SdoRequest;

/// Most ranges an object list holds.
pub const MAX_OBJECT_RANGES: usize = 16;
/// Most modes `sync_watchdog` watches.
pub const MAX_WATCHED_MODES: usize = 16;
/// SDO answers the delay queue of `sdo_response_delay` holds; more are dropped and counted
/// with the transmit queue's overflows.
pub const SDO_DELAY_QUEUE: usize = 64;

/// A set of objects: a range of indices and a range of sub-indices (`"0x1800-0x1803:5"`,
/// `"0x6061:0"`, `"0x1A00:1-8"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ObjectRange {
    /// First index.
    pub index_lo: u16,
    /// Last index (inclusive).
    pub index_hi: u16,
    /// First sub-index.
    pub sub_lo: u8,
    /// Last sub-index (inclusive).
    pub sub_hi: u8,
}

fn parse_number(s: &str) -> Option<u64> {
    let t = s.trim();
    if let Some(h) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        u64::from_str_radix(h, 16).ok()
    } else {
        t.parse().ok()
    }
}

impl ObjectRange {
    /// Parse `"0xIIII:S"`, `"0xIIII-0xJJJJ:S"` or `"0xIIII:S-T"` (hex with 0x, or decimal).
    /// The error says why, in words a profile's error message can quote.
    pub fn parse(text: &str) -> Result<ObjectRange, String> {
        let Some((idx, sub)) = text.split_once(':') else {
            return Err(format!(
                "{text:?}: not an object (write \"0xIIII:S\", \"0xIIII-0xJJJJ:S\" or \"0xIIII:S-T\")"
            ));
        };
        let range = |part: &str, max: u64, what: &str| -> Result<(u64, u64), String> {
            let (a, b) = match part.split_once('-') {
                Some((a, b)) => (a, b),
                None => (part, part),
            };
            let num = |s: &str| {
                parse_number(s).filter(|&v| v <= max).ok_or_else(|| {
                    format!(
                        "{text:?}: {what} {:?} is not a number 0..={max:#x}",
                        s.trim()
                    )
                })
            };
            let (lo, hi) = (num(a)?, num(b)?);
            if hi < lo {
                return Err(format!("{text:?}: {what} range end below start"));
            }
            Ok((lo, hi))
        };
        let (index_lo, index_hi) = range(idx, 0xFFFF, "index")?;
        let (sub_lo, sub_hi) = range(sub, 0xFF, "sub-index")?;
        Ok(ObjectRange {
            index_lo: index_lo as u16,
            index_hi: index_hi as u16,
            sub_lo: sub_lo as u8,
            sub_hi: sub_hi as u8,
        })
    }

    /// Whether (index, sub) is in the range.
    pub fn contains(&self, index: u16, sub: u8) -> bool {
        (self.index_lo..=self.index_hi).contains(&index)
            && (self.sub_lo..=self.sub_hi).contains(&sub)
    }
}

impl core::fmt::Display for ObjectRange {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "0x{:04X}", self.index_lo)?;
        if self.index_hi != self.index_lo {
            write!(f, "-0x{:04X}", self.index_hi)?;
        }
        write!(f, ":{}", self.sub_lo)?;
        if self.sub_hi != self.sub_lo {
            write!(f, "-{}", self.sub_hi)?;
        }
        Ok(())
    }
}

/// A list of object ranges, parsed at start-up into a fixed array.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ObjectList(pub HVec<ObjectRange, MAX_OBJECT_RANGES>);

impl ObjectList {
    /// Parse every entry ([`ObjectRange::parse`]); at most [`MAX_OBJECT_RANGES`].
    pub fn parse<S: AsRef<str>>(items: &[S]) -> Result<ObjectList, String> {
        let mut l = HVec::new();
        for s in items {
            let r = ObjectRange::parse(s.as_ref())?;
            l.push(r).map_err(|_| {
                format!("more than {MAX_OBJECT_RANGES} entries (write ranges: \"0x1800-0x1803:5\")")
            })?;
        }
        Ok(ObjectList(l))
    }

    /// Whether any range holds (index, sub).
    pub fn contains(&self, index: u16, sub: u8) -> bool {
        self.0.iter().any(|r| r.contains(index, sub))
    }

    /// No entry.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl core::fmt::Display for ObjectList {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for (i, r) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{r}")?;
        }
        Ok(())
    }
}

/// `homing_status_bits_missing`: which statusword bits homing never sets (3.3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HomingBitsMissing {
    /// Bit 10, target reached.
    pub target_reached: bool,
    /// Bit 12, homing attained.
    pub attained: bool,
}

impl HomingBitsMissing {
    /// The statusword bits cleared in HM.
    pub fn mask(&self) -> u16 {
        (u16::from(self.target_reached) << 10) | (u16::from(self.attained) << 12)
    }
}

/// `homing_method_zero`: what a write of 0 to 0x6098 does (3.4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HomingMethodZero {
    /// Stored like any value (CiA 402: "no homing method assigned"); strict.
    #[default]
    Store,
    /// Confirmed and not stored: the method stays (FAULHABER).
    Ignore,
    /// Aborted 0x06090030, an RPDO's 0 refused with EMCY 0x6320 (maxon EPOS4).
    Refuse,
}

impl HomingMethodZero {
    /// The profile's word for it.
    pub fn name(self) -> &'static str {
        <Self as Word>::WORDS[self as usize]
    }
}

/// Where `sync_watchdog` takes its period from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WatchdogPeriod {
    /// The interpolation time period 0x60C2, else 0x1006.
    #[default]
    Interpolation,
    /// The communication cycle period 0x1006.
    CommunicationCycle,
}

impl WatchdogPeriod {
    /// The profile's word for it.
    pub fn name(self) -> &'static str {
        <Self as Word>::WORDS[self as usize]
    }
}

const U16: i64 = u16::MAX as i64;
const U32: i64 = u32::MAX as i64;

// The parameters of the switches: each declared once, with its doc, default and range
// (`params!`, schema.rs); the profile reads them, `drive-emu profiles` and docs/quirks.md's
// table show them.

params! {
    /// `bootup_then_heartbeat` (3.5).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct BootupThenHeartbeat {
        /// Time from the boot-up to a first heartbeat, us.
        first_heartbeat_after_bootup_us: u32 = 100; schema::int(0, 1_000_000, "us"),
        /// 0x1017's default (the heartbeat producer runs from the boot), ms.
        heartbeat_ms_default: u16 = 100; schema::int(0, U16, "ms"),
    }
}

params! {
    /// `not_ready_after_bootup` (3.6).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct NotReadyAfterBootup {
        /// Time from the boot-up until the node is ready (heartbeat 0x7F, SDO answered), ms.
        ready_after_ms: u32 = 3000; schema::int(1, 600_000, "ms"),
        /// Heartbeat 0x00 period meanwhile, ms (0: none).
        initialising_heartbeat_ms: u16 = 100; schema::int(0, U16, "ms"),
    }
}

params! {
    /// `sdo_response_delay` (3.7).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct SdoResponseDelay {
        /// Delay of every answer, ms.
        delay_ms: u32 = 10; schema::int(0, 5000, "ms"),
        /// Delay of every `late_every`-th service's answers, ms.
        late_delay_ms: u32 = 0; schema::int(0, 5000, "ms"),
        /// Every n-th SDO service (counted from the boot) is late (0: never).
        late_every: u32 = 0; schema::int(0, U32, ""),
    }
}

params! {
    /// `sdo_first_upload_dropped` (3.8).
    #[derive(Clone, Debug, PartialEq, Eq)]
    pub struct SdoFirstUploadDropped {
        /// The objects whose first uploads get no answer.
        objects: ObjectList = ObjectList::parse(&["0x6061:0"]).unwrap_or_default(); Range::Objects,
        /// How many uploads of each, after every boot.
        count: u8 = 1; schema::int(1, 255, ""),
    }
}

params! {
    /// `tpdo_rtr_unsupported` (3.10).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct TpdoRtrUnsupported {
        /// Abort code of a TPDO COB-ID write with bit 30 clear.
        abort_code: u32 = 0x0609_0030; schema::code(U32, 8),
    }
}

params! {
    /// `controlword_min_hold` (3.11).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct ControlwordMinHold {
        /// A controlword value replaced within this time is never acted on, us.
        hold_us: u32 = 1000; schema::int(1, 100_000, "us"),
    }
}

params! {
    /// `sync_watchdog` (3.13).
    #[derive(Clone, Debug, PartialEq)]
    pub struct SyncWatchdog {
        /// Periods without SYNC before the alarm.
        missed_periods: f32 = 2.0; Range::Float { min: 1.0, max: 100.0 },
        /// The period's object: the interpolation time period 0x60C2 (else 0x1006), or 0x1006.
        period_from: WatchdogPeriod = WatchdogPeriod::Interpolation; Range::OneOf(<WatchdogPeriod as Word>::WORDS),
        /// The modes of operation (0x6061) in which SYNC is watched.
        modes: HVec<i8, MAX_WATCHED_MODES> = [7, 8].into_iter().collect(); Range::Modes,
        /// EMCY and 0x603F code of the alarm.
        emcy_code: u16 = 0x8100; schema::code(U16, 4),
    }
}

params! {
    /// `late_sync_statusword_bit15` (3.14).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct LateSyncBit15 {
        /// A SYNC later than last SYNC + 0x1006 + this sets statusword bit 15, us.
        late_tolerance_us: u32 = 200; schema::int(0, U32, "us"),
    }
}

params! {
    /// `homing_method_zero`'s table: the rule's one parameter.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct HomingMethodZeroRule {
        /// What a write of 0 to 0x6098 does: stored (strict), ignored (confirmed, not stored) or refused (abort 0x06090030).
        zero: HomingMethodZero = HomingMethodZero::Store; Range::OneOf(<HomingMethodZero as Word>::WORDS),
    }
}

/// A rule: always a value; off is its strict value, `store`.
impl SwitchField for HomingMethodZero {
    const PARAMS: &'static [Param] = HomingMethodZeroRule::PARAMS;
    fn from_written(w: Written<'_>) -> Result<Self, String> {
        Ok(w.map(HomingMethodZeroRule::from_written)
            .transpose()?
            .map_or(HomingMethodZero::Store, |r| r.zero))
    }
    fn on_values(&self) -> Option<Vec<(&'static str, String)>> {
        (*self != HomingMethodZero::Store).then(|| HomingMethodZeroRule { zero: *self }.values())
    }
}

params! {
    /// `homing_status_bits_missing`'s table.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct HomingBitsRule {
        /// The statusword bits homing never sets.
        bits: HomingBitsMissing = HomingBitsMissing { target_reached: false, attained: true }; Range::ListOf(&schema::HOMING_BITS),
    }
}

params! {
    /// The table of a switch that lists objects (`unmappable_objects`, `sdo_silent_objects`).
    #[derive(Clone, Debug, PartialEq, Eq)]
    pub struct ObjectsRule {
        /// The objects.
        objects: ObjectList; Range::Objects,
    }
}

/// `homing_status_bits_missing`: `None` is off.
impl SwitchField for Option<HomingBitsMissing> {
    const PARAMS: &'static [Param] = HomingBitsRule::PARAMS;
    fn from_written(w: Written<'_>) -> Result<Self, String> {
        Ok(w.map(HomingBitsRule::from_written)
            .transpose()?
            .map(|r| r.bits))
    }
    fn on_values(&self) -> Option<Vec<(&'static str, String)>> {
        self.map(|bits| HomingBitsRule { bits }.values())
    }
}

/// `unmappable_objects`, `sdo_silent_objects`: `None` is off.
impl SwitchField for Option<ObjectList> {
    const PARAMS: &'static [Param] = ObjectsRule::PARAMS;
    fn from_written(w: Written<'_>) -> Result<Self, String> {
        Ok(w.map(ObjectsRule::from_written)
            .transpose()?
            .map(|r| r.objects))
    }
    fn on_values(&self) -> Option<Vec<(&'static str, String)>> {
        self.as_ref()
            .map(|l| ObjectsRule { objects: l.clone() }.values())
    }
}

/// Declares the switches once: each a field of [`Quirks`] with its doc, section and kind;
/// generates [`Quirks`], [`QuirksPatch`] (what one profile writes), [`Quirks::SWITCHES`]
/// (the description every listing reads) and the serde side.
macro_rules! quirks {
    ($(
        $(#[doc = $doc:literal])+
        ($section:literal, $kind:ident) $f:ident : $T:ty,
    )*) => {
        /// The vendor behaviour switches of one node (docs/quirks.md, schema 1). All off
        /// ([`Quirks::default`]) is the strict drive. Read from a profile's `quirks` table
        /// with serde (an unknown switch or parameter is an error naming the nearest one).
        #[derive(Clone, Debug, Default, PartialEq)]
        pub struct Quirks {
            $( $(#[doc = $doc])+ pub $f: $T, )*
        }

        /// The switches one profile (or overlay) writes: `Some` for each `[quirks.NAME]`
        /// table, its whole setting; applied in order onto [`Quirks`]
        /// ([`QuirksPatch::apply_to`]).
        #[derive(Clone, Debug, Default, PartialEq)]
        pub struct QuirksPatch {
            $( $(#[doc = $doc])+ pub $f: Option<$T>, )*
        }

        impl Quirks {
            /// Every switch of schema 1, in the order of docs/quirks.md: the one description.
            pub const SWITCHES: &'static [Switch] = &[$(
                Switch {
                    name: stringify!($f),
                    section: $section,
                    kind: Kind::$kind,
                    doc: concat!($($doc),+),
                    params: <$T as SwitchField>::PARAMS,
                },
            )*];

            /// A switch (a name of [`Quirks::SWITCHES`]) that is on: its parameters as a
            /// profile writes them; `None` when it is off (its strict value) or unknown.
            pub fn on_values(&self, switch: &str) -> Option<Vec<(&'static str, String)>> {
                match switch {
                    $( stringify!($f) => self.$f.on_values(), )*
                    _ => None,
                }
            }
        }

        impl QuirksPatch {
            fn set(&mut self, i: usize, w: Written<'_>) -> Result<(), String> {
                let name = Quirks::SWITCHES[i].name;
                $(
                    if name == stringify!($f) {
                        self.$f = Some(<$T as SwitchField>::from_written(w)?);
                    }
                )*
                Ok(())
            }

            /// Set every switch it writes in `q` (its whole setting).
            pub fn apply_to(&self, q: &mut Quirks) {
                $( if let Some(v) = &self.$f { q.$f = v.clone(); } )*
            }

            /// The switches it writes, in [`Quirks::SWITCHES`] order.
            pub fn written(&self) -> Vec<&'static str> {
                let mut v = Vec::new();
                $( if self.$f.is_some() { v.push(stringify!($f)); } )*
                v
            }
        }
    };
}

quirks! {
    /// No transition 4 (OPERATION ENABLED) while 0x6060 is 0: enable stays in SWITCHED ON.
    ("3.1", Quirk) enable_requires_mode: bool,
    /// 0x6061 does not follow 0x6060 while controlword bit 8 (halt) is set.
    ("3.2", Quirk) mode_change_blocked_by_halt: bool,
    /// Homing never sets these statusword bits.
    ("3.3", Quirk) homing_status_bits_missing: Option<HomingBitsMissing>,
    /// What a write of 0 to 0x6098 does.
    ("3.4", Rule) homing_method_zero: HomingMethodZero,
    /// A heartbeat right after the boot-up hides it from a master watching the last state.
    ("3.5", Quirk) bootup_then_heartbeat: Option<BootupThenHeartbeat>,
    /// After the boot-up, heartbeat 0x00 and no SDO or NMT answer until ready.
    ("3.6", Quirk) not_ready_after_bootup: Option<NotReadyAfterBootup>,
    /// SDO answers leave late (every `late_every`-th service later still).
    ("3.7", Quirk) sdo_response_delay: Option<SdoResponseDelay>,
    /// The first uploads of these objects after each boot get no answer.
    ("3.8", Quirk) sdo_first_upload_dropped: Option<SdoFirstUploadDropped>,
    /// Mapping entries accepted while sub 0 != 0 (strict, Copley: abort 0x06010000).
    ("3.9", Rule) pdo_remap_lenient: bool,
    /// TPDO COB-IDs keep bit 30 (no RTR); a write clearing it is aborted.
    ("3.10", Quirk) tpdo_rtr_unsupported: Option<TpdoRtrUnsupported>,
    /// A controlword value replaced within `hold_us` is never acted on.
    ("3.11", Quirk) controlword_min_hold: Option<ControlwordMinHold>,
    /// A quick stop at standstill goes to SWITCH ON DISABLED without showing QUICK STOP ACTIVE.
    ("3.12", Quirk) quick_stop_skips_active_state: bool,
    /// A fault when SYNC is missing for `missed_periods` in OPERATION ENABLED in `modes`.
    ("3.13", Quirk) sync_watchdog: Option<SyncWatchdog>,
    /// Statusword bit 15 after a SYNC later than 0x1006 + `late_tolerance_us`.
    ("3.14", Quirk) late_sync_statusword_bit15: Option<LateSyncBit15>,
    /// Mapping entries naming these objects are aborted 0x06040041.
    ("3.15", Quirk) unmappable_objects: Option<ObjectList>,
    /// SDO requests for these objects get no answer at all.
    ("3.16", Quirk) sdo_silent_objects: Option<ObjectList>,
}

impl<'de> serde::Deserialize<'de> for QuirksPatch {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_map(schema::QuirksVisitor {
            switches: Quirks::SWITCHES,
            out: QuirksPatch::default(),
            set: |p: &mut QuirksPatch, i: usize, w: Written<'_>| p.set(i, w),
        })
    }
}

/// The switches of a `quirks` table onto the strict drive.
impl<'de> serde::Deserialize<'de> for Quirks {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let p = <QuirksPatch as serde::Deserialize>::deserialize(d)?;
        let mut q = Quirks::default();
        p.apply_to(&mut q);
        Ok(q)
    }
}

impl Quirks {
    /// Whether a switch (a name of [`Quirks::SWITCHES`]) is on; a rule is on when it is not
    /// its strict value.
    pub fn is_on(&self, switch: &str) -> bool {
        self.on_values(switch).is_some()
    }

    /// The switches that are on, in [`Quirks::SWITCHES`] order.
    pub fn on(&self) -> impl Iterator<Item = &'static str> + '_ {
        Quirks::SWITCHES
            .iter()
            .map(|s| s.name)
            .filter(|s| self.is_on(s))
    }

    /// No switch on: the strict drive.
    pub fn is_strict(&self) -> bool {
        self.on().next().is_none()
    }

    /// A switch for people: its name, and its parameters when it is on
    /// (`sdo_response_delay (delay_ms = 30, late_delay_ms = 0, late_every = 0)`).
    pub fn describe(&self, switch: &str) -> String {
        schema::describe(switch, &self.on_values(switch).unwrap_or_default())
    }

    /// The CiA 402 layer's part.
    pub(crate) fn cia402(&self) -> Cia402Quirks {
        Cia402Quirks {
            enable_requires_mode: self.enable_requires_mode,
            mode_change_blocked_by_halt: self.mode_change_blocked_by_halt,
            homing_hidden_bits: self.homing_status_bits_missing.map_or(0, |b| b.mask()),
            quick_stop_skips_active_state: self.quick_stop_skips_active_state,
        }
    }

    /// The PDO engine's part.
    pub(crate) fn pdo_rules(&self) -> PdoRules {
        PdoRules {
            lenient_remap: self.pdo_remap_lenient,
            no_rtr_abort: self.tpdo_rtr_unsupported.map(|t| t.abort_code),
            unmappable: self.unmappable_objects.clone().unwrap_or_default(),
        }
    }

    /// A switch that needs an object the dictionary lacks: (switch, index, sub).
    pub(crate) fn missing_object(&self, od: &ObjectDictionary) -> Option<(&'static str, u16, u8)> {
        if let Some(w) = &self.sync_watchdog {
            let (index, subs): (u16, &[u8]) = match w.period_from {
                WatchdogPeriod::Interpolation => (0x60C2, &[1, 2]),
                WatchdogPeriod::CommunicationCycle => (0x1006, &[0]),
            };
            for &sub in subs {
                if od.get(index, sub).is_none() {
                    return Some(("sync_watchdog", index, sub));
                }
            }
        }
        if self.late_sync_statusword_bit15.is_some() && od.get(0x1006, 0).is_none() {
            return Some(("late_sync_statusword_bit15", 0x1006, 0));
        }
        if self.homing_method_zero != HomingMethodZero::Store && od.get(0x6098, 0).is_none() {
            return Some(("homing_method_zero", 0x6098, 0));
        }
        None
    }
}

/// The switches the CiA 402 layer applies.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Cia402Quirks {
    pub enable_requires_mode: bool,
    pub mode_change_blocked_by_halt: bool,
    /// Statusword bits cleared while the mode is HM.
    pub homing_hidden_bits: u16,
    pub quick_stop_skips_active_state: bool,
}

/// The PDO write rules a profile changes.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct PdoRules {
    /// Mapping entries accepted while sub 0 != 0 (the PDO invalid).
    pub lenient_remap: bool,
    /// TPDO COB-IDs must keep bit 30; a write without it is aborted with this code.
    pub no_rtr_abort: Option<u32>,
    /// Objects refused in a mapping entry (0x06040041).
    pub unmappable: ObjectList,
}

/// The controlword as the CiA 402 tick sees it: every rising edge of bits 7 (fault reset) and
/// 4 (new set-point, homing start) written since the last tick is latched, so that a value
/// written and overwritten between two ticks is not lost (the strict drive, 3.11); with
/// `controlword_min_hold`, only a value that stood `hold_us` is seen at all.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct ControlwordLatch {
    /// Rising edges of the latched bits since the last tick.
    rising: u16,
    /// With a hold time: the last value written and when (communication clock).
    written: u16,
    written_at_us: u64,
    /// With a hold time: the value the drive acts on.
    seen: u16,
}

/// The controlword bits whose rising edge is a command.
pub(crate) const LATCHED_BITS: u16 =
    crate::cia402::controlword::BIT_FAULT_RESET | crate::cia402::controlword::BIT_NEW_SETPOINT;

impl ControlwordLatch {
    /// 0x6040 written (SDO download or RPDO) from `old` to `new` at `now_us`.
    pub fn on_write(&mut self, old: u16, new: u16, now_us: u64, hold: Option<ControlwordMinHold>) {
        match hold {
            None => self.rising |= new & !old & LATCHED_BITS,
            Some(h) => {
                if now_us.saturating_sub(self.written_at_us) >= u64::from(h.hold_us) {
                    // the value written before stood long enough: the drive saw it
                    self.see(self.written);
                }
                self.written = new;
                self.written_at_us = now_us;
            }
        }
    }

    fn see(&mut self, v: u16) {
        self.rising |= v & !self.seen & LATCHED_BITS;
        self.seen = v;
    }

    /// The tick's controlword (`store_cw`: 0x6040 as stored) and the rising edges latched
    /// since the last tick.
    pub fn for_tick(
        &mut self,
        store_cw: u16,
        now_us: u64,
        hold: Option<ControlwordMinHold>,
    ) -> (u16, u16) {
        let level = match hold {
            None => store_cw,
            Some(h) => {
                if store_cw != self.written {
                    // set by a reset, not by a write: it counts from now
                    self.written = store_cw;
                    self.written_at_us = now_us;
                }
                if now_us.saturating_sub(self.written_at_us) >= u64::from(h.hold_us) {
                    self.see(self.written);
                }
                self.seen
            }
        };
        (level, core::mem::take(&mut self.rising))
    }
}

/// What the node keeps for its switches while it runs (per boot counters, deadlines, the SDO
/// delay queue). Sized when the node is built.
#[derive(Clone, Debug, Default)]
pub(crate) struct QuirkState {
    /// `sdo_response_delay`: answers waiting, (due time us, frame), in order.
    sdo_queue: Deque<(u64, CanFrame), SDO_DELAY_QUEUE>,
    /// SDO services since the boot.
    sdo_services: u32,
    /// The delay of the service in progress, us.
    sdo_delay_us: u64,
    /// `sdo_first_upload_dropped`: (index, sub, uploads still to drop) of each listed object
    /// the dictionary has.
    first_uploads: Box<[(u16, u8, u8)]>,
    /// `bootup_then_heartbeat`: when the early heartbeat is due.
    early_heartbeat_us: Option<u64>,
    /// `not_ready_after_bootup`: when the node becomes ready; the next 0x00 heartbeat.
    ready_at_us: Option<u64>,
    init_heartbeat_us: Option<u64>,
    /// `sync_watchdog`: the last SYNC since the watched mode was entered (application clock).
    watchdog_last_sync_us: Option<u64>,
    /// `late_sync_statusword_bit15`: the last SYNC came late.
    pub late_sync: bool,
}

/// Where an SDO answer goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum SdoAnswer {
    /// Send it now.
    Now(CanFrame),
    /// It waits in the delay queue.
    Queued,
    /// The delay queue is full: dropped.
    Dropped,
}

/// What to do with an SDO request before the server sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum SdoGate {
    /// Serve it.
    Serve,
    /// No answer at all (a silent object, a dropped first upload, not ready).
    Drop,
}

impl QuirkState {
    /// The state for a node with `quirks` and dictionary `od`.
    pub fn new(quirks: &Quirks, od: &ObjectDictionary) -> QuirkState {
        let first_uploads = match &quirks.sdo_first_upload_dropped {
            Some(d) => od
                .iter()
                .filter(|(_, e)| d.objects.contains(e.index, e.sub))
                .map(|(_, e)| (e.index, e.sub, d.count))
                .collect(),
            None => Box::default(),
        };
        QuirkState {
            first_uploads,
            ..QuirkState::default()
        }
    }

    /// The boot-up was sent at `now_us` (communication clock): per-boot counters start over,
    /// the early heartbeat and the ready deadline are set.
    pub fn on_bootup(&mut self, quirks: &Quirks, now_us: u64) {
        self.sdo_queue.clear();
        self.sdo_services = 0;
        if let Some(d) = &quirks.sdo_first_upload_dropped {
            for e in self.first_uploads.iter_mut() {
                e.2 = d.count;
            }
        }
        self.early_heartbeat_us = quirks
            .bootup_then_heartbeat
            .map(|b| now_us.saturating_add(u64::from(b.first_heartbeat_after_bootup_us)));
        self.ready_at_us = quirks
            .not_ready_after_bootup
            .map(|n| now_us.saturating_add(u64::from(n.ready_after_ms) * 1000));
        self.init_heartbeat_us = quirks
            .not_ready_after_bootup
            .filter(|n| n.initialising_heartbeat_ms > 0)
            .map(|n| now_us.saturating_add(u64::from(n.initialising_heartbeat_ms) * 1000));
        self.watchdog_last_sync_us = None;
        self.late_sync = false;
    }

    /// An NMT reset: nothing pending survives it.
    pub fn on_reset(&mut self) {
        self.sdo_queue.clear();
        self.early_heartbeat_us = None;
        self.ready_at_us = None;
        self.init_heartbeat_us = None;
    }

    /// `not_ready_after_bootup`: booted, but not ready yet.
    pub fn not_ready(&self) -> bool {
        self.ready_at_us.is_some()
    }

    /// Communication timers of the switches at `now_us`: the frames to send (0x00 heartbeats
    /// while not ready, the 0x7F when ready, the early heartbeat, delayed SDO answers), and
    /// whether a heartbeat went out that restarts the heartbeat producer's period.
    pub fn poll_comm(
        &mut self,
        quirks: &Quirks,
        now_us: u64,
        node_id: u8,
        nmt_state: u8,
        out: &mut impl FnMut(CanFrame),
    ) -> bool {
        let hb =
            |state: u8| CanFrame::new(crate::wire::cob::HEARTBEAT + u32::from(node_id), &[state]);
        let mut restart = false;
        if let Some(t) = self.ready_at_us {
            if now_us >= t {
                self.ready_at_us = None;
                self.init_heartbeat_us = None;
                restart = true;
                out(hb(nmt_state));
            } else if let (Some(h), Some(n)) =
                (self.init_heartbeat_us, &quirks.not_ready_after_bootup)
            {
                if now_us >= h {
                    out(hb(0x00));
                    let p = u64::from(n.initialising_heartbeat_ms) * 1000;
                    self.init_heartbeat_us = Some(if now_us - h > p { now_us + p } else { h + p });
                }
            }
        }
        if let Some(t) = self.early_heartbeat_us {
            if now_us >= t {
                self.early_heartbeat_us = None;
                // not ready: the 0x7F comes when it is
                if !self.not_ready() && !restart {
                    out(hb(nmt_state));
                    restart = true;
                }
            }
        }
        while let Some(&(due, f)) = self.sdo_queue.front() {
            if due > now_us {
                break;
            }
            self.sdo_queue.pop_front();
            out(f);
        }
        restart
    }

    /// The next communication deadline of the switches.
    pub fn deadline_comm(&self) -> Option<u64> {
        [
            self.ready_at_us,
            self.init_heartbeat_us,
            self.early_heartbeat_us,
            self.sdo_queue.front().map(|&(t, _)| t),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// An SDO request `data` at `now_us`: dropped (a silent object, a first upload, not
    /// ready) or served; a new service also sets the delay of its answers. `in_block`: the
    /// server expects block download segments (which carry no command).
    pub fn sdo_request(&mut self, quirks: &Quirks, data: &[u8; 8], in_block: bool) -> SdoGate {
        if self.not_ready() {
            return SdoGate::Drop;
        }
        if in_block {
            return SdoGate::Serve;
        }
        let (mux, upload) = match SdoRequest::parse(data) {
            Ok(SdoRequest::InitiateUpload { mux }) => (mux, true),
            Ok(SdoRequest::BlockUploadInitiate { mux, .. }) => (mux, true),
            Ok(SdoRequest::InitiateDownload { mux, .. }) => (mux, false),
            Ok(SdoRequest::BlockDownloadInitiate { mux, .. }) => (mux, false),
            _ => return SdoGate::Serve,
        };
        if quirks
            .sdo_silent_objects
            .as_ref()
            .is_some_and(|l| l.contains(mux.index, mux.sub))
        {
            return SdoGate::Drop;
        }
        if upload {
            if let Some(e) = self
                .first_uploads
                .iter_mut()
                .find(|e| e.0 == mux.index && e.1 == mux.sub && e.2 > 0)
            {
                e.2 -= 1;
                return SdoGate::Drop;
            }
        }
        if let Some(d) = quirks.sdo_response_delay {
            self.sdo_services = self.sdo_services.wrapping_add(1);
            let late = d.late_every > 0 && self.sdo_services.is_multiple_of(d.late_every);
            let ms = if late { d.late_delay_ms } else { d.delay_ms };
            self.sdo_delay_us = u64::from(ms) * 1000;
        }
        SdoGate::Serve
    }

    /// An SDO answer caused by a request at `now_us`: sent now, or queued until its delay
    /// is over.
    pub fn sdo_answer(&mut self, quirks: &Quirks, f: CanFrame, now_us: u64) -> SdoAnswer {
        if quirks.sdo_response_delay.is_none()
            || (self.sdo_delay_us == 0 && self.sdo_queue.is_empty())
        {
            return SdoAnswer::Now(f);
        }
        // in order: an answer never overtakes one queued before it
        let due = now_us
            .saturating_add(self.sdo_delay_us)
            .max(self.sdo_queue.back().map_or(0, |&(t, _)| t));
        match self.sdo_queue.push_back((due, f)) {
            Ok(()) => SdoAnswer::Queued,
            Err(_) => SdoAnswer::Dropped,
        }
    }

    /// `sync_watchdog`: a SYNC at `now_us` (application clock); `watched`: the drive is in
    /// OPERATION ENABLED in a watched mode.
    pub fn watchdog_sync(&mut self, now_us: u64, watched: bool) {
        if watched {
            self.watchdog_last_sync_us = Some(now_us);
        }
    }

    /// `sync_watchdog` at a tick: `Some(code)` when the alarm goes off now. `period_us`: the
    /// watched period (0: none). Leaving the watched state disarms it.
    pub fn watchdog_poll(
        &mut self,
        quirks: &Quirks,
        now_us: u64,
        watched: bool,
        period_us: u64,
    ) -> Option<u16> {
        let w = quirks.sync_watchdog.as_ref()?;
        if !watched || period_us == 0 {
            self.watchdog_last_sync_us = None;
            return None;
        }
        let last = self.watchdog_last_sync_us?;
        let limit = (f64::from(w.missed_periods) * period_us as f64) as u64;
        if now_us.saturating_sub(last) > limit {
            self.watchdog_last_sync_us = None;
            return Some(w.emcy_code);
        }
        None
    }

    /// When [`QuirkState::watchdog_poll`] goes off if no SYNC comes first (application clock).
    pub fn watchdog_deadline(&self, quirks: &Quirks, period_us: u64) -> Option<u64> {
        let w = quirks.sync_watchdog.as_ref()?;
        let last = self.watchdog_last_sync_us?;
        (period_us > 0).then(|| last + (f64::from(w.missed_periods) * period_us as f64) as u64 + 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn object_ranges_parse_and_say_why_not() {
        let r = ObjectRange::parse("0x1800-0x1803:5").unwrap();
        assert!(r.contains(0x1802, 5) && !r.contains(0x1804, 5) && !r.contains(0x1800, 6));
        assert_eq!(r.to_string(), "0x1800-0x1803:5");
        let r = ObjectRange::parse("0x1A00:1-8").unwrap();
        assert!(r.contains(0x1A00, 8) && !r.contains(0x1A00, 0));
        assert_eq!(ObjectRange::parse("24673:0").unwrap().index_lo, 0x6061);
        let e = ObjectRange::parse("0x1800-0x17FF:5").unwrap_err();
        assert!(e.contains("range end below start"), "{e}");
        assert!(ObjectRange::parse("0x6061")
            .unwrap_err()
            .contains("not an object"));
        assert!(ObjectRange::parse("0x6061:256")
            .unwrap_err()
            .contains("sub-index"));
        assert!(ObjectRange::parse("0x16061:0")
            .unwrap_err()
            .contains("index"));
        let many: Vec<String> = (0..17).map(|i| format!("0x{:04X}:0", 0x2000 + i)).collect();
        assert!(ObjectList::parse(&many)
            .unwrap_err()
            .contains("more than 16"));
    }

    /// docs/quirks.md's table of switches is the one description's text (it cannot drift).
    #[test]
    fn docs_quirks_md_has_the_generated_table_of_switches() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/quirks.md");
        let doc = std::fs::read_to_string(path).unwrap();
        let begin =
            "<!-- switches: generated by `drive-emu profiles --markdown`, do not edit -->\n";
        let end = "<!-- end of the generated switches -->";
        let a = doc.find(begin).expect("begin marker") + begin.len();
        let b = doc[a..].find(end).expect("end marker") + a;
        assert_eq!(
            &doc[a..b],
            schema::markdown(Quirks::SWITCHES),
            "docs/quirks.md's table of switches is out of date: put the output of `drive-emu \
             profiles --markdown` between its markers"
        );
    }

    /// Every switch and parameter has a doc, a section and a default that passes its own
    /// check; the rules' off values are their defaults.
    #[test]
    fn the_description_is_complete_and_its_defaults_are_in_range() {
        assert_eq!(Quirks::SWITCHES.len(), 16);
        for sw in Quirks::SWITCHES {
            assert!(
                !sw.doc.trim().is_empty() && sw.section.starts_with("3."),
                "{}",
                sw.name
            );
            for p in sw.params {
                assert!(!p.doc.trim().is_empty(), "{}.{}", sw.name, p.name);
                if let Some(d) = p.default {
                    // the default as written, read back as a profile would
                    let v = match p.range {
                        Range::Int { .. } => {
                            let t = d();
                            let n = match t.strip_prefix("0x") {
                                Some(h) => i64::from_str_radix(h, 16).unwrap(),
                                None => t.parse().unwrap(),
                            };
                            schema::Value::Int(n)
                        }
                        Range::Float { .. } => schema::Value::Float(d().parse().unwrap()),
                        Range::OneOf(_) => schema::Value::Str(d().trim_matches('"').into()),
                        _ => continue,
                    };
                    (p.check)(&v).unwrap_or_else(|e| panic!("{}.{}: {e}", sw.name, p.name));
                }
            }
        }
        // an out-of-range value is refused by the same check
        let delay = Quirks::SWITCHES
            .iter()
            .find(|s| s.name == "sdo_response_delay")
            .unwrap()
            .params[0];
        assert_eq!(
            (delay.check)(&schema::Value::Int(70_000)).unwrap_err(),
            "70000 out of range 0..=5000 (ms)"
        );
        assert!(Quirks::default().is_strict());
        let q = Quirks {
            homing_method_zero: HomingMethodZero::Refuse,
            tpdo_rtr_unsupported: Some(TpdoRtrUnsupported {
                abort_code: 0x0609_0030,
            }),
            ..Quirks::default()
        };
        assert_eq!(
            q.on().collect::<Vec<_>>(),
            ["homing_method_zero", "tpdo_rtr_unsupported"]
        );
        assert_eq!(
            q.describe("tpdo_rtr_unsupported"),
            "tpdo_rtr_unsupported (abort_code = 0x06090030)"
        );
        assert_eq!(
            q.describe("homing_method_zero"),
            "homing_method_zero (zero = \"refuse\")"
        );
    }

    #[test]
    fn the_latch_keeps_edges_and_the_hold_hides_short_values() {
        let mut l = ControlwordLatch::default();
        // strict: 0x80 then 0x06 between two ticks: the fault-reset edge is kept
        l.on_write(0x00, 0x80, 10, None);
        l.on_write(0x80, 0x06, 20, None);
        assert_eq!(l.for_tick(0x06, 1000, None), (0x06, 0x80));
        assert_eq!(l.for_tick(0x06, 2000, None), (0x06, 0));
        // hold 1000 us: 0x80 replaced after 100 us is never seen, 0x06 is once it stood
        let hold = Some(ControlwordMinHold { hold_us: 1000 });
        let mut l = ControlwordLatch::default();
        l.on_write(0, 0x80, 5000, hold);
        l.on_write(0x80, 0x06, 5100, hold);
        assert_eq!(l.for_tick(0x06, 5500, hold), (0x00, 0));
        assert_eq!(l.for_tick(0x06, 6100, hold), (0x06, 0));
        // sent 1 ms apart, both are seen, the edge too (even between two ticks)
        l.on_write(0x06, 0x80, 10_000, hold);
        l.on_write(0x80, 0x06, 11_000, hold);
        assert_eq!(l.for_tick(0x06, 11_100, hold), (0x80, 0x80));
        assert_eq!(l.for_tick(0x06, 12_000, hold), (0x06, 0));
    }
}
