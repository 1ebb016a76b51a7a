//! The objects of an EDS: an object section, its sub-index sections and CompactSubObj read into
//! an [`EdsObject`](super::EdsObject).

use std::collections::HashSet;

use super::lex::{err, key_err, num_key, text_of, Ctx, Entry, Kind, Section};
use super::value::{clip, parse_plain_uint, strip_hash_comment, ValueExpr};
use super::{DataType, EdsError, EdsObject, EdsSub, ObjectCode};
use crate::od::Access;

pub(super) fn data_type_of(
    s: &Section,
    e: &Entry,
    structs: &HashSet<u16>,
) -> Result<DataType, EdsError> {
    let code = parse_plain_uint(e.value).map_err(|r| key_err(s, e, r))?;
    if code > 0xFFFF {
        return Err(key_err(s, e, format!("unknown data type 0x{code:X}")));
    }
    let code = code as u16;
    if let Some(t) = DataType::from_code(code) {
        return Ok(t);
    }
    let complex = match code {
        0x20 => Some("PDO_COMMUNICATION_PARAMETER"),
        0x21 => Some("PDO_MAPPING"),
        0x22 => Some("SDO_PARAMETER"),
        0x23 => Some("IDENTITY"),
        _ if structs.contains(&code) => Some("a DEFSTRUCT of this file"),
        _ => None,
    };
    Err(key_err(
        s,
        e,
        match complex {
            Some(what) => format!(
                "complex data type 0x{code:04X} ({what}) on a sub-index: a sub-index holds a basic type"
            ),
            None => format!("unknown data type 0x{code:04X}"),
        },
    ))
}

/// The attributes a value has in its section (VAR object, sub-index, CompactSubObj array).
pub(super) struct Attrs {
    pub(super) data_type: DataType,
    pub(super) access: Access,
    pub(super) pdo_mapping: bool,
    pub(super) default: Option<ValueExpr>,
    pub(super) parameter_value: Option<ValueExpr>,
    pub(super) low: Option<ValueExpr>,
    pub(super) high: Option<ValueExpr>,
    pub(super) obj_flags: u32,
    pub(super) upload_file: Option<String>,
    pub(super) download_file: Option<String>,
}

pub(super) fn value_key(
    cx: &mut Ctx,
    si: usize,
    key: &str,
    dtype: DataType,
) -> Result<Option<ValueExpr>, EdsError> {
    let s = &cx.sections[si];
    let Some(e) = s.get(key) else { return Ok(None) };
    let v = ValueExpr::parse(e.value, dtype).map_err(|r| key_err(s, e, r))?;
    let Some(mut v) = v else { return Ok(None) };
    let mut notes = Vec::new();
    if let Err(e2) = check_value(s, e, &v, dtype) {
        // A limit beyond the type's range limits nothing: python canopen takes it as it is,
        // Lely clamps it with a warning; read it as the type's bound (dcfchk refuses it).
        let clamped = match (is_limit(key), dtype.range(), &v) {
            (true, Some((lo, hi)), ValueExpr::Integer(_) | ValueExpr::Hex(_)) => {
                let x = match v {
                    ValueExpr::Integer(i) => i,
                    ValueExpr::Hex(u) => i128::try_from(u).unwrap_or(i128::MAX),
                    _ => 0,
                };
                Some(x.clamp(lo, hi))
            }
            _ => None,
        };
        let Some(c) = clamped else { return Err(e2) };
        notes.push(format!(
            "{} is outside the range of {}: read as {c} (Lely clamps it likewise)",
            e.value,
            dtype.name()
        ));
        v = ValueExpr::Integer(c);
    }
    let (line, name, k, text) = (e.line, s.name, e.key, e.value);
    notes.extend(v.prefix_note(text, dtype));
    if !dtype.variable() && text.contains(';') {
        notes.push(format!(
            "'{}': a ';' comment without a space before it; the number before it is read (python canopen reads such a value as text and fails)",
            clip(text)
        ));
    }
    if matches!(v, ValueExpr::Integer(_)) {
        let digits = strip_hash_comment(text).trim_start_matches(['-', '+']);
        if digits.len() > 1
            && digits.starts_with('0')
            && digits.bytes().all(|b| b.is_ascii_digit())
            && digits.bytes().any(|b| b >= b'8')
        {
            notes.push(format!(
                "'{text}' has a leading 0 (octal in CiA 306) but an 8 or 9: read as the decimal {} (python canopen and Lely stop here)",
                digits.trim_start_matches('0')
            ));
        }
    }
    if dtype.float() && matches!(v, ValueExpr::Integer(i) if i != 0) {
        notes.push(format!(
            "{} value '{text}' is a plain decimal integer: read as the number (python canopen); Lely reads it as IEEE 754 bits",
            dtype.name()
        ));
    }
    if let (ValueExpr::Integer(i), Some(t)) = (&v, strip_hash_comment(text).strip_prefix('0')) {
        if !t.is_empty()
            && t.bytes().all(|b| b.is_ascii_digit())
            && i.to_string() != t.trim_start_matches('0')
        {
            notes.push(format!(
                "'{text}' is octal (CiA 306, Lely): {i}; python canopen rejects it"
            ));
        }
    }
    for n in notes {
        cx.warn(line, Some(name), Some(k), n);
    }
    Ok(Some(v))
}

