//! Vendor behaviour profiles (docs/quirks.md section 4, schema 1): TOML files that turn the
//! node's vendor switches ([`drive_protocol::Quirks`]) on and set the drive's identity and
//! boot delays. The profiles of `profiles/` are embedded in the binary; `--profile PATH.toml`
//! loads another. On top of a profile: a machine file's `quirks = {...}` per axis and the
//! command line's `--quirk NAME[.PARAM=VALUE]` / `--no-quirk NAME`, each as one more child.
//!
//! Every switch and parameter is described once, in `drive_protocol::quirks` (the `Quirks`
//! struct and its `params!` structs: field, doc, default, range): a profile's `quirks` table
//! is read into a [`QuirksPatch`] with serde, and `drive-emu profiles`, the start-up message
//! and docs/quirks.md's table print [`Quirks::SWITCHES`]. Errors name the file, line, key and
//! reason (`profiles/x.toml:7: quirks.sdo_response_delay.delay_ms: 70000 out of range
//! 0..=5000 (ms)`; an unknown name with the nearest known one) and nothing is started with a
//! profile that did not validate.

use drive_protocol::quirks::schema::{listing, unknown};
use drive_protocol::quirks::QuirksPatch;
use drive_protocol::Quirks;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// The schema version this drive-emu reads.
pub const SCHEMA: i64 = 1;

/// The profiles shipped in `profiles/`, embedded at build time: (name, text).
pub const EMBEDDED: [(&str, &str); 11] = [
    ("strict", include_str!("../../../profiles/strict.toml")),
    (
        "copley-accelnet",
        include_str!("../../../profiles/copley-accelnet.toml"),
    ),
    (
        "delta-asda-a2",
        include_str!("../../../profiles/delta-asda-a2.toml"),
    ),
    (
        "engel-hbi",
        include_str!("../../../profiles/engel-hbi.toml"),
    ),
    (
        "faulhaber-mc5004",
        include_str!("../../../profiles/faulhaber-mc5004.toml"),
    ),
    (
        "isel-imd20",
        include_str!("../../../profiles/isel-imd20.toml"),
    ),
    ("jvl-mis", include_str!("../../../profiles/jvl-mis.toml")),
    (
        "maxon-epos4",
        include_str!("../../../profiles/maxon-epos4.toml"),
    ),
    (
        "nanotec-pd4c",
        include_str!("../../../profiles/nanotec-pd4c.toml"),
    ),
    (
        "roboteq-fbl2360",
        include_str!("../../../profiles/roboteq-fbl2360.toml"),
    ),
    (
        "technosoft-ipos",
        include_str!("../../../profiles/technosoft-ipos.toml"),
    ),
];

/// The `[identity]` keys: (key, what it sets).
pub const IDENTITY_KEYS: [(&str, &str); 8] = [
    ("boot_delay_ms", "power-on to boot-up, ms (0..=600000)"),
    (
        "reset_node_boot_delay_ms",
        "NMT reset node to boot-up, ms [boot_delay_ms]",
    ),
    (
        "reset_communication_boot_delay_ms",
        "NMT reset communication to boot-up, ms [boot_delay_ms]",
    ),
    ("device_type", "0x1000"),
    ("vendor_id", "0x1018:1"),
    ("product_code", "0x1018:2"),
    ("revision_number", "0x1018:3"),
    ("device_name", "0x1008 (at most 64 bytes)"),
];

const TOP_KEYS: [&str; 6] = [
    "schema",
    "name",
    "description",
    "extends",
    "identity",
    "quirks",
];

const U32: i64 = u32::MAX as i64;

/// Most bytes of `device_name`.
const DEVICE_NAME_MAX: usize = 64;
/// Longest boot delay, ms.
const BOOT_DELAY_MAX_MS: i64 = 600_000;

// ----------------------------------------------------------------------------- errors

/// A profile that cannot be used: where (file and line, when known), which key, why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ProfileError {
    /// The file, or the option (`--quirk ...`), the error is in.
    pub origin: String,
    /// 1-based line, when known.
    pub line: Option<usize>,
    /// The key at fault (`quirks.sdo_response_delay.delay_ms`), empty for the whole file.
    pub key: String,
    /// Why.
    pub reason: String,
}

impl std::fmt::Display for ProfileError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.origin)?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        // The reason may repeat the file's text: control characters escaped, length capped.
        let reason = crate::quote::text_max(&self.reason, 2 * crate::quote::MAX_MESSAGE_CHARS);
        if self.key.is_empty() {
            write!(f, ": {reason}")
        } else {
            write!(f, ": {}: {reason}", crate::quote::text(&self.key))
        }
    }
}

impl std::error::Error for ProfileError {}

/// Where a value was written: the file or option and the line.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Loc {
    origin: String,
    line: Option<usize>,
}

