//! The object dictionary of a vendor's ESI (ETG.2000 `Profile/Dictionary`): its `DataTypes`
//! (base types, records of `SubItem`s, arrays with `ArrayInfo`) and `Objects` (index, name,
//! type, default data, access, PDO mapping flag), as entries the drive's dictionary can hold.
//! The slave serves those the drive lacks ([`crate::slave::Slave::with_esi`]).
//!
//! Read as ETG.2000 writes them: `DefaultData` is the value's bytes in hex, little-endian
//! (`DefaultValue`, a number, is taken too); `Flags/Access` is `ro`, `rw` or `wo` (of the
//! object, or of a record's sub-item in its data type); `Flags/PdoMapping` (`R`, `T`, `RT`)
//! makes an entry mappable. An object this dictionary cannot hold (a type it does not know, a
//! bit-sized member other than a BOOL) is skipped and said so ([`Dictionary::skipped`]), not
//! refused: the rest of the file is still served.

use drive_protocol::od::{Access, DataType, DefaultValue, ObjType};

/// Objects read from one dictionary, at most.
const MAX_OBJECTS: usize = 4096;
/// Sub-indices of one object, at most (0..=254).
const MAX_SUBS: usize = 255;

/// One entry (sub-index) of an ESI object.
#[derive(Clone, Debug, PartialEq)]
pub struct EsiSub {
    /// Sub-index.
    pub sub: u8,
    /// Name.
    pub name: String,
    /// Data type.
    pub dtype: DataType,
    /// Access.
    pub access: Access,
    /// Mappable into a PDO.
    pub pdo: bool,
    /// Default value.
    pub default: DefaultValue,
    /// Bytes kept for a string.
    pub capacity: usize,
}

/// One object of an ESI's dictionary.
#[derive(Clone, Debug, PartialEq)]
pub struct EsiObject {
    /// Index.
    pub index: u16,
    /// Name.
    pub name: String,
    /// VAR, ARRAY or RECORD.
    pub otype: ObjType,
    /// Its entries, by sub-index.
    pub subs: Vec<EsiSub>,
    /// Line of the `<Object>` element.
    pub line: u32,
}

/// What a dictionary gave: the objects, and those skipped (line, why).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Dictionary {
    /// Objects, in file order.
    pub objects: Vec<EsiObject>,
    /// Objects this dictionary cannot hold: line, why.
    pub skipped: Vec<(u32, String)>,
}

/// An ETG.2000 number: `#x` then hex digits, or decimal.
pub fn number(text: &str) -> Option<u64> {
    let t = text.trim();
    match t.strip_prefix("#x").or_else(|| t.strip_prefix("#X")) {
        Some(h) if !h.is_empty() => u64::from_str_radix(h, 16).ok(),
        Some(_) => None,
        None if !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit()) => t.parse().ok(),
        None => None,
    }
}

/// A base type of ETG.2000 by name: the drive's type and, for a string, its length.
fn base_type(name: &str) -> Option<(DataType, usize)> {
    let t = name.trim();
    if let Some(n) = t.strip_prefix("STRING(").and_then(|r| r.strip_suffix(')')) {
        let len = number(n).filter(|&l| (1..=4096).contains(&l))? as usize;
        return Some((DataType::VisibleString, len));
    }
    let d = match t {
        "BOOL" | "BIT" => DataType::Boolean,
        "SINT" => DataType::I8,
        "INT" => DataType::I16,
        "DINT" => DataType::I32,
        "LINT" => DataType::I64,
        "USINT" | "BYTE" => DataType::U8,
        "UINT" | "WORD" => DataType::U16,
        "UDINT" | "DWORD" => DataType::U32,
        "ULINT" | "LWORD" => DataType::U64,
        "REAL" => DataType::Real32,
        "LREAL" => DataType::Real64,
        _ => return None,
    };
    Some((d, 0))
}

/// The first child element named `name`.
pub(crate) fn child<'a, 'i>(
    node: roxmltree::Node<'a, 'i>,
    name: &str,
) -> Option<roxmltree::Node<'a, 'i>> {
    node.children()
        .find(|c| c.is_element() && c.tag_name().name() == name)
}

/// The child elements named `name`.
pub(crate) fn children<'a, 'i: 'a>(
    node: roxmltree::Node<'a, 'i>,
    name: &'a str,
) -> impl Iterator<Item = roxmltree::Node<'a, 'i>> + 'a {
    node.children()
        .filter(move |c| c.is_element() && c.tag_name().name() == name)
}

fn text<'a>(node: roxmltree::Node<'a, '_>, name: &str) -> Option<&'a str> {
    child(node, name).and_then(|c| c.text()).map(str::trim)
}

