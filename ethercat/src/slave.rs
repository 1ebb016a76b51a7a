//! One EtherCAT slave: the ESC ([`crate::esc`]) in front of one [`DriveCore`] (built
//! as the emulator builds it, plus the CoE communication objects 0x1C00, 0x1C12, 0x1C13,
//! 0x1C32, 0x1C33). Frames reach it datagram by datagram ([`Slave::execute`]); the drive
//! runs one cycle per [`Slave::cycle`], with the [`Drive`] passed in as the node takes it.

use drive_protocol::od::{Access, DataType, DefaultValue, Entry, ObjType, ObjectDictionary};
use drive_protocol::{Clocks, ConfigError, CoreOutput, Drive, DriveCore, NodeConfig};

use crate::al::{code, Al, AlState, Checks};
use crate::coe::{self, Coe};
use crate::datagram;
use crate::dc::{self, DcClock, Sync0};
use crate::esc::{eep, reg, Esc};
use crate::frame::DatagramAt;
use crate::mailbox::{self, Header, Mailbox, TYPE_COE};
use crate::pdo::{self, ProcessData};
use crate::sii::{self, SiiConfig, SmEntry};

/// SM0 (mailbox, master to slave) start.
pub const MBX_OUT_START: u16 = 0x1000;
/// SM1 (mailbox, slave to master) start.
pub const MBX_IN_START: u16 = 0x1080;
/// SM2 (outputs) start.
pub const OUTPUTS_START: u16 = 0x1100;
/// SM3 (inputs) start.
pub const INPUTS_START: u16 = 0x1180;
/// SM0 control byte: mailbox, the master writes, PDI interrupt.
pub const SM0_CONTROL: u8 = 0x26;
/// SM1 control byte: mailbox, the master reads, PDI interrupt.
pub const SM1_CONTROL: u8 = 0x22;
/// SM2 control byte: buffered, the master writes, watchdog.
pub const SM2_CONTROL: u8 = 0x64;
/// SM3 control byte: buffered, the master reads.
pub const SM3_CONTROL: u8 = 0x20;

/// Why a slave could not be built.
#[derive(Debug)]
pub enum SlaveError {
    /// The node refused its configuration.
    Node(ConfigError),
    /// A CoE object could not be added to the dictionary.
    Dictionary(String),
    /// The default PDO assignment does not resolve (abort code).
    Pdo(u32),
    /// A vendor's ESI the drive cannot serve (line, why).
    Esi(crate::esi::EsiError),
}