impl Loc {
    fn err(&self, key: impl Into<String>, reason: impl Into<String>) -> ProfileError {
        ProfileError {
            origin: self.origin.clone(),
            line: self.line,
            key: key.into(),
            reason: reason.into(),
        }
    }
}

fn line_of(src: &str, offset: usize) -> usize {
    src[..offset.min(src.len())].matches('\n').count() + 1
}

// ------------------------------------------------------------------------- a profile file

/// The `[identity]` of a profile: each key optional; a child's keys override one by one.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Identity {
    /// Power-on to boot-up, ms.
    pub boot_delay_ms: Option<u32>,
    /// NMT reset node to boot-up, ms.
    pub reset_node_boot_delay_ms: Option<u32>,
    /// NMT reset communication to boot-up, ms.
    pub reset_communication_boot_delay_ms: Option<u32>,
    /// 0x1000.
    pub device_type: Option<u32>,
    /// 0x1018:1.
    pub vendor_id: Option<u32>,
    /// 0x1018:2.
    pub product_code: Option<u32>,
    /// 0x1018:3.
    pub revision_number: Option<u32>,
    /// 0x1008.
    pub device_name: Option<String>,
}

impl Identity {
    fn merge(&mut self, child: &Identity) {
        macro_rules! take {
            ($($f:ident),*) => { $( if child.$f.is_some() { self.$f = child.$f.clone(); } )* };
        }
        take!(
            boot_delay_ms,
            reset_node_boot_delay_ms,
            reset_communication_boot_delay_ms,
            device_type,
            vendor_id,
            product_code,
            revision_number,
            device_name
        );
    }

    /// The identity objects it sets: (index, sub, key, value).
    pub fn objects(&self) -> Vec<(u16, u8, &'static str, u32)> {
        [
            (0x1000, 0, "device_type", self.device_type),
            (0x1018, 1, "vendor_id", self.vendor_id),
            (0x1018, 2, "product_code", self.product_code),
            (0x1018, 3, "revision_number", self.revision_number),
        ]
        .into_iter()
        .filter_map(|(i, s, k, v)| v.map(|v| (i, s, k, v)))
        .collect()
    }

    fn set(&mut self, key: &str, v: &toml::Value, loc: &Loc) -> Result<(), ProfileError> {
        let k = format!("identity.{key}");
        let num = |max: i64, unit: &str| -> Result<u32, ProfileError> {
            let n = v
                .as_integer()
                .ok_or_else(|| loc.err(&k, format!("{v} is not an integer")))?;
            if !(0..=max).contains(&n) {
                return Err(loc.err(&k, format!("{n} out of range 0..={max}{unit}")));
            }
            Ok(n as u32)
        };
        match key {
            "boot_delay_ms" => self.boot_delay_ms = Some(num(BOOT_DELAY_MAX_MS, " (ms)")?),
            "reset_node_boot_delay_ms" => {
                self.reset_node_boot_delay_ms = Some(num(BOOT_DELAY_MAX_MS, " (ms)")?)
            }
            "reset_communication_boot_delay_ms" => {
                self.reset_communication_boot_delay_ms = Some(num(BOOT_DELAY_MAX_MS, " (ms)")?)
            }
            "device_type" => self.device_type = Some(num(U32, "")?),
            "vendor_id" => self.vendor_id = Some(num(U32, "")?),
            "product_code" => self.product_code = Some(num(U32, "")?),
            "revision_number" => self.revision_number = Some(num(U32, "")?),
            "device_name" => {
                let s = v
                    .as_str()
                    .ok_or_else(|| loc.err(&k, format!("{v} is not a string")))?;
                if s.len() > DEVICE_NAME_MAX {
                    return Err(
                        loc.err(&k, format!("{} bytes, at most {DEVICE_NAME_MAX}", s.len()))
                    );
                }
                self.device_name = Some(s.to_string());
            }
            other => {
                let known: Vec<&str> = IDENTITY_KEYS.iter().map(|(k, _)| *k).collect();
                return Err(loc.err(&k, unknown("[identity] key", other, &known)));
            }
        }
        Ok(())
    }
}

/// A table whose values keep where they were written (toml spans keys of a table only through
/// their values: a key's line is its value's).
type SpannedTable = BTreeMap<String, Spanned<toml::Value>>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProfile {
    schema: Option<Spanned<toml::Value>>,
    name: Option<Spanned<toml::Value>>,
    description: Option<Spanned<toml::Value>>,
    extends: Option<Spanned<toml::Value>>,
    identity: Option<Spanned<SpannedTable>>,
    /// Read by the protocol's description of the switches: an unknown switch or parameter,
    /// a value out of range, is an error toml gives the line of.
    quirks: Option<QuirksPatch>,
}