pub(super) fn is_limit(key: &str) -> bool {
    key == "LowLimit" || key == "HighLimit"
}

/// Resolve a value as the node would (at node IDs 1 and 127 if it uses $NODEID).
pub(super) fn check_value(
    s: &Section,
    e: &Entry,
    v: &ValueExpr,
    dtype: DataType,
) -> Result<(), EdsError> {
    if dtype.integer() && v.uses_node_id() {
        for id in [1u8, 127] {
            v.resolve(dtype, Some(id))
                .map_err(|r| key_err(s, e, format!("{r} (with $NODEID = {id})")))?;
        }
    } else if v.uses_node_id() {
        return Err(key_err(
            s,
            e,
            format!("$NODEID in a {} value", dtype.name()),
        ));
    } else {
        v.resolve(dtype, None).map_err(|r| key_err(s, e, r))?;
    }
    Ok(())
}

/// A value as a number for comparisons (at a node ID), `None` for strings.
pub(super) fn numeric(v: &ValueExpr, dtype: DataType, node_id: u8) -> Option<f64> {
    let b = v.resolve(dtype, Some(node_id)).ok()?;
    Some(match dtype {
        DataType::Real32 => f32::from_le_bytes(b[..4].try_into().ok()?) as f64,
        DataType::Real64 => f64::from_le_bytes(b[..8].try_into().ok()?),
        t if t.integer() => {
            let mut buf = [0u8; 16];
            buf[..b.len()].copy_from_slice(&b);
            let mut v = i128::from_le_bytes(buf);
            if t.signed() {
                let bits = (b.len() * 8) as u32;
                v = (v << (128 - bits)) >> (128 - bits);
            }
            v as f64
        }
        _ => return None,
    })
}

pub(super) fn read_attrs(
    cx: &mut Ctx,
    si: usize,
    dtype: DataType,
    code: ObjectCode,
) -> Result<Attrs, EdsError> {
    let access = access_of(cx, si, dtype, code)?;
    let (pdo_mapping, obj_flags) = flags_of(cx, si);
    let (low, high) = limits_of(cx, si, dtype)?;
    let high = unsigned_high_of_signed(cx, si, dtype, &low, high);
    let default = value_key(cx, si, "DefaultValue", dtype)?;
    let parameter_value = value_key(cx, si, "ParameterValue", dtype)?;
    let (upload_file, download_file) = files_of(cx, si, dtype);
    check_limits(cx, si, dtype, (&low, &high), [&default, &parameter_value])?;
    Ok(Attrs {
        data_type: dtype,
        access,
        pdo_mapping,
        default,
        parameter_value,
        low,
        high,
        obj_flags,
        upload_file,
        download_file,
    })
}

/// `AccessType`; a DOMAIN may omit it (read as rw, as Lely does, with a warning).
fn access_of(
    cx: &mut Ctx,
    si: usize,
    dtype: DataType,
    code: ObjectCode,
) -> Result<Access, EdsError> {
    let s = &cx.sections[si];
    let (line, name) = (s.line, s.name);
    let access = match s.get("AccessType") {
        Some(e) if !e.value.is_empty() => Access::from_eds(e.value).ok_or_else(|| {
            key_err(
                s,
                e,
                format!(
                    "'{}' is not an access type (ro, wo, rw, rwr, rww, const)",
                    e.value
                ),
            )
        })?,
        _ if dtype == DataType::Domain || code == ObjectCode::Domain => {
            cx.warn(
                line,
                Some(name),
                Some("AccessType"),
                "DOMAIN without AccessType: read as rw (Lely)",
            );
            Access::Rw
        }
        _ => {
            return Err(err(
                line,
                Some(name),
                Some("AccessType"),
                "AccessType is missing",
            ))
        }
    };
    Ok(access)
}

