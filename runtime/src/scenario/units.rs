//! Strictly parsed values of scenario files: times with units, parameter names with their units,
//! CiA 402 state names, EMCY codes. Each type's `Deserialize` rejects bad input with a reason,
//! and the TOML deserializer attaches the span of the offending value (or key) to the error.

use crate::drive::AxisParam;
use drive_physics::params::{Applies, Form, PARAMS};
use drive_protocol::Cia402State;
use serde::de::{self, Deserializer, Visitor};
use std::fmt;

/// A time or duration, microseconds. Written as a string with a unit: "250 ms", "3 s",
/// "5 min", "1.5 h", "200 us". Numbers without a unit and negative times are rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, serde::Serialize)]
pub struct Time(pub u64);

impl Time {
    pub fn us(self) -> u64 {
        self.0
    }
    pub fn secs(self) -> f64 {
        self.0 as f64 * 1e-6
    }
}

/// Units a [`Time`] may carry, with their length in microseconds.
pub const TIME_UNITS: &[(&str, f64)] = &[
    ("us", 1.0),
    ("ms", 1e3),
    ("s", 1e6),
    ("min", 60e6),
    ("h", 3600e6),
];

/// Longest time a scenario may name, us (about 31.7 years).
pub const MAX_TIME_US: f64 = 1e15;

/// Parse "3 s", "1.5h", "250 ms".
pub fn parse_time(s: &str) -> Result<Time, String> {
    let t = s.trim();
    // The unit is the trailing run of letters ("1e30 h": the `e` belongs to the number).
    let split = t.trim_end_matches(|c: char| c.is_ascii_alphabetic()).len();
    if split == t.len() {
        return Err(format!(
            "time `{s}` has no unit: write e.g. \"{t} s\" (units: us, ms, s, min, h)"
        ));
    }
    let (num, unit) = t.split_at(split);
    let num = num.trim();
    let value: f64 = num
        .parse()
        .map_err(|_| format!("time `{s}`: `{num}` is not a number"))?;
    let Some(&(_, scale)) = TIME_UNITS.iter().find(|(u, _)| *u == unit) else {
        return Err(format!(
            "time `{s}`: unknown unit `{unit}` (units: us, ms, s, min, h)"
        ));
    };
    if !value.is_finite() {
        return Err(format!("time `{s}` is not finite"));
    }
    if value < 0.0 {
        return Err(format!("time `{s}` is negative"));
    }
    let us = value * scale;
    if us > MAX_TIME_US {
        return Err(format!(
            "time `{s}` is out of range: at most {} h (1e15 us)",
            MAX_TIME_US / 3600e6
        ));
    }
    Ok(Time(us.round() as u64))
}

impl<'de> de::Deserialize<'de> for Time {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Time;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a time with a unit, such as \"5 s\" or \"10 min\"")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<Time, E> {
                parse_time(v).map_err(E::custom)
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Time, E> {
                Err(E::custom(format!(
                    "time {v} has no unit: write it as a string with a unit, e.g. \"{v} s\""
                )))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Time, E> {
                self.visit_i64(v as i64)
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Time, E> {
                Err(E::custom(format!(
                    "time {v} has no unit: write it as a string with a unit, e.g. \"{v} s\""
                )))
            }
        }
        d.deserialize_any(V)
    }
}

/// Which kind of axis a parameter key belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum AxisKind {
    Linear,
    Rotary,
    Any,
}

/// A scenario parameter key: the name used in files (units in the name) and how it maps onto
/// the drive's [`AxisParam`] in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamKey {
    pub key: &'static str,
    pub param: AxisParam,
    /// SI value = file value * scale.
    pub scale: f64,
    pub axis: AxisKind,
    /// Lowest accepted file value (values below are rejected when parsed).
    pub min: f64,
}

/// Every parameter a timeline event may set, ramp or drive (applied through the drive's
/// `set_param` while the axis runs): the parameter registry's live rows
/// (`drive_physics::params::PARAMS`), one entry per spelling (linear, rotary or both).
pub static PARAM_KEYS: [ParamKey; LIVE_FORMS] = live_keys();

