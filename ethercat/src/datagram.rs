//! The datagram commands as one ESC executes them while the frame passes (ETG.1000.4 5.4):
//! auto-increment (APxx, ARMW: addressed when ADP is 0 on arrival; every slave counts ADP
//! up), configured-address (FPxx, FRMW: ADP equals the station address 0x0010), broadcast
//! (BRD ORs its data in, BWR, BRW; every slave counts ADP up) and logical (LRD, LWR, LRW
//! through the FMMUs). Working counter: +1 for a read, +1 for a write, +3 for a read-write
//! that did both (+1 read, +2 write); a refused access (a full or empty mailbox) adds
//! nothing. ARMW / FRMW: the addressed slave reads, every other one writes.

use crate::esc::{Esc, FMMUS};
use crate::frame::DatagramAt;

/// Datagram command codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Command {
    /// No operation.
    Nop = 0,
    /// Auto-increment physical read.
    Aprd = 1,
    /// Auto-increment physical write.
    Apwr = 2,
    /// Auto-increment physical read-write.
    Aprw = 3,
    /// Configured-address physical read.
    Fprd = 4,
    /// Configured-address physical write.
    Fpwr = 5,
    /// Configured-address physical read-write.
    Fprw = 6,
    /// Broadcast read.
    Brd = 7,
    /// Broadcast write.
    Bwr = 8,
    /// Broadcast read-write.
    Brw = 9,
    /// Logical read.
    Lrd = 10,
    /// Logical write.
    Lwr = 11,
    /// Logical read-write.
    Lrw = 12,
    /// Auto-increment read, multiple write.
    Armw = 13,
    /// Configured-address read, multiple write.
    Frmw = 14,
}

impl Command {
    /// From the command byte (`None`: unknown, the slave leaves the datagram alone).
    pub fn from_u8(b: u8) -> Option<Command> {
        use Command::*;
        Some(match b {
            0 => Nop,
            1 => Aprd,
            2 => Apwr,
            3 => Aprw,
            4 => Fprd,
            5 => Fpwr,
            6 => Fprw,
            7 => Brd,
            8 => Bwr,
            9 => Brw,
            10 => Lrd,
            11 => Lwr,
            12 => Lrw,
            13 => Armw,
            14 => Frmw,
            _ => return None,
        })
    }
}

/// Largest datagram data a slave copies through a scratch buffer.
const SCRATCH: usize = crate::frame::MAX_DATA;

/// Execute datagram `d` of `frame` on `esc`; returns what it added to the working counter
/// (already added to the frame's). `station` is the configured station address.
pub fn execute(esc: &mut Esc, frame: &mut [u8], d: &DatagramAt) -> u16 {
    let Some(cmd) = Command::from_u8(d.cmd) else {
        return 0;
    };
    let a = d.address();
    let adp = u16::from_le_bytes([frame[a], frame[a + 1]]);
    let ado = u16::from_le_bytes([frame[a + 2], frame[a + 3]]);
    let station = esc.u16(crate::esc::reg::STATION_ADDRESS);
    let data = d.data..d.data + d.len;
    use Command::*;
    let add = match cmd {
        Nop => 0,
        Aprd | Apwr | Aprw | Armw | Brd | Bwr | Brw => {
            // every slave counts the position up as the frame passes
            frame[a..a + 2].copy_from_slice(&adp.wrapping_add(1).to_le_bytes());
            let here = adp == 0;
            match cmd {
                Aprd if here => read(esc, ado, &mut frame[data]),
                Apwr if here => write(esc, ado, &frame[data]),
                Aprw if here => read_write(esc, ado, &mut frame[data]),
                Armw if here => read(esc, ado, &mut frame[data]),
                Armw => write(esc, ado, &frame[data]),
                Brd => u16::from(esc.read_or(ado, &mut frame[data])),
                Bwr => write(esc, ado, &frame[data]),
                Brw => read_or_write(esc, ado, &mut frame[data]),
                _ => 0,
            }
        }
        Fprd | Fpwr | Fprw | Frmw => {
            let here = adp == station;
            match cmd {
                Fprd if here => read(esc, ado, &mut frame[data]),
                Fpwr if here => write(esc, ado, &frame[data]),
                Fprw if here => read_write(esc, ado, &mut frame[data]),
                Frmw if here => read(esc, ado, &mut frame[data]),
                Frmw => write(esc, ado, &frame[data]),
                _ => 0,
            }
        }
        Lrd | Lwr | Lrw => {
            let logical = u32::from_le_bytes([frame[a], frame[a + 1], frame[a + 2], frame[a + 3]]);
            logical_access(esc, cmd, logical, &mut frame[data])
        }
    };
    if add > 0 {
        let w = d.wkc();
        let wkc = u16::from_le_bytes([frame[w], frame[w + 1]]).wrapping_add(add);
        frame[w..w + 2].copy_from_slice(&wkc.to_le_bytes());
    }
    add
}

fn read(esc: &mut Esc, ado: u16, data: &mut [u8]) -> u16 {
    u16::from(esc.read(ado, data))
}

fn write(esc: &mut Esc, ado: u16, data: &[u8]) -> u16 {
    u16::from(esc.write(ado, data))
}

/// Read-write: the data read goes back, the data carried is written (+1 / +2).
fn read_write(esc: &mut Esc, ado: u16, data: &mut [u8]) -> u16 {
    let mut old = [0u8; SCRATCH];
    let old = &mut old[..data.len()];
    let r = esc.read(ado, old);
    let w = esc.write(ado, data);
    if r {
        data.copy_from_slice(old);
    }
    u16::from(r) + 2 * u16::from(w)
}

/// BRW: ORed read, then write.
fn read_or_write(esc: &mut Esc, ado: u16, data: &mut [u8]) -> u16 {
    let mut carried = [0u8; SCRATCH];
    let carried = &mut carried[..data.len()];
    carried.copy_from_slice(data);
    let r = esc.read_or(ado, data);
    let w = esc.write(ado, carried);
    u16::from(r) + 2 * u16::from(w)
}

/// LRD / LWR / LRW through the active FMMUs: +1 if an FMMU read, +2 (LRW) or +1 (LWR) if one
/// wrote.
fn logical_access(esc: &mut Esc, cmd: Command, logical: u32, data: &mut [u8]) -> u16 {
    let (mut did_read, mut did_write) = (false, false);
    let start = u64::from(logical);
    let end = start + data.len() as u64;
    for n in 0..FMMUS {
        let f = esc.fmmu(n);
        if !f.active || f.len == 0 {
            continue;
        }
        let (fs, fe) = (
            u64::from(f.logical),
            u64::from(f.logical) + u64::from(f.len),
        );
        let (s, e) = (start.max(fs), end.min(fe));
        if s >= e {
            continue;
        }
        let at = (s - start) as usize..(e - start) as usize;
        let phys = (u64::from(f.physical) + (s - fs)) as u16;
        if f.kind & 1 != 0 && matches!(cmd, Command::Lrd | Command::Lrw) {
            did_read |= esc.read(phys, &mut data[at.clone()]);
        }
        if f.kind & 2 != 0 && matches!(cmd, Command::Lwr | Command::Lrw) {
            did_write |= esc.write(phys, &data[at]);
        }
    }
    let w = if cmd == Command::Lrw { 2 } else { 1 };
    u16::from(did_read) + w * u16::from(did_write)
}