/// `PDOMapping` and `ObjFlags`.
fn flags_of(cx: &mut Ctx, si: usize) -> (bool, u32) {
    let s = &cx.sections[si];
    let name = s.name;
    // PDOMapping and ObjFlags are read past as Lely reads them (strtoul: a word is 0, any
    // non-zero number is set); python canopen reads PDOMapping with bool(int()), ignores
    // ObjFlags
    let mut notes: Vec<(usize, &str, String)> = Vec::new();
    let pdo_mapping = match s.get("PDOMapping") {
        Some(e) if !e.value.is_empty() => match parse_plain_uint(e.value) {
            Ok(v) if v <= 1 => v == 1,
            Ok(v) => {
                notes.push((e.line, e.key, format!("PDOMapping is 0 or 1, not {v}: read as 1 (mappable), as python canopen and Lely read it")));
                true
            }
            Err(_) => {
                let yes = matches!(e.value.to_ascii_lowercase().as_str(), "true" | "yes");
                notes.push((
                    e.line,
                    e.key,
                    format!(
                        "'{}' is not 0 or 1: read as {} ({})",
                        e.value,
                        yes as u8,
                        if yes {
                            "the word says so"
                        } else {
                            "not mappable, as Lely reads a word"
                        }
                    ),
                ));
                yes
            }
        },
        _ => false,
    };
    let obj_flags = match s.get("ObjFlags") {
        Some(e) if !e.value.is_empty() => match parse_plain_uint(e.value)
            .ok()
            .and_then(|v| u32::try_from(v).ok())
        {
            Some(v) => v,
            None => {
                notes.push((e.line, e.key, format!("'{}' is not a 32-bit number (CiA 306: bit 0 refuse write on download, bit 1 refuse read on scan): read as 0, as Lely reads it (python canopen ignores ObjFlags)", clip(e.value))));
                0
            }
        },
        _ => 0,
    };
    for (l, k, why) in notes {
        cx.warn(l, Some(name), Some(k), why);
    }
    (pdo_mapping, obj_flags)
}

/// `LowLimit` and `HighLimit` of a numeric type; on any other type ignored with a warning.
fn limits_of(
    cx: &mut Ctx,
    si: usize,
    dtype: DataType,
) -> Result<(Option<ValueExpr>, Option<ValueExpr>), EdsError> {
    let numeric_type = dtype.integer() || dtype.float();
    let mut low = None;
    let mut high = None;
    if numeric_type {
        low = value_key(cx, si, "LowLimit", dtype)?;
        high = value_key(cx, si, "HighLimit", dtype)?;
    } else {
        for key in ["LowLimit", "HighLimit"] {
            let s = &cx.sections[si];
            if let Some(e) = s.get(key).filter(|e| !e.value.is_empty()) {
                let (l, n, k) = (e.line, s.name, e.key);
                cx.warn(
                    l,
                    Some(n),
                    Some(k),
                    format!("a {} has no limits; ignored", dtype.name()),
                );
            }
        }
    }
    Ok((low, high))
}

/// `UploadFile` and `DownloadFile` of a DOMAIN; on any other type ignored with a warning.
fn files_of(cx: &mut Ctx, si: usize, dtype: DataType) -> (Option<String>, Option<String>) {
    let s = &cx.sections[si];
    let (line, name) = (s.line, s.name);
    let mut upload_file = text_of(Some(s), "UploadFile").filter(|t| !t.is_empty());
    let mut download_file = text_of(Some(s), "DownloadFile").filter(|t| !t.is_empty());
    if dtype != DataType::Domain && (upload_file.is_some() || download_file.is_some()) {
        cx.warn(
            line,
            Some(name),
            None,
            "UploadFile/DownloadFile on a type other than DOMAIN; ignored",
        );
        upload_file = None;
        download_file = None;
    }
    (upload_file, download_file)
}

