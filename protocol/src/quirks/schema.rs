//! The one description of the switches (docs/quirks.md section 4): the types a switch's
//! parameters are, their ranges, and the serde side that reads a profile's
//! `[quirks.NAME]` tables into [`super::Quirks`]. The switches themselves (field, doc, section,
//! kind) are declared once, in `quirks.rs`'s `quirks!` invocation, and each parameter (field,
//! doc, default, range) once, in its `params!` struct; everything here reads those: the
//! validation, the defaults, `drive-emu profiles`, the start-up message and the table of
//! docs/quirks.md.
//!
//! An unknown switch or parameter is an error naming the key and the nearest known name
//! ("did you mean"): the tables are read with unknown fields denied.

use core::fmt::{self, Write as _};

use heapless::Vec as HVec;
use serde::de::{self, DeserializeSeed, Deserializer, MapAccess, SeqAccess, Visitor};

use super::{HomingBitsMissing, HomingMethodZero, ObjectList, WatchdogPeriod, MAX_WATCHED_MODES};

/// What a switch is (docs/quirks.md section 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Off by default: the drive behaves as the standard until a profile turns it on.
    Quirk,
    /// A choice the standard leaves open; its default is the `strict` value.
    Rule,
}

impl Kind {
    /// The word docs/quirks.md uses.
    pub fn word(self) -> &'static str {
        match self {
            Kind::Quirk => "quirk",
            Kind::Rule => "rule",
        }
    }
}

/// A parameter's type and range, as a profile writes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    /// An integer in `min..=max`.
    Int {
        /// Lowest value.
        min: i64,
        /// Highest value.
        max: i64,
        /// Unit word (`ms`, `us`; empty: none).
        unit: &'static str,
        /// Written in hex (codes), with this many digits.
        hex_digits: u8,
    },
    /// A number in `min..=max`.
    Float {
        /// Lowest value.
        min: f64,
        /// Highest value.
        max: f64,
    },
    /// One of these strings.
    OneOf(&'static [&'static str]),
    /// A non-empty list of these strings.
    ListOf(&'static [&'static str]),
    /// A non-empty list of objects (`"0xIIII:S"`, ranges; [`ObjectList::parse`]).
    Objects,
    /// A non-empty list of mode of operation values (0x6060, i8).
    Modes,
}

/// An integer range in some unit.
pub const fn int(min: i64, max: i64, unit: &'static str) -> Range {
    Range::Int {
        min,
        max,
        unit,
        hex_digits: 0,
    }
}

/// A code (abort, EMCY) written in hex with `digits` digits, `0..=max`.
pub const fn code(max: i64, digits: u8) -> Range {
    Range::Int {
        min: 0,
        max,
        unit: "",
        hex_digits: digits,
    }
}

impl fmt::Display for Range {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let words = |f: &mut fmt::Formatter<'_>, w: &[&str], sep: &str| {
            for (i, w) in w.iter().enumerate() {
                if i > 0 {
                    f.write_str(sep)?;
                }
                write!(f, "\"{w}\"")?;
            }
            Ok(())
        };
        match *self {
            Range::Int {
                min,
                max,
                unit,
                hex_digits,
            } => {
                if hex_digits > 0 {
                    write!(f, "{min:#x}..={max:#x}")?;
                } else {
                    write!(f, "{min}..={max}")?;
                }
                if !unit.is_empty() {
                    write!(f, " {unit}")?;
                }
                Ok(())
            }
            Range::Float { min, max } => write!(f, "{min:?}..={max:?}"),
            Range::OneOf(w) => words(f, w, " | "),
            Range::ListOf(w) => {
                f.write_str("list of ")?;
                words(f, w, ", ")
            }
            Range::Objects => {
                f.write_str("list of \"0xIIII:S\", \"0xIIII-0xJJJJ:S\", \"0xIIII:S-T\"")
            }
            Range::Modes => f.write_str("list of 0x6060 values"),
        }
    }
}

/// One parameter of a switch, declared once next to its field (`params!`).
#[derive(Clone, Copy, Debug)]
pub struct Param {
    /// Its key in the switch's table.
    pub name: &'static str,
    /// What it sets (its doc comment's lines joined; trim it).
    pub doc: &'static str,
    /// Its type and range.
    pub range: Range,
    /// Its default as a profile writes it (`None`: required).
    pub default: Option<fn() -> String>,
    /// Checks a value written for it (the message says why not).
    pub check: fn(&Value) -> Result<(), String>,
}

