//! The machine file: which axes one process serves, on which node IDs, with which presets.
//!
//! ```toml
//! tick_hz = 1000            # loop rate, 250..8000
//! [[axis]]
//! node_id = 5
//! preset = "cnc1"
//! set = { backlash_mm = 0.05, kv_per_s = 30.0 }   # optional preset overrides
//! [[axis]]
//! node_id = 6
//! preset = "cnc3"
//! worn = true               # optional: the preset's worn drive train (its paper backlash)
//! eds = "vendor/epos4.eds"  # optional: serve this vendor's EDS/DCF (relative to this file)
//! objects_base = 0x4000     # optional: where the emulator's own objects go
//! profile = "maxon-epos4"   # optional: vendor behaviour (profiles/, or a .toml beside this file)
//! quirks = { sdo_response_delay = { delay_ms = 30 } }   # optional: switches on top
//! ```
//!
//! An axis may carry a `name = "X"` (unique in the file), and `[ballbar] axes = ["X", "Y"]`
//! names the two linear axes `drive-emu ballbar --config` runs its circle on (docs/ballbar.md);
//! `[contour] axes = ["X", "Y", "Z"]` (two or three, optional `accel_mm_s2`) those
//! `drive-emu contour --config` interpolates lines on (docs/contour.md).
//!
//! Wear (docs/decisions/0014-healthy-default.md): `drive-emu run` serves a healthy axis (the
//! preset with no gap in its drive train) unless the axis asks for wear: `worn = true` (the
//! preset's own, the paper's, backlash) or a gap of its own in `set` (`backlash_mm` /
//! `backlash_deg`). The study tools (`ballbar --config`) keep the presets' values.

use super::quirk_profile::{Overlay, QuirkProfile};
use crate::presets::AxisConfig;
use anyhow::{bail, Context, Result};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub const MIN_TICK_HZ: u32 = 250;
pub const MAX_TICK_HZ: u32 = 8000;

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MachineFile {
    #[serde(default = "default_tick_hz")]
    pub tick_hz: u32,
    #[serde(rename = "axis")]
    pub axes: Vec<AxisEntry>,
    /// The plane of `drive-emu ballbar --config`: which two named axes are its X and Y.
    #[serde(default)]
    pub ballbar: Option<BallbarPlane>,
    /// The axes of `drive-emu contour --config`: two or three named axes, in program order.
    #[serde(default)]
    pub contour: Option<ContourAxes>,
}

/// `[contour] axes = ["X", "Y", "Z"]`: the axes a line program runs on, by the axes' `name`
/// (letters only: the program's words are a name and a number, `X10`).
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ContourAxes {
    pub axes: Vec<String>,
    /// The path acceleration of each segment's feed ramp, mm/s^2 (`--accel-mm-s2` overrides).
    #[serde(default)]
    pub accel_mm_s2: Option<f64>,
}

/// `[ballbar] axes = ["X", "Y"]`: the circle's X and Y by the axes' `name`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BallbarPlane {
    pub axes: [String; 2],
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AxisEntry {
    pub node_id: u8,
    /// The axis's name in the machine's kinematic (X, Y, Z, ...), unique in the file.
    #[serde(default)]
    pub name: Option<String>,
    pub preset: String,
    /// Preset overrides, `key = value` with the preset file's keys (units in the names).
    #[serde(default)]
    pub set: BTreeMap<String, toml::Value>,
    /// `drive-emu run`: serve the preset's worn drive train (its backlash, the paper's) instead
    /// of a healthy axis (`run --worn`). A gap in `set` is wear too.
    #[serde(default)]
    pub worn: bool,
    /// A vendor's EDS or DCF the drive serves as its own (`drive/vendor.rs`); in a machine
    /// file, relative to the file's directory.
    #[serde(default)]
    pub eds: Option<PathBuf>,
    /// First index of the emulator's own objects (default 0x2000, or the first free base
    /// with `eds`).
    #[serde(default)]
    pub objects_base: Option<u16>,
    /// The vendor behaviour profile (docs/quirks.md): a name from `profiles/`, or a path to a
    /// `.toml` (relative to the machine file).
    #[serde(default)]
    pub profile: Option<String>,
    /// Switches on top of the profile: `{ NAME = { PARAM = VALUE } }`, `{ NAME = {} }` on with
    /// its defaults, `{ NAME = { enabled = false } }` off.
    #[serde(default)]
    pub quirks: Option<toml::Spanned<toml::Table>>,
    /// `profile` and `quirks` resolved when the file is read (or the command line's
    /// `--profile` / `--quirk` / `--no-quirk`); `None`: the strict drive.
    #[serde(skip)]
    pub quirk_profile: Option<Arc<QuirkProfile>>,
}