/// A signed type's HighLimit written as the all-ones pattern of an unsigned one (SEVCON's Gen4
/// files: INTEGER32 with `LowLimit=0`, `HighLimit=0xFFFFFFFF`): its two's complement (-1)
/// falls below LowLimit, where it means "no upper limit"; read as the type's maximum, with a
/// warning (python canopen reads -1 and checks no order; Lely's dcfchk refuses a limit beyond
/// the type). Any other HighLimit is returned as it is.
fn unsigned_high_of_signed(
    cx: &mut Ctx,
    si: usize,
    dtype: DataType,
    low: &Option<ValueExpr>,
    high: Option<ValueExpr>,
) -> Option<ValueExpr> {
    let (Some(ValueExpr::Hex(u)), Some(l), Some((_, max))) = (&high, low, dtype.range()) else {
        return high;
    };
    let bits = (dtype.size() * 8) as u32;
    let pattern = i128::try_from(*u).unwrap_or(i128::MAX);
    let h = ValueExpr::Hex(*u);
    let crossed = [1u8, 127].into_iter().all(
        |id| matches!((numeric(l, dtype, id), numeric(&h, dtype, id)), (Some(a), Some(b)) if a > b),
    );
    if !dtype.signed() || pattern <= max || pattern >= 1i128 << bits || !crossed {
        return high;
    }
    let s = &cx.sections[si];
    let (line, name) = (s.get("HighLimit").map_or(s.line, |e| e.line), s.name);
    cx.warn(
        line,
        Some(name),
        Some("HighLimit"),
        format!(
            "0x{u:X} on type {} is {} as two's complement, below LowLimit: read as no upper \
             limit, the type's maximum {max} (python canopen reads {}, Lely's dcfchk refuses it)",
            dtype.name(),
            pattern - (1i128 << bits),
            pattern - (1i128 << bits),
        ),
    );
    Some(ValueExpr::Integer(max))
}

/// LowLimit above HighLimit is an error (a warning when only at one of the node IDs 1 and
/// 127); a DefaultValue or ParameterValue outside the limits is a warning.
fn check_limits(
    cx: &mut Ctx,
    si: usize,
    dtype: DataType,
    (low, high): (&Option<ValueExpr>, &Option<ValueExpr>),
    [default, parameter_value]: [&Option<ValueExpr>; 2],
) -> Result<(), EdsError> {
    let s = &cx.sections[si];
    let (line, name) = (s.line, s.name);
    // limits
    if let (Some(l), Some(h)) = (low, high) {
        let at = |id| (numeric(l, dtype, id), numeric(h, dtype, id));
        let bad: Vec<u8> = [1u8, 127]
            .into_iter()
            .filter(|&id| matches!(at(id), (Some(a), Some(b)) if a > b))
            .collect();
        if bad.len() == 2 {
            let s = &cx.sections[si];
            let e = s.get("LowLimit").expect("read above");
            return Err(key_err(s, e, "LowLimit is greater than HighLimit"));
        } else if bad.len() == 1 {
            cx.warn(
                line,
                Some(name),
                Some("LowLimit"),
                format!("LowLimit is greater than HighLimit at node ID {}", bad[0]),
            );
        }
    }
    for (key, v) in [
        ("DefaultValue", default),
        ("ParameterValue", parameter_value),
    ] {
        let Some(v) = v else { continue };
        for id in [1u8, 127] {
            let x = numeric(v, dtype, id);
            let below = matches!((x, low.as_ref().and_then(|l| numeric(l, dtype, id))), (Some(x), Some(l)) if x < l);
            let above = matches!((x, high.as_ref().and_then(|h| numeric(h, dtype, id))), (Some(x), Some(h)) if x > h);
            if below || above {
                let s = &cx.sections[si];
                let l = s.get(key).map_or(line, |e| e.line);
                cx.warn(
                    l,
                    Some(name),
                    Some(key),
                    format!(
                        "{key} is {} the limits{}",
                        if below { "below" } else { "above" },
                        if v.uses_node_id() {
                            format!(" at node ID {id}")
                        } else {
                            String::new()
                        }
                    ),
                );
                break;
            }
        }
    }
    Ok(())
}

pub(super) fn sub_from(
    attrs: Attrs,
    sub: u8,
    name: String,
    denotation: Option<String>,
    line: usize,
) -> EdsSub {
    EdsSub {
        sub,
        name,
        data_type: attrs.data_type,
        access: attrs.access,
        pdo_mapping: attrs.pdo_mapping,
        default: attrs.default,
        parameter_value: attrs.parameter_value,
        low: attrs.low,
        high: attrs.high,
        denotation,
        obj_flags: attrs.obj_flags,
        upload_file: attrs.upload_file,
        download_file: attrs.download_file,
        line,
    }
}

