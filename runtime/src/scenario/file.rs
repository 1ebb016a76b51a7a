//! The scenario file as written: serde structures with spans, unknown keys rejected. The
//! semantic checks (which keys go together, which are required) live in `validate.rs`.

use super::units::{CobId, EmcyCode, MachineKey, ParamName, Share, StateName, Time};
use drive_protocol::cia402::mode::Mode;
use serde::de::{Deserializer, MapAccess, Visitor};
use serde::Deserialize;
use std::fmt;
use toml::Spanned;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawScenario {
    pub name: Spanned<String>,
    #[serde(default)]
    pub description: String,
    /// Seed of every PRNG (encoder noise, CAN faults).
    pub seed: Option<u64>,
    /// Scenario time at which the run stops (default: when the motion program ends).
    pub duration: Option<Spanned<Time>>,
    /// Skip the physics during `idle` steps (default true).
    pub fast_forward_idle: Option<bool>,
    pub machine: Spanned<RawMachine>,
    #[serde(default)]
    pub master: RawMaster,
    #[serde(default)]
    pub motion: Vec<Spanned<RawStep>>,
    #[serde(default)]
    pub event: Vec<Spanned<RawEvent>>,
    #[serde(default)]
    pub expect: Vec<Spanned<RawExpect>>,
    #[serde(default)]
    pub detector: RawDetector,
}

/// `[machine]`: `preset = "cnc1"` (or `presets = [...]` for a sweep) plus overrides with the
/// preset files' keys.
#[derive(Debug, Default)]
pub struct RawMachine {
    pub preset: Option<Spanned<String>>,
    pub presets: Option<Spanned<Vec<Spanned<String>>>>,
    pub overrides: Vec<(&'static str, Spanned<toml::Value>)>,
}

impl<'de> Deserialize<'de> for RawMachine {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = RawMachine;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a [machine] table")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<RawMachine, A::Error> {
                let mut m = RawMachine::default();
                while let Some(k) = map.next_key::<MachineKey>()? {
                    match k {
                        MachineKey::Preset => m.preset = Some(map.next_value()?),
                        MachineKey::Presets => m.presets = Some(map.next_value()?),
                        MachineKey::Override(key) => {
                            let v: Spanned<toml::Value> = map.next_value()?;
                            m.overrides.push((key, v));
                        }
                    }
                }
                Ok(m)
            }
        }
        d.deserialize_map(V)
    }
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawMaster {
    pub node_id: Option<u8>,
    pub master_id: Option<u8>,
    pub sync_period_us: Option<u32>,
    pub heartbeat_ms: Option<u16>,
    pub drive_heartbeat_ms: Option<u16>,
    pub step_timeout: Option<Time>,
    /// Physics tick, us (default: the SYNC period).
    pub tick_us: Option<u32>,
    /// The master closes the position loop itself, over the bus, with the drive in CSV.
    pub position_loop: Option<RawPositionLoop>,
}

/// `[master.position_loop]`: the CNC's own position loop (master::outer_loop).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawPositionLoop {
    pub kv_per_s: f64,
    /// `direct` (0x60E4 sub 1, the default) or `motor` (0x6064).
    pub encoder: Option<crate::master::outer_loop::LoopEncoder>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StepKind {
    Enable,
    SetMode,
    MoveTo,
    Cruise,
    Dwell,
    Idle,
    WriteSdo,
    StopHeartbeat,
    StopSync,
    Disable,
    Repeat,
}

/// A mode of operation the reference master's motion program runs (`mode = "csp"`): a name
/// or abbreviation the protocol's mode registry knows, one of [`ModeName::RUNNABLE`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModeName(pub Mode);

impl ModeName {
    /// The modes a motion program can run.
    pub const RUNNABLE: [Mode; 5] = [
        Mode::ProfilePosition,
        Mode::ProfileVelocity,
        Mode::CyclicSyncPosition,
        Mode::CyclicSyncVelocity,
        Mode::CyclicSyncTorque,
    ];

    /// Its 0x6060 value.
    pub fn value(self) -> i8 {
        self.0.value()
    }
}

impl<'de> Deserialize<'de> for ModeName {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        match Mode::parse(&text) {
            Some(m) if ModeName::RUNNABLE.contains(&m) => Ok(ModeName(m)),
            found => {
                let names: Vec<String> = ModeName::RUNNABLE
                    .iter()
                    .map(|m| format!("`{}`", m.abbrev().to_ascii_lowercase()))
                    .collect();
                let what = match found {
                    Some(m) => format!("{} is not a mode a motion program runs", m.abbrev()),
                    None => format!("unknown mode `{text}`"),
                };
                Err(serde::de::Error::custom(format!(
                    "{what}, expected one of {}",
                    names.join(", ")
                )))
            }
        }
    }
}

/// One `[[motion]]` step (or an entry of a `repeat` step's `body`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawStep {
    pub step: Spanned<StepKind>,
    pub mode: Option<Spanned<ModeName>>,
    pub velocity_mm_min: Option<Spanned<f64>>,
    pub velocity_mm_s: Option<Spanned<f64>>,
    pub velocity_deg_s: Option<Spanned<f64>>,
    pub velocity_deg_min: Option<Spanned<f64>>,
    /// User units (1 um linear, 0.001 deg rotary): for sweeps over both kinds of axis.
    pub velocity_uu_s: Option<Spanned<f64>>,
    pub accel_uu_s2: Option<Spanned<f64>>,
    pub target_uu: Option<Spanned<f64>>,
    pub accel_mm_s2: Option<Spanned<f64>>,
    pub accel_deg_s2: Option<Spanned<f64>>,
    pub target_mm: Option<Spanned<f64>>,
    pub target_deg: Option<Spanned<f64>>,
    pub duration: Option<Spanned<Time>>,
    pub index: Option<Spanned<u16>>,
    pub sub: Option<Spanned<u8>>,
    pub value: Option<Spanned<i64>>,
    pub len: Option<Spanned<u8>>,
    pub times: Option<Spanned<u32>>,
    pub body: Option<Vec<Spanned<RawStep>>>,
}