/// The access and PDO flag of a `Flags` element (`ro` without one).
fn flags(node: roxmltree::Node<'_, '_>) -> (Option<Access>, bool) {
    let Some(f) = child(node, "Flags") else {
        return (None, false);
    };
    let access = match text(f, "Access") {
        Some("rw") => Some(Access::Rw),
        Some("wo") => Some(Access::Wo),
        Some("ro") => Some(Access::Ro),
        _ => None,
    };
    let pdo = text(f, "PdoMapping").is_some_and(|m| !m.is_empty());
    (access, pdo)
}

/// A default: `Info/DefaultData` (hex bytes, little-endian) or `Info/DefaultValue`.
fn default_of(info: Option<roxmltree::Node<'_, '_>>, dtype: DataType) -> Option<DefaultValue> {
    let info = info?;
    if let Some(hex) = text(info, "DefaultData") {
        if hex.len() % 2 != 0 || hex.len() > 2 * 4096 {
            return None;
        }
        let bytes: Option<Vec<u8>> = (0..hex.len() / 2)
            .map(|k| u8::from_str_radix(hex.get(2 * k..2 * k + 2)?, 16).ok())
            .collect();
        let bytes = bytes?;
        if dtype.variable() {
            return Some(DefaultValue::Bytes(bytes));
        }
        let size = dtype.size();
        if bytes.len() > 8 || bytes.len() > size {
            return None;
        }
        let mut raw = [0u8; 8];
        raw[..bytes.len()].copy_from_slice(&bytes);
        let v = u64::from_le_bytes(raw);
        return Some(DefaultValue::Value(sign_extend(v, dtype, size)));
    }
    let t = text(info, "DefaultValue")?;
    if dtype.variable() {
        return Some(DefaultValue::Bytes(t.as_bytes().to_vec()));
    }
    let v = match t.strip_prefix('-') {
        Some(n) if dtype.signed() => (number(n)? as i64).checked_neg()? as u64,
        Some(_) => return None,
        None => number(t)?,
    };
    Some(DefaultValue::Value(v))
}

fn sign_extend(v: u64, dtype: DataType, size: usize) -> u64 {
    if !dtype.signed() || size == 0 || size >= 8 {
        return v;
    }
    let shift = 64 - 8 * size as u32;
    (((v << shift) as i64) >> shift) as u64
}

/// Read `Device/Profile/Dictionary` of `device` (nothing without one). `line_of` gives a
/// node's line.
pub fn read(
    device: roxmltree::Node<'_, '_>,
    line_of: impl Fn(roxmltree::Node<'_, '_>) -> u32,
) -> Dictionary {
    let mut out = Dictionary::default();
    let Some(dict) = child(device, "Profile").and_then(|p| child(p, "Dictionary")) else {
        return out;
    };
    let types: Vec<roxmltree::Node<'_, '_>> = child(dict, "DataTypes")
        .map(|d| children(d, "DataType").collect())
        .unwrap_or_default();
    let find_type = |name: &str| {
        types
            .iter()
            .copied()
            .find(|t| text(*t, "Name") == Some(name.trim()))
    };
    let Some(objects) = child(dict, "Objects") else {
        return out;
    };
    for o in children(objects, "Object") {
        let line = line_of(o);
        if out.objects.len() == MAX_OBJECTS {
            out.skipped.push((
                line,
                format!("more than {MAX_OBJECTS} objects: the rest is not read"),
            ));
            break;
        }
        match object(o, &find_type, line) {
            Ok(obj) => out.objects.push(obj),
            Err(why) => out.skipped.push((line, why)),
        }
    }
    out
}

/// One `<Object>`.
fn object<'a, 'i>(
    o: roxmltree::Node<'a, 'i>,
    find_type: &impl Fn(&str) -> Option<roxmltree::Node<'a, 'i>>,
    line: u32,
) -> Result<EsiObject, String> {
    let index = text(o, "Index")
        .and_then(number)
        .filter(|&i| i <= 0xFFFF)
        .ok_or("an <Object> without a valid <Index>")? as u16;
    let name = text(o, "Name").unwrap_or("").to_string();
    let ty = text(o, "Type").ok_or(format!("object #x{index:04X} has no <Type>"))?;
    let (access, pdo) = flags(o);
    let info = child(o, "Info");
    if let Some((dtype, capacity)) = base_type(ty) {
        let default = default_of(info, dtype).unwrap_or(zero(dtype));
        let sub = EsiSub {
            sub: 0,
            name: name.clone(),
            dtype,
            access: access.unwrap_or(Access::Ro),
            pdo,
            default,
            capacity,
        };
        return Ok(EsiObject {
            index,
            name,
            otype: ObjType::Var,
            subs: vec![sub],
            line,
        });
    }
    let dt = find_type(ty).ok_or(format!(
        "object #x{index:04X}: type {ty:?} is neither a base type nor in <DataTypes>"
    ))?;
    let (otype, subs) = members(index, dt, find_type, info, access)?;
    Ok(EsiObject {
        index,
        name,
        otype,
        subs,
        line,
    })
}