pub(super) fn name_of(s: &Section) -> Result<String, EdsError> {
    match s.get("ParameterName") {
        Some(e) if !e.value.is_empty() => Ok(e.value.to_string()),
        _ => Err(err(
            s.line,
            Some(s.name),
            Some("ParameterName"),
            "ParameterName is missing",
        )),
    }
}

pub(super) fn read_object(
    cx: &mut Ctx,
    index: u16,
    si: usize,
    subs: &[(u8, usize)],
    structs: &HashSet<u16>,
) -> Result<EdsObject, EdsError> {
    let s = &cx.sections[si];
    let (line, sname) = (s.line, s.name);
    let name = name_of(s)?;
    let denotation = text_of(Some(s), "Denotation").filter(|t| !t.is_empty());
    let code = object_code(s)?;
    let object_links = read_links(cx, index)?;
    let head = Head {
        index,
        si,
        line,
        sname,
        name: &name,
        code,
    };
    let (data_type, subs) = if code.structured() {
        read_structured(cx, &head, subs, structs)?
    } else {
        read_var(cx, &head, subs, structs, denotation.clone())?
    };
    Ok(EdsObject {
        index,
        name,
        denotation,
        code,
        data_type,
        subs,
        object_links,
        line,
    })
}

/// What every step of reading one object knows about it.
struct Head<'t, 'n> {
    index: u16,
    /// Its section.
    si: usize,
    line: usize,
    /// Its section's name, as written.
    sname: &'t str,
    /// `ParameterName`.
    name: &'n str,
    code: ObjectCode,
}

/// `ObjectType`, VAR when not given.
fn object_code(s: &Section) -> Result<ObjectCode, EdsError> {
    let code = match s.get("ObjectType") {
        Some(e) if !e.value.is_empty() => {
            let v = parse_plain_uint(e.value).map_err(|r| key_err(s, e, r))?;
            u8::try_from(v)
                .ok()
                .and_then(ObjectCode::from_code)
                .ok_or_else(|| {
                    key_err(s, e, format!("object type {v} is none of NULL 0, DOMAIN 2, DEFTYPE 5, DEFSTRUCT 6, VAR 7, ARRAY 8, RECORD 9"))
                })?
        }
        _ => ObjectCode::Var,
    };
    Ok(code)
}

/// NULL, DOMAIN, DEFTYPE or VAR: one value, sub-index 0, attributes in the object's section.
fn read_var(
    cx: &mut Ctx,
    head: &Head,
    subs: &[(u8, usize)],
    structs: &HashSet<u16>,
    denotation: Option<String>,
) -> Result<(Option<DataType>, Vec<EdsSub>), EdsError> {
    let Head {
        index,
        si,
        line,
        sname,
        name,
        code,
    } = *head;
    let s = &cx.sections[si];
    let dtype = match s.get("DataType").filter(|e| !e.value.is_empty()) {
        Some(e) => data_type_of(s, e, structs)?,
        None if code == ObjectCode::Domain => DataType::Domain,
        None => {
            return Err(err(
                line,
                Some(sname),
                Some("DataType"),
                "DataType is missing",
            ))
        }
    };
    if let Some(&(_, sub_si)) = subs.first() {
        let ss = &cx.sections[sub_si];
        let (l, n) = (ss.line, ss.name);
        cx.warn(
            l,
            Some(n),
            None,
            format!(
                "sub-index section of a {:?} object; ignored (a VAR's attributes are in [{:04X}])",
                code, index
            ),
        );
    }
    for key in ["SubNumber", "CompactSubObj"] {
        let s = &cx.sections[si];
        if let Some(e) = s
            .get(key)
            .filter(|e| parse_plain_uint(e.value).is_ok_and(|v| v != 0))
        {
            let (l, k) = (e.line, e.key);
            cx.warn(
                l,
                Some(sname),
                Some(k),
                format!("{key} on a {code:?} object; ignored"),
            );
        }
    }
    let attrs = read_attrs(cx, si, dtype, code)?;
    let sub = sub_from(attrs, 0, name.to_string(), denotation, line);
    Ok((Some(dtype), vec![sub]))
}

