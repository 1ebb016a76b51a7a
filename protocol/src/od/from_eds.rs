//! A dictionary built from a vendor's EDS or DCF ([`ObjectDictionary::from_eds`]): every
//! object of the file becomes an entry with its type, access, PDO mapping, default and limits.
//! An (index, sub) the node knows (a CiA 301 / CiA 402 object it simulates) takes the node's
//! slot with the vendor's attributes; any other is stored. What the file lacks of the
//! standard objects stays hidden (still simulated with the standard default). A
//! [`BuildReport`] says what became of every object, and why.
//!
//! Rules (each reported):
//! - 0x1000 must be a CiA 402 drive (device profile 402 in its low 16 bits), else an error.
//! - Data type definitions (0x0001..=0x025F: DEFTYPE, DEFSTRUCT) and NULL objects are not
//!   served (dropped).
//! - The default is the file's DefaultValue; a DCF's ParameterValue is the value a master
//!   writes (`load_configuration`, a concise DCF), not the drive's out-of-the-box value, and
//!   is only used where there is no DefaultValue. `$NODEID+k` stays tied to the node ID.
//! - A standard object whose type the file changes to one of another kind (a string for a
//!   number, say) cannot be simulated with it: the file's entry is dropped, the standard one
//!   served.
//! - 0x6502: the file's modes that the emulator simulates (a mode it lists and we cannot run
//!   is refused in 0x6060 and reported).
//! - Every CiA 301 node has 0x1000, 0x1001 and 0x1018:1..4 (LSS needs the whole identity): a
//!   file without one gets the standard entry (reported as added).
//! - Strings and DOMAINs keep room to be written: writable ones at least
//!   [`WRITABLE_STRING_CAPACITY`] / [`WRITABLE_DOMAIN_CAPACITY`] bytes, read-only ones their
//!   default's length.

use super::eds_parse::{EdsFile, EdsObject, EdsSub, ObjectCode, ValueExpr};
use super::placeholders;
use super::{decode, standard, DataType, DefaultValue, Entry, ObjType, ObjectDictionary, OdError};
use crate::cia402::mode::{MODES, SIMULATED_MODES_MASK};
use crate::drive::DriveInfo;

/// Bytes a writable string keeps (a name a master may write).
pub const WRITABLE_STRING_CAPACITY: usize = 256;
/// Bytes a writable DOMAIN keeps (a program or a parameter block); a longer download is
/// refused with SDO abort 0x06070012.
pub const WRITABLE_DOMAIN_CAPACITY: usize = 65536;

/// What became of one object (index, sub) of the file, or of one the node simulates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Fate {
    /// A CiA 301 / CiA 402 object the drive simulates, with the file's attributes.
    Simulated,
    /// Served as a stored value: SDO reads what was written, PDOs carry it.
    Stored,
    /// In the file, not served.
    Dropped,
    /// Simulated by the drive but not in the file: out of reach of SDO and PDO.
    Hidden,
    /// Not in the file, added from the standard objects (every node has it).
    Added,
}

impl Fate {
    /// "simulated", "stored", ...
    pub fn as_str(self) -> &'static str {
        match self {
            Fate::Simulated => "simulated",
            Fate::Stored => "stored",
            Fate::Dropped => "dropped",
            Fate::Hidden => "hidden",
            Fate::Added => "added",
        }
    }
}

/// One line of the report.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReportLine {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Its name (the file's, or the standard one).
    pub name: String,
    /// What became of it.
    pub fate: Fate,
    /// Why, where it is not obvious from the fate (empty otherwise).
    pub why: String,
}

/// What the build did with every object.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BuildReport {
    /// One line per (index, sub), sorted.
    pub lines: Vec<ReportLine>,
    /// Notes on the whole file (modes, identity, PDOs).
    pub notes: Vec<String>,
    /// What the parser read past ([`EdsFile::warnings`], as `line N, [section] key: why`;
    /// the caller names the file).
    pub warnings: Vec<String>,
}

impl BuildReport {
    fn line(&mut self, index: u16, sub: u8, name: &str, fate: Fate, why: impl Into<String>) {
        self.lines.push(ReportLine {
            index,
            sub,
            name: name.to_string(),
            fate,
            why: why.into(),
        });
    }

    /// How many lines have this fate.
    pub fn count(&self, fate: Fate) -> usize {
        self.lines.iter().filter(|l| l.fate == fate).count()
    }

    /// The fate of (index, sub), if the report has it.
    pub fn fate(&self, index: u16, sub: u8) -> Option<Fate> {
        self.lines
            .iter()
            .find(|l| l.index == index && l.sub == sub)
            .map(|l| l.fate)
    }
}

/// Why a file cannot be the drive's dictionary.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EdsBuildError {
    /// Line of the object in the file (0: the file as a whole).
    pub line: usize,
    /// The object, if one is at fault.
    pub object: Option<(u16, u8)>,
    /// Why.
    pub reason: String,
}

impl core::fmt::Display for EdsBuildError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if self.line > 0 {
            write!(f, "line {}, ", self.line)?;
        }
        // The reason may quote the file's text (a name, a value): rendered.
        let reason = crate::quote::text_max(&self.reason, super::eds_parse::MAX_REASON_CHARS);
        match self.object {
            Some((i, 0)) => write!(f, "[{i:04X}]: {reason}"),
            Some((i, s)) => write!(f, "[{i:04X}sub{s:X}]: {reason}"),
            None => write!(f, "{reason}"),
        }
    }
}

impl std::error::Error for EdsBuildError {}

fn err(sub: &EdsSub, index: u16, reason: impl Into<String>) -> EdsBuildError {
    EdsBuildError {
        line: sub.line,
        object: Some((index, sub.sub)),
        reason: reason.into(),
    }
}

/// The kind of value a type holds, for "same kind" checks against the standard objects.
fn kind(t: DataType) -> u8 {
    if t.integer() {
        0
    } else if t.float() {
        1
    } else if t.variable() {
        2
    } else {
        3
    }
}