impl core::fmt::Display for SlaveError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SlaveError::Node(e) => write!(f, "node: {e}"),
            SlaveError::Dictionary(e) => write!(f, "object dictionary: {e}"),
            SlaveError::Pdo(c) => write!(f, "default PDO assignment: abort 0x{c:08X}"),
            SlaveError::Esi(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for SlaveError {}

/// A sub-index of a CoE record: sub, name, type, access, default, limits.
type SubSpec = (
    u8,
    &'static str,
    DataType,
    Access,
    u64,
    Option<(i128, i128)>,
);

/// Add the CoE communication objects a dictionary lacks: 0x1C00 sync manager types,
/// 0x1C12 / 0x1C13 PDO assignment (by default the second RxPDO and TxPDO: controlword +
/// target position, statusword + position actual), 0x1C32 / 0x1C33 sync manager parameters.
pub fn add_coe_objects(od: &mut ObjectDictionary) -> Result<(), String> {
    add_sm_types(od).map_err(|e| e.to_string())?;
    for (index, base, name) in [
        (0x1C12u16, 0x1600u16, "RxPDO assign"),
        (0x1C13, 0x1A00, "TxPDO assign"),
    ] {
        add_pdo_assign(od, index, base, name).map_err(|e| e.to_string())?;
    }
    for (index, name) in [
        (0x1C32u16, "SM output parameter"),
        (0x1C33, "SM input parameter"),
    ] {
        add_sm_parameters(od, index, name).map_err(|e| e.to_string())?;
    }
    Ok(())
}

type OdResult = Result<(), drive_protocol::od::OdError>;

/// 0x1C00: the four sync managers' types (mailbox out, in, outputs, inputs).
fn add_sm_types(od: &mut ObjectDictionary) -> OdResult {
    if od.has_index(0x1C00) {
        return Ok(());
    }
    let arr = ObjType::Array;
    let name = "Sync manager communication type";
    let count = Entry::member(
        0x1C00,
        0,
        arr,
        name,
        "Used sync managers",
        DataType::U8,
        Access::Const,
    );
    od.insert(count.with_default(DefaultValue::Value(4)))?;
    for s in 1..=4u8 {
        let e = Entry::member(
            0x1C00,
            s,
            arr,
            name,
            format!("SM{}", s - 1),
            DataType::U8,
            Access::Const,
        );
        od.insert(e.with_default(DefaultValue::Value(u64::from(s))))?;
    }
    Ok(())
}

/// 0x1C12 / 0x1C13 (`index`): every mapping object from `base` the dictionary has, the
/// second first (position set-point / actual), one assigned by default.
fn add_pdo_assign(
    od: &mut ObjectDictionary,
    index: u16,
    base: u16,
    name: &'static str,
) -> OdResult {
    if od.has_index(index) {
        return Ok(());
    }
    let mut order: Vec<u16> = (0..8u16)
        .map(|n| base + n)
        .filter(|&m| od.get(m, 0).is_some())
        .collect();
    if order.len() > 1 {
        order.swap(0, 1);
    }
    let arr = ObjType::Array;
    let count = Entry::member(
        index,
        0,
        arr,
        name,
        "Number of assigned PDOs",
        DataType::U8,
        Access::Rw,
    );
    od.insert(
        count
            .with_default(DefaultValue::Value(u64::from(!order.is_empty())))
            .with_limits(Some(0), Some(order.len() as i128)),
    )?;
    for (k, &m) in order.iter().enumerate() {
        let e = Entry::member(
            index,
            k as u8 + 1,
            arr,
            name,
            format!("PDO {}", k + 1),
            DataType::U16,
            Access::Rw,
        );
        od.insert(
            e.with_default(DefaultValue::Value(u64::from(m)))
                .with_limits(Some(i128::from(base)), Some(i128::from(base) + 0x1FF)),
        )?;
    }
    Ok(())
}

/// 0x1C32 / 0x1C33 (`index`): synchronisation type (free run, SM, DC SYNC0), cycle time,
/// the types supported, the minimum cycle time, sync error.
fn add_sm_parameters(od: &mut ObjectDictionary, index: u16, name: &'static str) -> OdResult {
    if od.has_index(index) {
        return Ok(());
    }
    let subs: [SubSpec; 6] = [
        (
            0,
            "Highest sub-index supported",
            DataType::U8,
            Access::Const,
            0x20,
            None,
        ),
        (
            1,
            "Synchronization type",
            DataType::U16,
            Access::Rw,
            0,
            Some((0, 2)),
        ),
        (2, "Cycle time", DataType::U32, Access::Rw, 1_000_000, None),
        (
            4,
            "Synchronization types supported",
            DataType::U16,
            Access::Const,
            0x0007,
            None,
        ),
        (
            5,
            "Minimum cycle time",
            DataType::U32,
            Access::Const,
            125_000,
            None,
        ),
        (0x20, "Sync error", DataType::Boolean, Access::Ro, 0, None),
    ];
    for (sub, n, dt, acc, def, lim) in subs {
        let mut e = Entry::member(index, sub, ObjType::Record, name, n, dt, acc)
            .with_default(DefaultValue::Value(def));
        if let Some((lo, hi)) = lim {
            e = e.with_limits(Some(lo), Some(hi));
        }
        od.insert(e)?;
    }
    Ok(())
}

fn esi_err(line: u32, why: String) -> crate::esi::EsiError {
    crate::esi::EsiError { line, why }
}

/// Whether the ESI's object at `index` is the slave's own business, not the file's to add:
/// PDO mappings (the drive's PDO engine has 0x1600.. / 0x1A00..) and the sync manager
/// objects (0x1C00..0x1C3F, the slave's).
fn slave_managed(index: u16) -> bool {
    // 0x1600..=0x1BFF mappings, 0x1C00..=0x1C3F sync manager objects
    matches!(index, 0x1600..=0x1C3F)
}

/// The ESI's own objects the drive lacks, into its dictionary (default value, access, PDO
/// mapping flag); objects the drive has stay the drive's. Returns the objects added.
fn add_esi_objects(
    od: &mut ObjectDictionary,
    dict: &crate::esi_od::Dictionary,
) -> Result<usize, crate::esi::EsiError> {
    let mut added = 0;
    for o in &dict.objects {
        if slave_managed(o.index) || od.has_index(o.index) {
            continue;
        }
        for s in &o.subs {
            let mut e = Entry::member(
                o.index,
                s.sub,
                o.otype,
                o.name.clone(),
                s.name.clone(),
                s.dtype,
                s.access,
            )
            .with_pdo(s.pdo)
            .with_default(s.default.clone());
            if s.capacity > 0 {
                e = e.with_capacity(s.capacity);
            }
            od.insert(e)
                .map_err(|err| esi_err(o.line, format!("object #x{:04X}: {err}", o.index)))?;
        }
        added += 1;
    }
    Ok(added)
}

/// The ESI's identity, PDO mappings and own objects as the dictionary's defaults (before the
/// CoE objects are added); everything checked against the drive's objects.
fn apply_esi(
    od: &mut ObjectDictionary,
    esi: &crate::esi::EsiDevice,
) -> Result<(), crate::esi::EsiError> {
    let c = &esi.config;
    check_esi_sms(&c.sms)?;
    let id = [
        (1u8, c.identity.vendor, "vendor"),
        (2, c.identity.product, "product code"),
        (3, c.identity.revision, "revision"),
    ];
    for (sub, v, what) in id {
        od.set_default(0x1018, sub, DefaultValue::Value(u64::from(v)))
            .map_err(|e| esi_err(0, format!("the {what} as 0x1018:{sub}: {e}")))?;
    }
    add_esi_objects(od, &esi.dictionary)?;
    let all = c
        .rx_pdos
        .iter()
        .chain(&esi.optional.0)
        .chain(&c.tx_pdos)
        .chain(&esi.optional.1);
    for p in all {
        apply_esi_pdo(od, esi, p)?;
    }
    Ok(())
}

/// The ESI's sync managers must be where this slave has them.
fn check_esi_sms(sms: &[SmEntry]) -> Result<(), crate::esi::EsiError> {
    let want = [
        (1u8, MBX_OUT_START, Some(mailbox::SIZE as u16), "MBoxOut"),
        (2, MBX_IN_START, Some(mailbox::SIZE as u16), "MBoxIn"),
        (3, OUTPUTS_START, None, "Outputs"),
        (4, INPUTS_START, None, "Inputs"),
    ];
    if sms.len() != want.len() {
        return Err(esi_err(
            0,
            format!(
                "the device has {} sync managers; this slave serves 4 (MBoxOut, MBoxIn, \
                 Outputs, Inputs)",
                sms.len()
            ),
        ));
    }
    for (k, (sm, (kind, start, len, name))) in sms.iter().zip(want).enumerate() {
        let len_ok = len.is_none_or(|l| sm.len == l);
        if sm.kind != kind || sm.start != start || !len_ok {
            return Err(esi_err(
                0,
                format!(
                    "sync manager {k} is type {} at #x{:04X} ({} bytes); this slave serves SM{k} \
                     as {name} at #x{start:04X}{}",
                    sm.kind,
                    sm.start,
                    sm.len,
                    len.map_or(String::new(), |l| format!(", {l} bytes"))
                ),
            ));
        }
    }
    Ok(())
}

/// One PDO of the ESI as the default of its mapping object: each entry the drive's object
/// (mappable, of the entry's bit length) or a padding of whole bytes.
fn apply_esi_pdo(
    od: &mut ObjectDictionary,
    esi: &crate::esi::EsiDevice,
    p: &crate::sii::Pdo,
) -> Result<(), crate::esi::EsiError> {
    let at = esi
        .pdos_at
        .iter()
        .find(|(i, _)| *i == p.index)
        .map_or(0, |(_, l)| *l);
    let subs = (1..=u8::MAX)
        .take_while(|&s| od.get(p.index, s).is_some())
        .count();
    if od.get(p.index, 0).is_none() {
        return Err(esi_err(
            at,
            format!(
                "PDO #x{:04X}: the drive has no mapping object 0x{:04X}",
                p.index, p.index
            ),
        ));
    }
    if p.entries.len() > subs {
        return Err(esi_err(
            at,
            format!(
                "PDO #x{:04X} has {} entries; the drive's mapping object holds {subs}",
                p.index,
                p.entries.len()
            ),
        ));
    }
    for (k, e) in p.entries.iter().enumerate() {
        let at = esi
            .entries_at
            .iter()
            .find(|a| a.pdo == p.index && a.index == e.index && a.sub == e.sub)
            .map_or(at, |a| a.line);
        if e.index != 0 {
            check_esi_entry(od, p.index, e, at)?;
        }
        let v = (u32::from(e.index) << 16) | (u32::from(e.sub) << 8) | u32::from(e.bits);
        od.set_default(p.index, k as u8 + 1, DefaultValue::Value(u64::from(v)))
            .map_err(|err| esi_err(at, format!("PDO #x{:04X}: {err}", p.index)))?;
    }
    od.set_default(p.index, 0, DefaultValue::Value(p.entries.len() as u64))
        .map_err(|err| esi_err(at, format!("PDO #x{:04X}: {err}", p.index)))
}

/// A PDO entry of the ESI against the drive's object: there, mappable, as many bits.
fn check_esi_entry(
    od: &ObjectDictionary,
    pdo: u16,
    e: &crate::sii::PdoEntry,
    at: u32,
) -> Result<(), crate::esi::EsiError> {
    let Some((_, obj)) = od.get(e.index, e.sub) else {
        return Err(esi_err(
            at,
            format!(
                "PDO #x{pdo:04X} maps 0x{:04X}:{}, an object the drive does not have",
                e.index, e.sub
            ),
        ));
    };
    if !obj.pdo {
        return Err(esi_err(
            at,
            format!(
                "PDO #x{pdo:04X} maps 0x{:04X}:{} ({}), which the drive does not map \
                 into PDOs",
                e.index, e.sub, obj.name
            ),
        ));
    }
    let bits = obj.dtype.size() * 8;
    if bits != usize::from(e.bits) {
        return Err(esi_err(
            at,
            format!(
                "PDO #x{pdo:04X} maps 0x{:04X}:{} ({}) with BitLen {}; the object has {bits} bits",
                e.index, e.sub, obj.name, e.bits
            ),
        ));
    }
    Ok(())
}

/// The ESI's PDOs with an `Sm` attribute as the default assignment 0x1C12 / 0x1C13.
fn assign_esi(od: &mut ObjectDictionary, c: &SiiConfig) -> Result<(), crate::esi::EsiError> {
    for (index, pdos, sm) in [(0x1C12u16, &c.rx_pdos, 2u8), (0x1C13, &c.tx_pdos, 3)] {
        if let Some(p) = pdos.iter().find(|p| p.sm != sm) {
            return Err(esi_err(
                0,
                format!(
                    "PDO #x{:04X} is assigned to SM{}; this slave has its {} on SM{sm}",
                    p.index,
                    p.sm,
                    if sm == 2 { "outputs" } else { "inputs" }
                ),
            ));
        }
        let room = (1..=u8::MAX)
            .take_while(|&s| od.get(index, s).is_some())
            .count();
        if pdos.len() > room {
            return Err(esi_err(
                0,
                format!(
                    "{} PDOs assigned to SM{sm}; the drive's 0x{index:04X} holds {room}",
                    pdos.len()
                ),
            ));
        }
        for (k, p) in pdos.iter().enumerate() {
            od.set_default(index, k as u8 + 1, DefaultValue::Value(u64::from(p.index)))
                .map_err(|e| esi_err(0, format!("0x{index:04X}: {e}")))?;
        }
        od.set_default(index, 0, DefaultValue::Value(pdos.len() as u64))
            .map_err(|e| esi_err(0, format!("0x{index:04X}: {e}")))?;
    }
    Ok(())
}

/// One slave.
#[derive(Clone, Debug)]
pub struct Slave {
    node: DriveCore,
    esc: Esc,
    sii: Vec<u16>,
    al: Al,
    mbx: Mailbox,
    coe: Coe,
    pd: Option<ProcessData>,
    /// Outputs written since SAFE-OP was entered.
    outputs_seen: bool,
    /// Frame time of the last outputs write, ns.
    last_outputs_ns: Option<u64>,
    /// The slave's clock as of the last frame, ns.
    now_ns: u64,
    /// Outputs the drive refused (an RPDO value out of range), counted.
    pub refused_outputs: u32,
    /// The SM watchdog took the slave out of OP; the drive core's connection is lost until
    /// OP again.
    outputs_lost: bool,
    /// SM watchdog expiries, counted.
    pub watchdog_expiries: u32,
    /// The SYNC0 unit as last activated through 0x0981.
    sync0: Sync0,
    /// The ESC's local clock and its drift control.
    dc: DcClock,
    /// DC SYNC0 chosen (0x1C32:1 = 2) and checked at SAFE-OP: the drive follows SYNC0.
    dc_synchronised: bool,
    /// A vendor's ESI served instead of the drive's own description: its names and sync
    /// manager control bytes go into the SII.
    esi: Option<SiiConfig>,
}

struct Transition<'a> {
    node: &'a DriveCore,
    esc: &'a mut Esc,
    pd: &'a mut Option<ProcessData>,
    mbx: &'a mut Mailbox,
    coe: &'a mut Coe,
    outputs_seen: &'a mut bool,
    last_outputs_ns: &'a mut Option<u64>,
    now_ns: u64,
    sync0: &'a Sync0,
    dc_synchronised: &'a mut bool,
}