/// DEFSTRUCT, ARRAY or RECORD: sub-indices from CompactSubObj or from their own sections.
fn read_structured(
    cx: &mut Ctx,
    head: &Head,
    subs: &[(u8, usize)],
    structs: &HashSet<u16>,
) -> Result<(Option<DataType>, Vec<EdsSub>), EdsError> {
    let s = &cx.sections[head.si];
    let sub_number = match s.get("SubNumber").filter(|e| !e.value.is_empty()) {
        Some(e) => {
            let v = parse_plain_uint(e.value).map_err(|r| key_err(s, e, r))?;
            if v > 255 {
                return Err(key_err(s, e, format!("SubNumber {v} is more than 255")));
            }
            Some((v as usize, e.line))
        }
        None => None,
    }
    .filter(|(v, _)| *v != 0);
    let compact = match s.get("CompactSubObj").filter(|e| !e.value.is_empty()) {
        Some(e) => {
            let v = parse_plain_uint(e.value).map_err(|r| key_err(s, e, r))?;
            if v > 254 {
                return Err(key_err(
                    s,
                    e,
                    format!("CompactSubObj {v} is more than 254 sub-indices"),
                ));
            }
            Some((v as u8, e.line))
        }
        None => None,
    }
    .filter(|(v, _)| *v != 0);
    let data_type = match s.get("DataType").filter(|e| !e.value.is_empty()) {
        Some(e) if compact.is_some() => Some(data_type_of(s, e, structs)?),
        Some(e) => parse_plain_uint(e.value)
            .ok()
            .and_then(|c| u16::try_from(c).ok())
            .and_then(DataType::from_code),
        None => None,
    };

    let out_subs = if let Some(compact) = compact {
        compact_subs(cx, head, compact, sub_number, subs, data_type)?
    } else {
        section_subs(cx, head, sub_number, subs, structs)?
    };
    Ok((data_type, out_subs))
}

/// The sub-indices of `CompactSubObj=n` (given at line `cline`): sub 0 `NrOfObjects` and
/// subs 1..=n with the object's attributes.
fn compact_subs(
    cx: &mut Ctx,
    head: &Head,
    (n, cline): (u8, usize),
    sub_number: Option<(usize, usize)>,
    subs: &[(u8, usize)],
    data_type: Option<DataType>,
) -> Result<Vec<EdsSub>, EdsError> {
    let Head {
        index,
        si,
        line,
        sname,
        name,
        code,
    } = *head;
    let mut out_subs: Vec<EdsSub> = Vec::new();
    if let Some((_, l)) = sub_number {
        return Err(err(
            l,
            Some(sname),
            Some("SubNumber"),
            "both SubNumber and CompactSubObj given (Lely and dcfchk refuse this)",
        ));
    }
    if let Some(&(_, sub_si)) = subs.first() {
        let ss = &cx.sections[sub_si];
        return Err(err(
            ss.line,
            Some(ss.name),
            None,
            format!("sub-index section of an object with CompactSubObj (line {cline})"),
        ));
    }
    let Some(dtype) = data_type else {
        return Err(err(
            line,
            Some(sname),
            Some("DataType"),
            "DataType is missing (CompactSubObj needs the sub-indices' type)",
        ));
    };
    let attrs = read_attrs(cx, si, dtype, code)?;
    let names = read_compact_names(cx, index, n)?;
    let values = read_compact_values(cx, index, n, dtype)?;
    out_subs.reserve(n as usize + 1);
    out_subs.push(EdsSub {
        sub: 0,
        name: "NrOfObjects".into(),
        data_type: DataType::U8,
        access: Access::Ro,
        pdo_mapping: false,
        default: Some(ValueExpr::Integer(n as i128)),
        parameter_value: None,
        low: None,
        high: None,
        denotation: None,
        obj_flags: 0,
        upload_file: None,
        download_file: None,
        line,
    });
    for i in 1..=n {
        let sub_name = names[i as usize]
            .clone()
            .unwrap_or_else(|| format!("{name}{i}"));
        out_subs.push(EdsSub {
            sub: i,
            name: sub_name,
            data_type: dtype,
            access: attrs.access,
            pdo_mapping: attrs.pdo_mapping,
            default: attrs.default.clone(),
            parameter_value: values[i as usize]
                .clone()
                .or_else(|| attrs.parameter_value.clone()),
            low: attrs.low.clone(),
            high: attrs.high.clone(),
            denotation: None,
            obj_flags: attrs.obj_flags,
            upload_file: None,
            download_file: None,
            line,
        });
    }
    Ok(out_subs)
}