/// A profile file, parsed and validated on its own (not yet merged with what it extends).
#[derive(Clone, Debug, PartialEq)]
pub struct ProfileFile {
    /// Its name (the file stem).
    pub name: String,
    /// Its one-line description.
    pub description: String,
    /// The profile it extends: (name or path, where written).
    extends: Option<(String, Loc)>,
    /// Its `[identity]`.
    pub identity: Identity,
    /// Its switch tables.
    pub quirks: QuirksPatch,
    /// Where it came from (`profiles/NAME.toml` for an embedded one, else the path).
    pub origin: String,
    /// The directory a relative `extends` path is taken from (none for embedded ones).
    dir: Option<PathBuf>,
}

/// A message of the switches' description (`quirks.NAME[.PARAM]: reason`) as key and reason.
fn quirk_message(msg: &str) -> Option<(String, String)> {
    let (key, reason) = msg.trim().split_once(": ")?;
    key.starts_with("quirks.")
        .then(|| (key.to_string(), reason.to_string()))
}

/// A toml error as the profile's error: line, key and reason.
fn toml_error(e: &toml::de::Error, src: &str, origin: &str) -> ProfileError {
    let line = e.span().map(|s| line_of(src, s.start));
    let msg = e.message().trim();
    if let Some((key, reason)) = quirk_message(msg) {
        return ProfileError {
            origin: origin.to_string(),
            line,
            key,
            reason,
        };
    }
    // serde's "unknown field `x`, expected one of ..." in the schema's words
    if let Some(rest) = msg.strip_prefix("unknown field `") {
        let name = rest.split('`').next().unwrap_or("");
        return ProfileError {
            origin: origin.to_string(),
            line,
            key: crate::quote::text(name),
            reason: unknown("top-level key", name, &TOP_KEYS),
        };
    }
    ProfileError {
        origin: origin.to_string(),
        line,
        key: String::new(),
        reason: crate::quote::text_max(msg, crate::quote::MAX_MESSAGE_CHARS),
    }
}

impl ProfileFile {
    /// Parse `src`; `origin` names it in errors, `stem` is the name it must have, `dir`
    /// where a relative `extends` path is read from.
    pub fn parse(
        src: &str,
        origin: &str,
        stem: &str,
        dir: Option<PathBuf>,
    ) -> Result<ProfileFile, ProfileError> {
        let raw: RawProfile = toml::from_str(src).map_err(|e| toml_error(&e, src, origin))?;
        let at = |span: std::ops::Range<usize>| Loc {
            origin: origin.to_string(),
            line: Some(line_of(src, span.start)),
        };
        let whole = Loc {
            origin: origin.to_string(),
            line: None,
        };
        let string = |v: &Option<Spanned<toml::Value>>,
                      key: &str|
         -> Result<Option<String>, ProfileError> {
            match v {
                None => Ok(None),
                Some(s) => match s.get_ref().as_str() {
                    Some(t) => Ok(Some(t.to_string())),
                    None => Err(at(s.span()).err(key, format!("{} is not a string", s.get_ref()))),
                },
            }
        };
        let schema = raw
            .schema
            .as_ref()
            .ok_or_else(|| whole.err("schema", "missing (write `schema = 1`)"))?;
        match schema.get_ref().as_integer() {
            Some(SCHEMA) => {}
            Some(n) => {
                return Err(at(schema.span()).err(
                    "schema",
                    format!("{n} not supported (this drive-emu reads schema {SCHEMA})"),
                ))
            }
            None => {
                return Err(at(schema.span())
                    .err("schema", format!("{} is not an integer", schema.get_ref())))
            }
        }
        let name = string(&raw.name, "name")?
            .ok_or_else(|| whole.err("name", "missing (the file's stem)"))?;
        if name != stem {
            let span = raw.name.as_ref().map(|s| s.span()).unwrap_or(0..0);
            return Err(at(span).err(
                "name",
                format!("\"{name}\" is not the file's stem \"{stem}\""),
            ));
        }
        let description = string(&raw.description, "description")?
            .ok_or_else(|| whole.err("description", "missing (one line)"))?;
        if description.contains('\n') {
            let span = raw.description.as_ref().map(|s| s.span()).unwrap_or(0..0);
            return Err(at(span).err("description", "more than one line"));
        }
        let extends = match (&raw.extends, string(&raw.extends, "extends")?) {
            (Some(s), Some(t)) => Some((t, at(s.span()))),
            _ => None,
        };
        let mut identity = Identity::default();
        if let Some(t) = &raw.identity {
            for (k, v) in t.get_ref() {
                identity.set(k, v.get_ref(), &at(v.span()))?;
            }
        }
        Ok(ProfileFile {
            name,
            description,
            extends,
            identity,
            quirks: raw.quirks.unwrap_or_default(),
            origin: origin.to_string(),
            dir,
        })
    }