impl Transition<'_> {
    /// The synchronisation type of the outputs, 0x1C32:1.
    fn sync_type(&self) -> u16 {
        self.node.object_raw(0x1C32, 1).unwrap_or(0) as u16
    }
}

impl Checks for Transition<'_> {
    fn mailbox(&mut self) -> Result<(), u16> {
        let (out, inp) = (self.esc.sm(0), self.esc.sm(1));
        let good = out.enabled()
            && out.mailbox()
            && out.master_writes()
            && out.start == MBX_OUT_START
            && out.len as usize == mailbox::SIZE
            && inp.enabled()
            && inp.mailbox()
            && !inp.master_writes()
            && inp.start == MBX_IN_START
            && inp.len as usize == mailbox::SIZE;
        if good {
            Ok(())
        } else {
            Err(code::INVALID_MAILBOX_CONFIG)
        }
    }

    fn process_data(&mut self) -> Result<(), u16> {
        let min_cycle_ns = self.node.object_raw(0x1C32, 5).unwrap_or(0);
        dc::check(self.sync_type(), self.sync0, min_cycle_ns)?;
        *self.pd = Some(ProcessData::configure(self.node, self.esc)?);
        Ok(())
    }

    fn outputs(&mut self) -> Result<(), u16> {
        Ok(())
    }

    fn entered(&mut self, state: AlState) {
        match state {
            AlState::Init | AlState::Boot => {
                self.mbx.reset();
                self.coe.reset();
                *self.pd = None;
                self.esc.set_mailbox_full(0, false);
                self.esc.set_mailbox_full(1, false);
                *self.dc_synchronised = false;
            }
            AlState::PreOp => {
                *self.pd = None;
                *self.dc_synchronised = false;
            }
            AlState::SafeOp => {
                *self.outputs_seen = false;
                *self.dc_synchronised = self.sync_type() == dc::SYNC_DC_SYNC0;
            }
            AlState::Op => *self.last_outputs_ns = Some(self.now_ns),
        }
    }
}