/// The default of an entry of the file (DefaultValue, else ParameterValue).
fn default_of(
    s: &EdsSub,
    index: u16,
    dtype: DataType,
) -> Result<Option<DefaultValue>, EdsBuildError> {
    let Some(expr) = s.default.as_ref().or(s.parameter_value.as_ref()) else {
        return Ok(None);
    };
    if let ValueExpr::NodeIdPlus(off) = expr {
        if !dtype.integer() {
            return Err(err(
                s,
                index,
                format!("$NODEID in a {} value", dtype.name()),
            ));
        }
        // checked by the parser at node IDs 1 and 127
        return Ok(Some(DefaultValue::NodeId(*off as i64 as u64)));
    }
    let bytes = expr.resolve(dtype, None).map_err(|e| err(s, index, e))?;
    Ok(Some(if dtype.variable() {
        DefaultValue::Bytes(bytes)
    } else {
        DefaultValue::Value(decode(dtype, &bytes))
    }))
}

fn limit_of(
    e: Option<&ValueExpr>,
    s: &EdsSub,
    index: u16,
    dtype: DataType,
) -> Result<Option<u64>, EdsBuildError> {
    let Some(expr) = e else { return Ok(None) };
    if dtype.variable() {
        return Ok(None);
    }
    // a limit with $NODEID (rare) is taken at the highest node ID: it never refuses a value
    // that some node ID allows
    let bytes = expr
        .resolve(dtype, Some(127))
        .map_err(|e| err(s, index, format!("limit: {e}")))?;
    Ok(Some(decode(dtype, &bytes)))
}

/// The entry of one sub of the file.
fn entry_of(s: &EdsSub, index: u16, otype: ObjType, parent: &str) -> Result<Entry, EdsBuildError> {
    let mut e = Entry::member(
        index,
        s.sub,
        otype,
        parent.to_string(),
        s.name.clone(),
        s.data_type,
        s.access,
    )
    .with_pdo(s.pdo_mapping && !s.data_type.variable());
    if let Some(d) = default_of(s, index, s.data_type)? {
        e = e.with_default(d);
    }
    e = e.with_raw_limits(
        limit_of(s.low.as_ref(), s, index, s.data_type)?,
        limit_of(s.high.as_ref(), s, index, s.data_type)?,
    );
    if s.data_type.variable() {
        let default_len = match &e.default {
            DefaultValue::Bytes(b) => b.len(),
            _ => 0,
        };
        let room = match (s.access.writable(), s.data_type) {
            (false, _) => 0,
            (true, DataType::Domain) => WRITABLE_DOMAIN_CAPACITY,
            (true, _) => WRITABLE_STRING_CAPACITY,
        };
        e = e.with_capacity(default_len.max(room));
    }
    Ok(e)
}

impl ObjectDictionary {
    /// The dictionary of a vendor's EDS or DCF for a drive with these static facts (the
    /// hidden standard objects' defaults). Errors: not a CiA 402 drive, a value that does not
    /// fit its entry.
    pub fn from_eds(
        file: &EdsFile,
        info: &DriveInfo,
    ) -> Result<(ObjectDictionary, BuildReport), EdsBuildError> {
        let mut od = ObjectDictionary::standard_hidden(info);
        let mut report = BuildReport {
            warnings: file.warnings.iter().map(|w| w.to_string()).collect(),
            ..BuildReport::default()
        };
        check_device_type(file)?;
        // the file's user units (its factor group and SI units) against the axis's: a
        // placeholder is filled in the file's units; 0x60A8 gives the feed constant the
        // file lacks
        let feed_from_si = feed_from_si_position(file, info);
        if let Some((feed, revs, why)) = &feed_from_si {
            for (sub, v) in [(1u8, *feed), (2, *revs)] {
                if let Some(slot) = standard::slot_of(0x6092, sub) {
                    od.slots[slot].entry.default = DefaultValue::Value(u64::from(v));
                }
            }
            report.notes.push(why.clone());
        }
        let mut b = Builder {
            // the simulated axis's own values (placeholders), untouched by the file
            axis_od: ObjectDictionary::standard_hidden(info),
            units: FileUnits::of(file, info, feed_from_si.map(|(f, r, _)| (f, r))),
            od,
            report,
            fe_window_zero: false,
            fixed_pdo_can_ids: Vec::new(),
            info: *info,
        };
        for obj in &file.objects {
            b.add_object(file, obj)?;
        }
        let Builder {
            mut od,
            mut report,
            fe_window_zero,
            fixed_pdo_can_ids,
            ..
        } = b;
        add_identity(&mut od, &mut report);
        for s in &od.slots {
            if !s.visible {
                report.line(s.entry.index, s.entry.sub, &s.entry.name, Fate::Hidden, "not in the file: simulated with the standard default, out of reach of SDO and PDO");
            }
        }
        od.resort();
        od.device = device_description(file, fe_window_zero, fixed_pdo_can_ids);
        od.device.emcy_cob_id_zero_predefined = emcy_cob_id_zero(file, &mut report);
        sync_producer_note(file, &mut report);
        od.device.shipped_pdo_can_ids = shipped_pdo_can_ids(file, &mut report);
        add_mapped_members(file, &mut od, &mut report)?;
        od.device.shipped_short_entries = shipped_short_entries(file, &od, &mut report);
        od.device.shipped_read_only_rpdo_entries = shipped_read_only_rpdo_entries(&od, &mut report);
        note_fixed_maps(&od, &mut report);
        report.lines.sort_by_key(|l| (l.index, l.sub));
        check_default_mappings(&od, &mut report);
        Ok((od, report))
    }
}

/// [`ObjectDictionary::from_eds`] while it reads the file's objects.
struct Builder {
    od: ObjectDictionary,
    report: BuildReport,
    /// The simulated axis's own values (placeholders), untouched by the file.
    axis_od: ObjectDictionary,
    units: FileUnits,
    /// The file's 0x6065 is 0 (default or ParameterValue): its vendor's 0 means off.
    fe_window_zero: bool,
    /// The PDOs whose COB-ID the file marks read-only (a fixed CAN-ID: bit 31 only).
    fixed_pdo_can_ids: Vec<u16>,
    /// The drive's static facts (its own encoder, gear and feed for placeholders).
    info: DriveInfo,
}

impl Builder {
    /// One object of the file: each of its sub-indices, or none for a data type definition.
    fn add_object(&mut self, file: &EdsFile, obj: &EdsObject) -> Result<(), EdsBuildError> {
        if obj.defines_type()
            || matches!(
                obj.code,
                ObjectCode::Null | ObjectCode::DefType | ObjectCode::DefStruct
            )
        {
            for s in &obj.subs {
                self.report.line(
                    obj.index,
                    s.sub,
                    &s.name,
                    Fate::Dropped,
                    "a data type definition, not an object",
                );
            }
            return Ok(());
        }
        let otype = match obj.code {
            ObjectCode::Array => ObjType::Array,
            ObjectCode::Record => ObjType::Record,
            _ => ObjType::Var,
        };
        for s in &obj.subs {
            self.add_sub(file, obj, s, otype)?;
        }
        Ok(())
    }

