//! `drive-emu run --lss-store FILE`: the drive's non-volatile memory for LSS (CiA 305) store
//! configuration. A real drive writes the node-ID and bit timing a master stored to its
//! EEPROM and boots with them after a power cycle; the emulator writes them to FILE and a
//! later `drive-emu run` with the same FILE boots with them (FILE's node-ID wins over
//! `--node`, which is the factory default a drive has before anything was stored).
//!
//! The file is TOML:
//!
//! ```toml
//! node_id = 12          # 1..=127, or 255: non-configured
//! bit_timing_index = 0  # CiA 301 table: 0 = 1 Mbit/s, 1 = 800k, 2 = 500k, 3 = 250k, ...
//! ```

use anyhow::{bail, Context, Result};
use drive_protocol::wire::lss::{bit_rate_kbit_per_s, UNCONFIGURED_NODE_ID};
use drive_protocol::LssStore;
use serde::Deserialize;
use std::path::Path;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StoreFile {
    node_id: u8,
    bit_timing_index: u8,
}

/// What an LSS store file holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stored {
    /// `None`: non-configured (255).
    pub node_id: Option<u8>,
    /// CiA 301 bit timing table index.
    pub bit_timing_index: u8,
}

/// Parse the text of a store file; `origin` names it in errors (with line and key from the
/// TOML reader, or the key and the allowed values).
pub fn parse(text: &str, origin: &str) -> Result<Stored> {
    let f: StoreFile = toml::from_str(text)
        .map_err(|e| anyhow::anyhow!("{origin}: {}", crate::quote::toml_error(&e, text)))?;
    if !(1..=127).contains(&f.node_id) && f.node_id != UNCONFIGURED_NODE_ID {
        bail!(
            "{origin}: key `node_id`: {} is outside 1..=127 (255: non-configured)",
            f.node_id
        );
    }
    if bit_rate_kbit_per_s(f.bit_timing_index).is_none() {
        bail!(
            "{origin}: key `bit_timing_index`: {} is not a CiA 301 bit timing (0..=4, 6..=8)",
            f.bit_timing_index
        );
    }
    Ok(Stored {
        node_id: (f.node_id != UNCONFIGURED_NODE_ID).then_some(f.node_id),
        bit_timing_index: f.bit_timing_index,
    })
}

/// Read a store file; `Ok(None)` when it does not exist yet (nothing stored), an error when
/// it cannot be read or is not a store file. A file whose directory does not exist is an
/// error now rather than at the first store.
pub fn load(path: &Path) -> Result<Option<Stored>> {
    match crate::infile::read_text(path, "--lss-store", MAX_FILE_BYTES) {
        Ok(text) => parse(&text, &crate::quote::text(&path.to_string_lossy())).map(Some),
        Err(e) if e.is_not_found() => {
            let dir = path
                .parent()
                .filter(|d| !d.as_os_str().is_empty())
                .unwrap_or(Path::new("."));
            if !dir.is_dir() {
                bail!(
                    "--lss-store {}: the directory {} does not exist",
                    crate::quote::text(&path.to_string_lossy()),
                    crate::quote::text(&dir.to_string_lossy())
                );
            }
            Ok(None)
        }
        Err(e) => Err(e.into()),
    }
}

/// Largest LSS store file read, bytes (one is about 150).
pub const MAX_FILE_BYTES: u64 = 64 << 10;

/// The file's text for a store.
pub fn text(s: &LssStore) -> String {
    format!(
        "# drive-emu LSS store (CiA 305 store configuration): what this drive boots with\n\
         node_id = {}  # 1..=127, 255: non-configured\n\
         bit_timing_index = {}  # CiA 301 table index: {} kbit/s\n",
        s.node_id.unwrap_or(UNCONFIGURED_NODE_ID),
        s.bit_timing_index,
        bit_rate_kbit_per_s(s.bit_timing_index).unwrap_or(0)
    )
}