/// The sub-indices of an object from their `[IIIIsubS]` sections, checked against SubNumber.
fn section_subs(
    cx: &mut Ctx,
    head: &Head,
    sub_number: Option<(usize, usize)>,
    subs: &[(u8, usize)],
    structs: &HashSet<u16>,
) -> Result<Vec<EdsSub>, EdsError> {
    let Head {
        index,
        line,
        sname,
        code,
        ..
    } = *head;
    for kind in [Kind::Names(index), Kind::Values(index)] {
        if let Some(ss) = cx.section(kind) {
            let (l, n) = (ss.line, ss.name);
            cx.warn(
                l,
                Some(n),
                None,
                format!("[{sname}] has no CompactSubObj; this section is ignored"),
            );
        }
    }
    match sub_number {
        Some((n, l)) if n > subs.len() => {
            cx.warn(
                l,
                Some(sname),
                Some("SubNumber"),
                format!(
                    "SubNumber={n} but only {} sub-index sections are present; those are read (Lely and python canopen read them alike)",
                    subs.len()
                ),
            );
        }
        Some((n, l)) if n < subs.len() => {
            let listed: Vec<String> = subs.iter().map(|(s, _)| format!("{s:X}")).collect();
            cx.warn(
                l,
                Some(sname),
                Some("SubNumber"),
                format!(
                    "SubNumber={n} but {} sub-index sections are present (sub {}): all are read, as python canopen reads them (Lely reads the first {n})",
                    subs.len(),
                    listed.join(", ")
                ),
            );
        }
        None if subs.is_empty() => {
            return Err(err(line, Some(sname), None, format!("{code:?} object with neither SubNumber nor CompactSubObj nor sub-index sections")));
        }
        None => {
            cx.warn(
                line,
                Some(sname),
                Some("SubNumber"),
                format!(
                    "SubNumber missing; the {} sub-index sections present are read",
                    subs.len()
                ),
            );
        }
        _ => {}
    }
    let mut out_subs: Vec<EdsSub> = Vec::with_capacity(subs.len());
    for &(sub, sub_si) in subs {
        out_subs.push(read_sub(cx, sub, sub_si, structs)?);
    }
    if let Some(s0) = out_subs.first().filter(|s| s.sub == 0) {
        if s0.data_type != DataType::U8 {
            let (l, n) = (s0.line, cx.sections[subs[0].1].name);
            cx.warn(
                l,
                Some(n),
                Some("DataType"),
                "sub-index 0 of an ARRAY/RECORD should be UNSIGNED8 (highest sub-index)",
            );
        }
    } else {
        cx.warn(
            line,
            Some(sname),
            None,
            "no sub-index 0 (highest sub-index supported)",
        );
    }
    Ok(out_subs)
}

/// One `[IIIIsubS]` section.
fn read_sub(
    cx: &mut Ctx,
    sub: u8,
    sub_si: usize,
    structs: &HashSet<u16>,
) -> Result<EdsSub, EdsError> {
    let ss = &cx.sections[sub_si];
    let sub_line = ss.line;
    let sub_name = name_of(ss)?;
    let sub_den = text_of(Some(ss), "Denotation").filter(|t| !t.is_empty());
    // a sub-index is a VAR (0x7); tools write DOMAIN (0x2) for a DOMAIN sub-index
    if let Some(e) = ss
        .get("ObjectType")
        .filter(|e| !matches!(parse_plain_uint(e.value), Ok(7) | Ok(2)))
    {
        let (l, n, k) = (e.line, ss.name, e.key);
        cx.warn(
            l,
            Some(n),
            Some(k),
            "a sub-index is a VAR (ObjectType=0x7); the value is ignored",
        );
    }
    let ss = &cx.sections[sub_si];
    let dtype = match ss.get("DataType").filter(|e| !e.value.is_empty()) {
        Some(e) => data_type_of(ss, e, structs)?,
        None => {
            return Err(err(
                sub_line,
                Some(ss.name),
                Some("DataType"),
                "DataType is missing",
            ))
        }
    };
    let attrs = read_attrs(cx, sub_si, dtype, ObjectCode::Var)?;
    Ok(sub_from(attrs, sub, sub_name, sub_den, sub_line))
}