impl RawStep {
    /// The keys present (other than `step`), with their spans.
    pub fn present(&self) -> Vec<(&'static str, std::ops::Range<usize>)> {
        let mut v = Vec::new();
        macro_rules! p {
            ($($f:ident),*) => {$(
                if let Some(x) = &self.$f { v.push((stringify!($f), x.span())); }
            )*};
        }
        p!(
            mode,
            velocity_mm_min,
            velocity_mm_s,
            velocity_deg_s,
            velocity_deg_min,
            velocity_uu_s,
            accel_uu_s2,
            target_uu,
            accel_mm_s2,
            accel_deg_s2,
            target_mm,
            target_deg,
            duration,
            index,
            sub,
            value,
            len,
            times
        );
        if self.body.is_some() {
            v.push(("body", self.step.span()));
        }
        v
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SensorKind {
    MotorEncoderLoss,
    DirectEncoderLoss,
    MotorEncoderGlitch,
    DirectEncoderGlitch,
    Restore,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CanKind {
    Drop,
    Delay,
    SyncLoss,
    HeartbeatLoss,
    Restore,
}

/// `ethercat = "..."`: an EtherCAT fault (`run --ethercat` only).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EcatKind {
    Lost,
    Late,
    LinkDown,
    BadWkc,
    OutOfOp,
    Corrupt,
    Restore,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProfileShape {
    Sine,
    /// Half-wave rectified sine: one force pulse per tooth engagement.
    Teeth,
}

/// One `[[event]]`: a trigger (`at`, or `on_state` / `on_emcy` with an optional `after`) and
/// one action (`set`, `ramp`, `profile`, `sensor`, `can` or `ethercat`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawEvent {
    pub id: Option<Spanned<String>>,
    pub at: Option<Spanned<Time>>,
    pub on_state: Option<Spanned<StateName>>,
    pub on_emcy: Option<Spanned<EmcyCode>>,
    pub after: Option<Spanned<Time>>,
    pub set: Option<Spanned<ParamName>>,
    pub value: Option<Spanned<f64>>,
    pub ramp: Option<Spanned<ParamName>>,
    pub from: Option<Spanned<f64>>,
    pub to: Option<Spanned<f64>>,
    pub over: Option<Spanned<Time>>,
    pub profile: Option<Spanned<ParamName>>,
    pub shape: Option<Spanned<ProfileShape>>,
    pub mean: Option<Spanned<f64>>,
    pub amplitude: Option<Spanned<f64>>,
    pub frequency_hz: Option<Spanned<f64>>,
    pub sensor: Option<Spanned<SensorKind>>,
    pub counts: Option<Spanned<i64>>,
    pub can: Option<Spanned<CanKind>>,
    pub share: Option<Spanned<Share>>,
    pub ticks: Option<Spanned<u32>>,
    pub cob_id: Option<Spanned<CobId>>,
    pub ethercat: Option<Spanned<EcatKind>>,
    /// `ethercat = "lost"`: this many frames.
    pub frames: Option<Spanned<u32>>,
    /// `ethercat = "late"`: how long each frame is held.
    pub hold: Option<Spanned<Time>>,
    /// `ethercat = "out_of_op"`: the AL status code (ETG.1000.6).
    pub al_code: Option<Spanned<EmcyCode>>,
}

pub use crate::analysis::detector::Verdict;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProgramOutcome {
    Finished,
    Failed,
}

/// One `[[expect]]`: exactly one of `emcy`, `no_emcy`, `state`, `following_error_max_*`,
/// `verdict`, `frequency_hz`, `frequency_over_kv_min/max`, `program`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawExpect {
    pub emcy: Option<Spanned<EmcyCode>>,
    pub no_emcy: Option<Spanned<bool>>,
    pub within: Option<Spanned<Time>>,
    pub after: Option<Spanned<String>>,
    pub state: Option<Spanned<StateName>>,
    pub at: Option<Spanned<Time>>,
    pub following_error_max_mm: Option<Spanned<f64>>,
    pub following_error_max_deg: Option<Spanned<f64>>,
    pub from: Option<Spanned<Time>>,
    pub until: Option<Spanned<Time>>,
    pub verdict: Option<Spanned<Verdict>>,
    pub by: Option<Spanned<Time>>,
    pub not_before: Option<Spanned<Time>>,
    pub frequency_hz: Option<Spanned<f64>>,
    pub tolerance_pct: Option<Spanned<f64>>,
    pub frequency_over_kv_min: Option<Spanned<f64>>,
    pub frequency_over_kv_max: Option<Spanned<f64>>,
    pub program: Option<Spanned<ProgramOutcome>>,
}

/// `[detector]`: thresholds and windowing; every key optional.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDetector {
    pub enabled: Option<bool>,
    /// Position gain used for the band check (default: the machine's).
    pub kv_per_s: Option<Spanned<f64>>,
    /// Oscillation amplitude (displacement equivalent, um or mdeg) above which backlash is
    /// suspected / reported.
    pub suspect_um: Option<Spanned<f64>>,
    pub alarm_um: Option<Spanned<f64>>,
    pub min_window: Option<Spanned<Time>>,
    pub settle: Option<Spanned<Time>>,
    /// Consecutive flagged windows needed for a verdict.
    pub confirm_windows: Option<Spanned<u32>>,
}