impl Slave {
    /// Build the slave around the node of `cfg` (the CoE objects added to its dictionary),
    /// boot the node and generate the SII from its identity and default PDO assignment.
    pub fn new(cfg: NodeConfig, drive: &mut impl Drive) -> Result<Slave, SlaveError> {
        Slave::build(cfg, drive, None)
    }

    /// [`Slave::new`] serving a vendor's ESI ([`crate::esi::parse`]): its identity in 0x1018
    /// (the drive's serial kept), its PDOs as the default mappings 0x1600.. / 0x1A00.. and
    /// assignment 0x1C12 / 0x1C13 (the drive's objects behind each entry), its names and sync
    /// manager control bytes in the SII. Refused (with the ESI's line) where the drive lacks a
    /// mapped object or a mapping object, a bit length differs from the object's, or the
    /// sync managers are not where this slave has them (0x1000 / 0x1080 mailboxes of 128
    /// bytes, outputs at 0x1100, inputs at 0x1180).
    pub fn with_esi(
        mut cfg: NodeConfig,
        drive: &mut impl Drive,
        esi: &crate::esi::EsiDevice,
    ) -> Result<Slave, SlaveError> {
        apply_esi(&mut cfg.od, esi).map_err(SlaveError::Esi)?;
        Slave::build(cfg, drive, Some(esi.config.clone()))
    }