    /// One sub-index of the file's object `obj`.
    fn add_sub(
        &mut self,
        file: &EdsFile,
        obj: &EdsObject,
        s: &EdsSub,
        otype: ObjType,
    ) -> Result<(), EdsBuildError> {
        let mut e = entry_of(s, obj.index, otype, &obj.name)?;
        let std_slot = standard::slot_of(obj.index, s.sub);
        let mut why = String::new();
        if let Some((d, w)) = placeholders::empty_pdo_mapping(file, obj.index, s) {
            (e, why) = (e.with_default(d), w);
        }
        if let Some(slot) = std_slot {
            match self.standard_entry(file, obj, s, otype, slot, e, &mut why) {
                Some(served) => e = served,
                None => return Ok(()),
            }
        }
        let Builder {
            od,
            report,
            axis_od,
            units,
            fe_window_zero,
            fixed_pdo_can_ids,
            info,
        } = self;
        let (od, report, axis_od, units) = (od, report, &*axis_od, &*units);
        let file_zero = |v: &Option<_>| {
            v.as_ref()
                .is_some_and(|v: &crate::od::eds_parse::ValueExpr| {
                    v.resolve(s.data_type, Some(1))
                        .is_ok_and(|b| b.iter().all(|&x| x == 0))
                })
        };
        if (obj.index, s.sub) == (0x6065, 0)
            && (file_zero(&s.default) || file_zero(&s.parameter_value))
        {
            *fe_window_zero = true;
        }
        if let Some(w) = placeholder(&mut e, obj.index, s.sub, axis_od, units) {
            why = w;
        }
        if let Some((v, w)) = placeholders::factor_group(file, info, obj.index, s.sub) {
            (e.default, why) = (DefaultValue::Value(u64::from(v)), w);
        }
        if let Some((a, w)) = placeholders::read_only_pdo_cob_id(obj.index, s) {
            (e.access, why) = (a, w);
            fixed_pdo_can_ids.push(obj.index);
        }
        // a DCF's ParameterValue 0 there is what a master writes (load_configuration,
        // a concise DCF): the drive then takes 0 as CiA 402 says; say so
        let zero_pv = s.parameter_value.as_ref().is_some_and(|v| {
            v.resolve(s.data_type, Some(1))
                .is_ok_and(|b| b.iter().all(|&x| x == 0))
        });
        if (obj.index, s.sub) == (0x6065, 0) && zero_pv {
            report.notes.push(format!(
                "0x6065 ({}): the DCF's ParameterValue is 0: a master that loads it \
             (load_configuration, a concise DCF) sets 0, which this drive takes as \
             its vendor documents it: the following-error check off, as \
             0xFFFFFFFF is in CiA 402",
                s.name
            ));
        } else if s.sub == 0 && zero_pv && PLACEHOLDERS.iter().any(|p| p.0 == obj.index) {
            report.notes.push(format!(
                "0x{:04X} ({}): the DCF's ParameterValue is 0: a master that loads it \
             (load_configuration, a concise DCF) sets 0, which the drive takes as \
             CiA 402 says, not as a placeholder",
                obj.index, s.name
            ));
        }
        let fate = if std_slot.is_some() {
            Fate::Simulated
        } else {
            Fate::Stored
        };
        // a DCF's ParameterValue outside the file's limits is what the device held (read from
        // it): a master loading the DCF writes it, and the device takes it
        let pv_raw = s
            .parameter_value
            .as_ref()
            .filter(|_| e.dtype.integer())
            .and_then(|v| v.resolve(e.dtype, Some(1)).ok())
            .map(|b| decode(e.dtype, &b));
        let default_raw = match e.default {
            DefaultValue::Value(v) => Some(v),
            _ => None,
        };
        let outside = |v: Option<u64>| v.and_then(|v| e.check_limits(v).err());
        if let (None, Some(high)) = (outside(default_raw), outside(pv_raw)) {
            why = format!(
                "the DCF's ParameterValue is {} its {}: limits not applied",
                if high { "above" } else { "below" },
                if high { "HighLimit" } else { "LowLimit" }
            );
            e.low = None;
            e.high = None;
        }
        if let DefaultValue::Value(v) = e.default {
            if let Err(high) = e.check_limits(v) {
                // the file contradicts itself; a master that writes the default back
                // (load_configuration, a concise DCF) must not be refused
                why = format!(
                    "the file's default is {} its {}: limits not applied",
                    if high { "above" } else { "below" },
                    if high { "HighLimit" } else { "LowLimit" }
                );
                e.low = None;
                e.high = None;
            }
        }
        match od.insert_unsorted(e) {
            Ok(_) => report.line(obj.index, s.sub, &s.name, fate, why),
            Err(OdError::Invalid { reason, .. }) => return Err(err(s, obj.index, reason)),
            Err(OdError::Duplicate { .. }) => return Err(err(s, obj.index, "given twice")),
        }
        Ok(())
    }