/// How many spellings the registry's live parameters have.
const LIVE_FORMS: usize = {
    let mut n = 0;
    let mut i = 0;
    while i < PARAMS.len() {
        if PARAMS[i].live.is_some() {
            n += if PARAMS[i].rotary.is_some() { 2 } else { 1 };
        }
        i += 1;
    }
    n
};

const fn key_of(form: &Form, param: AxisParam, min: f64) -> ParamKey {
    ParamKey {
        key: form.key,
        param,
        scale: form.si_per_unit,
        axis: match form.applies {
            Applies::Linear => AxisKind::Linear,
            Applies::Rotary => AxisKind::Rotary,
            Applies::Any => AxisKind::Any,
        },
        min,
    }
}

const fn live_keys() -> [ParamKey; LIVE_FORMS] {
    let placeholder = ParamKey {
        key: "",
        param: AxisParam::Kv,
        scale: 1.0,
        axis: AxisKind::Any,
        min: 0.0,
    };
    let mut out = [placeholder; LIVE_FORMS];
    let (mut i, mut k) = (0, 0);
    while i < PARAMS.len() {
        let p = &PARAMS[i];
        if let Some(param) = p.live {
            out[k] = key_of(&p.linear, param, p.min);
            k += 1;
            if let Some(r) = &p.rotary {
                out[k] = key_of(r, param, p.min);
                k += 1;
            }
        }
        i += 1;
    }
    out
}

pub fn param_key(name: &str) -> Option<&'static ParamKey> {
    PARAM_KEYS.iter().find(|k| k.key == name)
}

fn known_keys() -> String {
    PARAM_KEYS
        .iter()
        .map(|k| k.key)
        .collect::<Vec<_>>()
        .join(", ")
}

/// A parameter name as written in an event (`set = "backlash_mm"`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamName(pub &'static ParamKey);

impl<'de> de::Deserialize<'de> for ParamName {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        param_key(&s).map(ParamName).ok_or_else(|| {
            let keys = PARAM_KEYS.iter().map(|k| k.key);
            let hint = match drive_physics::params::moved(&s) {
                Some(new) => format!(" (now `{new}`)"),
                None => drive_physics::params::did_you_mean(&s, keys),
            };
            de::Error::custom(format!(
                "unknown parameter `{s}`{hint} (known: {})",
                known_keys()
            ))
        })
    }
}

/// The keys of the preset files (`presets::AxisConfig`'s fields), found by asking its
/// `Deserialize` implementation which fields it expects.
pub fn preset_keys() -> &'static [&'static str] {
    use serde::forward_to_deserialize_any;
    struct Fields<'a>(&'a mut &'static [&'static str]);
    impl<'de> Deserializer<'de> for Fields<'_> {
        type Error = de::value::Error;
        fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Self::Error> {
            Err(de::Error::custom("fields only"))
        }
        fn deserialize_struct<V: Visitor<'de>>(
            self,
            _: &'static str,
            fields: &'static [&'static str],
            _: V,
        ) -> Result<V::Value, Self::Error> {
            *self.0 = fields;
            Err(de::Error::custom("fields only"))
        }
        forward_to_deserialize_any! {
            bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
            option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
            ignored_any
        }
    }
    static KEYS: std::sync::OnceLock<&'static [&'static str]> = std::sync::OnceLock::new();
    KEYS.get_or_init(|| {
        let mut f: &'static [&'static str] = &[];
        let _ = <crate::presets::AxisConfig as de::Deserialize>::deserialize(Fields(&mut f));
        f
    })
}

/// A key of the `[machine]` table: `preset`, `presets` or a preset-file key to override.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MachineKey {
    Preset,
    Presets,
    Override(&'static str),
}

