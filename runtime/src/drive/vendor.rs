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
        let mut report = report;
        // the feed constant 0x60A8 gave (0x6092 stays hidden: the file lacks it), as the
        // build report's note says it: "... 0x6092 = N/D user units per shaft revolution"
        let feed_from_si = report
            .notes
            .iter()
            .filter(|n| n.starts_with("0x60A8 SI unit position = ") && n.contains(" applied: "))
            .find_map(|n| {
                let ratio = n.split("0x6092 = ").nth(1)?.split(' ').next()?;
                let (num, den) = ratio.split_once('/')?;
                Some((num.parse::<u32>().ok()?, den.parse::<u32>().ok()?))
            });
        report
            .notes
            .insert(0, user_unit_note(&od, info, feed_from_si));
        Ok((od, objects, report))
    }
}

/// What one user unit on the bus is, with the file's factor group (0x608F encoder
/// resolution, 0x6091 gear ratio, 0x6092 feed constant; where the file lacks one, the
/// simulated axis's): increments of the motor encoder and travel of the simulated axis.
/// Speeds are user units per second, accelerations per second squared, unless the file's SI
/// unit velocity 0x60A9 or acceleration 0x60AA names a unit the drive applies (revolutions
/// per time, or 0x60A8's unit per time; an acceleration that per second): said here, with
/// 0x60A8 where it gives the feed constant the file lacks.
/// `feed_from_si_position`: the file lacks 0x6092 and its 0x60A8 gave it (the build
/// report's note says so): the feed constant served (user units / shaft revolutions).
pub fn user_unit_note(
    od: &ObjectDictionary,
    info: &DriveInfo,
    feed_from_si_position: Option<(u32, u32)>,
) -> String {
    let v = |index: u16, sub: u8, fallback: u32| {
        od.get(index, sub)
            .map(|(_, e)| e.default_raw(1) as u32)
            .filter(|&x| x != 0)
            .unwrap_or(fallback)
    };
    // increments per user unit (CiA 402 factor group), None for a zero term
    let inc_per_uu = |enc: u32, enc_r: u32, gm: u32, gs: u32, feed: u32, feed_r: u32| {
        let terms = [enc, enc_r, gm, gs, feed, feed_r];
        (!terms.contains(&0)).then(|| {
            f64::from(enc) / f64::from(enc_r) * (f64::from(gm) / f64::from(gs))
                / (f64::from(feed) / f64::from(feed_r))
        })
    };
    let f = inc_per_uu(
        v(0x608F, 1, info.encoder_increments_per_rev),
        v(0x608F, 2, 1),
        v(0x6091, 1, info.gear_motor_revs),
        v(0x6091, 2, info.gear_shaft_revs),
        feed_from_si_position.map_or_else(|| v(0x6092, 1, info.feed_user_units), |f| f.0),
        feed_from_si_position.map_or_else(|| v(0x6092, 2, info.feed_shaft_revs), |f| f.1),
    );
    // the simulated axis: its own factor says what an increment is in its units
    // (1 um linear, 0.001 deg rotary)
    let axis = inc_per_uu(
        info.encoder_increments_per_rev,
        1,
        info.gear_motor_revs,
        info.gear_shaft_revs,
        info.feed_user_units,
        info.feed_shaft_revs,
    );
    let mut s = match (f, axis) {
        (Some(f), Some(a)) => {
            let inc = f;
            let std_uu = inc / a;
            let travel = if info.rotary {
                format!("{} deg", sig(std_uu * 1e-3))
            } else {
                format!("{} mm", sig(std_uu * 1e-3))
            };
            format!(
                "1 uu = {} increments of the motor encoder = {travel} of the simulated axis \
                 (factor group 0x608F/0x6091/0x6092 as served)",
                sig(inc)
            )
        }
        _ => "1 uu: the factor group has a zero term; positions are in increments".into(),
    };
    let si = |index: u16| od.get(index, 0).map(|(_, e)| e.default_raw(1) as u32);
    use drive_protocol::cia402::SiUnit;
    // a unit this drive tells in increments: revolutions of the shaft, or 0x60A8's unit
    let tellable = |raw: u32| {
        let u = SiUnit::decode(raw);
        u.per_seconds().is_some()
            && (u.unit == drive_protocol::cia402::SI_REVOLUTION
                || si(0x60A8).is_some_and(|p| {
                    let p = SiUnit::decode(p);
                    p.unit == u.unit && p.per == 0
                }))
    };
    let mut velocity_applied = false;
    if let Some(p) = si(0x60A8) {
        s.push_str(&format!(
            "; 0x60A8 SI unit position = 0x{p:08X} ({}): {}",
            si_unit_text(p),
            if feed_from_si_position.is_some() {
                format!(
                    "applied, 1 uu = {} (the feed constant 0x6092 the file lacks is derived \
                     from it)",
                    si_one_unit_text(p)
                )
            } else {
                "positions stay in the factor group's user units".into()
            }
        ));
    }
    if let Some(v) = si(0x60A9) {
        s.push_str(&format!(
            "; 0x60A9 SI unit velocity = 0x{v:08X} ({})",
            si_unit_text(v)
        ));
        velocity_applied = tellable(v);
        s.push_str(if velocity_applied {
            ": applied, velocities in that unit, accelerations in that unit per second"
        } else {
            ": not applied (a unit this drive cannot tell in increments)"
        });
    }
    let mut acceleration_applied = false;
    if let Some(a) = si(0x60AA) {
        acceleration_applied = tellable(a);
        s.push_str(&format!(
            "; 0x60AA SI unit acceleration = 0x{a:08X} ({}): {}",
            si_unit_text(a),
            if acceleration_applied {
                "applied, accelerations in that unit per second"
            } else {
                "not applied (a unit this drive cannot tell in increments)"
            }
        ));
    }
    match (velocity_applied, acceleration_applied) {
        (false, false) => s.push_str("; speeds in uu/s, accelerations in uu/s^2"),
        (false, true) => s.push_str("; speeds in uu/s"),
        _ => {}
    }
    s
}