/// One switch, declared once as a field of [`super::Quirks`].
#[derive(Clone, Copy, Debug)]
pub struct Switch {
    /// Its name: the field and the profile's `[quirks.NAME]`.
    pub name: &'static str,
    /// Its section of docs/quirks.md.
    pub section: &'static str,
    /// Quirk or rule.
    pub kind: Kind,
    /// What the drive does with it (the field's doc comment's lines joined; trim it).
    pub doc: &'static str,
    /// Its parameters.
    pub params: &'static [Param],
}

// ------------------------------------------------------------------ values as written

/// A value as a profile (or `--quirk NAME.PARAM=VALUE`) wrote it, before it is checked
/// against its parameter's range.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// `true` / `false`.
    Bool(bool),
    /// An integer.
    Int(i64),
    /// A float.
    Float(f64),
    /// A string.
    Str(String),
    /// A list.
    List(Vec<Value>),
    /// A table (or a date: nothing a parameter takes).
    Table,
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Bool(b) => write!(f, "{b}"),
            Value::Int(n) => write!(f, "{n}"),
            Value::Float(x) => write!(f, "{x:?}"),
            Value::Str(s) => write!(f, "\"{}\"", crate::quote::text(s)),
            Value::List(l) => {
                f.write_char('[')?;
                for (i, v) in l.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{v}")?;
                }
                f.write_char(']')
            }
            Value::Table => f.write_str("a table"),
        }
    }
}

struct ValueVisitor;

impl<'de> Visitor<'de> for ValueVisitor {
    type Value = Value;
    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a value")
    }
    fn visit_bool<E: de::Error>(self, v: bool) -> Result<Value, E> {
        Ok(Value::Bool(v))
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Value, E> {
        Ok(Value::Int(v))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Value, E> {
        i64::try_from(v)
            .map(Value::Int)
            .map_err(|_| E::custom(format!("{v} is too large")))
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Value, E> {
        Ok(Value::Float(v))
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<Value, E> {
        Ok(Value::Str(v.to_string()))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Value, A::Error> {
        let mut l = Vec::new();
        while let Some(v) = seq.next_element::<Value>()? {
            l.push(v);
        }
        Ok(Value::List(l))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Value, A::Error> {
        while map
            .next_entry::<de::IgnoredAny, de::IgnoredAny>()?
            .is_some()
        {}
        Ok(Value::Table)
    }
}

impl<'de> serde::Deserialize<'de> for Value {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Value, D::Error> {
        d.deserialize_any(ValueVisitor)
    }
}

// ------------------------------------------------------------------ parameter types

/// A type a parameter can have: read from a [`Value`] within its [`Range`], and written back
/// as a profile writes it.
pub trait ParamValue: Sized {
    /// The value, checked against `range`; the error says why not.
    fn from_value(v: &Value, range: &Range) -> Result<Self, String>;
    /// As a profile writes it.
    fn write(&self, range: &Range, out: &mut String);
}

fn int_in(v: &Value, range: &Range) -> Result<i64, String> {
    let Range::Int {
        min,
        max,
        unit,
        hex_digits,
    } = *range
    else {
        return Err(format!("{v}: not an integer parameter"));
    };
    let Value::Int(n) = *v else {
        return Err(format!("{v} is not an integer"));
    };
    if !(min..=max).contains(&n) {
        let unit = if unit.is_empty() {
            String::new()
        } else {
            format!(" ({unit})")
        };
        return Err(if hex_digits > 0 {
            format!("{n} out of range {min:#x}..={max:#x}{unit}")
        } else {
            format!("{n} out of range {min}..={max}{unit}")
        });
    }
    Ok(n)
}

fn write_int(n: i64, range: &Range, out: &mut String) {
    match *range {
        Range::Int { hex_digits, .. } if hex_digits > 0 => {
            let _ = write!(out, "0x{n:0w$X}", w = usize::from(hex_digits));
        }
        _ => {
            let _ = write!(out, "{n}");
        }
    }
}

macro_rules! int_param {
    ($($t:ty),*) => {$(
        impl ParamValue for $t {
            fn from_value(v: &Value, range: &Range) -> Result<Self, String> {
                let n = int_in(v, range)?;
                <$t>::try_from(n).map_err(|_| format!("{n} out of range of {}", stringify!($t)))
            }
            fn write(&self, range: &Range, out: &mut String) {
                write_int(i64::from(*self), range, out)
            }
        }
    )*};
}
int_param!(u8, u16, u32);

impl ParamValue for f32 {
    fn from_value(v: &Value, range: &Range) -> Result<Self, String> {
        let x = match *v {
            Value::Float(x) => x,
            Value::Int(n) => n as f64,
            _ => return Err(format!("{v} is not a number")),
        };
        if let Range::Float { min, max } = *range {
            if !(min..=max).contains(&x) {
                return Err(format!("{x} out of range {min:?}..={max:?}"));
            }
        }
        Ok(x as f32)
    }
    fn write(&self, _: &Range, out: &mut String) {
        let _ = write!(out, "{self:?}");
    }
}

fn one_of(v: &Value, words: &'static [&'static str]) -> Result<usize, String> {
    let Value::Str(s) = v else {
        return Err(format!("{v} is not a string"));
    };
    words.iter().position(|w| w == s).ok_or_else(|| {
        let quoted: Vec<String> = words.iter().map(|w| format!("\"{w}\"")).collect();
        format!("{v} is not one of {}", quoted.join(", "))
    })
}

/// A parameter that is one word of a list (`"store"`, `"ignore"`, `"refuse"`).
pub trait Word: Sized + Copy + 'static {
    /// Every value, in the order of [`Word::WORDS`].
    const ALL: &'static [Self];
    /// Their words.
    const WORDS: &'static [&'static str];
}

impl<T: Word + PartialEq> ParamValue for T {
    fn from_value(v: &Value, _: &Range) -> Result<Self, String> {
        one_of(v, T::WORDS).map(|i| T::ALL[i])
    }
    fn write(&self, _: &Range, out: &mut String) {
        let i = T::ALL.iter().position(|w| w == self).unwrap_or(0);
        let _ = write!(out, "\"{}\"", T::WORDS[i]);
    }
}

impl Word for HomingMethodZero {
    const ALL: &'static [Self] = &[
        HomingMethodZero::Store,
        HomingMethodZero::Ignore,
        HomingMethodZero::Refuse,
    ];
    const WORDS: &'static [&'static str] = &["store", "ignore", "refuse"];
}