    /// The embedded profile `name`.
    pub fn embedded(name: &str) -> Option<Result<ProfileFile, ProfileError>> {
        EMBEDDED
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(n, text)| ProfileFile::parse(text, &format!("profiles/{n}.toml"), n, None))
    }

    /// A profile by name (embedded) or path (ending in `.toml`; relative to `dir`).
    pub fn load(which: &str, dir: Option<&Path>) -> Result<ProfileFile, ProfileError> {
        if which.ends_with(".toml") || which.contains('/') {
            let p = Path::new(which);
            let path = match dir {
                Some(d) if p.is_relative() => d.join(p),
                _ => p.to_path_buf(),
            };
            let origin = path.display().to_string();
            let src = crate::infile::read_text(&path, "", crate::infile::MAX_CONFIG_BYTES)
                .map_err(|e| {
                    let (line, reason) = match e.problem {
                        crate::infile::Problem::NotUtf8 { line, column } => {
                            (Some(line), format!("column {column}: not UTF-8 text"))
                        }
                        _ => (None, format!("cannot read the profile: {}", e.reason())),
                    };
                    ProfileError {
                        origin: origin.clone(),
                        line,
                        key: String::new(),
                        reason,
                    }
                })?;
            let stem = path
                .file_stem()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_default();
            return ProfileFile::parse(&src, &origin, &stem, path.parent().map(Path::to_path_buf));
        }
        ProfileFile::embedded(which).unwrap_or_else(|| {
            let known: Vec<&str> = EMBEDDED.iter().map(|(n, _)| *n).collect();
            Err(ProfileError {
                origin: "--profile".into(),
                line: None,
                key: which.to_string(),
                reason: format!(
                    "{} (or a path to a .toml file)",
                    unknown("profile", which, &known)
                ),
            })
        })
    }

    /// The switches this file turns on (as written, not merged).
    pub fn switches_on(&self) -> Vec<&'static str> {
        let mut q = Quirks::default();
        self.quirks.apply_to(&mut q);
        q.on().collect()
    }
}

// --------------------------------------------------------- overlays: machine file, options

/// Switch tables on top of a profile: a machine file's `quirks = {...}` or the command
/// line's `--quirk` / `--no-quirk`, validated.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overlay {
    quirks: QuirksPatch,
}

/// A `quirks` table read by the switches' description; `origin_of(key)` says where the key
/// at fault was written.
fn read_quirks(
    table: toml::Table,
    origin_of: impl Fn(&str) -> Loc,
) -> Result<QuirksPatch, ProfileError> {
    use serde::Deserialize as _;
    QuirksPatch::deserialize(toml::Value::Table(table)).map_err(|e| {
        let msg = e.message().trim().to_string();
        match quirk_message(&msg) {
            Some((key, reason)) => origin_of(&key).err(key, reason),
            None => origin_of("").err("quirks", crate::quote::text_max(&msg, 400)),
        }
    })
}

impl Overlay {
    /// `--quirk NAME[.PARAM=VALUE]` (repeatable; several for one switch make one table) and
    /// `--no-quirk NAME`.
    pub fn from_args(quirk: &[String], no_quirk: &[String]) -> Result<Overlay, ProfileError> {
        let mut tables = toml::Table::new();
        // (key written, the option that wrote it), for the error's origin
        let mut written: Vec<(String, String)> = Vec::new();
        for arg in quirk {
            let origin = format!("--quirk {arg}");
            let (name, param) = match arg.split_once('.') {
                Some((n, p)) => (n.trim(), Some(p)),
                None => (arg.trim(), None),
            };
            written.push((format!("quirks.{name}"), origin.clone()));
            let entry = tables
                .entry(name.to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            if let Some(p) = param {
                let Some((k, v)) = p.split_once('=') else {
                    return Err(Loc { origin, line: None }.err(
                        format!("quirks.{name}.{p}"),
                        "write NAME.PARAM=VALUE (or NAME alone to turn it on)",
                    ));
                };
                let value = toml::from_str::<toml::Table>(&format!("v = {v}"))
                    .ok()
                    .and_then(|mut t| t.remove("v"))
                    .unwrap_or_else(|| toml::Value::String(v.to_string()));
                written.insert(0, (format!("quirks.{name}.{}", k.trim()), origin));
                if let toml::Value::Table(t) = entry {
                    t.insert(k.trim().to_string(), value);
                }
            }
        }
        for name in no_quirk {
            let origin = format!("--no-quirk {name}");
            let name = name.trim();
            if tables.contains_key(name) {
                return Err(Loc { origin, line: None }.err(
                    format!("quirks.{name}"),
                    "also given with --quirk: on or off?",
                ));
            }
            let mut t = toml::Table::new();
            t.insert("enabled".into(), toml::Value::Boolean(false));
            tables.insert(name.to_string(), toml::Value::Table(t));
            written.push((format!("quirks.{name}"), origin));
        }
        let quirks = read_quirks(tables, |key| Loc {
            origin: written
                .iter()
                .find(|(k, _)| k == key || key.starts_with(&format!("{k}.")))
                .map_or_else(|| "--quirk".to_string(), |(_, o)| o.clone()),
            line: None,
        })?;
        Ok(Overlay { quirks })
    }

    /// A machine file's `quirks = { NAME = { PARAM = VALUE } }` of one axis; `origin` and
    /// `line` say where it was written.
    pub fn from_table(
        table: &toml::Table,
        origin: &str,
        line: Option<usize>,
    ) -> Result<Overlay, ProfileError> {
        let quirks = read_quirks(table.clone(), |_| Loc {
            origin: origin.to_string(),
            line,
        })?;
        Ok(Overlay { quirks })
    }

    /// Nothing in it.
    pub fn is_empty(&self) -> bool {
        self.quirks.written().is_empty()
    }
}

// ------------------------------------------------------------------------ the result

/// What a drive behaves as: the profile (after `extends`) and the overlays on top.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QuirkProfile {
    /// The profile's name (`None`: no profile, the strict drive unless overlays say more).
    pub profile: Option<String>,
    /// The profiles read, parent first.
    pub chain: Vec<String>,
    /// The switches.
    pub quirks: Quirks,
    /// The identity keys and boot delays.
    pub identity: Identity,
}