fn zero(dtype: DataType) -> DefaultValue {
    if dtype.variable() {
        DefaultValue::Bytes(Vec::new())
    } else {
        DefaultValue::Value(0)
    }
}

/// The sub-items of a record or array data type, with the object's defaults (`Info/SubItem`,
/// by name, else in order) and access (the sub-item's, else the object's).
fn members<'a, 'i>(
    index: u16,
    dt: roxmltree::Node<'a, 'i>,
    find_type: &impl Fn(&str) -> Option<roxmltree::Node<'a, 'i>>,
    info: Option<roxmltree::Node<'a, 'i>>,
    object_access: Option<Access>,
) -> Result<(ObjType, Vec<EsiSub>), String> {
    let defaults: Vec<roxmltree::Node<'_, '_>> = info
        .map(|i| children(i, "SubItem").collect())
        .unwrap_or_default();
    let mut subs: Vec<EsiSub> = Vec::new();
    let mut array = false;
    for item in children(dt, "SubItem") {
        let name = text(item, "Name").unwrap_or("").to_string();
        let ty = text(item, "Type").unwrap_or("");
        let (acc, pdo) = flags(item);
        let access = acc.or(object_access).unwrap_or(Access::Ro);
        // an array's elements: a sub-item whose type has ArrayInfo
        if let Some(arr) = find_type(ty).filter(|t| child(*t, "ArrayInfo").is_some()) {
            let ai = child(arr, "ArrayInfo").ok_or("ArrayInfo")?;
            let lbound = text(ai, "LBound").and_then(number).unwrap_or(1);
            let n = text(ai, "Elements").and_then(number).unwrap_or(0);
            let base = text(arr, "BaseType").unwrap_or("");
            let (dtype, capacity) = base_type(base).ok_or(format!(
                "object #x{index:04X}: array of {base:?}, not a base type"
            ))?;
            if lbound + n > MAX_SUBS as u64 || n == 0 {
                return Err(format!("object #x{index:04X}: {n} elements from {lbound}"));
            }
            array = true;
            for k in 0..n {
                subs.push(EsiSub {
                    sub: (lbound + k) as u8,
                    name: format!("{name} {}", k + 1),
                    dtype,
                    access,
                    pdo,
                    default: zero(dtype),
                    capacity,
                });
            }
            continue;
        }
        let (dtype, capacity) = base_type(ty).ok_or(format!(
            "object #x{index:04X}, {name:?}: type {ty:?} is not a base type"
        ))?;
        let sub = text(item, "SubIdx")
            .and_then(number)
            .filter(|&s| s < MAX_SUBS as u64)
            .ok_or(format!("object #x{index:04X}, {name:?}: no valid <SubIdx>"))?
            as u8;
        subs.push(EsiSub {
            sub,
            name,
            dtype,
            access,
            pdo,
            default: zero(dtype),
            capacity,
        });
    }
    if subs.is_empty() || subs[0].sub != 0 {
        return Err(format!("object #x{index:04X}: its type has no sub-index 0"));
    }
    subs.sort_by_key(|s| s.sub);
    if subs.windows(2).any(|w| w[0].sub == w[1].sub) {
        return Err(format!("object #x{index:04X}: a sub-index twice"));
    }
    // defaults: sub 0 is the highest sub-index (record) or the element count (array) unless
    // the file gives it
    let highest = subs.last().map_or(0, |s| s.sub);
    subs[0].default = DefaultValue::Value(if array {
        (subs.len() - 1) as u64
    } else {
        u64::from(highest)
    });
    let by_position = defaults.len() == subs.len();
    for (k, s) in subs.iter_mut().enumerate() {
        let named = defaults
            .iter()
            .find(|d| text(**d, "Name") == Some(s.name.as_str()));
        let d = named.or(if by_position { defaults.get(k) } else { None });
        if let Some(v) = d.and_then(|d| default_of(child(*d, "Info"), s.dtype)) {
            s.default = v;
        }
    }
    Ok((
        if array {
            ObjType::Array
        } else {
            ObjType::Record
        },
        subs,
    ))
}