    /// The file's entry `e` of a standard object the drive simulates (its slot `slot`): the
    /// standard entry is served instead when the file gives another kind of type (false:
    /// nothing more to add); a value the file leaves to the device is the drive's own.
    #[allow(clippy::too_many_arguments)]
    fn standard_entry(
        &mut self,
        file: &EdsFile,
        obj: &EdsObject,
        s: &EdsSub,
        otype: ObjType,
        slot: usize,
        mut e: Entry,
        why: &mut String,
    ) -> Option<Entry> {
        let (od, report) = (&mut self.od, &mut self.report);
        let std_type = od.slots[slot].entry.dtype;
        if kind(std_type) != kind(e.dtype) {
            report.line(
                obj.index,
                s.sub,
                &s.name,
                Fate::Dropped,
                format!(
            "the file makes it {}, the drive simulates it as {}: the standard entry is served",
            e.dtype.name(),
            std_type.name()
        ),
            );
            od.slots[slot].visible = true;
            // One object, one object code: the served entry takes the file's
            // (an ARRAY stays an ARRAY on export and read-back).
            od.slots[slot].entry.otype = otype;
            return None;
        }
        let no_value = s.default.is_none() && s.parameter_value.is_none() && why.is_empty();
        if no_value && std_type == e.dtype {
            // the file leaves the value to the device: the drive's own, not 0
            // (a profile velocity of 0 would never move); the device name is the
            // file's product name
            // the device name and the identity from [DeviceInfo] (what python
            // canopen and Lely take for them too)
            let info = &file.device_info;
            let ident = |v: Option<u32>| v.map(|x| DefaultValue::Value(u64::from(x)));
            let from_info = match (obj.index, s.sub) {
                // the device name and versions as the file gives them: an
                // empty default stays empty (python canopen reads "")
                (0x1008..=0x100A, 0) if e.dtype.variable() => Some(DefaultValue::Bytes(Vec::new())),
                (0x1018, 1) => ident(info.vendor_number),
                (0x1018, 2) => ident(info.product_number),
                (0x1018, 3) => ident(info.revision_number),
                _ => None,
            };
            *why = if from_info.is_some() && (0x1008..=0x100A).contains(&obj.index) {
                "no DefaultValue in the file: empty, as the file says".into()
            } else {
                "no DefaultValue in the file: the drive's standard value".into()
            };
            let d = from_info.unwrap_or_else(|| od.slots[slot].entry.default.clone());
            e = e.with_default(d);
        }
        if (obj.index, s.sub) == (0x6502, 0) {
            e = supported_modes(e, report);
        }
        Some(e)
    }
}

/// The identity every CiA 301 node has, added where the file lacks it.
fn add_identity(od: &mut ObjectDictionary, report: &mut BuildReport) {
    for (index, sub) in [
        (0x1000, 0),
        (0x1001, 0),
        (0x1018, 0),
        (0x1018, 1),
        (0x1018, 2),
        (0x1018, 3),
        (0x1018, 4),
    ] {
        let slot = standard::slot_of(index, sub).expect("standard object");
        if !od.slots[slot].visible {
            od.slots[slot].visible = true;
            // An added sub takes the object type the file gave its object (0x1018 as an
            // ARRAY with sub 1 only): an export writes one ObjectType for the object, and
            // what it reads back must be the same dictionary.
            let file_otype = od
                .slots
                .iter()
                .find(|s| s.visible && s.entry.index == index && s.entry.sub != sub)
                .map(|s| s.entry.otype);
            if let Some(t) = file_otype {
                od.slots[slot].entry.otype = t;
            }
            let name = od.slots[slot].entry.name.to_string();
            report.line(
                index,
                sub,
                &name,
                Fate::Added,
                "every CiA 301 node has it (LSS needs the whole identity)",
            );
        }
    }
}

/// What the file's `[DeviceInfo]` and `[DummyUsage]` say about the device.
fn device_description(
    file: &EdsFile,
    fe_window_zero: bool,
    fixed_pdo_can_ids: Vec<u16>,
) -> super::DeviceDescription {
    super::DeviceDescription {
        vendor_name: file.device_info.vendor_name.clone().unwrap_or_default(),
        product_name: file.device_info.product_name.clone().unwrap_or_default(),
        order_code: file.device_info.order_code.clone().unwrap_or_default(),
        baud_rates_kbit: file.device_info.baud_rates_kbit.clone(),
        granularity: file.device_info.granularity.unwrap_or(8),
        lss_supported: file.device_info.lss_supported.unwrap_or(false),
        dummy_usage: file.dummy_usage,
        shipped_read_only_rpdo_entries: Vec::new(),
        shipped_short_entries: Vec::new(),
        following_error_window_zero_off: fe_window_zero,
        fixed_pdo_can_ids,
        emcy_cob_id_zero_predefined: false,
        shipped_pdo_can_ids: Vec::new(),
        padding_entries: false,
    }
}

/// The file's EMCY COB-ID 0x1014 is 0 (its default, else a DCF's ParameterValue): CAN-ID 0 is
/// NMT's, which CiA 301 does not allow for an EMCY, but the device takes its own file's 0
/// (SEVCON's Gen4: its EDS default and the value a live controller reads back) as "EMCY on the
/// predefined CAN-ID", $NODEID + 0x80. The drive does the same, and says so.
fn emcy_cob_id_zero(file: &EdsFile, report: &mut BuildReport) -> bool {
    let Some(s) = file.sub(0x1014, 0) else {
        return false;
    };
    let zero = |v: &Option<ValueExpr>| {
        v.as_ref().is_some_and(|v| {
            v.resolve(s.data_type, Some(1))
                .is_ok_and(|b| b.iter().all(|&x| x == 0))
        })
    };
    let zero = match &s.default {
        Some(_) => zero(&s.default),
        None => zero(&s.parameter_value),
    };
    if zero {
        report.notes.push(
            "0x1014 (COB-ID EMCY): the file's value is 0, CAN-ID 0 (NMT's), which CiA 301 \
             allows no EMCY: taken as the device takes it, EMCY on the predefined CAN-ID \
             $NODEID+0x80; 0x1014 reads 0 and a master may write 0 back (any other \
             dictionary refuses 0 with 0x06090030)"
                .into(),
        );
    }
    zero
}

/// The file makes the device the SYNC producer (0x1005 bit 30, SEVCON's Gen4): say that the
/// drive produces it, and at what period.
fn sync_producer_note(file: &EdsFile, report: &mut BuildReport) {
    let Some(cob) = file_u32(file, 0x1005, 0).filter(|c| c & crate::cia301::sync::GEN_BIT != 0)
    else {
        return;
    };
    let period_us = file_u32(file, 0x1006, 0).unwrap_or(0);
    report.notes.push(format!(
        "0x1005 = 0x{cob:08X}: the device is the SYNC producer (bit 30): the drive sends SYNC on \
         CAN-ID 0x{:03X} every 0x1006 = {period_us} us at boot (none while 0x1006 is 0), in \
         pre-operational and operational; its own synchronous PDOs act on it",
        cob & 0x7FF
    ));
}

