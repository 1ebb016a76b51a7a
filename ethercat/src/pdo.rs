//! Process data: the PDO assignment (0x1C12 RxPDOs = the master's outputs on SM2, 0x1C13
//! TxPDOs = its inputs on SM3), each assigned PDO's image through the drive core's mapping
//! (0x1600.. / 0x1A00.., the same rules as an RPDO / a TPDO on CAN), checked at the SAFE-OP
//! transition against the sync managers the master configured. The images sit in the ESC
//! RAM where the FMMUs map them into the master's logical process image.

use drive_protocol::DriveCore;

use crate::al::code;
use crate::esc::Esc;

/// PDOs an assignment may list here.
pub const MAX_ASSIGNED: usize = 8;
/// Sync manager of the outputs.
pub const SM_OUTPUTS: usize = 2;
/// Sync manager of the inputs.
pub const SM_INPUTS: usize = 3;
/// Bytes of process data one direction may carry: the ESC RAM between the outputs' buffer
/// (SM2, 0x1100) and the inputs' (SM3, 0x1180). One PDO may be as long (the drive core's
/// mapping limit on this front end, [`DriveCore::set_pdo_max_len`]); the PDOs of an assignment
/// together too (a longer assignment is refused at SAFE-OP, AL status 0x001D / 0x001E).
pub const MAX_IMAGE: usize = 128;

/// One assigned PDO: its mapping index, offset in the SM buffer and length.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Assigned {
    /// Mapping index.
    pub mapping: u16,
    /// Offset in the sync manager's buffer.
    pub offset: usize,
    /// Bytes.
    pub len: usize,
}

/// The assignment of one direction, resolved.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Layout {
    /// PDOs in order.
    pub pdos: heapless::Vec<Assigned, MAX_ASSIGNED>,
    /// Total bytes.
    pub len: usize,
}

/// Resolve the assignment object `assign` (0x1C12 / 0x1C13): each listed mapping must
/// exist and compile. Err: the CiA 301 abort code of the first bad one.
pub fn resolve(node: &DriveCore, assign: u16) -> Result<Layout, u32> {
    let count = node.object_raw(assign, 0).unwrap_or(0) as usize;
    let mut l = Layout::default();
    for s in 1..=count.min(MAX_ASSIGNED) {
        let mapping = node
            .object_raw(assign, s as u8)
            .ok_or(drive_protocol::wire::sdo::abort::NO_SUB)? as u16;
        let len = node.pdo_image_len(mapping)?;
        let _ = l.pdos.push(Assigned {
            mapping,
            offset: l.len,
            len,
        });
        l.len += len;
    }
    Ok(l)
}

/// The process data of a slave in SAFE-OP / OP.
#[derive(Clone, Debug, Default)]
pub struct ProcessData {
    /// RxPDOs (outputs, SM2).
    pub outputs: Layout,
    /// TxPDOs (inputs, SM3).
    pub inputs: Layout,
}

impl ProcessData {
    /// The PRE-OP -> SAFE-OP check: the assignment resolves and the process-data sync
    /// managers match it (enabled, right direction and mode, the image's length).
    pub fn configure(node: &DriveCore, esc: &Esc) -> Result<ProcessData, u16> {
        let outputs = resolve(node, 0x1C12)
            .ok()
            .filter(|l| l.len <= MAX_IMAGE)
            .ok_or(code::INVALID_OUTPUT_CONFIG)?;
        let inputs = resolve(node, 0x1C13)
            .ok()
            .filter(|l| l.len <= MAX_IMAGE)
            .ok_or(code::INVALID_INPUT_CONFIG)?;
        let ok = |n: usize, len: usize, master_writes: bool| {
            let sm = esc.sm(n);
            if len == 0 {
                return !sm.enabled();
            }
            sm.enabled()
                && !sm.mailbox()
                && sm.master_writes() == master_writes
                && sm.len as usize == len
        };
        if !ok(SM_OUTPUTS, outputs.len, true) {
            return Err(code::INVALID_OUTPUT_CONFIG);
        }
        if !ok(SM_INPUTS, inputs.len, false) {
            return Err(code::INVALID_INPUT_CONFIG);
        }
        Ok(ProcessData { outputs, inputs })
    }

    /// Apply the outputs in SM2 to the drive core (each RxPDO with the RPDO rules).
    /// Returns false if a value was refused.
    pub fn apply_outputs(&self, node: &mut DriveCore, esc: &Esc) -> bool {
        let start = esc.sm(SM_OUTPUTS).start;
        let mut ok = true;
        for p in &self.outputs.pdos {
            let mut buf = [0u8; MAX_IMAGE];
            let b = &mut buf[..p.len.min(MAX_IMAGE)];
            esc.get(start.wrapping_add(p.offset as u16), b);
            ok &= node.apply_rpdo_image(p.mapping, b).unwrap_or(false);
        }
        ok
    }

    /// Write the inputs (each TxPDO's image) into SM3.
    pub fn write_inputs(&self, node: &DriveCore, esc: &mut Esc) {
        let start = esc.sm(SM_INPUTS).start;
        for p in &self.inputs.pdos {
            let mut buf = [0u8; MAX_IMAGE];
            if let Ok(n) = node.tpdo_image(p.mapping, &mut buf) {
                esc.set(start.wrapping_add(p.offset as u16), &buf[..n.min(p.len)]);
            }
        }
    }
}
