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
//! eds = "vendor/epos4.eds"  # optional: serve this vendor's EDS/DCF (relative to this file)
//! objects_base = 0x4000     # optional: where the emulator's own objects go
//! ```

use anyhow::{bail, Context, Result};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub const MIN_TICK_HZ: u32 = 250;
pub const MAX_TICK_HZ: u32 = 8000;

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MachineFile {
    #[serde(default = "default_tick_hz")]
    pub tick_hz: u32,
    #[serde(rename = "axis")]
    pub axes: Vec<AxisEntry>,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AxisEntry {
    pub node_id: u8,
    pub preset: String,
    /// Preset overrides, `key = value` with the preset file's keys (units in the names).
    #[serde(default)]
    pub set: BTreeMap<String, toml::Value>,
    /// A vendor's EDS or DCF the drive serves as its own (`drive/vendor.rs`); in a machine
    /// file, relative to the file's directory.
    #[serde(default)]
    pub eds: Option<PathBuf>,
    /// First index of the emulator's own objects (default 0x2000, or the first free base
    /// with `eds`).
    #[serde(default)]
    pub objects_base: Option<u16>,
}

fn default_tick_hz() -> u32 {
    1000
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
    Ok(())
}

/// Parse machine-file text; `origin` names the file in errors.
pub fn parse(text: &str, origin: &str) -> Result<MachineFile> {
    let m: MachineFile = toml::from_str(text).map_err(|e| {
        // toml's message carries the line, column and key; prefix the file.
        anyhow::anyhow!("{origin}: {e}")
    })?;
    validate(&m).with_context(|| origin.to_string())?;
    Ok(m)
}

pub fn load(path: &Path) -> Result<MachineFile> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read machine file {}", path.display()))?;
    let mut m = parse(&text, &path.display().to_string())?;
    // an EDS path is relative to the machine file, as a user writes it beside it
    let dir = path.parent().unwrap_or(Path::new("."));
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
}