/// Write a store: to a temporary file beside it, then renamed over it, so a crash leaves the
/// old file or the new one, never half of one.
///
/// The temporary file `FILE.tmp` is made new (`O_EXCL|O_NOFOLLOW`, mode 0600): a stale one
/// is removed first (unlinking a symlink never touches its target); one that cannot be
/// removed, or that appears again in between (someone else's), is an error, never written
/// through.
pub fn save(path: &Path, s: &LssStore) -> Result<()> {
    use std::io::Write;
    use std::os::unix::fs::OpenOptionsExt;
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = std::path::PathBuf::from(tmp);
    match std::fs::remove_file(&tmp) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            return Err(e).with_context(|| {
                format!("cannot remove the stale temporary file {}", tmp.display())
            })
        }
        _ => {}
    }
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC)
        .open(&tmp)
        .with_context(|| format!("cannot create {} (new, not through a link)", tmp.display()))?;
    f.write_all(text(s).as_bytes())
        .and_then(|()| f.sync_all())
        .with_context(|| format!("cannot write {}", tmp.display()))?;
    drop(f);
    std::fs::rename(&tmp, path)
        .with_context(|| format!("cannot rename {} to {}", tmp.display(), path.display()))
}

/// A bit timing for people: "index 2 (500 kbit/s)".
pub fn bit_timing_text(index: u8) -> String {
    match bit_rate_kbit_per_s(index) {
        Some(k) => format!("index {index} ({k} kbit/s)"),
        None => format!("index {index}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_saved_store_loads_back() {
        let dir = std::env::temp_dir().join(format!("lss-store-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("drive.lss");
        let _ = std::fs::remove_file(&path);
        assert_eq!(load(&path).unwrap(), None, "nothing stored yet");
        for (node_id, bit_timing_index) in [(Some(12), 0), (None, 2), (Some(127), 8)] {
            let s = LssStore {
                node_id,
                bit_timing_index,
            };
            save(&path, &s).unwrap();
            assert_eq!(
                load(&path).unwrap(),
                Some(Stored {
                    node_id,
                    bit_timing_index
                })
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bad_files_are_clear_errors() {
        for (text, want) in [
            (
                "node_id = 0\nbit_timing_index = 0\n",
                "`node_id`: 0 is outside 1..=127",
            ),
            ("node_id = 200\nbit_timing_index = 0\n", "200 is outside"),
            (
                "node_id = 5\nbit_timing_index = 5\n",
                "`bit_timing_index`: 5",
            ),
            ("node_id = 5\n", "bit_timing_index"),
            ("node_id = 5\nbit_timing_index = 0\nbaud = 3\n", "baud"),
            ("node_id = 300\nbit_timing_index = 0\n", "line 1"),
            ("node_id = \"x\nbit_timing_index = 0\n", "line 1"),
        ] {
            let e = parse(text, "drive.lss").unwrap_err().to_string();
            assert!(
                e.starts_with("drive.lss: ") && e.contains(want),
                "{text:?}: {e}"
            );
        }
        let e = load(Path::new("/nonexistent-dir-drive-emu/x.lss"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not exist"), "{e}");
        // A device or a FIFO is refused by name, not read for ever.
        let e = load(Path::new("/dev/zero")).unwrap_err().to_string();
        assert!(
            e.contains("/dev/zero: a character device, not a regular file"),
            "{e}"
        );
    }

    #[test]
    fn a_planted_temporary_symlink_is_not_written_through() {
        let dir = std::env::temp_dir().join(format!("lss-store-plant-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let victim = dir.join("victim");
        std::fs::write(&victim, "root-only\n").unwrap();
        let path = dir.join("drive.lss");
        std::os::unix::fs::symlink(&victim, dir.join("drive.lss.tmp")).unwrap();
        let s = LssStore {
            node_id: Some(12),
            bit_timing_index: 0,
        };
        save(&path, &s).unwrap();
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "root-only\n");
        assert_eq!(load(&path).unwrap().unwrap().node_id, Some(12));
        assert!(!std::fs::symlink_metadata(&path).unwrap().is_symlink());
        assert!(!dir.join("drive.lss.tmp").exists());
        // A temporary name that cannot be removed (a non-empty directory here, as another
        // user's file in a sticky folder would be): an error, the store untouched.
        std::fs::create_dir(dir.join("drive.lss.tmp")).unwrap();
        std::fs::write(dir.join("drive.lss.tmp").join("x"), "").unwrap();
        let e = save(
            &path,
            &LssStore {
                node_id: Some(3),
                bit_timing_index: 0,
            },
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("drive.lss.tmp"), "{e}");
        assert_eq!(load(&path).unwrap().unwrap().node_id, Some(12));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_file_that_is_not_utf8_says_where() {
        let dir = std::env::temp_dir().join(format!("lss-store-utf8-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("drive.lss");
        std::fs::write(&path, b"node_id = 5\nbit_timing_index = \xff\n").unwrap();
        let e = load(&path).unwrap_err().to_string();
        assert!(e.contains("line 2, column 20: not UTF-8"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