/// PDO COB-IDs the file gives (default or a DCF's ParameterValue) on a CAN-ID CiA 301
/// restricts: the device holds them (SEVCON's Gen4 DCF, read from a live controller, has
/// TPDOs on 0x120, 0x145 and 0x178, in 0x101..=0x180), so the drive takes them for that PDO;
/// any other restricted CAN-ID is refused as before.
fn shipped_pdo_can_ids(file: &EdsFile, report: &mut BuildReport) -> Vec<(u16, u32)> {
    let mut v = Vec::new();
    let records = file
        .objects
        .iter()
        .filter(|o| matches!(o.index, 0x1400..=0x15FF | 0x1800..=0x19FF));
    for obj in records {
        let Some(s) = obj.subs.iter().find(|s| s.sub == 1) else {
            continue;
        };
        for expr in [&s.default, &s.parameter_value].into_iter().flatten() {
            let Ok(b) = expr.resolve(DataType::U32, Some(1)) else {
                continue;
            };
            let raw = decode(DataType::U32, &b) as u32;
            let can_id = raw & 0x7FF;
            // an invalid PDO (bit 31) takes any CAN-ID anyway
            if raw & 0x8000_0000 != 0
                || !crate::cia301::cob_id::restricted(can_id)
                || v.contains(&(obj.index, can_id))
            {
                continue;
            }
            v.push((obj.index, can_id));
            report.notes.push(format!(
                "0x{:04X} sub 1: the file gives the PDO CAN-ID 0x{can_id:03X}, in a range CiA 301 \
                 restricts: taken as the device takes it, for this PDO (a master may write it)",
                obj.index
            ));
        }
    }
    v
}

/// Members the file's own default PDO maps name, of an object that lists fewer members than
/// its sub 0 counts (SEVCON's Gen4 maps 0x6C11 sub 4 in RPDO1; its 0x6C11 lists subs 1..3 with
/// sub 0 = 7): the device has them (its sub 0 says so, its map uses them), so the drive adds
/// them, with the type, access and mapping of the members the file lists (which must agree),
/// default 0; reported as added.
fn add_mapped_members(
    file: &EdsFile,
    od: &mut ObjectDictionary,
    report: &mut BuildReport,
) -> Result<(), EdsBuildError> {
    let maps = file
        .objects
        .iter()
        .filter(|o| matches!(o.index, 0x1600..=0x17FF | 0x1A00..=0x1BFF));
    for map in maps {
        for s in map.subs.iter().filter(|s| s.sub >= 1) {
            for expr in [&s.default, &s.parameter_value].into_iter().flatten() {
                let Ok(b) = expr.resolve(DataType::U32, Some(1)) else {
                    continue;
                };
                let value = decode(DataType::U32, &b) as u32;
                let (index, sub) = ((value >> 16) as u16, (value >> 8) as u8);
                if sub == 0 || od.get(index, sub).is_some() {
                    continue;
                }
                let Some(e) = missing_member(od, index, sub) else {
                    continue;
                };
                let why = format!(
                    "named by the file's default map 0x{:04X} sub {} (0x{value:08X}), below \
                     the {} members sub 0 counts: the device has it; added as its listed \
                     members are ({}, {})",
                    map.index,
                    s.sub,
                    od.get(index, 0).map_or(0, |(_, c)| c.default_raw(0)),
                    e.dtype.name(),
                    e.access.eds()
                );
                let name = e.name.to_string();
                od.insert(e).map_err(|er| EdsBuildError {
                    line: 0,
                    object: Some((index, sub)),
                    reason: er.to_string(),
                })?;
                report.notes.push(format!("0x{index:04X} sub {sub}: {why}"));
                report.line(index, sub, &name, Fate::Added, why);
            }
        }
    }
    Ok(())
}

/// The entry of member `sub` of `index`, missing from the dictionary: when sub 0 counts it and
/// the listed members agree on type, access and mapping.
fn missing_member(od: &ObjectDictionary, index: u16, sub: u8) -> Option<Entry> {
    let (_, count) = od.get(index, 0)?;
    if !count.dtype.integer() || u64::from(sub) > count.default_raw(0) {
        return None;
    }
    let members: Vec<&Entry> = od
        .object(index)
        .map(|(_, e)| e)
        .filter(|e| e.sub >= 1)
        .collect();
    let first = *members.first()?;
    let alike = members
        .iter()
        .all(|e| e.dtype == first.dtype && e.access == first.access && e.pdo == first.pdo);
    if !alike || first.dtype.variable() {
        return None;
    }
    let mut e = first.clone().with_default(DefaultValue::Value(0));
    e.sub = sub;
    e.name = format!("{} {sub}", first.parent).into();
    e.low = None;
    e.high = None;
    Some(e)
}

/// The limits and windows whose default 0 is a placeholder: the value a real drive never runs
/// with (its vendor's tool sets it up), which would stop every move or fault at the first
/// one. (index, what 0 would do, the standard object whose value the simulated axis has.)
pub const PLACEHOLDERS: [(u16, &str, u16); 7] = [
    (
        0x607F,
        "would clamp every profile move to zero speed",
        0x607F,
    ),
    (0x6080, "would allow the motor no speed", 0x6080),
    (0x6072, "would allow the motor no torque", 0x6072),
    (0x6073, "would allow the motor no current", 0x6072),
    (0x60C5, "would allow no acceleration", 0x6083),
    (0x60C6, "would allow no deceleration", 0x6084),
    (
        0x6065,
        "would fault the drive at the first motion (vendors document 0 as 'off')",
        0x6065,
    ),
];

/// The file's user units: its factor group (0x608F, 0x6091, 0x6092 defaults, a DCF's
/// ParameterValue where it has no default, the simulated axis's where the file has none) with
/// its SI units (0x60A8, 0x60A9, 0x60AA) applied as the drive applies them, and the simulated
/// axis's own. A placeholder taken from the axis is converted through revolutions of the
/// motor (each side's encoder increments per motor revolution) into the file's units.
#[derive(Clone, Copy, Debug)]
struct FileUnits {
    file: Option<crate::cia402::factor::Factor>,
    axis: Option<crate::cia402::factor::Factor>,
    /// Encoder increments per motor revolution: the file's 0x608F, the axis's.
    file_inc_per_rev: f64,
    axis_inc_per_rev: f64,
    /// 0x60A9 applies: velocities are in its unit.
    si_velocity: bool,
    /// 0x60AA applies: accelerations are in its unit.
    si_acceleration: bool,
}

/// What a placeholder's value measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Quantity {
    Position,
    Velocity,
    Acceleration,
    /// A value in its own units (rpm, per mille): taken as the axis has it.
    Other,
}

