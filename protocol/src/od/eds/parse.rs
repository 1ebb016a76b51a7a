//! Reading an EDS, top level: the sections classified, the fixed sections read, every object
//! read and the lists checked.

use std::collections::{HashMap, HashSet};

use super::check::{check_lists, warn_unknown_keys};
use super::lex::{
    add_entry, bool_key, classify, err, kind_counts_object, lex, lex_warn, num_key, text_of, Ctx,
    Kind,
};
use super::object::read_object;
use super::value::parse_plain_uint;
use super::{
    Commissioning, DeviceInfo, EdsError, EdsFile, EdsObject, FileInfo, MAX_INPUT_BYTES,
    MAX_OBJECTS, MAX_SUBS,
};

/// Parse the text of an EDS or DCF (CiA 306). See the module documentation for what is
/// accepted and what is an error.
pub fn parse(text: &str) -> Result<EdsFile, EdsError> {
    check_size(text)?;
    let (sections, lex_warnings) = lex(text)?;
    let mut cx = Ctx {
        sections,
        by_kind: HashMap::new(),
        warnings: lex_warnings,
    };
    classify_sections(&mut cx)?;

    let file_info = read_file_info(&cx);
    let device_info = read_device_info(&mut cx)?;
    let dummy_usage = read_dummy_usage(&mut cx)?;
    let comments = read_comments(&mut cx)?;
    let commissioning = read_commissioning(&mut cx)?;

    let structs = defined_structs(&cx);
    let subs_of = sub_sections(&cx)?;
    let (objects, indices) = read_objects(&mut cx, subs_of, &structs)?;

    check_lists(&mut cx, &indices)?;
    warn_unknown_keys(&mut cx);

    let mut warnings = std::mem::take(&mut cx.warnings);
    warnings.sort_by_key(|w| w.line); // stable: same-line warnings keep their order
    Ok(EdsFile {
        file_info,
        device_info,
        dummy_usage,
        comments,
        commissioning,
        objects,
        warnings,
    })
}

/// At most [`MAX_INPUT_BYTES`] of text; the error names the line where the limit is reached.
fn check_size(text: &str) -> Result<(), EdsError> {
    if text.len() > MAX_INPUT_BYTES {
        let line = text.as_bytes()[..MAX_INPUT_BYTES]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1;
        return Err(err(
            line,
            None,
            None,
            format!(
                "input of {} bytes, more than the {} MiB an EDS may have (limit reached at this line)",
                text.len(),
                MAX_INPUT_BYTES >> 20
            ),
        ));
    }
    Ok(())
}

/// What every section is ([`Kind`], into `cx.by_kind`): unknown sections are ignored with a
/// warning, two names of one thing (`[1018sub1]`, `[1018sub01]`) read as one section.
fn classify_sections(cx: &mut Ctx) -> Result<(), EdsError> {
    let mut n_objects = 0usize;
    for i in 0..cx.sections.len() {
        let (name, line) = (cx.sections[i].name, cx.sections[i].line);
        let kind =
            classify(&name.to_ascii_lowercase()).map_err(|r| err(line, Some(name), None, r))?;
        if let Kind::Object(0) = kind {
            return Err(err(
                line,
                Some(name),
                None,
                "object index 0x0000 does not exist",
            ));
        }
        if let Kind::Sub(0, _) = kind {
            return Err(err(
                line,
                Some(name),
                None,
                "object index 0x0000 does not exist",
            ));
        }
        if kind == Kind::Other {
            cx.warn(
                line,
                Some(name),
                None,
                "section not known to CiA 306 EDS/DCF readers here; ignored",
            );
            continue;
        }
        if let Kind::Object(_) = kind {
            n_objects += 1;
            if n_objects > MAX_OBJECTS {
                return Err(err(
                    line,
                    Some(name),
                    None,
                    format!("more than {MAX_OBJECTS} objects"),
                ));
            }
        }
        if let Some(&first) = cx.by_kind.get(&kind) {
            // [1018sub1] and [1018sub01]: one section, read as Lely reads a section twice
            let (fname, fline) = (cx.sections[first].name, cx.sections[first].line);
            cx.warn(
                line,
                Some(name),
                None,
                format!(
                    "names the same thing as [{fname}] at line {fline}: its keys are read as part of [{fname}] (as Lely reads a section given twice)"
                ),
            );
            let entries = std::mem::take(&mut cx.sections[i].entries);
            cx.sections[i].keys.clear();
            let mut w = Vec::new();
            for e in entries {
                add_entry(&mut cx.sections[first], name, e, &mut w);
            }
            cx.warnings.append(&mut w);
            if kind_counts_object(kind) {
                n_objects -= 1;
            }
            continue;
        }
        cx.by_kind.insert(kind, i);
    }
    Ok(())
}

