//! The ESI (EtherCAT Slave Information, ETG.2000) of the slave as served: the XML file masters
//! such as TwinCAT or IgH's tools import, as a CANopen master imports an EDS. Written from the
//! same [`SiiConfig`] the EEPROM image is generated from, so the file, the SII and CoE agree:
//! identity (0x1018), sync managers, FMMUs, the assigned PDOs with their entries, CoE details.

use core::fmt::Write;

use crate::sii::{Pdo, PdoEntry, SiiConfig, SmEntry, COE_DETAILS};

/// The ETG.2000 name of a CoE data type code (0 for an unknown code: its bit length decides).
pub fn data_type_name(code: u8, bits: u8) -> &'static str {
    match code {
        0x01 => "BOOL",
        0x02 => "SINT",
        0x03 => "INT",
        0x04 => "DINT",
        0x05 => "USINT",
        0x06 => "UINT",
        0x07 => "UDINT",
        0x08 => "REAL",
        0x11 => "LREAL",
        0x15 => "LINT",
        0x1B => "ULINT",
        _ => match bits {
            1 => "BOOL",
            8 => "USINT",
            16 => "UINT",
            32 => "UDINT",
            _ => "ULINT",
        },
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The ESI XML of one device. `entry_name(index, sub)` names a mapped object (the object
/// dictionary's name).
pub fn xml(cfg: &SiiConfig, entry_name: impl Fn(u16, u8) -> String) -> String {
    let id = &cfg.identity;
    let mut x = String::with_capacity(8192);
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(x, r#"<EtherCATInfo Version="1.6">"#);
    let _ = writeln!(
        x,
        "  <Vendor>\n    <Id>#x{:08X}</Id>\n    <Name>drive-emu</Name>\n  </Vendor>",
        id.vendor
    );
    let _ = writeln!(x, "  <Descriptions>");
    let group = escape(&cfg.group);
    let _ = writeln!(
        x,
        "    <Groups>\n      <Group>\n        <Type>{group}</Type>\n        <Name>{group}</Name>\n      </Group>\n    </Groups>"
    );
    let _ = writeln!(x, "    <Devices>");
    let _ = writeln!(x, r#"      <Device Physics="YY">"#);
    let _ = writeln!(
        x,
        r##"        <Type ProductCode="#x{:08X}" RevisionNo="#x{:08X}">{}</Type>"##,
        id.product,
        id.revision,
        escape(&cfg.order)
    );
    let _ = writeln!(x, "        <Name>{}</Name>", escape(&cfg.name));
    let _ = writeln!(x, "        <GroupType>{group}</GroupType>");
    for f in ["Outputs", "Inputs", "MBoxState"] {
        let _ = writeln!(x, "        <Fmmu>{f}</Fmmu>");
    }
    for sm in &cfg.sms {
        let kind = match sm.kind {
            1 => "MBoxOut",
            2 => "MBoxIn",
            3 => "Outputs",
            _ => "Inputs",
        };
        let size = if sm.kind <= 2 {
            format!(r#" MinSize="34" MaxSize="{0}" DefaultSize="{0}""#, sm.len)
        } else {
            format!(r#" DefaultSize="{}""#, sm.len)
        };
        let _ = writeln!(
            x,
            r##"        <Sm{size} StartAddress="#x{:04X}" ControlByte="#x{:02X}" Enable="{}">{kind}</Sm>"##,
            sm.start, sm.control, sm.enable
        );
    }
    for (tag, pdos) in [("RxPdo", &cfg.rx_pdos), ("TxPdo", &cfg.tx_pdos)] {
        for p in pdos {
            let _ = writeln!(
                x,
                r#"        <{tag} Fixed="0" Mandatory="1" Sm="{}">"#,
                p.sm
            );
            let _ = writeln!(x, "          <Index>#x{:04X}</Index>", p.index);
            let _ = writeln!(
                x,
                "          <Name>{} 0x{:04X}</Name>",
                if tag == "RxPdo" { "RxPDO" } else { "TxPDO" },
                p.index
            );
            for e in &p.entries {
                if e.index == 0 {
                    // a padding entry: a gap of whole bytes
                    let _ = writeln!(
                        x,
                        "          <Entry>\n            <Index>#x0</Index>\n            <BitLen>{}</BitLen>\n          </Entry>",
                        e.bits
                    );
                    continue;
                }
                let _ = writeln!(
                    x,
                    "          <Entry>\n            <Index>#x{:04X}</Index>\n            <SubIndex>{}</SubIndex>\n            <BitLen>{}</BitLen>\n            <Name>{}</Name>\n            <DataType>{}</DataType>\n          </Entry>",
                    e.index,
                    e.sub,
                    e.bits,
                    escape(&entry_name(e.index, e.sub)),
                    data_type_name(e.data_type, e.bits)
                );
            }
            let _ = writeln!(x, "        </{tag}>");
        }
    }
    let flag = |bit: u8| {
        if COE_DETAILS & bit != 0 {
            "true"
        } else {
            "false"
        }
    };
    let _ = writeln!(
        x,
        r#"        <Mailbox DataLinkLayer="true">
          <CoE SdoInfo="{}" PdoAssign="{}" PdoConfig="{}" CompleteAccess="{}"/>
        </Mailbox>"#,
        flag(0x02),
        flag(0x04),
        flag(0x08),
        flag(0x20)
    );
    let _ = writeln!(
        x,
        "      </Device>\n    </Devices>\n  </Descriptions>\n</EtherCATInfo>"
    );
    x
}

/// Where a PDO entry of a read ESI stands in its file (for errors that come later, when the
/// drive's dictionary is checked against it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EntryAt {
    /// The PDO (mapping index) the entry is in.
    pub pdo: u16,
    /// The mapped object.
    pub index: u16,
    /// Its sub-index.
    pub sub: u8,
    /// The line of the `<Entry>` element (1-based).
    pub line: u32,
}

/// The first device of a vendor's ESI file, as the slave serves it.
#[derive(Clone, Debug, Default)]
pub struct EsiDevice {
    /// Identity (no serial: an ESI has none), names, sync managers, the PDOs assigned by
    /// default (those with an `Sm` attribute) with their entries.
    pub config: SiiConfig,
    /// PDOs without an `Sm` attribute: mapped, not assigned by default (RxPDOs, TxPDOs).
    pub optional: (Vec<Pdo>, Vec<Pdo>),
    /// Where each PDO entry is.
    pub entries_at: Vec<EntryAt>,
    /// Line of each PDO element, by mapping index.
    pub pdos_at: Vec<(u16, u32)>,
    /// The device's own object dictionary (`Profile/Dictionary`), where the file has one.
    pub dictionary: crate::esi_od::Dictionary,
}

/// An ESI that cannot be served: the line (1-based; 0 for the file as a whole) and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EsiError {
    /// Line.
    pub line: u32,
    /// Why.
    pub why: String,
}

impl core::fmt::Display for EsiError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if self.line == 0 {
            write!(f, "{}", self.why)
        } else {
            write!(f, "line {}: {}", self.line, self.why)
        }
    }
}

impl std::error::Error for EsiError {}

/// Most PDOs a direction may have (0x1600..0x17FF, 0x1A00..0x1BFF; the slave serves 8).
const MAX_PDOS: usize = 64;
/// Most entries a PDO may have (sub-indices 1..=254 of a mapping object).
const MAX_ENTRIES: usize = 254;

fn line_of(doc: &roxmltree::Document<'_>, node: roxmltree::Node<'_, '_>) -> u32 {
    doc.text_pos_at(node.range().start).row
}

fn err(doc: &roxmltree::Document<'_>, node: roxmltree::Node<'_, '_>, why: String) -> EsiError {
    EsiError {
        line: line_of(doc, node),
        why,
    }
}

use crate::esi_od::{child, children};

pub use crate::esi_od::number;

fn quoted(s: &str) -> String {
    let short: String = s.chars().take(40).collect();
    format!(
        "{short:?}{}",
        if s.chars().count() > 40 { "..." } else { "" }
    )
}

struct Reader<'d, 'i> {
    doc: &'d roxmltree::Document<'i>,
}

impl<'d, 'i> Reader<'d, 'i> {
    fn required(
        &self,
        parent: roxmltree::Node<'d, 'i>,
        name: &str,
    ) -> Result<roxmltree::Node<'d, 'i>, EsiError> {
        child(parent, name).ok_or_else(|| {
            err(
                self.doc,
                parent,
                format!("<{}> has no <{name}>", parent.tag_name().name()),
            )
        })
    }

    /// The number in an element's text, at most `max`.
    fn text_number(&self, node: roxmltree::Node<'d, 'i>, max: u64) -> Result<u64, EsiError> {
        let t = node.text().unwrap_or("");
        self.checked(node, node.tag_name().name(), t, max)
    }

    fn attr_number(
        &self,
        node: roxmltree::Node<'d, 'i>,
        attr: &str,
        max: u64,
    ) -> Result<Option<u64>, EsiError> {
        match node.attribute(attr) {
            None => Ok(None),
            Some(t) => self.checked(node, attr, t, max).map(Some),
        }
    }

    fn checked(
        &self,
        node: roxmltree::Node<'d, 'i>,
        what: &str,
        t: &str,
        max: u64,
    ) -> Result<u64, EsiError> {
        let v = number(t).ok_or_else(|| {
            err(
                self.doc,
                node,
                format!(
                    "{what} {} is not a number (ETG.2000: #x then hex digits, or decimal)",
                    quoted(t)
                ),
            )
        })?;
        if v > max {
            return Err(err(
                self.doc,
                node,
                format!("{what} {} is out of range (at most {max:#X})", quoted(t)),
            ));
        }
        Ok(v)
    }

    fn pdo(&self, node: roxmltree::Node<'d, 'i>, out: &mut EsiDevice) -> Result<Pdo, EsiError> {
        let tag = node.tag_name().name();
        let (lo, hi) = if tag == "RxPdo" {
            (0x1600, 0x17FF)
        } else {
            (0x1A00, 0x1BFF)
        };
        let index_node = self.required(node, "Index")?;
        let index = self.text_number(index_node, 0xFFFF)? as u16;
        if !(lo..=hi).contains(&index) {
            return Err(err(
                self.doc,
                index_node,
                format!(
                    "{tag} index #x{index:04X} is not a mapping object (#x{lo:04X}..#x{hi:04X})"
                ),
            ));
        }
        let sm = self.attr_number(node, "Sm", 7)?.map_or(0, |v| v as u8);
        let mut entries = Vec::new();
        for e in children(node, "Entry") {
            if entries.len() == MAX_ENTRIES {
                return Err(err(
                    self.doc,
                    e,
                    format!("{tag} #x{index:04X} has more than {MAX_ENTRIES} entries"),
                ));
            }
            let ei = self.text_number(self.required(e, "Index")?, 0xFFFF)? as u16;
            let sub = match child(e, "SubIndex") {
                Some(s) => self.text_number(s, 0xFF)? as u8,
                None => 0,
            };
            let bits = self.text_number(self.required(e, "BitLen")?, 64)? as u8;
            if bits == 0 {
                return Err(err(self.doc, e, "BitLen 0".into()));
            }
            if ei == 0 && (sub != 0 || !bits.is_multiple_of(8)) {
                return Err(err(
                    self.doc,
                    e,
                    format!(
                        "{tag} #x{index:04X}: a padding entry (Index #x0) of {bits} bits: \
                         only whole bytes are served (the drive maps bytes, not bits)"
                    ),
                ));
            }
            out.entries_at.push(EntryAt {
                pdo: index,
                index: ei,
                sub,
                line: line_of(self.doc, e),
            });
            entries.push(PdoEntry {
                index: ei,
                sub,
                data_type: 0,
                bits,
            });
        }
        out.pdos_at.push((index, line_of(self.doc, node)));
        Ok(Pdo { index, sm, entries })
    }
}

/// Read the first device of `Descriptions/Devices` of an ESI file (ETG.2000): vendor, type
/// (product code, revision, order), name, group, the sync managers, the RxPDOs and TxPDOs
/// with their entries (padding entries, `Index` #x0, of whole bytes), that it speaks CoE, and
/// its object dictionary ([`crate::esi_od`]). Numbers as `#x1234` or decimal.
pub fn parse(text: &str) -> Result<EsiDevice, EsiError> {
    let doc = roxmltree::Document::parse(text).map_err(|e| EsiError {
        line: e.pos().row,
        why: format!("not well-formed XML: {e}"),
    })?;
    let r = Reader { doc: &doc };
    let (vendor, dev) = r.device()?;
    let mut identity = r.identity(dev)?;
    identity.vendor = vendor;
    let (name, order, group) = r.names(dev)?;
    let mailbox = r.required(dev, "Mailbox")?;
    r.required(mailbox, "CoE")?;
    let mut out = EsiDevice::default();
    let sms = r.sync_managers(dev)?;
    let ((rx_pdos, rx_opt), (tx_pdos, tx_opt)) = r.pdos(dev, &mut out)?;
    out.optional = (rx_opt, tx_opt);
    out.config = SiiConfig {
        identity,
        name,
        group,
        order,
        sms,
        rx_pdos,
        tx_pdos,
    };
    out.dictionary = crate::esi_od::read(dev, |n| line_of(&doc, n));
    Ok(out)
}

/// PDOs of one direction: (assigned by default, the others).
type Split = (Vec<Pdo>, Vec<Pdo>);

impl<'d, 'i> Reader<'d, 'i> {
    /// The vendor id and the first device.
    fn device(&self) -> Result<(u32, roxmltree::Node<'d, 'i>), EsiError> {
        let root = self.doc.root_element();
        if root.tag_name().name() != "EtherCATInfo" {
            return Err(err(
                self.doc,
                root,
                format!(
                    "the root element is <{}>, not <EtherCATInfo> (not an ESI file)",
                    root.tag_name().name()
                ),
            ));
        }
        let vendor = self.text_number(
            self.required(self.required(root, "Vendor")?, "Id")?,
            0xFFFF_FFFF,
        )?;
        let devices = self.required(self.required(root, "Descriptions")?, "Devices")?;
        Ok((vendor as u32, self.required(devices, "Device")?))
    }

    /// Product code and revision of `<Type>` (the vendor and serial left 0).
    fn identity(&self, dev: roxmltree::Node<'d, 'i>) -> Result<crate::sii::Identity, EsiError> {
        let ty = self.required(dev, "Type")?;
        let product = self
            .attr_number(ty, "ProductCode", 0xFFFF_FFFF)?
            .ok_or_else(|| err(self.doc, ty, "<Type> has no ProductCode".into()))?;
        let revision = self
            .attr_number(ty, "RevisionNo", 0xFFFF_FFFF)?
            .ok_or_else(|| err(self.doc, ty, "<Type> has no RevisionNo".into()))?;
        Ok(crate::sii::Identity {
            vendor: 0,
            product: product as u32,
            revision: revision as u32,
            serial: 0,
        })
    }

    /// Name, order code (the `<Type>` text) and group type.
    fn names(&self, dev: roxmltree::Node<'d, 'i>) -> Result<(String, String, String), EsiError> {
        let name = self
            .required(dev, "Name")?
            .text()
            .unwrap_or("")
            .trim()
            .to_string();
        let order = self
            .required(dev, "Type")?
            .text()
            .unwrap_or("")
            .trim()
            .to_string();
        let group = child(dev, "GroupType")
            .and_then(|g| g.text())
            .unwrap_or("")
            .trim()
            .to_string();
        Ok((name, order, group))
    }

    /// The `<Sm>` elements.
    fn sync_managers(&self, dev: roxmltree::Node<'d, 'i>) -> Result<Vec<SmEntry>, EsiError> {
        let mut sms = Vec::new();
        for sm in children(dev, "Sm") {
            if sms.len() == 8 {
                return Err(err(self.doc, sm, "more than 8 sync managers".into()));
            }
            sms.push(self.sync_manager(sm)?);
        }
        Ok(sms)
    }

    fn sync_manager(&self, sm: roxmltree::Node<'d, 'i>) -> Result<SmEntry, EsiError> {
        let kind = match sm.text().unwrap_or("").trim() {
            "MBoxOut" => 1,
            "MBoxIn" => 2,
            "Outputs" => 3,
            "Inputs" => 4,
            other => {
                return Err(err(
                    self.doc,
                    sm,
                    format!(
                        "sync manager type {} (MBoxOut, MBoxIn, Outputs or Inputs)",
                        quoted(other)
                    ),
                ))
            }
        };
        let start = self
            .attr_number(sm, "StartAddress", 0xFFFF)?
            .ok_or_else(|| err(self.doc, sm, "<Sm> has no StartAddress".into()))?;
        let control = self
            .attr_number(sm, "ControlByte", 0xFF)?
            .ok_or_else(|| err(self.doc, sm, "<Sm> has no ControlByte".into()))?;
        let len = match self.attr_number(sm, "DefaultSize", 0xFFFF)? {
            Some(v) => v,
            None => self.attr_number(sm, "MaxSize", 0xFFFF)?.unwrap_or(0),
        };
        let enable = self.attr_number(sm, "Enable", 0xFF)?.unwrap_or(1);
        Ok(SmEntry {
            start: start as u16,
            len: len as u16,
            control: control as u8,
            enable: enable as u8,
            kind,
        })
    }

    /// The RxPDOs and TxPDOs, each split into those with an `Sm` attribute (the default
    /// assignment) and the others.
    fn pdos(
        &self,
        dev: roxmltree::Node<'d, 'i>,
        out: &mut EsiDevice,
    ) -> Result<(Split, Split), EsiError> {
        let mut rx: Vec<(bool, Pdo)> = Vec::new();
        let mut tx: Vec<(bool, Pdo)> = Vec::new();
        for (tag, list) in [("RxPdo", &mut rx), ("TxPdo", &mut tx)] {
            for p in children(dev, tag) {
                if list.len() == MAX_PDOS {
                    return Err(err(self.doc, p, format!("more than {MAX_PDOS} {tag}s")));
                }
                let pdo = self.pdo(p, out)?;
                if list.iter().any(|(_, q)| q.index == pdo.index) {
                    return Err(err(
                        self.doc,
                        p,
                        format!("{tag} #x{:04X} is described twice", pdo.index),
                    ));
                }
                list.push((p.attribute("Sm").is_some(), pdo));
            }
        }
        let split = |list: Vec<(bool, Pdo)>| -> Split {
            let (a, o): (Vec<_>, Vec<_>) = list.into_iter().partition(|(s, _)| *s);
            (
                a.into_iter().map(|(_, p)| p).collect(),
                o.into_iter().map(|(_, p)| p).collect(),
            )
        };
        Ok((split(rx), split(tx)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEVICE: &str = r##"<?xml version="1.0"?>
<EtherCATInfo>
  <Vendor><Id>2652</Id></Vendor>
  <Descriptions><Devices>
    <Device>
      <Type ProductCode="#xC0FFEE" RevisionNo="#x10">T</Type>
      <Name>N</Name>
      <Sm StartAddress="#x1000" ControlByte="#x26" DefaultSize="128">MBoxOut</Sm>
      <Sm StartAddress="#x1080" ControlByte="#x22" DefaultSize="128">MBoxIn</Sm>
      <Sm StartAddress="#x1100" ControlByte="#x64">Outputs</Sm>
      <Sm StartAddress="#x1180" ControlByte="#x20" Enable="1">Inputs</Sm>
      <RxPdo Sm="2"><Index>#x1600</Index>
        <Entry><Index>#x6040</Index><SubIndex>0</SubIndex><BitLen>16</BitLen></Entry>
      </RxPdo>
      <TxPdo><Index>#x1A01</Index>
        <Entry><Index>#x6041</Index><BitLen>16</BitLen></Entry>
      </TxPdo>
      <Mailbox><CoE/></Mailbox>
    </Device>
  </Devices></Descriptions>
</EtherCATInfo>"##;

    #[test]
    fn numbers_hex_and_decimal() {
        assert_eq!(number("#x1A00"), Some(0x1A00));
        assert_eq!(number(" 131075 "), Some(131_075));
        for bad in ["0x10", "#x", "", "-1", "1e3", "#xG"] {
            assert_eq!(number(bad), None, "{bad}");
        }
    }

    #[test]
    fn reads_the_first_device() {
        let d = parse(DEVICE).unwrap();
        let c = &d.config;
        assert_eq!(c.identity.vendor, 2652);
        assert_eq!(c.identity.product, 0xC0FFEE);
        assert_eq!(c.identity.revision, 0x10);
        assert_eq!((c.name.as_str(), c.order.as_str()), ("N", "T"));
        assert_eq!(c.sms.len(), 4);
        assert_eq!(
            (c.sms[2].start, c.sms[2].control, c.sms[2].kind),
            (0x1100, 0x64, 3)
        );
        assert_eq!(c.rx_pdos.len(), 1);
        assert_eq!(c.rx_pdos[0].entries[0].index, 0x6040);
        assert!(c.tx_pdos.is_empty());
        assert_eq!(d.optional.1[0].index, 0x1A01);
        assert_eq!(d.optional.1[0].entries[0].sub, 0);
        assert_eq!(d.entries_at[0].line, 13);
    }

    #[test]
    fn errors_say_the_line() {
        let e = parse(&DEVICE.replace(
            "<BitLen>16</BitLen></Entry>\n      </RxPdo>",
            "<BitLen>x</BitLen></Entry>\n      </RxPdo>",
        ))
        .unwrap_err();
        assert_eq!(e.line, 13, "{e}");
        assert!(e.why.contains("BitLen \"x\" is not a number"), "{e}");
        let e = parse(&DEVICE.replace("#x1A01", "#x1601")).unwrap_err();
        assert_eq!(e.line, 15, "{e}");
        assert!(e.why.contains("not a mapping object"), "{e}");
        let e = parse(&DEVICE.replace("<Mailbox><CoE/></Mailbox>", "")).unwrap_err();
        assert!(e.why.contains("no <Mailbox>"), "{e}");
        let e = parse("<a>").unwrap_err();
        assert_eq!(e.line, 1, "{e}");
        assert!(parse("").is_err());
        let e = parse("<Other/>").unwrap_err();
        assert!(e.why.contains("not <EtherCATInfo>"), "{e}");
    }
}