    fn build(
        mut cfg: NodeConfig,
        drive: &mut impl Drive,
        esi: Option<SiiConfig>,
    ) -> Result<Slave, SlaveError> {
        add_coe_objects(&mut cfg.od).map_err(SlaveError::Dictionary)?;
        // an ESI's padding entries (index 0): gaps of whole bytes in the process data
        cfg.od.device.padding_entries = true;
        if let Some(e) = &esi {
            assign_esi(&mut cfg.od, e).map_err(SlaveError::Esi)?;
        }
        let mut node = DriveCore::new(cfg).map_err(SlaveError::Node)?;
        // a PDO is not one CAN frame here: a mapping may fill a sync manager's buffer
        node.set_pdo_max_len(pdo::MAX_IMAGE);
        node.boot(0);
        while node.take_output().is_some() {}
        // EtherCAT has no COB-IDs: every PDO is "not valid" on CAN, which is also what lets a
        // master change a mapping in PRE-OP (CiA 301's dynamic mapping procedure)
        let mut maps = Vec::new();
        node.for_each_pdo_mapping(|tx, m| maps.push((tx, m)));
        for (tx, m) in maps {
            let comm = m - 0x200;
            if let Some(cob) = node.object_raw(comm, 1) {
                let _ = node.write_object(comm, 1, &(cob | 0x8000_0000).to_le_bytes(), drive);
            }
            let _ = tx;
        }
        // the transfer buffer holds the largest object whole (complete access: sub 0 as 16
        // bits plus every sub-index)
        let mut largest = 0usize;
        let (mut index, mut sum) = (None, 0usize);
        for (_, e) in node.od().iter() {
            if index != Some(e.index) {
                index = Some(e.index);
                sum = 1;
            }
            sum += e.dtype.size().max(e.capacity);
            largest = largest.max(sum);
        }
        let bytes = largest.clamp(mailbox::SIZE, 1 << 20);
        let mut s = Slave {
            esc: Esc::new(),
            sii: Vec::new(),
            al: Al::default(),
            mbx: Mailbox::default(),
            coe: Coe::new(bytes),
            pd: None,
            outputs_seen: false,
            last_outputs_ns: None,
            now_ns: 0,
            refused_outputs: 0,
            outputs_lost: false,
            watchdog_expiries: 0,
            sync0: Sync0::default(),
            dc: DcClock::default(),
            dc_synchronised: false,
            esi,
            node,
        };
        s.sii = sii::image(&s.sii_config()?);
        s.set_line_ports(false);
        s.publish_al();
        Ok(s)
    }

    fn sii_config(&self) -> Result<SiiConfig, SlaveError> {
        let n = &self.node;
        let id = |sub| n.object_raw(0x1018, sub).unwrap_or(0);
        let outputs = pdo::resolve(n, 0x1C12).map_err(SlaveError::Pdo)?;
        let inputs = pdo::resolve(n, 0x1C13).map_err(SlaveError::Pdo)?;
        let pdos = |l: &pdo::Layout, sm: u8| -> Vec<sii::Pdo> {
            l.pdos
                .iter()
                .map(|p| {
                    let count = n.object_raw(p.mapping, 0).unwrap_or(0) as u8;
                    let entries = (1..=count)
                        .filter_map(|s| n.object_raw(p.mapping, s))
                        .map(|v| {
                            let (index, sub) = ((v >> 16) as u16, (v >> 8) as u8);
                            let data_type = n
                                .od()
                                .get(index, sub)
                                .map_or(0, |(_, e)| e.dtype.code() as u8);
                            sii::PdoEntry {
                                index,
                                sub,
                                data_type,
                                bits: v as u8,
                            }
                        })
                        .collect();
                    sii::Pdo {
                        index: p.mapping,
                        sm,
                        entries,
                    }
                })
                .collect()
        };
        let mut sii = SiiConfig {
            identity: sii::Identity {
                vendor: id(1),
                product: id(2),
                revision: id(3),
                serial: id(4),
            },
            name: "drive-emu CiA 402 drive".into(),
            group: "Drives".into(),
            order: "drive-emu".into(),
            sms: vec![
                SmEntry {
                    start: MBX_OUT_START,
                    len: mailbox::SIZE as u16,
                    control: SM0_CONTROL,
                    enable: 1,
                    kind: 1,
                },
                SmEntry {
                    start: MBX_IN_START,
                    len: mailbox::SIZE as u16,
                    control: SM1_CONTROL,
                    enable: 1,
                    kind: 2,
                },
                SmEntry {
                    start: OUTPUTS_START,
                    len: outputs.len as u16,
                    control: SM2_CONTROL,
                    enable: 1,
                    kind: 3,
                },
                SmEntry {
                    start: INPUTS_START,
                    len: inputs.len as u16,
                    control: SM3_CONTROL,
                    enable: 1,
                    kind: 4,
                },
            ],
            rx_pdos: pdos(&outputs, 2),
            tx_pdos: pdos(&inputs, 3),
        };
        if let Some(esi) = &self.esi {
            sii.name.clone_from(&esi.name);
            sii.group.clone_from(&esi.group);
            sii.order.clone_from(&esi.order);
            for (mine, theirs) in sii.sms.iter_mut().zip(&esi.sms) {
                mine.control = theirs.control;
                mine.enable = theirs.enable;
            }
        }
        Ok(sii)
    }