/// The DEFSTRUCTs the file defines: their codes are complex types.
fn defined_structs(cx: &Ctx) -> HashSet<u16> {
    let mut structs: HashSet<u16> = HashSet::new();
    for (kind, &i) in &cx.by_kind {
        if let Kind::Object(index) = kind {
            let s = &cx.sections[i];
            if let Some(e) = s.get("ObjectType") {
                if parse_plain_uint(e.value).ok() == Some(6) {
                    structs.insert(*index);
                }
            }
        }
    }
    structs
}

/// The sub-index sections of each object, as (sub-index, section); an error for the first
/// (by line) sub-index, name, value or link section whose object is missing.
fn sub_sections(cx: &Ctx) -> Result<HashMap<u16, Vec<(u8, usize)>>, EdsError> {
    let mut subs_of: HashMap<u16, Vec<(u8, usize)>> = HashMap::new();
    let mut orphan: Option<(usize, usize)> = None; // (line, section idx)
    for (kind, &i) in &cx.by_kind {
        let index = match *kind {
            Kind::Sub(index, sub) => {
                subs_of.entry(index).or_default().push((sub, i));
                index
            }
            Kind::Names(index) | Kind::Values(index) | Kind::Links(index) => index,
            _ => continue,
        };
        // the first (by line) section whose object is missing
        let line = cx.sections[i].line;
        if !cx.by_kind.contains_key(&Kind::Object(index)) && orphan.is_none_or(|(l, _)| line < l) {
            orphan = Some((line, i));
        }
    }
    if let Some((line, i)) = orphan {
        let s = &cx.sections[i];
        return Err(err(
            line,
            Some(s.name),
            None,
            format!("section without its object [{}]", &s.name[..4]),
        ));
    }
    Ok(subs_of)
}

/// The (index, section) of every object, in index order.
type ObjectSections = Vec<(u16, usize)>;

/// Every object, in index order, and the (index, section) of each.
fn read_objects(
    cx: &mut Ctx,
    mut subs_of: HashMap<u16, Vec<(u8, usize)>>,
    structs: &HashSet<u16>,
) -> Result<(Vec<EdsObject>, ObjectSections), EdsError> {
    let mut indices: Vec<(u16, usize)> = cx
        .by_kind
        .iter()
        .filter_map(|(k, &i)| match k {
            Kind::Object(index) => Some((*index, i)),
            _ => None,
        })
        .collect();
    indices.sort_unstable();
    let mut objects = Vec::with_capacity(indices.len());
    let mut n_subs = 0usize;
    for &(index, si) in &indices {
        let mut subs = subs_of.remove(&index).unwrap_or_default();
        subs.sort_unstable();
        let obj = read_object(cx, index, si, &subs, structs)?;
        n_subs += obj.subs.len();
        if n_subs > MAX_SUBS {
            return Err(err(
                obj.line,
                Some(cx.sections[si].name),
                None,
                format!("more than {MAX_SUBS} sub-indices in all objects"),
            ));
        }
        objects.push(obj);
    }
    Ok((objects, indices))
}

pub(super) fn read_file_info(cx: &Ctx) -> FileInfo {
    let s = cx.section(Kind::FileInfo);
    FileInfo {
        file_name: text_of(s, "FileName"),
        file_version: text_of(s, "FileVersion"),
        file_revision: text_of(s, "FileRevision"),
        eds_version: text_of(s, "EDSVersion"),
        description: text_of(s, "Description"),
        creation_time: text_of(s, "CreationTime"),
        creation_date: text_of(s, "CreationDate"),
        created_by: text_of(s, "CreatedBy"),
        modification_time: text_of(s, "ModificationTime"),
        modification_date: text_of(s, "ModificationDate"),
        modified_by: text_of(s, "ModifiedBy"),
        last_eds: text_of(s, "LastEDS"),
    }
}