fn default_tick_hz() -> u32 {
    1000
}

/// The preset keys that are wear: a gap in the drive train.
pub const WEAR_KEYS: [&str; 2] = ["backlash_mm", "backlash_deg"];

impl AxisEntry {
    /// Whether this axis asks for wear: `worn` (`run --worn`) or a gap of its own in `set`.
    pub fn asks_for_wear(&self) -> bool {
        self.worn || self.set.keys().any(|k| WEAR_KEYS.contains(&k.trim()))
    }

    /// The preset with this entry's overrides, as the study tools take it (the paper's worn
    /// machine where the preset is one). Errors name the node.
    pub fn preset_config(&self) -> Result<AxisConfig> {
        let mut cfg = AxisConfig::from_preset(&self.preset)
            .map_err(|err| anyhow::anyhow!("axis node {}: {err}", self.node_id))?;
        for (k, v) in &self.set {
            cfg = cfg
                .with_override(k, &value_text(v))
                .map_err(|err| anyhow::anyhow!("axis node {}: {err}", self.node_id))?;
        }
        Ok(cfg)
    }

    /// The axis `drive-emu run` serves: [`preset_config`](Self::preset_config), made healthy
    /// (no gap) unless the entry asks for wear.
    pub fn run_config(&self) -> Result<AxisConfig> {
        Ok(served(self.preset_config()?, self.asks_for_wear()))
    }
}

/// Whether `--set key=value` overrides give the drive train a gap of their own (wear).
pub fn sets_ask_for_wear<S: AsRef<str>>(sets: &[S]) -> bool {
    sets.iter().any(|s| {
        s.as_ref()
            .split_once('=')
            .is_some_and(|(k, _)| WEAR_KEYS.contains(&k.trim()))
    })
}

/// The axis `drive-emu run` (and `drive-emu eds`, which describes it) serves: `cfg` as it is
/// where wear was asked for, else [`healthy`].
pub fn served(cfg: AxisConfig, asks_for_wear: bool) -> AxisConfig {
    if asks_for_wear {
        cfg
    } else {
        healthy(cfg)
    }
}

/// The axis with no gap in its drive train (a twin pinion's pair then moves as one whatever
/// its preload): every other key as the preset says.
pub fn healthy(mut cfg: AxisConfig) -> AxisConfig {
    cfg.backlash_mm = cfg.backlash_mm.map(|_| 0.0);
    cfg.backlash_deg = cfg.backlash_deg.map(|_| 0.0);
    cfg
}

/// The gap an axis was built with as a user writes it (`backlash 0.03 mm`), `None` without
/// one; `gap_si` in m (linear) or rad (rotary).
pub fn wear_text(gap_si: f64, rotary: bool) -> Option<String> {
    (gap_si > 0.0).then(|| {
        if rotary {
            format!("backlash {} deg", round_sig(gap_si.to_degrees()))
        } else {
            format!("backlash {} mm", round_sig(gap_si * 1e3))
        }
    })
}

/// About 4 significant digits, no trailing zeros.
fn round_sig(x: f64) -> String {
    let digits = (3 - x.abs().log10().floor() as i32).clamp(0, 9) as usize;
    let t = format!("{x:.digits$}");
    if t.contains('.') {
        t.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        t
    }
}