impl Word for WatchdogPeriod {
    const ALL: &'static [Self] = &[
        WatchdogPeriod::Interpolation,
        WatchdogPeriod::CommunicationCycle,
    ];
    const WORDS: &'static [&'static str] = &["0x60C2", "0x1006"];
}

fn list<'a>(v: &'a Value, what: &str) -> Result<&'a [Value], String> {
    match v {
        Value::List(l) if l.is_empty() => Err(format!(
            "an empty list of {what} (turn the switch off with enabled = false)"
        )),
        Value::List(l) => Ok(l),
        _ => Err(format!("{v} is not a list of {what}")),
    }
}

/// The bits of `homing_status_bits_missing`, as words.
pub const HOMING_BITS: [&str; 2] = ["target_reached", "attained"];

impl ParamValue for HomingBitsMissing {
    fn from_value(v: &Value, _: &Range) -> Result<Self, String> {
        let mut b = HomingBitsMissing::default();
        for it in list(v, "bits")? {
            match one_of(it, &HOMING_BITS)? {
                0 => b.target_reached = true,
                _ => b.attained = true,
            }
        }
        Ok(b)
    }
    fn write(&self, _: &Range, out: &mut String) {
        let mut w = Vec::new();
        if self.target_reached {
            w.push("\"target_reached\"");
        }
        if self.attained {
            w.push("\"attained\"");
        }
        let _ = write!(out, "[{}]", w.join(", "));
    }
}

impl ParamValue for ObjectList {
    fn from_value(v: &Value, _: &Range) -> Result<Self, String> {
        let mut texts = Vec::new();
        for it in list(v, "objects")? {
            let Value::Str(s) = it else {
                return Err(format!("{it} is not a string like \"0x6061:0\""));
            };
            texts.push(s.as_str());
        }
        ObjectList::parse(&texts)
    }
    fn write(&self, _: &Range, out: &mut String) {
        out.push('[');
        for (i, r) in self.0.iter().enumerate() {
            if i > 0 {
                out.push_str(", ");
            }
            let _ = write!(out, "\"{r}\"");
        }
        out.push(']');
    }
}