/// The value a file gives (index, sub): its default, or a DCF's ParameterValue, as a number.
fn file_u32(file: &EdsFile, index: u16, sub: u8) -> Option<u32> {
    let s = file.sub(index, sub)?;
    let v = s.default.as_ref().or(s.parameter_value.as_ref())?;
    let b = v.resolve(s.data_type, Some(1)).ok()?;
    s.data_type
        .integer()
        .then(|| decode(s.data_type, &b))
        .and_then(|x| u32::try_from(x).ok())
}

impl FileUnits {
    fn of(file: &EdsFile, info: &DriveInfo, feed: Option<(u32, u32)>) -> FileUnits {
        use crate::cia402::factor::Factor;
        let v = |index: u16, sub: u8, fallback: u32| {
            file_u32(file, index, sub)
                .filter(|&x| x != 0)
                .unwrap_or(fallback)
        };
        // the factor group as served (a placeholder's value the drive's own)
        let served = |index, sub, fallback| {
            placeholders::factor_group(file, info, index, sub)
                .map_or_else(|| v(index, sub, fallback), |x| x.0)
        };
        let (feed_uu, feed_revs) = feed.unwrap_or((
            served(0x6092, 1, info.feed_user_units),
            v(0x6092, 2, info.feed_shaft_revs),
        ));
        let enc = served(0x608F, 1, info.encoder_increments_per_rev);
        let enc_revs = v(0x608F, 2, 1);
        let gm = v(0x6091, 1, info.gear_motor_revs);
        let gs = v(0x6091, 2, info.gear_shaft_revs);
        let mut si_velocity = false;
        let mut si_acceleration = false;
        let f = Factor::from_objects(enc, enc_revs, gm, gs, feed_uu, feed_revs).map(|f| {
            let inc_per_shaft_rev =
                f64::from(enc) / f64::from(enc_revs) * f64::from(gm) / f64::from(gs);
            let pos = file_u32(file, 0x60A8, 0);
            let f = match file_u32(file, 0x60A9, 0) {
                Some(vel) => {
                    let (f, on) = f.with_si_units(pos, vel, inc_per_shaft_rev);
                    si_velocity = on;
                    f
                }
                None => f,
            };
            match file_u32(file, 0x60AA, 0) {
                Some(acc) => {
                    let (f, on) = f.with_si_acceleration(pos, acc, inc_per_shaft_rev);
                    si_acceleration = on;
                    f
                }
                None => f,
            }
        });
        FileUnits {
            file: f,
            axis: Factor::from_info(info),
            file_inc_per_rev: f64::from(enc) / f64::from(enc_revs),
            axis_inc_per_rev: f64::from(info.encoder_increments_per_rev),
            si_velocity,
            si_acceleration,
        }
    }

    /// The axis's value of a quantity in the file's units, and the unit's name; `None` where
    /// a factor has a zero term.
    fn convert(&self, axis_value: u64, q: Quantity) -> Option<(f64, &'static str)> {
        let x = axis_value as f64;
        let (file, axis) = (self.file?, self.axis?);
        // the axis's increments to the file's: the same motor revolutions
        let inc = self.file_inc_per_rev / self.axis_inc_per_rev;
        if !(inc.is_finite() && inc > 0.0) {
            return None;
        }
        Some(match q {
            Quantity::Position => (file.to_uu(axis.to_inc(x) * inc), "uu"),
            Quantity::Velocity => (
                file.vel_to_uu(axis.vel_to_inc(x) * inc),
                if self.si_velocity {
                    "in 0x60A9's unit"
                } else {
                    "uu/s"
                },
            ),
            Quantity::Acceleration => (
                file.acc_to_uu(axis.acc_to_inc(x) * inc),
                if self.si_acceleration {
                    "in 0x60AA's unit"
                } else if self.si_velocity {
                    "in 0x60A9's unit per s"
                } else {
                    "uu/s^2"
                },
            ),
            Quantity::Other => (x, ""),
        })
    }
}

/// The feed constant 0x6092 (user units per shaft revolution, sub 1 and 2) a file's SI unit
/// position 0x60A8 makes on the simulated axis, where the file has no 0x6092 of its own: a
/// length (metre with a prefix) on a linear axis, or an angle of the drive shaft (revolution,
/// degree or radian with a prefix) on either. With why; `None` where the file has 0x6092, no
/// 0x60A8, or one this drive cannot map (another unit, a length on a rotary axis, a ratio
/// beyond UNSIGNED32). A radian's 2*pi per revolution is no fraction: 0x6092 is the nearest
/// one whose terms fit UNSIGNED32 (`cia402::factor::ratio_u32`, relative error below 1e-9).
fn feed_from_si_position(file: &EdsFile, info: &DriveInfo) -> Option<(u32, u32, String)> {
    use crate::cia402::{SiUnit, SI_DEGREE, SI_METRE, SI_RADIAN, SI_REVOLUTION};
    if file.object(0x6092).is_some() {
        return None;
    }
    let raw = file_u32(file, 0x60A8, 0)?;
    let u = SiUnit::decode(raw);
    if u.per != 0 {
        return None;
    }
    if u.unit == SI_RADIAN {
        let per_rev = std::f64::consts::TAU / u.scale();
        let (n, d) = crate::cia402::factor::ratio_u32(per_rev)?;
        return Some((
            n,
            d,
            format!(
                "0x60A8 SI unit position = 0x{raw:08X} applied: the file has no feed constant \
                 0x6092, so the drive serves 0x6092 = {n}/{d} user units per shaft revolution \
                 (2 pi rad of the drive shaft: {per_rev} of 1e{} rad), 1 uu being 0x60A8's unit",
                u.prefix
            ),
        ));
    }
    // the unit per shaft revolution as numerator / denominator * 10^-prefix
    let (num, den, what): (u64, u64, String) = match u.unit {
        SI_METRE if !info.rotary => (
            // the simulated axis's user unit is 1 um: feed_user_units um per feed_shaft_revs
            u64::from(info.feed_user_units),
            u64::from(info.feed_shaft_revs) * 1_000_000,
            format!(
                "{} mm of the simulated axis per shaft revolution",
                f64::from(info.feed_user_units) / f64::from(info.feed_shaft_revs.max(1)) / 1e3
            ),
        ),
        SI_REVOLUTION => (1, 1, "1 revolution of the drive shaft".into()),
        SI_DEGREE => (360, 1, "360 deg of the drive shaft".into()),
        _ => return None,
    };
    // feed = num / den / 10^prefix
    let (mut num, mut den) = (num, den);
    let p = i32::from(u.prefix);
    let pow = 10u64.checked_pow(p.unsigned_abs())?;
    if p < 0 {
        num = num.checked_mul(pow)?;
    } else {
        den = den.checked_mul(pow)?;
    }
    let g = gcd(num, den);
    let (num, den) = (num / g, den / g);
    let (n, d) = (u32::try_from(num).ok()?, u32::try_from(den).ok()?);
    if n == 0 || d == 0 {
        return None;
    }
    Some((
        n,
        d,
        format!(
            "0x60A8 SI unit position = 0x{raw:08X} applied: the file has no feed constant \
             0x6092, so the drive serves 0x6092 = {n}/{d} user units per shaft revolution \
             ({what}), 1 uu being 0x60A8's unit"
        ),
    ))
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a.max(1)
    } else {
        gcd(b, a % b)
    }
}

