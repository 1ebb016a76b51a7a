//! A vendor's EDS or DCF as the drive's own (`run --eds FILE`, `eds = "FILE"` in a machine
//! file, `drive-emu eds --from FILE`): the drive boots with that identity, device type, PDO
//! defaults and COB-IDs and serves every object of the file (`od::from_eds` in the protocol
//! crate decides what is simulated, stored or dropped). Here, what the emulator adds:
//!
//! - the file is read as a user gives it (UTF-8 or Latin-1), and every error names it;
//! - the simulated motor encoder takes the file's resolution (0x608F default: increments per
//!   motor revolution), so positions in the vendor's units mean what they mean on that drive;
//! - the emulator's own objects (`objects.rs`) go where the file has nothing: 0x2000 if free,
//!   else the first free base of 0x3000, 0x4000, 0x5000, 0x2000 + k * 0x200 (or where the
//!   user says, if free).

use super::objects;
use crate::presets::AxisConfig;
use anyhow::{bail, Result};
use drive_protocol::od::eds_parse::{self, EdsFile};
use drive_protocol::od::{BuildReport, Fate, ObjectDictionary};
use drive_protocol::DriveInfo;
use std::path::{Path, PathBuf};

/// A vendor's EDS or DCF, read.
#[derive(Clone, Debug, PartialEq)]
pub struct VendorEds {
    /// Where it came from.
    pub path: PathBuf,
    /// What it says.
    pub file: EdsFile,
}

impl VendorEds {
    /// Read and parse `path` (errors: `FILE: line N, [section] key: reason`).
    pub fn load(path: &Path) -> Result<VendorEds> {
        let bytes = crate::infile::read_bytes(path, "EDS", crate::infile::MAX_CONFIG_BYTES)?;
        let text = eds_parse::decode_text(&bytes);
        let file = eds_parse::parse(&text)
            .map_err(|e| anyhow::anyhow!("{}: {e}", crate::quote::text(&path.to_string_lossy())))?;
        Ok(VendorEds {
            path: path.to_path_buf(),
            file,
        })
    }

    /// The motor encoder's increments per motor revolution the file's 0x608F says, if it
    /// gives a usable one.
    pub fn encoder_counts_per_rev(&self) -> Option<u64> {
        let value = |sub: u8| {
            let s = self.file.sub(0x608F, sub)?;
            let v = s.default.as_ref().or(s.parameter_value.as_ref())?;
            let b = v.resolve(s.data_type, Some(1)).ok()?;
            let raw = drive_protocol::od::decode(s.data_type, &b);
            (s.data_type.integer() && raw > 0).then_some(raw)
        };
        let inc = value(1)?;
        let revs = value(2).unwrap_or(1);
        (inc % revs == 0 && inc / revs >= 4).then_some(inc / revs)
    }

    /// The axis with the file's encoder resolution (where it gives one).
    pub fn adapt(&self, cfg: AxisConfig) -> Result<AxisConfig> {
        match self.encoder_counts_per_rev() {
            Some(cpr) if cpr != cfg.motor_encoder_counts_per_rev => cfg
                .with_override("motor_encoder_counts_per_rev", &cpr.to_string())
                .map_err(|e| {
                    anyhow::anyhow!(
                        "{}: 0x608F says {cpr} increments per motor revolution: {e}",
                        self.path.display()
                    )
                }),
            _ => Ok(cfg),
        }
    }

    /// The base of the emulator's objects: `wanted` if given (an error if the file has
    /// objects there), else 0x2000 if free, else the first free candidate.
    pub fn objects_base(&self, wanted: Option<u16>) -> Result<u16> {
        let used = |base: u16| {
            self.file
                .objects
                .iter()
                .any(|o| objects::range(base).contains(&o.index))
        };
        if let Some(b) = wanted {
            if used(b) {
                bail!(
                    "{}: the file has objects in 0x{b:04X}..=0x{:04X}, where the emulator's own \
                     objects were asked to go (--objects-base / objects_base)",
                    self.path.display(),
                    b + objects::INJECT_OFFSET
                );
            }
            return Ok(b);
        }
        let candidates = [0x2000u16, 0x3000, 0x4000, 0x5000]
            .into_iter()
            .chain((0..24).map(|k| 0x2000 + k * 0x200));
        for b in candidates {
            if b.checked_add(objects::INJECT_OFFSET)
                .is_some_and(|end| end <= 0x5FFF)
                && !used(b)
            {
                return Ok(b);
            }
        }
        bail!(
            "{}: no free room for the emulator's own objects in 0x2000..=0x5FFF; give \
             --objects-base",
            self.path.display()
        )
    }

    /// The drive's dictionary from the file, with the emulator's objects at `base`.
    pub fn dictionary(
        &self,
        info: &DriveInfo,
        base: u16,
        rotary: bool,
    ) -> Result<(ObjectDictionary, objects::EmuObjects, BuildReport)> {
        let (mut od, report) = ObjectDictionary::from_eds(&self.file, info)
            .map_err(|e| anyhow::anyhow!("{}: {e}", self.path.display()))?;
        let objects = objects::register(&mut od, base, rotary)
            .map_err(|e| anyhow::anyhow!("{}: the emulator's objects: {e}", self.path.display()))?;
        Ok((od, objects, report))
    }
}

/// The build report as text: a summary line, the notes, then every object that is dropped,
/// added or hidden with its reason (simulated and stored ones are counted).
pub fn report_text(r: &BuildReport, base: u16, file: &Path) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} simulated, {} stored, {} dropped, {} added, {} hidden; the emulator's own objects at 0x{base:04X}",
        file.display(),
        r.count(Fate::Simulated),
        r.count(Fate::Stored),
        r.count(Fate::Dropped),
        r.count(Fate::Added),
        r.count(Fate::Hidden),
    );
    for n in &r.notes {
        let _ = writeln!(s, "  note: {n}");
    }
    for l in &r.lines {
        if matches!(l.fate, Fate::Simulated | Fate::Stored) && l.why.is_empty() {
            continue;
        }
        let _ = writeln!(
            s,
            "  0x{:04X} sub {:<3} {:<9} {}{}{}",
            l.index,
            l.sub,
            l.fate.as_str(),
            l.name,
            if l.why.is_empty() { "" } else { ": " },
            l.why
        );
    }
    s
}