impl ParamValue for HVec<i8, MAX_WATCHED_MODES> {
    fn from_value(v: &Value, _: &Range) -> Result<Self, String> {
        let mut out = HVec::new();
        for it in list(v, "modes")? {
            let m = match *it {
                Value::Int(n) => i8::try_from(n).ok(),
                _ => None,
            }
            .ok_or_else(|| format!("{it} is not a mode of operation (-128..=127)"))?;
            out.push(m)
                .map_err(|_| format!("more than {MAX_WATCHED_MODES} modes"))?;
        }
        Ok(out)
    }
    fn write(&self, _: &Range, out: &mut String) {
        let m: Vec<String> = self.iter().map(|m| m.to_string()).collect();
        let _ = write!(out, "[{}]", m.join(", "));
    }
}

// ------------------------------------------------------------------ switch types

/// The values written in one switch's table, in the order of its parameters (`None`: not
/// written, the default applies); the whole is `None` for `enabled = false`.
pub type Written<'a> = Option<&'a [Option<Value>]>;

/// A struct of parameters (declared with `params!`).
pub trait Params: Sized + Clone {
    /// Its parameters.
    const PARAMS: &'static [Param];
    /// From the values written (each checked); defaults for the others.
    fn from_written(vals: &[Option<Value>]) -> Result<Self, String>;
    /// Its values as a profile writes them: (parameter, value).
    fn values(&self) -> Vec<(&'static str, String)>;
}

/// The type of a field of [`super::Quirks`]: a switch's setting.
pub trait SwitchField: Sized + Clone {
    /// Its parameters.
    const PARAMS: &'static [Param];
    /// The setting a table says.
    fn from_written(w: Written<'_>) -> Result<Self, String>;
    /// On: its parameters as written; off (the strict value): `None`.
    fn on_values(&self) -> Option<Vec<(&'static str, String)>>;
}

/// A switch without parameters.
impl SwitchField for bool {
    const PARAMS: &'static [Param] = &[];
    fn from_written(w: Written<'_>) -> Result<Self, String> {
        Ok(w.is_some())
    }
    fn on_values(&self) -> Option<Vec<(&'static str, String)>> {
        self.then(Vec::new)
    }
}

/// A switch with parameters: `None` is off.
impl<P: Params> SwitchField for Option<P> {
    const PARAMS: &'static [Param] = P::PARAMS;
    fn from_written(w: Written<'_>) -> Result<Self, String> {
        w.map(P::from_written).transpose()
    }
    fn on_values(&self) -> Option<Vec<(&'static str, String)>> {
        self.as_ref().map(P::values)
    }
}

/// The value written for `name` (or `None`).
pub fn written<'a>(params: &[Param], vals: &'a [Option<Value>], name: &str) -> Option<&'a Value> {
    params
        .iter()
        .position(|p| p.name == name)
        .and_then(|i| vals.get(i))
        .and_then(Option::as_ref)
}

/// Declares a struct of parameters once: each field with its doc, type, default (none:
/// required) and range; generates the struct, its [`Params`] table, reading and writing.
macro_rules! params {
    (
        $(#[$sattr:meta])*
        pub struct $S:ident {
            $(
                $(#[doc = $doc:literal])+
                $f:ident : $T:ty $(= $default:expr)? ; $range:expr
            ),* $(,)?
        }
    ) => {
        $(#[$sattr])*
        pub struct $S {
            $( $(#[doc = $doc])+ pub $f: $T, )*
        }

        impl $crate::quirks::schema::Params for $S {
            const PARAMS: &'static [$crate::quirks::schema::Param] = &[$(
                $crate::quirks::schema::Param {
                    name: stringify!($f),
                    doc: concat!($($doc),+),
                    range: $range,
                    default: params!(@default $T, $range $(, $default)?),
                    check: |v| {
                        <$T as $crate::quirks::schema::ParamValue>::from_value(v, &$range)
                            .map(drop)
                    },
                },
            )*];

            fn from_written(
                vals: &[Option<$crate::quirks::schema::Value>],
            ) -> Result<Self, String> {
                use $crate::quirks::schema::{written, ParamValue};
                Ok($S {$(
                    $f: match written(Self::PARAMS, vals, stringify!($f)) {
                        Some(v) => <$T as ParamValue>::from_value(v, &$range)
                            .map_err(|e| format!("{}: {e}", stringify!($f)))?,
                        None => params!(@or_required $f $(, $default)?),
                    },
                )*})
            }

            fn values(&self) -> Vec<(&'static str, String)> {
                use $crate::quirks::schema::ParamValue;
                vec![$({
                    let mut s = String::new();
                    ParamValue::write(&self.$f, &$range, &mut s);
                    (stringify!($f), s)
                }),*]
            }
        }
    };
    (@default $T:ty, $range:expr) => { None };
    (@default $T:ty, $range:expr, $default:expr) => {
        Some(|| {
            let mut s = String::new();
            let d: $T = $default;
            $crate::quirks::schema::ParamValue::write(&d, &$range, &mut s);
            s
        })
    };
    (@or_required $f:ident) => {
        return Err(format!("parameter `{}` is required", stringify!($f)))
    };
    (@or_required $f:ident, $default:expr) => { $default };
}
pub(crate) use params;

// ------------------------------------------------------------------ names

/// The known name nearest to `name` (edit distance at most 3), for "did you mean".
pub fn nearest<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    fn distance(a: &str, b: &str) -> usize {
        let b: Vec<char> = b.chars().collect();
        let mut prev: Vec<usize> = (0..=b.len()).collect();
        for (i, ca) in a.chars().enumerate() {
            let mut cur = vec![i + 1];
            for (j, cb) in b.iter().enumerate() {
                let sub = prev[j] + usize::from(ca != *cb);
                cur.push(sub.min(prev[j + 1] + 1).min(cur[j] + 1));
            }
            prev = cur;
        }
        prev[b.len()]
    }
    known
        .into_iter()
        .map(|k| (distance(name, k), k))
        .filter(|(d, _)| *d <= 3)
        .min()
        .map(|(_, k)| k)
}

/// "unknown WHAT `name` (did you mean `x`? known: a, b, c)".
pub fn unknown(what: &str, name: &str, known: &[&str]) -> String {
    let hint = nearest(name, known.iter().copied())
        .map(|n| format!("did you mean `{n}`? "))
        .unwrap_or_default();
    format!(
        "unknown {what} `{}` ({hint}known: {})",
        crate::quote::text(name),
        known.join(", ")
    )
}

// ------------------------------------------------------------------ reading a table

/// A key of a switch's table: `enabled` (`None`) or a parameter's index.
struct ParamKey {
    switch: &'static Switch,
}

impl<'de> DeserializeSeed<'de> for ParamKey {
    type Value = Option<usize>;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Option<usize>, D::Error> {
        let k: String = serde::Deserialize::deserialize(d)?;
        if k == "enabled" {
            return Ok(None);
        }
        let sw = self.switch;
        sw.params
            .iter()
            .position(|p| p.name == k)
            .map(Some)
            .ok_or_else(|| {
                let mut known: Vec<&str> = sw.params.iter().map(|p| p.name).collect();
                known.push("enabled");
                de::Error::custom(format!(
                    "quirks.{}.{}: {}",
                    sw.name,
                    crate::quote::text(&k),
                    unknown(&format!("parameter of {}", sw.name), &k, &known)
                ))
            })
    }
}

/// A value of a switch's table, checked against its parameter (so that the error points at
/// the value).
struct ParamSeed {
    switch: &'static Switch,
    /// `None`: `enabled`.
    param: Option<&'static Param>,
}

impl<'de> DeserializeSeed<'de> for ParamSeed {
    type Value = Value;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Value, D::Error> {
        let v = Value::deserialize(d)?;
        let (key, r) = match self.param {
            None => (
                "enabled",
                match v {
                    Value::Bool(_) => Ok(()),
                    _ => Err(format!("{v} is not true or false")),
                },
            ),
            Some(p) => (p.name, (p.check)(&v)),
        };
        r.map(|()| v)
            .map_err(|e| de::Error::custom(format!("quirks.{}.{key}: {e}", self.switch.name)))
    }
}

use serde::Deserialize as _;

/// One switch's table: the values written (`None`: `enabled = false`).
struct TableSeed {
    switch: &'static Switch,
}

impl<'de> DeserializeSeed<'de> for TableSeed {
    type Value = Option<Vec<Option<Value>>>;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for TableSeed {
    type Value = Option<Vec<Option<Value>>>;
    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "the table of switch {} (write {} = {{}} to turn it on)",
            self.switch.name, self.switch.name
        )
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
        let sw = self.switch;
        let mut enabled = true;
        let mut vals: Vec<Option<Value>> = vec![None; sw.params.len()];
        while let Some(k) = map.next_key_seed(ParamKey { switch: sw })? {
            let param = k.map(|i| &sw.params[i]);
            let v = map.next_value_seed(ParamSeed { switch: sw, param })?;
            match (k, v) {
                (None, Value::Bool(b)) => enabled = b,
                (Some(i), v) => vals[i] = Some(v),
                (None, _) => {}
            }
        }
        if !enabled {
            return Ok(None);
        }
        if let Some(p) = sw
            .params
            .iter()
            .zip(&vals)
            .find(|(p, v)| v.is_none() && p.default.is_none())
        {
            return Err(de::Error::custom(format!(
                "quirks.{}: parameter `{}` is required",
                sw.name, p.0.name
            )));
        }
        Ok(Some(vals))
    }
}

/// A key of the `quirks` table: a switch's index in `switches`.
struct SwitchKey {
    switches: &'static [Switch],
}

impl<'de> DeserializeSeed<'de> for SwitchKey {
    type Value = usize;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<usize, D::Error> {
        let k: String = serde::Deserialize::deserialize(d)?;
        self.switches
            .iter()
            .position(|s| s.name == k)
            .ok_or_else(|| {
                let known: Vec<&str> = self.switches.iter().map(|s| s.name).collect();
                de::Error::custom(format!(
                    "quirks.{}: {}",
                    crate::quote::text(&k),
                    unknown("switch", &k, &known)
                ))
            })
    }
}

/// Reads the `quirks` table: calls `set(index, values)` for each switch written.
pub(crate) struct QuirksVisitor<T, F> {
    pub switches: &'static [Switch],
    pub out: T,
    pub set: F,
}

impl<'de, T, F> Visitor<'de> for QuirksVisitor<T, F>
where
    F: Fn(&mut T, usize, Written<'_>) -> Result<(), String>,
{
    type Value = T;
    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a table of switches (docs/quirks.md section 4)")
    }
    fn visit_map<A: MapAccess<'de>>(mut self, mut map: A) -> Result<T, A::Error> {
        while let Some(i) = map.next_key_seed(SwitchKey {
            switches: self.switches,
        })? {
            let sw = &self.switches[i];
            let w = map.next_value_seed(TableSeed { switch: sw })?;
            (self.set)(&mut self.out, i, w.as_deref())
                .map_err(|e| de::Error::custom(format!("quirks.{}: {e}", sw.name)))?;
        }
        Ok(self.out)
    }
}

// ------------------------------------------------------------------ text for people

/// A switch that is on, with its parameters: `sdo_response_delay (delay_ms = 30, ...)`.
pub fn describe(name: &str, values: &[(&'static str, String)]) -> String {
    if values.is_empty() {
        return name.to_string();
    }
    let p: Vec<String> = values.iter().map(|(k, v)| format!("{k} = {v}")).collect();
    format!("{name} ({})", p.join(", "))
}

/// The table of switches of docs/quirks.md section 4, in markdown.
pub fn markdown(switches: &[Switch]) -> String {
    let mut s = String::from("| switch | § | kind | what it does | parameters [default] |\n");
    s += "|---|---|---|---|---|\n";
    for sw in switches {
        let params: Vec<String> = sw
            .params
            .iter()
            .map(|p| {
                format!(
                    "`{}`: {} ({}) [{}]",
                    p.name,
                    p.doc.trim(),
                    p.range,
                    p.default.map_or("required".to_string(), |d| d())
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "| `{}` | {} | {} | {} | {} |",
            sw.name,
            sw.section,
            sw.kind.word(),
            sw.doc.trim(),
            if params.is_empty() {
                "—".to_string()
            } else {
                params.join("; ")
            }
            .replace('|', "\\|")
        );
    }
    s
}

/// The switches for a terminal (`drive-emu profiles`).
pub fn listing(switches: &[Switch]) -> String {
    let mut s = String::new();
    for sw in switches {
        let _ = writeln!(
            s,
            "  {:<31} {} {}: {}",
            sw.name,
            sw.section,
            sw.kind.word(),
            sw.doc.trim()
        );
        for p in sw.params {
            let _ = writeln!(
                s,
                "  {:<31}   {} = {} [{}]: {}",
                "",
                p.name,
                p.range,
                p.default.map_or("required".to_string(), |d| d()),
                p.doc.trim()
            );
        }
    }
    s
}