/// `[IIIIName]`: names of CompactSubObj sub-indices (slot i for sub i).
pub(super) fn read_compact_names(
    cx: &mut Ctx,
    index: u16,
    n: u8,
) -> Result<Vec<Option<String>>, EdsError> {
    let mut names = vec![None; n as usize + 1];
    let Some(&si) = cx.by_kind.get(&Kind::Names(index)) else {
        return Ok(names);
    };
    let s = &cx.sections[si];
    let mut count = 0usize;
    for e in &s.entries {
        if e.key.eq_ignore_ascii_case("NrOfEntries") {
            continue;
        }
        let sub = parse_plain_uint(e.key)
            .map_err(|_| key_err(s, e, "a key here is a sub-index number or NrOfEntries"))?;
        if sub == 0 || sub > n as u128 {
            return Err(key_err(
                s,
                e,
                format!("names sub-index {sub}, but CompactSubObj={n}"),
            ));
        }
        names[sub as usize] = Some(e.value.to_string());
        count += 1;
    }
    let nr = num_key(&mut cx.warnings, Some(s), "NrOfEntries", 255);
    if nr.is_some_and(|v| v as usize != count) {
        let (l, name) = (s.line, s.name);
        cx.warn(
            l,
            Some(name),
            Some("NrOfEntries"),
            format!("NrOfEntries={} but {count} entries", nr.unwrap_or(0)),
        );
    }
    Ok(names)
}

/// `[IIIIValue]`: ParameterValues of CompactSubObj sub-indices.
pub(super) fn read_compact_values(
    cx: &mut Ctx,
    index: u16,
    n: u8,
    dtype: DataType,
) -> Result<Vec<Option<ValueExpr>>, EdsError> {
    let mut values = vec![None; n as usize + 1];
    let Some(&si) = cx.by_kind.get(&Kind::Values(index)) else {
        return Ok(values);
    };
    let s = &cx.sections[si];
    let mut count = 0usize;
    for e in &s.entries {
        if e.key.eq_ignore_ascii_case("NrOfEntries") {
            continue;
        }
        let sub = parse_plain_uint(e.key)
            .map_err(|_| key_err(s, e, "a key here is a sub-index number or NrOfEntries"))?;
        if sub == 0 || sub > n as u128 {
            return Err(key_err(
                s,
                e,
                format!("gives sub-index {sub} a value, but CompactSubObj={n}"),
            ));
        }
        let v = ValueExpr::parse(e.value, dtype).map_err(|r| key_err(s, e, r))?;
        if let Some(v) = &v {
            check_value(s, e, v, dtype)?;
        }
        values[sub as usize] = v;
        count += 1;
    }
    let nr = num_key(&mut cx.warnings, Some(s), "NrOfEntries", 255);
    if nr.is_some_and(|v| v as usize != count) {
        let (l, name) = (s.line, s.name);
        cx.warn(
            l,
            Some(name),
            Some("NrOfEntries"),
            format!("NrOfEntries={} but {count} entries", nr.unwrap_or(0)),
        );
    }
    Ok(values)
}

pub(super) fn read_links(cx: &mut Ctx, index: u16) -> Result<Vec<u16>, EdsError> {
    let Some(&si) = cx.by_kind.get(&Kind::Links(index)) else {
        return Ok(Vec::new());
    };
    let s = &cx.sections[si];
    let n = num_key(&mut cx.warnings, Some(s), "ObjectLinks", 65_535).unwrap_or(0) as usize;
    let mut links = Vec::with_capacity(n.min(1024));
    for e in &s.entries {
        if e.key.eq_ignore_ascii_case("ObjectLinks") {
            continue;
        }
        let i = parse_plain_uint(e.key)
            .map_err(|_| key_err(s, e, "a key here is a link number or ObjectLinks"))?;
        if i == 0 || i as usize > n {
            return Err(key_err(s, e, format!("link {i} beyond ObjectLinks={n}")));
        }
        let v = parse_plain_uint(e.value).map_err(|r| key_err(s, e, r))?;
        let v = u16::try_from(v)
            .map_err(|_| key_err(s, e, format!("0x{v:X} is not an object index")))?;
        links.push(v);
    }
    if links.len() != n {
        let (l, name) = (s.line, s.name);
        cx.warn(
            l,
            Some(name),
            Some("ObjectLinks"),
            format!("ObjectLinks={n} but {} links", links.len()),
        );
    }
    Ok(links)
}