impl QuirkProfile {
    /// Resolve `profile` (a name or path, `None`: none) with `overlays` on top, in order;
    /// `dir` is where a relative profile path is read from.
    pub fn resolve(
        profile: Option<&str>,
        dir: Option<&Path>,
        overlays: &[&Overlay],
    ) -> Result<QuirkProfile, ProfileError> {
        let mut b = QuirkProfile::default();
        let mut files = Vec::new();
        if let Some(p) = profile {
            let mut f = ProfileFile::load(p, dir)?;
            let mut seen = vec![f.origin.clone()];
            loop {
                let parent = f.extends.clone();
                files.push(f);
                let Some((which, loc)) = parent else { break };
                let parent_dir = files.last().and_then(|f| f.dir.clone());
                let pf = ProfileFile::load(&which, parent_dir.as_deref()).map_err(|e| {
                    loc.err(
                        "extends",
                        if e.origin == "--profile" {
                            e.reason
                        } else {
                            e.to_string()
                        },
                    )
                })?;
                if seen.contains(&pf.origin) {
                    seen.push(pf.origin.clone());
                    return Err(loc.err("extends", format!("a cycle: {}", seen.join(" -> "))));
                }
                seen.push(pf.origin.clone());
                f = pf;
            }
            b.profile = files.first().map(|f| f.name.clone());
        }
        for f in files.iter().rev() {
            b.chain.push(f.name.clone());
            b.identity.merge(&f.identity);
            f.quirks.apply_to(&mut b.quirks);
        }
        for o in overlays {
            o.quirks.apply_to(&mut b.quirks);
        }
        Ok(b)
    }

    /// `--profile` / `--quirk` / `--no-quirk` of `drive-emu run` (or `eds`): `None` when none
    /// is given.
    pub fn from_args(
        profile: Option<&str>,
        quirk: &[String],
        no_quirk: &[String],
    ) -> Result<Option<QuirkProfile>, ProfileError> {
        if profile.is_none() && quirk.is_empty() && no_quirk.is_empty() {
            return Ok(None);
        }
        let o = Overlay::from_args(quirk, no_quirk)?;
        QuirkProfile::resolve(profile, None, &[&o]).map(Some)
    }

    /// The switches on, with their parameters, for people (`enable_requires_mode,
    /// sdo_response_delay (delay_ms = 30)`); `strict` when none.
    pub fn switches_text(&self) -> String {
        let on: Vec<String> = self.quirks.on().map(|s| self.quirks.describe(s)).collect();
        if on.is_empty() {
            "no switch on (strict)".into()
        } else {
            on.join(", ")
        }
    }

    /// One line for the start-up message: profile, switches, boot delays that differ.
    pub fn announce(&self, node_id: u8, default_boot_delay_ms: u64) -> String {
        let mut s = format!(
            "drive-emu: node {node_id}: profile {}: {}",
            self.profile.as_deref().unwrap_or("none"),
            self.switches_text()
        );
        let id = &self.identity;
        let power = id.boot_delay_ms.map_or(default_boot_delay_ms, u64::from);
        let node = id.reset_node_boot_delay_ms.map_or(power, u64::from);
        let comm = id
            .reset_communication_boot_delay_ms
            .map_or(power, u64::from);
        if id.boot_delay_ms.is_some()
            || id.reset_node_boot_delay_ms.is_some()
            || id.reset_communication_boot_delay_ms.is_some()
        {
            s += &format!(
                "; boot-up {power} ms after power-on, {node} ms after NMT reset node, {comm} ms \
                 after reset communication"
            );
        }
        for (index, sub, key, v) in id.objects() {
            s += &format!("; {key} 0x{index:04X}:{sub} = 0x{v:08X}");
        }
        if let Some(n) = &id.device_name {
            s += &format!("; device_name 0x1008 = \"{n}\"");
        }
        s
    }
}