/// A placeholder default (see [`PLACEHOLDERS`]) replaced by the simulated axis's value in the
/// file's units (`units`: a velocity in 0x60A9's unit where it applies, a position window in
/// the file's user units), and why; a window of 0xFFFFFFFF (CiA 402: the function off) said
/// so. `axis`: the standard dictionary of the simulated axis.
fn placeholder(
    e: &mut Entry,
    index: u16,
    sub: u8,
    axis: &ObjectDictionary,
    units: &FileUnits,
) -> Option<String> {
    if sub != 0 || !e.dtype.integer() {
        return None;
    }
    let value = match e.default {
        DefaultValue::Value(v) => v,
        _ => return None,
    };
    let windows = [0x6065u16, 0x6067, 0x606D];
    if windows.contains(&index) && e.dtype == DataType::U32 && value == u64::from(u32::MAX) {
        return Some("0xFFFFFFFF: the window is off (CiA 402), as the file says".into());
    }
    let &(_, what, from) = PLACEHOLDERS.iter().find(|p| p.0 == index)?;
    if value != 0 {
        return None;
    }
    let slot = standard::slot_of(from, 0)?;
    let axis_value = axis.slots[slot].entry.default_raw(1);
    let quantity = match index {
        0x607F => Quantity::Velocity,
        0x60C5 | 0x60C6 => Quantity::Acceleration,
        0x6065 => Quantity::Position,
        _ => Quantity::Other,
    };
    let (x, unit) = units.convert(axis_value, quantity)?;
    // the axis's value in the file's units, within the file's type and limits (at least 1)
    let max = e.dtype.range().map_or(0, |(_, hi)| hi.max(0) as u64);
    let mut v = if x.is_finite() && x >= 1.0 {
        (x.round() as u64).min(max)
    } else {
        1
    };
    if let Some(hi) = e.high {
        v = v.min(hi);
    }
    if v == 0 || axis_value == 0 {
        return None;
    }
    e.default = DefaultValue::Value(v);
    let unit = if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    };
    let conv = if quantity == Quantity::Other || (x - axis_value as f64).abs() < 0.5 {
        String::new()
    } else {
        format!(" ({axis_value} in the axis's own units, converted to the file's)")
    };
    Some(format!(
        "the file's default 0 is a placeholder (it {what}): {v}{unit}, the simulated axis's \
         value (0x{from:04X}){conv}, is served instead"
    ))
}

/// 0x1000's default must say device profile 402.
fn check_device_type(file: &EdsFile) -> Result<(), EdsBuildError> {
    let Some(obj) = file.object(0x1000) else {
        return Err(EdsBuildError {
            line: 0,
            object: Some((0x1000, 0)),
            reason: "no device type (0x1000): not a CANopen device description".into(),
        });
    };
    let Some(s) = obj.sub(0) else {
        return Err(EdsBuildError {
            line: obj.line,
            object: Some((0x1000, 0)),
            reason: "0x1000 has no value".into(),
        });
    };
    // CiA 301 7.5.2.1: UNSIGNED32. Another type would be served with another size, and an
    // export of it would refuse itself.
    if s.data_type != DataType::U32 {
        return Err(err(
            s,
            0x1000,
            format!(
                "device type (0x1000) is {}, not UNSIGNED32 as CiA 301 defines it",
                s.data_type.name()
            ),
        ));
    }
    let value = s
        .default
        .as_ref()
        .or(s.parameter_value.as_ref())
        .and_then(|v| v.resolve(DataType::U32, Some(1)).ok())
        .map(|b| decode(DataType::U32, &b));
    let drive_objects = [0x6040u16, 0x6041, 0x6060, 0x6061]
        .iter()
        .all(|&i| file.object(i).is_some());
    match value {
        Some(v) if v & 0xFFFF == 402 => Ok(()),
        Some(v) => Err(err(s, 0x1000, format!(
            "device type 0x{v:08X} is device profile {} (low 16 bits), not a CiA 402 drive (402 = 0x0192)",
            v & 0xFFFF
        ))),
        // many files leave 0x1000 to the device; the CiA 402 objects say what it is
        None if drive_objects => Ok(()),
        None => Err(err(s, 0x1000, "no device type value and no CiA 402 objects (0x6040, 0x6041, 0x6060, 0x6061): not a drive")),
    }
}

/// 0x6502: the file's modes the emulator runs; the others reported.
fn supported_modes(mut e: Entry, report: &mut BuildReport) -> Entry {
    let listed = e.default_raw(0) as u32;
    let kept = listed & SIMULATED_MODES_MASK;
    let dropped: Vec<&str> = MODES
        .iter()
        .filter(|m| m.bit.is_some_and(|b| listed & (1 << b) != 0) && !m.simulated)
        .map(|m| m.abbrev)
        .collect();
    if !dropped.is_empty() {
        report.notes.push(format!(
            "0x6502: the file lists {}, which the emulator does not simulate: 0x6060 refuses them",
            dropped.join(", ")
        ));
    }
    let unknown = listed
        & !MODES
            .iter()
            .filter_map(|m| m.bit)
            .fold(0u32, |a, b| a | (1 << b));
    if unknown != 0 {
        report.notes.push(format!(
            "0x6502: bits 0x{unknown:08X} (manufacturer-specific modes) are not simulated"
        ));
    }
    e.default = DefaultValue::Value(kept as u64);
    e
}