pub(super) fn read_device_info(cx: &mut Ctx) -> Result<DeviceInfo, EdsError> {
    let Some(&si) = cx.by_kind.get(&Kind::DeviceInfo) else {
        cx.warn(
            1,
            None,
            None,
            "no [DeviceInfo] section (CiA 306 makes it mandatory)",
        );
        return Ok(DeviceInfo::default());
    };
    let s = Some(&cx.sections[si]);
    let w = &mut cx.warnings;
    let mut baud_rates_kbit = Vec::new();
    for kbit in [10u16, 20, 50, 125, 250, 500, 800, 1000] {
        if bool_key(w, s, &format!("BaudRate_{kbit}")) == Some(true) {
            baud_rates_kbit.push(kbit);
        }
    }
    let d = DeviceInfo {
        vendor_name: text_of(s, "VendorName"),
        vendor_number: num_key(w, s, "VendorNumber", u32::MAX as u128).map(|v| v as u32),
        product_name: text_of(s, "ProductName"),
        product_number: num_key(w, s, "ProductNumber", u32::MAX as u128).map(|v| v as u32),
        revision_number: num_key(w, s, "RevisionNumber", u32::MAX as u128).map(|v| v as u32),
        order_code: text_of(s, "OrderCode"),
        baud_rates_kbit,
        simple_boot_up_master: bool_key(w, s, "SimpleBootUpMaster"),
        simple_boot_up_slave: bool_key(w, s, "SimpleBootUpSlave"),
        granularity: num_key(w, s, "Granularity", 64).map(|v| v as u8),
        dynamic_channels_supported: num_key(w, s, "DynamicChannelsSupported", 255).map(|v| v as u8),
        group_messaging: bool_key(w, s, "GroupMessaging"),
        nr_of_rx_pdo: num_key(w, s, "NrOfRXPDO", 512).map(|v| v as u16),
        nr_of_tx_pdo: num_key(w, s, "NrOfTXPDO", 512).map(|v| v as u16),
        lss_supported: bool_key(w, s, "LSS_Supported"),
        compact_pdo: num_key(w, s, "CompactPDO", 255).map(|v| v as u8),
    };
    if d.compact_pdo.is_some_and(|m| m != 0) {
        let (line, name) = (cx.sections[si].line, cx.sections[si].name);
        cx.warn(
            line,
            Some(name),
            Some("CompactPDO"),
            "implicit PDO objects (CompactPDO) are not expanded: only the PDO objects the file lists exist",
        );
    }
    Ok(d)
}

pub(super) fn read_dummy_usage(cx: &mut Ctx) -> Result<[bool; 8], EdsError> {
    let mut d = [false; 8];
    let s = cx.by_kind.get(&Kind::DummyUsage).map(|&i| &cx.sections[i]);
    let w = &mut cx.warnings;
    for (t, slot) in d.iter_mut().enumerate().skip(1) {
        *slot = bool_key(w, s, &format!("Dummy{t:04X}")) == Some(true);
    }
    Ok(d)
}

pub(super) fn read_comments(cx: &mut Ctx) -> Result<Vec<String>, EdsError> {
    let Some(&si) = cx.by_kind.get(&Kind::Comments) else {
        return Ok(Vec::new());
    };
    let s = &cx.sections[si];
    let n = num_key(&mut cx.warnings, Some(s), "Lines", 65_535).unwrap_or(0) as usize;
    let mut lines = Vec::with_capacity(n);
    let mut missing = None;
    for i in 1..=n {
        match s.get(&format!("Line{i}")) {
            Some(e) => lines.push(e.value.to_string()),
            None => {
                missing.get_or_insert(i);
                lines.push(String::new());
            }
        }
    }
    let extra = s
        .entries
        .len()
        .saturating_sub(1 + n - missing.map_or(0, |_| 1));
    let (line, name) = (s.line, s.name);
    if let Some(i) = missing {
        cx.warn(
            line,
            Some(name),
            None,
            format!("Lines={n} but Line{i} is missing (read as empty)"),
        );
    } else if extra > 0 && s.get("Lines").is_some() {
        cx.warn(
            line,
            Some(name),
            None,
            format!("more Line entries than Lines={n}; the extra ones are ignored"),
        );
    }
    Ok(lines)
}

pub(super) fn read_commissioning(cx: &mut Ctx) -> Result<Option<Commissioning>, EdsError> {
    let Some(&si) = cx.by_kind.get(&Kind::Commissioning) else {
        return Ok(None);
    };
    let s = Some(&cx.sections[si]);
    let w = &mut cx.warnings;
    let mut node_id = num_key(w, s, "NodeID", 255);
    if let Some(id) = node_id.filter(|id| !(1..=127).contains(id)) {
        let e = s.and_then(|s| s.get("NodeID")).expect("read above");
        lex_warn(
            w,
            e.line,
            s.map(|s| s.name),
            Some(e.key),
            format!("node ID {id} is outside 1..=127: read as not given (the node ID comes from the command line)"),
        );
        node_id = None;
    }
    Ok(Some(Commissioning {
        node_id: node_id.map(|v| v as u8),
        node_name: text_of(s, "NodeName"),
        baudrate_kbit: num_key(w, s, "Baudrate", 1000).map(|v| v as u16),
        net_number: num_key(w, s, "NetNumber", u32::MAX as u128).map(|v| v as u32),
        network_name: text_of(s, "NetworkName"),
        canopen_manager: bool_key(w, s, "CANopenManager"),
        lss_serial_number: num_key(w, s, "LSS_SerialNumber", u32::MAX as u128).map(|v| v as u32),
    }))
}