    /// The drive core.
    pub fn node(&self) -> &DriveCore {
        &self.node
    }
    /// The drive core, mutable (the application's own objects, faults).
    pub fn node_mut(&mut self) -> &mut DriveCore {
        &mut self.node
    }
    /// A frame with a bad frame check sequence came in (see [`Esc::count_rx_error`]).
    pub fn count_rx_error(&mut self, forwarded: bool) {
        self.esc.count_rx_error(forwarded);
    }
    /// The ESC memory.
    pub fn esc(&self) -> &Esc {
        &self.esc
    }
    /// The SII EEPROM image, words.
    pub fn sii(&self) -> &[u16] {
        &self.sii
    }
    /// The ESI XML (ETG.2000) of the slave as it is served now: identity, sync managers,
    /// the assigned PDOs with their entries, CoE details; what the SII says, as a file.
    pub fn esi_xml(&self) -> Result<String, SlaveError> {
        let cfg = self.sii_config()?;
        let od = self.node.od();
        Ok(crate::esi::xml(&cfg, |index, sub| {
            od.get(index, sub).map_or_else(
                || format!("0x{index:04X}:{sub}"),
                |(_, e)| e.name.to_string(),
            )
        }))
    }
    /// AL state.
    pub fn al_state(&self) -> AlState {
        self.al.state
    }
    /// AL status code (0 without an error).
    pub fn al_status_code(&self) -> u16 {
        self.al.code
    }
    /// The process-data layout of SAFE-OP / OP.
    pub fn process_data(&self) -> Option<&ProcessData> {
        self.pd.as_ref()
    }
    /// The slave's place on the line, in DL status (0x0110): port 0 (towards the master)
    /// open with a link and communication; port 1 the same when a slave follows
    /// (`downstream`), else closed (looped back), as are ports 2 and 3 (not there); the PDI
    /// operational and its watchdog reloaded. Masters read it for the topology (ethercrab
    /// needs it for a line of more than one slave).
    pub fn set_line_ports(&mut self, downstream: bool) {
        let mut v = 0x0003 | 0x0010 | 0x0200 | 0x1000 | 0x4000;
        v |= if downstream { 0x0020 | 0x0800 } else { 0x0400 };
        self.esc.set_u16(reg::DL_STATUS, v);
    }

    /// The SYNC0 unit as the master activated it (0x0981, 0x0990, 0x09A0).
    pub fn sync0(&self) -> &Sync0 {
        &self.sync0
    }
    /// Whether the drive follows SYNC0: DC SYNC0 chosen (0x1C32:1 = 2) and accepted at
    /// SAFE-OP, in SAFE-OP or OP.
    pub fn dc_synchronised(&self) -> bool {
        self.dc_synchronised && matches!(self.al.state, AlState::SafeOp | AlState::Op)
    }
    /// The next SYNC0 pulse at or after `t_ns` on the frames' clock (the clock of
    /// [`Slave::execute`]'s `now_ns`), in that clock, while the drive follows SYNC0 (else
    /// `None`): the pulse grid is in system time, the ESC's local clock (the frames' clock
    /// with its drift, as the master's drift control steers it) plus the offset 0x0920.
    pub fn next_sync0_ns(&self, t_ns: u64) -> Option<u64> {
        if !self.dc_synchronised() {
            return None;
        }
        let offset = self.esc.u64(reg::DC_OFFSET);
        let local = self.dc.local_ns(t_ns);
        let system = self.sync0.next_at_or_after(local.wrapping_add(offset))?;
        Some(self.dc.host_ns(system.wrapping_sub(offset)))
    }

    /// The ESC's local clock and its drift control (see [`DcClock`]).
    pub fn dc_clock(&self) -> &DcClock {
        &self.dc
    }