impl<'de> de::Deserialize<'de> for MachineKey {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        match s.as_str() {
            "preset" => Ok(MachineKey::Preset),
            "presets" => Ok(MachineKey::Presets),
            "name" | "description" => Err(de::Error::custom(format!(
                "`{s}` of a preset cannot be overridden here"
            ))),
            _ => preset_keys()
                .iter()
                .find(|k| **k == s)
                .map(|k| MachineKey::Override(k))
                .ok_or_else(|| {
                    de::Error::custom(format!(
                        "unknown machine key `{s}` (expected preset, presets or a preset file key: {})",
                        preset_keys().join(", ")
                    ))
                }),
        }
    }
}

/// A CiA 402 state as a scenario file names it: `operation_enabled` or `OPERATION ENABLED`
/// (case-insensitive); serialised as the standard's name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StateName(pub Cia402State);

impl serde::Serialize for StateName {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.0.name())
    }
}

impl<'de> de::Deserialize<'de> for StateName {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        let norm = s.trim().to_ascii_lowercase().replace([' ', '-'], "_");
        Cia402State::ALL
            .iter()
            .find(|st| st.key() == norm)
            .map(|st| StateName(*st))
            .ok_or_else(|| {
                de::Error::custom(format!(
                    "unknown CiA 402 state `{s}` (known: {})",
                    Cia402State::ALL
                        .iter()
                        .map(|st| st.key())
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            })
    }
}

/// An EMCY error code: "0x7300" or 29440.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct EmcyCode(pub u16);

impl<'de> de::Deserialize<'de> for EmcyCode {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = EmcyCode;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("an EMCY code such as \"0x7300\"")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<EmcyCode, E> {
                let t = v.trim();
                let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
                    Some(h) => u16::from_str_radix(h, 16).ok(),
                    None => t.parse().ok(),
                };
                parsed
                    .map(EmcyCode)
                    .ok_or_else(|| E::custom(format!("`{v}` is not a 16-bit EMCY code")))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<EmcyCode, E> {
                u16::try_from(v)
                    .map(EmcyCode)
                    .map_err(|_| E::custom(format!("{v} is not a 16-bit EMCY code")))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<EmcyCode, E> {
                self.visit_i64(v as i64)
            }
        }
        d.deserialize_any(V)
    }
}

/// A COB-ID: "0x080" or 128; 11-bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct CobId(pub u32);

impl<'de> de::Deserialize<'de> for CobId {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let c = EmcyCode::deserialize(d)?;
        if c.0 > 0x7FF {
            return Err(de::Error::custom(format!(
                "COB-ID {:#05X} is not an 11-bit identifier",
                c.0
            )));
        }
        Ok(CobId(u32::from(c.0)))
    }
}

/// A share, 0..=1.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Share(pub f64);

impl<'de> de::Deserialize<'de> for Share {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = f64::deserialize(d)?;
        if !(0.0..=1.0).contains(&v) {
            return Err(de::Error::custom(format!(
                "share {v} is outside 0..1 (write 0.1 for 10 %)"
            )));
        }
        Ok(Share(v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_parse_strictly() {
        assert_eq!(parse_time("3 s"), Ok(Time(3_000_000)));
        assert_eq!(parse_time("1.5h"), Ok(Time(5_400_000_000)));
        assert_eq!(parse_time("250 ms"), Ok(Time(250_000)));
        assert_eq!(parse_time(" 5 min "), Ok(Time(300_000_000)));
        assert!(parse_time("5").unwrap_err().contains("no unit"));
        assert!(parse_time("5 mins")
            .unwrap_err()
            .contains("unknown unit `mins`"));
        let e = parse_time("1e30 h").unwrap_err();
        assert!(e.contains("out of range"), "{e}");
        assert_eq!(parse_time("1e3 ms").unwrap(), Time(1_000_000));
        assert!(parse_time("1e3").unwrap_err().contains("no unit"));
        assert!(parse_time("-1 s").unwrap_err().contains("negative"));
        assert!(parse_time("x s").unwrap_err().contains("not a number"));
    }

    #[test]
    fn every_param_key_is_unique() {
        for (i, a) in PARAM_KEYS.iter().enumerate() {
            assert!(
                PARAM_KEYS[i + 1..].iter().all(|b| b.key != a.key),
                "{}",
                a.key
            );
        }
    }
}