/// Check the values serde cannot: ranges and uniqueness. Errors name the key.
pub fn validate(m: &MachineFile) -> Result<()> {
    if !(MIN_TICK_HZ..=MAX_TICK_HZ).contains(&m.tick_hz) {
        bail!(
            "key `tick_hz`: {} is outside {MIN_TICK_HZ}..={MAX_TICK_HZ}",
            m.tick_hz
        );
    }
    if 1_000_000 % m.tick_hz != 0 {
        bail!(
            "key `tick_hz`: {} Hz does not give a whole number of microseconds per tick",
            m.tick_hz
        );
    }
    if m.axes.is_empty() {
        bail!("no [[axis]] entries: a machine needs at least one axis");
    }
    let mut seen = std::collections::BTreeSet::new();
    for (i, a) in m.axes.iter().enumerate() {
        // 255: non-configured (LSS), for a single drive: two would share one LSS address
        let lss_single = a.node_id == 255 && m.axes.len() == 1;
        if !(1..=127).contains(&a.node_id) && !lss_single {
            bail!(
                "axis {} key `node_id`: {} is outside 1..=127 (255, non-configured for LSS, \
                 only on a machine of one axis)",
                i + 1,
                a.node_id
            );
        }
        if !seen.insert(a.node_id) {
            bail!("axis {} key `node_id`: {} is used twice", i + 1, a.node_id);
        }
    }
    let mut names = std::collections::BTreeSet::new();
    for (i, a) in m.axes.iter().enumerate() {
        if let Some(n) = &a.name {
            if n.trim().is_empty() || n.chars().any(char::is_control) {
                bail!(
                    "axis {} key `name`: must be a non-empty printable name",
                    i + 1
                );
            }
            if !names.insert(n.as_str()) {
                bail!("axis {} key `name`: {n:?} is used twice", i + 1);
            }
        }
    }
    if let Some(b) = &m.ballbar {
        for n in &b.axes {
            if !names.contains(n.as_str()) {
                bail!(
                    "key `ballbar.axes`: no axis is named {n:?} (give the axes `name = \"X\"`; \
                     named here: {})",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names
                            .iter()
                            .map(|n| format!("{n:?}"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    }
                );
            }
        }
        if b.axes[0] == b.axes[1] {
            bail!(
                "key `ballbar.axes`: X and Y are the same axis {:?}",
                b.axes[0]
            );
        }
    }
    if let Some(c) = &m.contour {
        validate_contour(c, &names)?;
    }
    Ok(())
}

/// `[contour]`: two or three distinct named axes with names of letters, a positive finite
/// acceleration.
fn validate_contour(c: &ContourAxes, names: &std::collections::BTreeSet<&str>) -> Result<()> {
    if !(2..=3).contains(&c.axes.len()) {
        bail!(
            "key `contour.axes`: {} axes; a line program runs on two or three (e.g. [\"X\", \"Y\"])",
            c.axes.len()
        );
    }
    for (i, n) in c.axes.iter().enumerate() {
        if !names.contains(n.as_str()) {
            bail!("key `contour.axes`: no axis is named {n:?} (give the axes `name = \"X\"`)");
        }
        if !n.chars().all(|ch| ch.is_ascii_alphabetic()) {
            bail!(
                "key `contour.axes`: {n:?} is not a name of letters (the program's words are a \
                 name and a number, X10)"
            );
        }
        if c.axes[..i].contains(n) {
            bail!("key `contour.axes`: {n:?} is named twice");
        }
    }
    if let Some(a) = c.accel_mm_s2 {
        if !(a.is_finite() && a > 0.0) {
            bail!("key `contour.accel_mm_s2`: {a} must be a finite acceleration > 0 mm/s^2");
        }
    }
    Ok(())
}

/// Parse machine-file text; `origin` names the file in errors.
pub fn parse(text: &str, origin: &str) -> Result<MachineFile> {
    parse_in(text, origin, None)
}

/// [`parse`], with profile paths relative to `dir`.
fn parse_in(text: &str, origin: &str, dir: Option<&Path>) -> Result<MachineFile> {
    let mut m: MachineFile = toml::from_str(text)
        .map_err(|e| anyhow::anyhow!("{origin}: {}", crate::quote::toml_error(&e, text)))?;
    validate(&m).with_context(|| origin.to_string())?;
    for (i, a) in m.axes.iter_mut().enumerate() {
        let overlay = match &a.quirks {
            Some(q) => {
                let line = text[..q.span().start.min(text.len())].matches('\n').count() + 1;
                Overlay::from_table(q.get_ref(), &format!("{origin} axis {}", i + 1), Some(line))?
            }
            None => Overlay::default(),
        };
        if a.profile.is_some() || !overlay.is_empty() {
            let b = QuirkProfile::resolve(a.profile.as_deref(), dir, &[&overlay])
                .with_context(|| format!("{origin}: axis {} (node {})", i + 1, a.node_id))?;
            a.quirk_profile = Some(Arc::new(b));
        }
    }
    Ok(m)
}

pub fn load(path: &Path) -> Result<MachineFile> {
    let text = crate::infile::read_text(path, "machine file", crate::infile::MAX_CONFIG_BYTES)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut m = parse_in(&text, &path.display().to_string(), Some(dir))?;
    // an EDS path is relative to the machine file, as a user writes it beside it
    for a in &mut m.axes {
        if let Some(e) = &a.eds {
            if e.is_relative() {
                a.eds = Some(dir.join(e));
            }
        }
    }
    Ok(m)
}

/// Render an override value as the text a preset's `--set key=value` takes.
pub fn value_text(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Node-ID 255 (non-configured, LSS) on a machine of one axis; not on two (they would
    /// share one LSS address).
    #[test]
    fn node_id_255_only_on_a_single_axis() {
        assert!(parse("[[axis]]\nnode_id = 255\npreset = \"cnc1\"\n", "m.toml").is_ok());
        let e = parse(
            "[[axis]]\nnode_id = 255\npreset = \"a\"\n[[axis]]\nnode_id = 6\npreset = \"b\"\n",
            "m.toml",
        )
        .unwrap_err();
        let e = format!("{e:#}");
        assert!(e.contains("255") && e.contains("one axis"), "{e}");
        for bad in [0u8, 128, 254] {
            let text = format!("[[axis]]\nnode_id = {bad}\npreset = \"a\"\n");
            assert!(parse(&text, "m.toml").is_err(), "{bad}");
        }
    }

    #[test]
    fn parses_axes_and_overrides() {
        let m = parse(
            "tick_hz = 2000\n[[axis]]\nnode_id = 5\npreset = \"cnc1\"\nset = { backlash_mm = 0.05 }\n\
             [[axis]]\nnode_id = 6\npreset = \"cnc3\"\n",
            "m.toml",
        )
        .unwrap();
        assert_eq!(m.tick_hz, 2000);
        assert_eq!(m.axes.len(), 2);
        assert_eq!(value_text(&m.axes[0].set["backlash_mm"]), "0.05");
    }

    #[test]
    fn errors_name_file_key_and_reason() {
        let e = parse(
            "[[axis]]\nnode_id = 5\npreset = \"cnc1\"\nspeed = 3\n",
            "m.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("m.toml") && e.contains("speed") && e.contains("line 4"),
            "{e}"
        );
        let e = format!(
            "{:#}",
            parse(
                "tick_hz = 100\n[[axis]]\nnode_id = 5\npreset = \"cnc1\"\n",
                "m.toml"
            )
            .unwrap_err()
        );
        assert!(e.contains("tick_hz") && e.contains("250"), "{e}");
        let e = format!(
            "{:#}",
            parse(
                "[[axis]]\nnode_id = 5\npreset = \"a\"\n[[axis]]\nnode_id = 5\npreset = \"b\"\n",
                "m.toml"
            )
            .unwrap_err()
        );
        assert!(e.contains("used twice"), "{e}");
        let e = format!(
            "{:#}",
            parse("[[axis]]\nnode_id = 0\npreset = \"a\"\n", "m.toml").unwrap_err()
        );
        assert!(e.contains("node_id") && e.contains("1..=127"), "{e}");
    }

    /// Axis names and the ballbar's plane: unique names, the plane's axes must exist.
    #[test]
    fn names_and_the_ballbar_plane() {
        let m = parse(
            "[ballbar]\naxes = [\"X\", \"Y\"]\n[[axis]]\nnode_id = 5\nname = \"X\"\npreset = \"cnc1\"\n\
             [[axis]]\nnode_id = 6\nname = \"Y\"\npreset = \"cnc2\"\n",
            "m.toml",
        )
        .unwrap();
        assert_eq!(m.axes[1].name.as_deref(), Some("Y"));
        assert_eq!(m.ballbar.unwrap().axes, ["X".to_string(), "Y".to_string()]);
        for (text, want) in [
            (
                "[ballbar]\naxes = [\"X\", \"Z\"]\n[[axis]]\nnode_id = 5\nname = \"X\"\npreset = \"cnc1\"\n",
                "no axis is named \"Z\"",
            ),
            (
                "[[axis]]\nnode_id = 5\nname = \"X\"\npreset = \"cnc1\"\n[[axis]]\nnode_id = 6\nname = \"X\"\npreset = \"cnc1\"\n",
                "used twice",
            ),
            (
                "[ballbar]\naxes = [\"X\", \"X\"]\n[[axis]]\nnode_id = 5\nname = \"X\"\npreset = \"cnc1\"\n",
                "same axis",
            ),
            (
                "[ballbar]\naxes = [\"X\"]\n[[axis]]\nnode_id = 5\nname = \"X\"\npreset = \"cnc1\"\n",
                "expected an array of length 2",
            ),
        ] {
            let e = format!("{:#}", parse(text, "m.toml").unwrap_err());
            assert!(e.contains(want), "{e}");
        }
    }

    /// The contour's axes: two or three existing, distinct names of letters; a positive
    /// acceleration; `[ballbar]` and `[contour]` side by side.
    #[test]
    fn the_contour_section() {
        let axes = "[[axis]]\nnode_id = 5\nname = \"X\"\npreset = \"cnc1\"\n\
                    [[axis]]\nnode_id = 6\nname = \"Y\"\npreset = \"cnc2\"\n\
                    [[axis]]\nnode_id = 7\nname = \"Z1\"\npreset = \"cnc4\"\n";
        let m = parse(
            &format!(
                "[ballbar]\naxes = [\"X\", \"Y\"]\n[contour]\naxes = [\"Y\", \"X\"]\naccel_mm_s2 = 50.0\n{axes}"
            ),
            "m.toml",
        )
        .unwrap();
        let c = m.contour.unwrap();
        assert_eq!(c.axes, ["Y".to_string(), "X".to_string()]);
        assert_eq!(c.accel_mm_s2, Some(50.0));
        for (section, want) in [
            ("axes = [\"X\"]", "1 axes"),
            ("axes = [\"X\", \"Y\", \"X\"]", "\"X\" is named twice"),
            ("axes = [\"X\", \"W\"]", "no axis is named \"W\""),
            ("axes = [\"X\", \"Z1\"]", "\"Z1\" is not a name of letters"),
            (
                "axes = [\"X\", \"Y\"]\naccel_mm_s2 = 0.0",
                "key `contour.accel_mm_s2`",
            ),
            ("axes = [\"X\", \"Y\"]\nfeed = 1", "unknown field `feed`"),
        ] {
            let e = format!(
                "{:#}",
                parse(&format!("[contour]\n{section}\n{axes}"), "m.toml").unwrap_err()
            );
            assert!(e.contains(want), "{section}: {e}");
        }
    }

    /// `profile` and `quirks` per axis: resolved when the file is read; a bad switch is an
    /// error naming the file, its line and the key.
    #[test]
    fn profiles_and_quirks_per_axis() {
        let m = parse(
            "[[axis]]\nnode_id = 5\npreset = \"cnc1\"\nprofile = \"maxon-epos4\"\n\
             quirks = { sdo_response_delay = { delay_ms = 30 } }\n\
             [[axis]]\nnode_id = 6\npreset = \"cnc1\"\n",
            "m.toml",
        )
        .unwrap();
        let b = m.axes[0].quirk_profile.as_ref().unwrap();
        assert_eq!(b.profile.as_deref(), Some("maxon-epos4"));
        assert_eq!(
            b.quirks.on().collect::<Vec<_>>(),
            ["homing_method_zero", "sdo_response_delay"]
        );
        assert_eq!(b.quirks.sdo_response_delay.unwrap().delay_ms, 30);
        assert!(m.axes[1].quirk_profile.is_none(), "no profile: strict");
        let e = format!(
            "{:#}",
            parse(
                "[[axis]]\nnode_id = 5\npreset = \"cnc1\"\n\
                 quirks = { sdo_response_delay = { delay_ms = 9000 } }\n",
                "m.toml"
            )
            .unwrap_err()
        );
        assert!(
            e.contains("m.toml axis 1:4: quirks.sdo_response_delay.delay_ms: 9000 out of range"),
            "{e}"
        );
        let e = format!(
            "{:#}",
            parse(
                "[[axis]]\nnode_id = 5\npreset = \"cnc1\"\nprofile = \"maxon\"\n",
                "m.toml"
            )
            .unwrap_err()
        );
        assert!(
            e.contains("m.toml: axis 1 (node 5)") && e.contains("unknown profile `maxon`"),
            "{e}"
        );
    }
}