    /// Let the ESC's local clock drift by `drift_ppm` (+: fast) against the frames' clock from
    /// the last frame on: a crystal's error, for a master's drift control to correct. 0 by
    /// default (the local clock is then the frames' clock).
    pub fn set_dc_drift_ppm(&mut self, drift_ppm: f64) {
        let ppb = (drift_ppm * 1000.0).round();
        let ppb = if ppb.is_finite() { ppb as i64 } else { 0 };
        self.dc.set_drift_ppb(self.now_ns, ppb);
    }

    /// Mailbox messages dropped because the queue was full.
    pub fn mailbox_dropped(&self) -> u32 {
        self.mbx.dropped
    }

    fn publish_al(&mut self) {
        self.esc.set_u16(reg::AL_STATUS, self.al.status());
        self.esc.set_u16(reg::AL_STATUS_CODE, self.al.code);
    }

    fn transition<R>(&mut self, f: impl FnOnce(&mut Al, &mut Transition<'_>) -> R) -> R {
        let mut t = Transition {
            node: &self.node,
            esc: &mut self.esc,
            pd: &mut self.pd,
            mbx: &mut self.mbx,
            coe: &mut self.coe,
            outputs_seen: &mut self.outputs_seen,
            last_outputs_ns: &mut self.last_outputs_ns,
            now_ns: self.now_ns,
            sync0: &self.sync0,
            dc_synchronised: &mut self.dc_synchronised,
        };
        let r = f(&mut self.al, &mut t);
        self.publish_al();
        r
    }

    /// Execute one datagram of `frame` as the frame passes this slave at `now_ns` (the
    /// slave's clock, ns, the same clock as [`Slave::cycle`]'s communication time); then act
    /// on what it did (AL control, EEPROM command, mailbox). Returns the working counter it
    /// added.
    pub fn execute(
        &mut self,
        frame: &mut [u8],
        d: &DatagramAt,
        now_ns: u64,
        drive: &mut impl Drive,
    ) -> u16 {
        self.now_ns = now_ns;
        let offset = self.esc.u64(reg::DC_OFFSET);
        let local_ns = self.dc.local_ns(now_ns);
        let system_ns = local_ns.wrapping_add(offset);
        self.esc.set_u64(reg::DC_SYSTEM_TIME, system_ns);
        if let Some(next) = self.sync0.next_at_or_after(system_ns) {
            // read back while active, the start time register is the next pulse
            self.esc.set_u64(reg::DC_START_TIME, next);
        }
        let add = datagram::execute(&mut self.esc, frame, d);
        let ev = core::mem::take(&mut self.esc.events);
        if ev.dc_activation {
            self.sync0 = Sync0::activate(&self.esc, system_ns);
        }
        if ev.dc_latch {
            self.esc.set_u32(reg::DC_RECV_TIME0, local_ns as u32);
            self.esc.set_u32(reg::DC_RECV_TIME0 + 4, local_ns as u32);
            self.esc.set_u64(reg::DC_RECV_TIME_PU, local_ns);
        }
        if let Some((value, wide)) = ev.dc_system_time {
            let at = (self.esc.u64(reg::DC_OFFSET), self.esc.u32(reg::DC_DELAY));
            let depth = self.esc.u8(reg::DC_DIFF_FILTER);
            let diff = self.dc.received(now_ns, value, wide, at, depth);
            self.esc.set_u32(reg::DC_DIFF, diff);
        }
        if ev.dc_loop_reset {
            self.dc.reset(now_ns, self.esc.u16(reg::DC_SPEED_START));
            self.esc.set_u32(reg::DC_DIFF, 0);
        }
        if ev.al_control {
            let v = self.esc.u16(reg::AL_CONTROL);
            self.transition(|al, t| al.request(v, t));
            if self.outputs_lost && self.al.state == AlState::Op {
                self.outputs_lost = false;
                self.node
                    .connection_restored(drive_protocol::EMCY_RPDO_TIMEOUT);
            }
        }
        if ev.eeprom_command {
            self.eeprom_command();
        }
        if ev.outputs_written {
            self.outputs_seen = true;
            self.last_outputs_ns = Some(now_ns);
        }
        if ev.mailbox_written {
            self.mailbox_in(drive);
        }
        if ev.mailbox_written || ev.mailbox_read {
            self.mailbox_out();
        }
        add
    }

    fn eeprom_command(&mut self) {
        let ctl = self.esc.u16(reg::EEP_CONTROL);
        let status = eep::READ_8 | eep::ADDR_16;
        match ctl & eep::CMD_MASK {
            eep::CMD_READ => {
                let at = self.esc.u32(reg::EEP_ADDRESS) as usize;
                for k in 0..4 {
                    let w = sii::word(&self.sii, at + k);
                    self.esc.set_u16(reg::EEP_DATA + 2 * k as u16, w);
                }
                self.esc.set_u16(reg::EEP_CONTROL, status);
            }
            eep::CMD_RELOAD | 0 => self.esc.set_u16(reg::EEP_CONTROL, status),
            _ => self.esc.set_u16(reg::EEP_CONTROL, status | eep::ERR_CMD),
        }
    }

    /// A request completed in SM0: parse it and answer.
    fn mailbox_in(&mut self, drive: &mut impl Drive) {
        let sm = self.esc.sm(0);
        self.esc.set_mailbox_full(0, false);
        if matches!(self.al.state, AlState::Init | AlState::Boot) {
            return;
        }
        let mut buf = [0u8; mailbox::SIZE];
        let n = (sm.len as usize).min(mailbox::SIZE);
        self.esc.get(sm.start, &mut buf[..n]);
        let h = match Header::parse(&buf[..n]) {
            Ok(h) => h,
            Err(detail) => return self.mbx.error(detail),
        };
        if h.counter != 0 && self.mbx.last_in == Some(h.counter) {
            return; // a repeated request
        }
        self.mbx.last_in = Some(h.counter);
        let body = &buf[mailbox::HEADER..mailbox::HEADER + h.len];
        match h.kind {
            TYPE_COE => self
                .coe
                .handle(body, &mut self.node, drive, self.al.state, &mut self.mbx),
            _ => self.mbx.error(mailbox::error::UNSUPPORTED_PROTOCOL),
        }
    }

    /// Put the next waiting message into SM1 when it is free.
    fn mailbox_out(&mut self) {
        self.coe.pump(&self.node, &mut self.mbx);
        let sm = self.esc.sm(1);
        if !sm.enabled() || self.esc.mailbox_full(1) {
            return;
        }
        let Some(m) = self.mbx.out.pop_front() else {
            return;
        };
        let mut buf = [0u8; mailbox::SIZE];
        buf[..m.len].copy_from_slice(&m.buf[..m.len]);
        let n = (sm.len as usize).min(mailbox::SIZE);
        self.esc.set(sm.start, &buf[..n]);
        self.esc.set_mailbox_full(1, true);
        self.coe.pump(&self.node, &mut self.mbx);
    }

    /// A local error (an injected fault): an OP slave drops to SAFE-OP with the error flag and
    /// AL status code `code` (ETG.1000.6), as a real slave does, and its drive loses the
    /// outputs as on a watchdog expiry (EMCY 0x8250, the reaction per 0x6007) until the
    /// master acknowledges and requests OP again. Outside OP: nothing (false).
    pub fn drop_out_of_op(&mut self, code: u16) -> bool {
        if self.al.state != AlState::Op {
            return false;
        }
        self.transition(|al, t| al.fall_to(AlState::SafeOp, code, t));
        self.outputs_lost = true;
        self.node.connection_lost(drive_protocol::EMCY_RPDO_TIMEOUT);
        true
    }

    /// The SM watchdog time, ns (0: off).
    fn watchdog_ns(&self) -> u64 {
        let sm = self.esc.sm(pdo::SM_OUTPUTS);
        if sm.control & 0x40 == 0 {
            return 0;
        }
        let tick_ns = (u64::from(self.esc.u16(reg::WD_DIVIDER)) + 2) * 40;
        u64::from(self.esc.u16(reg::WD_TIME_PD)) * tick_ns
    }

    /// One drive cycle at `clocks` (the communication clock in us is the frames' clock):
    /// in OP the outputs go to the drive core (each RxPDO with the RPDO rules), the drive
    /// runs its cycle ([`DriveCore::cycle`]), in SAFE-OP and OP the inputs are written; the
    /// drive's EMCYs become CoE emergencies; the SM watchdog takes an OP slave whose outputs
    /// stopped down to SAFE-OP with AL status code 0x001B, and the drive reacts as 0x6007
    /// says (EMCY 0x8250 held until OP again; 1: fault, 2: disable voltage, 3: quick stop).
    pub fn cycle(&mut self, clocks: Clocks, drive: &mut impl Drive) {
        let now_ns = clocks.comm_us.saturating_mul(1000);
        if self.al.state == AlState::Op {
            let wd = self.watchdog_ns();
            let last = self.last_outputs_ns.unwrap_or(0);
            if wd > 0 && now_ns.saturating_sub(last) > wd {
                self.now_ns = now_ns;
                self.transition(|al, t| al.fall_to(AlState::SafeOp, code::SM_WATCHDOG, t));
                self.watchdog_expiries = self.watchdog_expiries.wrapping_add(1);
                self.outputs_lost = true;
                self.node.connection_lost(drive_protocol::EMCY_RPDO_TIMEOUT);
            }
        }
        if let (AlState::Op, Some(pd)) = (self.al.state, &self.pd) {
            if !pd.apply_outputs(&mut self.node, &self.esc) {
                self.refused_outputs = self.refused_outputs.wrapping_add(1);
            }
        }
        self.node.cycle(clocks, drive);
        if let (AlState::SafeOp | AlState::Op, Some(pd)) = (self.al.state, &self.pd) {
            pd.write_inputs(&self.node, &mut self.esc);
        }
        let mailbox_up = !matches!(self.al.state, AlState::Init | AlState::Boot);
        // the core's EMCYs become CoE emergencies; its heartbeats and CAN-only frames have no
        // place on EtherCAT
        while let Some(o) = self.node.take_output() {
            if let (true, CoreOutput::Emcy(d)) = (mailbox_up, o) {
                coe::emergency(&mut self.mbx, &d);
            }
        }
        self.mailbox_out();
    }
}