/// A default mapping the dictionary cannot run (an object that is missing, not mappable, or
/// read-only in an RPDO, which CiA 301 7.5.2.36 does not allow) leaves its PDO invalid until
/// a master remaps it; say which.
fn check_default_mappings(od: &ObjectDictionary, report: &mut BuildReport) {
    for (base, dir, tx) in [(0x1600u16, "RPDO", false), (0x1A00, "TPDO", true)] {
        for n in 0..512u16 {
            let index = base + n;
            let Some((_, count)) = od.get(index, 0) else {
                continue;
            };
            let count = count.default_raw(0) as u8;
            for sub in 1..=count.min(8) {
                let Some((_, e)) = od.get(index, sub) else {
                    report.notes.push(format!(
                        "{dir}{} (0x{index:04X}): the default mapping counts {count} entries, sub {sub} is missing: the PDO is invalid until remapped",
                        n + 1
                    ));
                    break;
                };
                let value = e.default_raw(0) as u32;
                if let Err(code) = crate::cia301::pdo::check_entry(od, value, tx) {
                    report.notes.push(format!(
                        "{dir}{} (0x{index:04X}): default mapping entry 0x{value:08X} cannot be mapped \
                         (abort 0x{code:08X}: missing, not PDO-mappable, or read-only in an RPDO): \
                         the PDO is invalid until remapped",
                        n + 1
                    ));
                }
            }
        }
    }
}

/// The mapping entries of the file's default PDO maps that map fewer bits of an object than
/// it has (a DCF mapping 32 bits of a 64-bit object; SEVCON's Gen4 mapping BOOLEANs in 1 bit
/// each, its `Granularity=64` notwithstanding): the device takes its own file's mapping, so the
/// drive takes it too, carrying the value's low bits (at bit positions where they are not
/// whole bytes, `cia301::pdo::mapping`).
fn shipped_short_entries(
    file: &EdsFile,
    od: &ObjectDictionary,
    report: &mut BuildReport,
) -> Vec<u32> {
    let mut v: Vec<u32> = Vec::new();
    for obj in &file.objects {
        let (dir, n) = match obj.index {
            0x1600..=0x17FF => ("RPDO", obj.index - 0x1600),
            0x1A00..=0x1BFF => ("TPDO", obj.index - 0x1A00),
            _ => continue,
        };
        for s in obj.subs.iter().filter(|s| s.sub >= 1) {
            // the default, and a DCF's ParameterValue (what load_configuration writes)
            for expr in [&s.default, &s.parameter_value].into_iter().flatten() {
                let Ok(b) = expr.resolve(DataType::U32, Some(1)) else {
                    continue;
                };
                let value = decode(DataType::U32, &b) as u32;
                let bits = (value & 0xFF) as usize;
                let Some((_, target)) = od.get((value >> 16) as u16, (value >> 8) as u8) else {
                    continue;
                };
                let size_bits = target.dtype.size() * 8;
                // a 1-bit BOOLEAN on a device of granularity 1 maps by CiA 301's own rule
                let bit_bool =
                    od.device.granularity == 1 && target.dtype == DataType::Boolean && bits == 1;
                if bit_bool
                    || !(target.pdo && bits > 0 && bits < size_bits && size_bits <= 64)
                    || v.contains(&value)
                {
                    continue;
                }
                v.push(value);
                report.notes.push(format!(
                    "{dir}{} (0x{:04X}): the file's mapping entry 0x{value:08X} maps {bits} of the \
                     {size_bits} bits of 0x{:04X}:{} ({}): taken as the device takes it, the \
                     value's low {}{}",
                    n + 1,
                    obj.index,
                    target.index,
                    target.sub,
                    target.dtype.name(),
                    match bits {
                        1 => "bit, at a bit position".to_string(),
                        b if b.is_multiple_of(8) => format!("{} bytes", b / 8),
                        b => format!("{b} bits, at a bit position"),
                    },
                    if dir == "RPDO" {
                        " (a received value zero-extended)"
                    } else {
                        ""
                    }
                ));
            }
        }
    }
    v
}

/// The RPDO mapping entries of the file's defaults that map a read-only object: CiA 301 wants
/// writable objects in an RPDO, but the device ships them (a scanned file shows what the
/// device holds), so it takes them; the drive accepts them too, and ignores what is received
/// for those objects.
/// Mapping records whose count the file makes read-only (`const`, `ro`) while an entry is
/// writable (AMD's Kria KD240 file): a fixed mapping, whose entries take a write that leaves
/// them as they stand (`cia301::pdo::rules`); said in the report's notes.
fn note_fixed_maps(od: &ObjectDictionary, report: &mut BuildReport) {
    for index in (0x1600..0x1800u16).chain(0x1A00..0x1C00) {
        let Some((_, count)) = od.get(index, 0) else {
            continue;
        };
        let rw_entry =
            (1..=8).any(|sub| od.get(index, sub).is_some_and(|(_, e)| e.access.writable()));
        if !count.access.writable() && rw_entry {
            report.notes.push(format!(
                "0x{index:04X}: the file makes the number of mapped objects read-only and its \
                 entries writable: a fixed mapping; an entry written as it stands is taken \
                 (nothing changes), any other value refused with 0x06010000"
            ));
        }
    }
}

fn shipped_read_only_rpdo_entries(od: &ObjectDictionary, report: &mut BuildReport) -> Vec<u32> {
    let mut v = Vec::new();
    for n in 0..512u16 {
        let index = 0x1600 + n;
        let Some((_, count)) = od.get(index, 0) else {
            continue;
        };
        for sub in 1..=(count.default_raw(0) as u8).min(8) {
            let Some((_, e)) = od.get(index, sub) else {
                break;
            };
            let value = e.default_raw(0) as u32;
            let Some((_, target)) = od.get((value >> 16) as u16, (value >> 8) as u8) else {
                continue;
            };
            if target.pdo && target.access.readable() && !target.access.writable() {
                v.push(value);
                report.notes.push(format!(
                    "RPDO{} (0x{index:04X}): the shipped mapping entry 0x{value:08X} maps the \
                     read-only 0x{:04X}:{} (CiA 301 wants writable objects in an RPDO): taken as \
                     the device takes it, a received value for it ignored",
                    n + 1,
                    target.index,
                    target.sub
                ));
            }
        }
    }
    v
}