/// An SI unit object's value in words: `1e-1 rev/min`, `mm`, or its bytes where unknown.
fn si_unit_text(raw: u32) -> String {
    use drive_protocol::cia402 as c;
    let u = c::SiUnit::decode(raw);
    let name = |code: u8| match code {
        c::SI_METRE => Some("m"),
        c::SI_SECOND => Some("s"),
        c::SI_RADIAN => Some("rad"),
        c::SI_DEGREE => Some("deg"),
        c::SI_MINUTE => Some("min"),
        c::SI_HOUR => Some("h"),
        c::SI_REVOLUTION => Some("rev"),
        _ => None,
    };
    let unit = name(u.unit)
        .map(str::to_string)
        .unwrap_or_else(|| format!("unit 0x{:02X}", u.unit));
    let per = match u.per {
        0 => String::new(),
        p => format!(
            "/{}",
            name(p).map(str::to_string).unwrap_or(format!("0x{p:02X}"))
        ),
    };
    let prefix = if u.prefix == 0 {
        String::new()
    } else {
        format!("1e{} ", u.prefix)
    };
    format!("{prefix}{unit}{per}")
}

/// One SI unit of a position (0x60A8) as a number and its unit: `0.001 rad`, `1 um` for
/// 1e-6 m, `0.1 deg`.
fn si_one_unit_text(raw: u32) -> String {
    use drive_protocol::cia402 as c;
    let u = c::SiUnit::decode(raw);
    match (u.unit, u.prefix) {
        (c::SI_METRE, -6) => "1 um".into(),
        (c::SI_METRE, -3) => "1 mm".into(),
        _ => format!(
            "{} {}",
            sig(u.scale()),
            si_unit_text(u32::from(u.unit) << 16)
        ),
    }
}

/// A number with about 6 significant digits, without trailing zeros.
fn sig(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let digits = (5 - x.abs().log10().floor() as i32).clamp(0, 12) as usize;
    let t = format!("{x:.digits$}");
    if t.contains('.') {
        t.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        t
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
    for w in &r.warnings {
        let _ = writeln!(s, "  warning: {}: {w}", file.display());
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// `eds --from` of a file whose SI unit position 0x60A8 is a milliradian (and no feed
    /// constant): one user unit is said as 0.001 rad, and as the same angle of the simulated
    /// rotary axis (0.001 rad = 0.0572958 deg).
    #[test]
    fn a_user_unit_in_radians_is_said_in_radians() {
        let path =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/eds/units/position-radian.eds");
        let eds = VendorEds::load(&path).unwrap();
        // the motor encoder takes the file's resolution (`adapt`): 2000 per revolution
        let info = DriveInfo {
            encoder_increments_per_rev: 2000,
            gear_motor_revs: 1,
            gear_shaft_revs: 1,
            feed_user_units: 360_000,
            feed_shaft_revs: 1,
            rated_torque_mnm: 1000,
            rated_current_ma: 2000,
            max_motor_speed_rpm: 3000,
            rotary: true,
        };
        let base = eds.objects_base(None).unwrap();
        let (_, _, report) = eds.dictionary(&info, base, true).unwrap();
        let note = &report.notes[0];
        assert!(
            note.contains(
                "0x60A8 SI unit position = 0xFD100000 (1e-3 rad): applied, 1 uu = 0.001 rad"
            ),
            "{note}"
        );
        // the file's 2000 increments per revolution: 2000 / (2000 pi) increments per uu,
        // 360 / (2000 pi) deg of the axis
        assert!(
            note.contains("= 0.0572958 deg of the simulated axis"),
            "{note}"
        );
        assert!(note.contains("1 uu = 0.31831 increments"), "{note}");
    }
}