/// `drive-emu profiles`: the profiles shipped (name, what they turn on, description) and the
/// switches of schema 1 with their parameters.
pub fn list_text() -> Result<String, ProfileError> {
    let mut s = String::from("Profiles (--profile NAME, or a path to a .toml file):\n");
    for (name, _) in EMBEDDED {
        let f = ProfileFile::embedded(name).expect("embedded")?;
        let b = QuirkProfile::resolve(Some(name), None, &[])?;
        let on: Vec<&str> = b.quirks.on().collect();
        s += &format!(
            "  {name:<18} {}\n  {:<18}   on: {}\n",
            f.description,
            "",
            if on.is_empty() {
                "nothing (strict)".to_string()
            } else {
                on.join(", ")
            }
        );
    }
    s += "\nSwitches (--quirk NAME[.PARAM=VALUE], --no-quirk NAME; docs/quirks.md):\n";
    s += &listing(Quirks::SWITCHES);
    s += "\n[identity] keys of a profile:\n";
    for (k, what) in IDENTITY_KEYS {
        s += &format!("  {k:<34} {what}\n");
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use drive_protocol::quirks::{
        BootupThenHeartbeat, HomingBitsMissing, HomingMethodZero, SdoResponseDelay,
    };

    fn parse(src: &str) -> Result<ProfileFile, ProfileError> {
        ProfileFile::parse(src, "profiles/x.toml", "x", None)
    }

    fn err(src: &str) -> String {
        parse(src).unwrap_err().to_string()
    }

    const HEAD: &str = "schema = 1\nname = \"x\"\ndescription = \"d\"\n";

    #[test]
    fn every_shipped_profile_parses_resolves_and_is_embedded() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../profiles");
        let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .map(|p| p.file_stem().unwrap().to_string_lossy().to_string())
            .collect();
        on_disk.sort();
        let mut embedded: Vec<String> = EMBEDDED.iter().map(|(n, _)| n.to_string()).collect();
        embedded.sort();
        assert_eq!(on_disk, embedded, "every file of profiles/ is embedded");
        for (name, _) in EMBEDDED {
            let b = QuirkProfile::resolve(Some(name), None, &[]).unwrap();
            assert_eq!(b.profile.as_deref(), Some(name));
            if name != "strict" {
                assert_eq!(b.chain[0], "strict", "{name} extends strict");
                assert!(!b.quirks.is_strict() || name == "copley-accelnet", "{name}");
            }
        }
        // strict lists every switch, off
        let f = ProfileFile::embedded("strict").unwrap().unwrap();
        let all: Vec<&str> = Quirks::SWITCHES.iter().map(|s| s.name).collect();
        assert_eq!(f.quirks.written(), all);
        assert!(QuirkProfile::resolve(Some("strict"), None, &[])
            .unwrap()
            .quirks
            .is_strict());
    }

    #[test]
    fn the_profiles_turn_on_what_docs_quirks_md_says() {
        let q = |n: &str| QuirkProfile::resolve(Some(n), None, &[]).unwrap();
        let b = q("nanotec-pd4c");
        assert!(b.quirks.enable_requires_mode);
        assert_eq!(
            b.quirks.bootup_then_heartbeat,
            Some(BootupThenHeartbeat {
                first_heartbeat_after_bootup_us: 100,
                heartbeat_ms_default: 100
            })
        );
        assert_eq!(b.identity.reset_communication_boot_delay_ms, Some(0));
        assert!(q("engel-hbi").quirks.mode_change_blocked_by_halt);
        assert_eq!(
            q("jvl-mis").quirks.homing_status_bits_missing,
            Some(HomingBitsMissing {
                target_reached: true,
                attained: false
            })
        );
        assert_eq!(
            q("faulhaber-mc5004").quirks.homing_method_zero,
            HomingMethodZero::Ignore
        );
        assert_eq!(
            q("maxon-epos4").quirks.homing_method_zero,
            HomingMethodZero::Refuse
        );
        let c = q("copley-accelnet");
        assert!(!c.quirks.pdo_remap_lenient && c.identity.vendor_id == Some(0xAB));
        assert_eq!(
            q("roboteq-fbl2360")
                .quirks
                .tpdo_rtr_unsupported
                .unwrap()
                .abort_code,
            0x0609_0030
        );
        assert_eq!(
            q("technosoft-ipos")
                .quirks
                .controlword_min_hold
                .unwrap()
                .hold_us,
            1000
        );
        let w = q("delta-asda-a2").quirks.sync_watchdog.unwrap();
        assert_eq!((w.missed_periods, w.emcy_code), (2.0, 0x8100));
        assert_eq!(&w.modes[..], &[7, 8]);
        assert_eq!(
            q("isel-imd20")
                .quirks
                .late_sync_statusword_bit15
                .unwrap()
                .late_tolerance_us,
            200
        );
    }

    /// Each validation rule of docs/quirks.md section 4, with its message.
    #[test]
    fn validation_errors_name_file_line_key_and_reason() {
        assert_eq!(
            err("schema = 2\nname = \"x\"\ndescription = \"d\"\n"),
            "profiles/x.toml:1: schema: 2 not supported (this drive-emu reads schema 1)"
        );
        assert!(err("name = \"x\"\ndescription = \"d\"\n").contains("schema: missing"));
        let e = err(&format!("{HEAD}colour = 3\n"));
        assert!(
            e.starts_with("profiles/x.toml:4: colour: unknown top-level key `colour`"),
            "{e}"
        );
        let e = err(&format!("{HEAD}[identity]\nvendor = 1\n"));
        assert!(
            e.starts_with("profiles/x.toml:5: identity.vendor: unknown [identity] key `vendor`")
                && e.contains("did you mean `vendor_id`?"),
            "{e}"
        );
        let e = err(&format!("{HEAD}[quirks.sdo_reponse_delay]\n"));
        assert!(
            e.starts_with("profiles/x.toml:4: quirks.sdo_reponse_delay: unknown switch")
                && e.contains("did you mean `sdo_response_delay`?")
                && e.contains("known: enable_requires_mode"),
            "{e}"
        );
        let e = err(&format!("{HEAD}[quirks.sdo_response_delay]\ndelay = 5\n"));
        assert!(
            e.starts_with(
                "profiles/x.toml:5: quirks.sdo_response_delay.delay: unknown parameter of \
                 sdo_response_delay `delay`"
            ) && e.contains("did you mean `delay_ms`?"),
            "{e}"
        );
        assert_eq!(
            err(&format!("{HEAD}[quirks.sdo_response_delay]\n\ndelay_ms = 70000\n")),
            "profiles/x.toml:6: quirks.sdo_response_delay.delay_ms: 70000 out of range 0..=5000 (ms)"
        );
        assert_eq!(
            err(&format!(
                "{HEAD}[quirks.homing_method_zero]\nzero = \"skip\"\n"
            )),
            "profiles/x.toml:5: quirks.homing_method_zero.zero: \"skip\" is not one of \"store\", \
             \"ignore\", \"refuse\""
        );
        assert!(err(&format!(
            "{HEAD}[quirks.sdo_response_delay]\ndelay_ms = \"5\"\n"
        ))
        .contains("delay_ms: \"5\" is not an integer"));
        let e = err(&format!(
            "{HEAD}[quirks.sdo_silent_objects]\nobjects = [\"0x1800-0x17FF:5\"]\n"
        ));
        assert!(
            e.starts_with("profiles/x.toml:5: quirks.sdo_silent_objects.objects: ")
                && e.ends_with("range end below start"),
            "{e}"
        );
        assert_eq!(
            err(&format!("{HEAD}[quirks.unmappable_objects]\n")),
            "profiles/x.toml:4: quirks.unmappable_objects: parameter `objects` is required"
        );
        // off: the required parameter may be left out
        assert!(parse(&format!(
            "{HEAD}[quirks.unmappable_objects]\nenabled = false\n"
        ))
        .is_ok());
        assert!(err(&format!(
            "{HEAD}[quirks.sync_watchdog]\nmissed_periods = 0.5\n"
        ))
        .contains("missed_periods: 0.5 out of range 1.0..=100.0"));
        assert!(
            err(&format!("{HEAD}[quirks.sync_watchdog]\nmodes = [300]\n"))
                .contains("modes: 300 is not a mode of operation")
        );
        assert!(err(&format!(
            "{HEAD}[quirks.homing_status_bits_missing]\nbits = []\n"
        ))
        .contains("an empty list"));
        assert!(err(&format!("{HEAD}[identity]\nboot_delay_ms = 700000\n"))
            .contains("identity.boot_delay_ms: 700000 out of range 0..=600000 (ms)"));
        assert!(err(&format!(
            "{HEAD}[identity]\ndevice_name = \"{}\"\n",
            "x".repeat(65)
        ))
        .contains("identity.device_name: 65 bytes, at most 64"));
        assert_eq!(
            ProfileFile::parse(HEAD, "profiles/y.toml", "y", None)
                .unwrap_err()
                .to_string(),
            "profiles/y.toml:2: name: \"x\" is not the file's stem \"y\""
        );
        // a syntax error keeps toml's reason and gets the line
        let e = err(&format!("{HEAD}[quirks\n"));
        assert!(e.starts_with("profiles/x.toml:4: "), "{e}");
    }

    #[test]
    fn extends_merges_whole_switch_tables_and_identity_keys_and_finds_cycles() {
        let dir = std::env::temp_dir().join(format!("profiles-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let write = |n: &str, body: &str| {
            std::fs::write(
                dir.join(format!("{n}.toml")),
                format!("schema = 1\nname = \"{n}\"\ndescription = \"{n}\"\n{body}"),
            )
            .unwrap();
        };
        write(
            "base",
            "extends = \"delta-asda-a2\"\n[identity]\nvendor_id = 7\nboot_delay_ms = 500\n\
             [quirks.sdo_response_delay]\ndelay_ms = 30\nlate_every = 4\nlate_delay_ms = 90\n",
        );
        write(
            "child",
            "extends = \"base.toml\"\n[identity]\nvendor_id = 9\n\
             [quirks.sdo_response_delay]\ndelay_ms = 5\n[quirks.sync_watchdog]\nenabled = false\n",
        );
        let path = dir.join("child.toml").display().to_string();
        let b = QuirkProfile::resolve(Some(&path), None, &[]).unwrap();
        assert_eq!(b.chain, ["strict", "delta-asda-a2", "base", "child"]);
        assert_eq!(b.identity.vendor_id, Some(9));
        assert_eq!(b.identity.boot_delay_ms, Some(500), "kept from the parent");
        // the child's table replaces the parent's whole table
        assert_eq!(
            b.quirks.sdo_response_delay,
            Some(SdoResponseDelay {
                delay_ms: 5,
                late_delay_ms: 0,
                late_every: 0
            })
        );
        assert_eq!(b.quirks.sync_watchdog, None, "turned off by the child");
        // overlays on top: --quirk / --no-quirk
        let o = Overlay::from_args(
            &[
                "sdo_response_delay.delay_ms=30".into(),
                "enable_requires_mode".into(),
            ],
            &["sdo_response_delay_x".into()],
        );
        assert!(o
            .unwrap_err()
            .to_string()
            .contains("did you mean `sdo_response_delay`"));
        let o = Overlay::from_args(
            &[
                "sdo_response_delay.delay_ms=30".into(),
                "sdo_response_delay.late_every=3".into(),
                "enable_requires_mode".into(),
            ],
            &[],
        )
        .unwrap();
        let b = QuirkProfile::resolve(Some(&path), None, &[&o]).unwrap();
        assert_eq!(
            b.quirks.sdo_response_delay,
            Some(SdoResponseDelay {
                delay_ms: 30,
                late_delay_ms: 0,
                late_every: 3
            })
        );
        assert!(b.quirks.enable_requires_mode);
        let off = Overlay::from_args(&[], &["sdo_response_delay".into()]).unwrap();
        let b = QuirkProfile::resolve(Some(&path), None, &[&off]).unwrap();
        assert_eq!(b.quirks.sdo_response_delay, None);
        let e = Overlay::from_args(&["sdo_response_delay.delay_ms=9000".into()], &[])
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "--quirk sdo_response_delay.delay_ms=9000: quirks.sdo_response_delay.delay_ms: 9000 \
             out of range 0..=5000 (ms)"
        );
        // a cycle, an unknown parent
        write("a", "extends = \"b.toml\"\n");
        write("b", "extends = \"a.toml\"\n");
        let e = QuirkProfile::resolve(Some(&dir.join("a.toml").display().to_string()), None, &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(":4: extends: a cycle: ") && e.contains("a.toml"),
            "{e}"
        );
        write("c", "extends = \"nanotec-pd4\"\n");
        let e = QuirkProfile::resolve(Some(&dir.join("c.toml").display().to_string()), None, &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(
                "c.toml:4: extends: unknown profile `nanotec-pd4` (did you mean \
                        `nanotec-pd4c`?"
            ),
            "{e}"
        );
        let e = QuirkProfile::resolve(Some("nanotec"), None, &[])
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("--profile: nanotec: unknown profile"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_listing_has_every_profile_and_switch() {
        let t = list_text().unwrap();
        for (n, _) in EMBEDDED {
            assert!(t.contains(n), "{n}");
        }
        for s in Quirks::SWITCHES {
            assert!(t.contains(s.name), "{}", s.name);
            for p in s.params {
                assert!(t.contains(&format!("{} = ", p.name)), "{}", p.name);
            }
        }
        assert!(t.contains("delay_ms = 0..=5000 ms [10]"), "{t}");
    }
}
