//! The EtherCAT slave controller's memory as a master sees it (ETG.1000.4 / the ESC register
//! description): registers 0x0000..0x0FFF and process RAM 0x1000..0x1FFF. Read-only
//! registers ignore writes; sync managers in mailbox mode gate access to their buffer (a
//! write into a full mailbox or a read of an empty one is refused: no working counter); a
//! write that completes a mailbox, a write to AL control, an EEPROM command, a DC receive
//! time latch, a DC system time write (drift control), a write of the speed counter start,
//! a DC activation and a process-data write are reported as [`Events`] for the slave to act on
//! after the datagram. Nothing here allocates after [`Esc::new`].

/// ESC type register value (0x0000); 0x04: an emulated ESC answers as a generic one.
pub const ESC_TYPE: u8 = 0x04;
/// Size of the whole address space emulated (registers + RAM).
pub const MEM_SIZE: usize = 0x2000;
/// First byte of process RAM.
pub const RAM_START: u16 = 0x1000;
/// FMMUs the ESC has.
pub const FMMUS: usize = 3;
/// Sync managers the ESC has.
pub const SMS: usize = 4;
/// The ESC's default speed counter start (0x0930), the bandwidth of its time control loop.
pub const SPEED_COUNTER_START_DEFAULT: u16 = 0x1000;
/// The ESC's default system time difference filter depth (0x0934).
pub const DIFF_FILTER_DEPTH_DEFAULT: u8 = 4;

/// Register addresses.
pub mod reg {
    /// Type, revision (0x0000, 0x0001), build (0x0002).
    pub const TYPE: u16 = 0x0000;
    /// Number of FMMUs.
    pub const FMMU_COUNT: u16 = 0x0004;
    /// Number of sync managers.
    pub const SM_COUNT: u16 = 0x0005;
    /// RAM size, KiB.
    pub const RAM_SIZE: u16 = 0x0006;
    /// Port descriptor.
    pub const PORT_DESC: u16 = 0x0007;
    /// ESC features supported (bit 2: DC, bit 3: 64-bit DC).
    pub const FEATURES: u16 = 0x0008;
    /// Configured station address.
    pub const STATION_ADDRESS: u16 = 0x0010;
    /// Configured station alias.
    pub const STATION_ALIAS: u16 = 0x0012;
    /// DL control.
    pub const DL_CONTROL: u16 = 0x0100;
    /// DL status.
    pub const DL_STATUS: u16 = 0x0110;
    /// AL control.
    pub const AL_CONTROL: u16 = 0x0120;
    /// AL status.
    pub const AL_STATUS: u16 = 0x0130;
    /// AL status code.
    pub const AL_STATUS_CODE: u16 = 0x0134;
    /// PDI control.
    pub const PDI_CONTROL: u16 = 0x0140;
    /// RX error counters: per port an invalid-frame (CRC) counter and an RX error counter
    /// (0x0300 + 2 port, + 1), then the forwarded RX error counters (0x0308 + port), the
    /// processing unit and PDI error counters (0x030C, 0x030D). A write to any of
    /// 0x0300..=0x030B clears all twelve.
    pub const RX_ERROR: u16 = 0x0300;
    /// Forwarded RX error counter of port 0 (a frame that came in already marked as
    /// corrupted by a slave before).
    pub const FWD_RX_ERROR: u16 = 0x0308;
    /// Watchdog divider.
    pub const WD_DIVIDER: u16 = 0x0400;
    /// Sync manager watchdog time.
    pub const WD_TIME_PD: u16 = 0x0420;
    /// Sync manager watchdog status.
    pub const WD_STATUS_PD: u16 = 0x0440;
    /// SII EEPROM configuration (owner).
    pub const EEP_CONFIG: u16 = 0x0500;
    /// SII EEPROM control / status.
    pub const EEP_CONTROL: u16 = 0x0502;
    /// SII EEPROM address (word).
    pub const EEP_ADDRESS: u16 = 0x0504;
    /// SII EEPROM data (8 bytes here).
    pub const EEP_DATA: u16 = 0x0508;
    /// FMMU 0 (16 bytes each).
    pub const FMMU0: u16 = 0x0600;
    /// Sync manager 0 (8 bytes each).
    pub const SM0: u16 = 0x0800;
    /// DC receive time port 0 (a write latches the receive times).
    pub const DC_RECV_TIME0: u16 = 0x0900;
    /// DC system time (64 bit).
    pub const DC_SYSTEM_TIME: u16 = 0x0910;
    /// DC receive time of the processing unit (64 bit).
    pub const DC_RECV_TIME_PU: u16 = 0x0918;
    /// DC system time offset (64 bit).
    pub const DC_OFFSET: u16 = 0x0920;
    /// DC system time delay (32 bit).
    pub const DC_DELAY: u16 = 0x0928;
    /// DC system time difference (sign bit 31, magnitude bits 0..30).
    pub const DC_DIFF: u16 = 0x092C;
    /// DC speed counter start (a write resets the time control loop).
    pub const DC_SPEED_START: u16 = 0x0930;
    /// DC system time difference filter depth (bits 0..3).
    pub const DC_DIFF_FILTER: u16 = 0x0934;
    /// DC cyclic unit control.
    pub const DC_CYCLIC_CONTROL: u16 = 0x0980;
    /// DC activation (bit 0 cyclic operation, bit 1 SYNC0, bit 2 SYNC1).
    pub const DC_ACTIVATION: u16 = 0x0981;
    /// Start time of cyclic operation (64 bit).
    pub const DC_START_TIME: u16 = 0x0990;
    /// SYNC0 cycle time, ns.
    pub const DC_SYNC0_CYCLE: u16 = 0x09A0;
    /// SYNC1 cycle time, ns.
    pub const DC_SYNC1_CYCLE: u16 = 0x09A4;
}

/// EEPROM control/status bits (0x0502).
pub mod eep {
    /// Read 8 bytes per command (status).
    pub const READ_8: u16 = 0x0040;
    /// Two address bytes (status).
    pub const ADDR_16: u16 = 0x0080;
    /// Command: read.
    pub const CMD_READ: u16 = 0x0100;
    /// Command: write.
    pub const CMD_WRITE: u16 = 0x0200;
    /// Command: reload.
    pub const CMD_RELOAD: u16 = 0x0400;
    /// Command mask.
    pub const CMD_MASK: u16 = 0x0700;
    /// Error: command (acknowledge / command error).
    pub const ERR_CMD: u16 = 0x2000;
}

/// One sync manager as configured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SyncManager {
    /// Physical start address.
    pub start: u16,
    /// Length, bytes.
    pub len: u16,
    /// Control register (bits 0-1 mode: 2 mailbox, 0 buffered; bits 2-3 direction: 1 the
    /// master writes, 0 it reads; bit 6 watchdog).
    pub control: u8,
    /// Activate register (bit 0 enable).
    pub activate: u8,
}

impl SyncManager {
    /// Enabled with a length, its buffer in process RAM (an ESC has no sync manager over
    /// its registers).
    pub fn enabled(&self) -> bool {
        self.activate & 1 != 0 && self.len > 0 && self.start >= RAM_START
    }
    /// Mailbox mode.
    pub fn mailbox(&self) -> bool {
        self.control & 0x03 == 0x02
    }
    /// The master writes through it.
    pub fn master_writes(&self) -> bool {
        self.control & 0x0C == 0x04
    }
    /// Whether [addr, addr+len) touches its buffer, and whether it covers the last byte.
    fn overlap(&self, addr: u32, len: u32) -> Option<(bool, bool)> {
        let (s, e) = (
            u32::from(self.start),
            u32::from(self.start) + u32::from(self.len),
        );
        if !self.enabled() || addr >= e || addr + len <= s {
            return None;
        }
        Some((addr <= s, addr + len >= e))
    }
}

/// One FMMU as configured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Fmmu {
    /// Logical start address.
    pub logical: u32,
    /// Length, bytes.
    pub len: u16,
    /// Physical start address.
    pub physical: u16,
    /// Type: bit 0 read (inputs to the master), bit 1 write (outputs).
    pub kind: u8,
    /// Active.
    pub active: bool,
}

/// What a datagram did that the slave acts on afterwards.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Events {
    /// The master completed a mailbox write into SM0.
    pub mailbox_written: bool,
    /// The master read the whole SM1 mailbox (it is empty now).
    pub mailbox_read: bool,
    /// AL control was written.
    pub al_control: bool,
    /// An EEPROM command was written.
    pub eeprom_command: bool,
    /// Process data outputs (an SM the master writes, not a mailbox) were written.
    pub outputs_written: bool,
    /// The DC receive times were latched (a write to 0x0900).
    pub dc_latch: bool,
    /// The DC activation register (0x0981) was written: the SYNC0 unit starts or stops.
    pub dc_activation: bool,
    /// The system time (0x0910) was written: the value, and whether 8 bytes (else the low
    /// 4); not stored: it feeds the time control loop.
    pub dc_system_time: Option<(u64, bool)>,
    /// The speed counter start (0x0930) was written: the time control loop starts over.
    pub dc_loop_reset: bool,
}

/// The ESC memory.
#[derive(Clone, Debug)]
pub struct Esc {
    mem: Vec<u8>,
    /// What the last datagrams did (taken by the slave).
    pub events: Events,
}

fn read_only(addr: u16) -> bool {
    matches!(addr,
        0x0000..=0x000F
        | 0x0110..=0x011F
        | 0x0130..=0x013F
        | 0x0140..=0x015F
        | 0x0300..=0x030D
        | 0x0440..=0x0441
        | 0x0501
        | 0x0910..=0x091F
        | 0x092C..=0x092F
        | 0x0932..=0x0933)
        || (0x0800..0x0800 + 8 * SMS as u16).contains(&addr) && matches!(addr % 8, 5 | 7)
}

impl Esc {
    /// A fresh ESC (as after power-on).
    pub fn new() -> Esc {
        let mut esc = Esc {
            mem: vec![0; MEM_SIZE],
            events: Events::default(),
        };
        esc.mem[0] = ESC_TYPE;
        esc.mem[1] = 1; // revision
        esc.set_u16(0x0002, 1); // build
        esc.mem[reg::FMMU_COUNT as usize] = FMMUS as u8;
        esc.mem[reg::SM_COUNT as usize] = SMS as u8;
        esc.mem[reg::RAM_SIZE as usize] = ((MEM_SIZE - RAM_START as usize) / 1024) as u8;
        esc.mem[reg::PORT_DESC as usize] = 0x0F; // ports 0 and 1 MII
        esc.set_u16(reg::FEATURES, 0x000C); // DC, 64-bit DC
        esc.set_u16(reg::PDI_CONTROL, 0x0005); // a PDI (the drive's processor behind)
        esc.set_u16(reg::WD_DIVIDER, 2498); // 100 us watchdog ticks
        esc.set_u16(reg::WD_TIME_PD, 1000); // 100 ms
        esc.set_u16(reg::EEP_CONTROL, eep::READ_8 | eep::ADDR_16);
        esc.set_u16(reg::AL_STATUS, 1);
        esc.set_u16(reg::DC_SPEED_START, SPEED_COUNTER_START_DEFAULT);
        esc.set(reg::DC_DIFF_FILTER, &[DIFF_FILTER_DEPTH_DEFAULT, 0x0C]);
        esc
    }

    /// A byte (0 outside the space).
    pub fn u8(&self, addr: u16) -> u8 {
        self.mem.get(addr as usize).copied().unwrap_or(0)
    }
    /// A little-endian u16.
    pub fn u16(&self, addr: u16) -> u16 {
        u16::from_le_bytes([self.u8(addr), self.u8(addr.wrapping_add(1))])
    }
    /// A little-endian u32.
    pub fn u32(&self, addr: u16) -> u32 {
        u32::from(self.u16(addr)) | u32::from(self.u16(addr.wrapping_add(2))) << 16
    }
    /// A little-endian u64.
    pub fn u64(&self, addr: u16) -> u64 {
        u64::from(self.u32(addr)) | u64::from(self.u32(addr.wrapping_add(4))) << 32
    }
    /// Set bytes from the slave's side (PDI): read-only registers too.
    pub fn set(&mut self, addr: u16, data: &[u8]) {
        let a = addr as usize;
        if let Some(m) = self.mem.get_mut(a..(a + data.len()).min(MEM_SIZE)) {
            let n = m.len();
            m.copy_from_slice(&data[..n]);
        }
    }
    /// Set a u16 from the PDI side.
    pub fn set_u16(&mut self, addr: u16, v: u16) {
        self.set(addr, &v.to_le_bytes());
    }
    /// Set a u32 from the PDI side.
    pub fn set_u32(&mut self, addr: u16, v: u32) {
        self.set(addr, &v.to_le_bytes());
    }
    /// Set a u64 from the PDI side.
    pub fn set_u64(&mut self, addr: u16, v: u64) {
        self.set(addr, &v.to_le_bytes());
    }
    /// Bytes from the PDI side.
    pub fn get(&self, addr: u16, out: &mut [u8]) {
        for (k, b) in out.iter_mut().enumerate() {
            *b = self.u8(addr.wrapping_add(k as u16));
        }
    }

    /// Sync manager `n`.
    pub fn sm(&self, n: usize) -> SyncManager {
        let b = reg::SM0 + 8 * n as u16;
        SyncManager {
            start: self.u16(b),
            len: self.u16(b + 2),
            control: self.u8(b + 4),
            activate: self.u8(b + 6),
        }
    }
    /// Whether sync manager `n`'s mailbox is full (status bit 3).
    pub fn mailbox_full(&self, n: usize) -> bool {
        self.u8(reg::SM0 + 8 * n as u16 + 5) & 0x08 != 0
    }
    /// Set or clear sync manager `n`'s mailbox full flag (PDI side).
    pub fn set_mailbox_full(&mut self, n: usize, full: bool) {
        let a = (reg::SM0 + 8 * n as u16 + 5) as usize;
        if full {
            self.mem[a] |= 0x08;
        } else {
            self.mem[a] &= !0x08;
        }
    }

    /// FMMU `n`.
    pub fn fmmu(&self, n: usize) -> Fmmu {
        let b = reg::FMMU0 + 16 * n as u16;
        Fmmu {
            logical: self.u32(b),
            len: self.u16(b + 4),
            physical: self.u16(b + 8),
            kind: self.u8(b + 11),
            active: self.u8(b + 12) & 1 != 0,
        }
    }

    /// Mailbox gating for a master access of `len` bytes at `addr`: whether it is allowed,
    /// and the events it makes.
    fn gate(&mut self, addr: u16, len: usize, write: bool) -> bool {
        for n in 0..SMS {
            let sm = self.sm(n);
            let Some((_, last)) = sm.overlap(u32::from(addr), len as u32) else {
                continue;
            };
            if sm.mailbox() {
                let full = self.mailbox_full(n);
                if sm.master_writes() != write {
                    return false; // wrong direction: refused
                }
                if write && full || !write && !full {
                    return false;
                }
                if last {
                    self.set_mailbox_full(n, write);
                    if write {
                        self.events.mailbox_written = true;
                    } else {
                        self.events.mailbox_read = true;
                    }
                }
            } else if write && sm.master_writes() {
                self.events.outputs_written = true;
            }
        }
        true
    }

    /// A frame with a bad frame check sequence came in on port 0: its invalid-frame counter
    /// (0x0300) counts it, or with `forwarded` (a slave before had marked it) the forwarded RX
    /// error counter (0x0308). Counters stop at 0xFF, as the ESC's do.
    pub fn count_rx_error(&mut self, forwarded: bool) {
        let a = if forwarded {
            reg::FWD_RX_ERROR
        } else {
            reg::RX_ERROR
        } as usize;
        self.mem[a] = self.mem[a].saturating_add(1);
    }

    /// A master read of `out.len()` bytes at `addr`. False: refused (an empty mailbox, say).
    pub fn read(&mut self, addr: u16, out: &mut [u8]) -> bool {
        if !self.gate(addr, out.len(), false) {
            return false;
        }
        self.get(addr, out);
        true
    }

    /// A broadcast read: the data ORed with what is there.
    pub fn read_or(&mut self, addr: u16, out: &mut [u8]) -> bool {
        if !self.gate(addr, out.len(), false) {
            return false;
        }
        for (k, b) in out.iter_mut().enumerate() {
            *b |= self.u8(addr.wrapping_add(k as u16));
        }
        true
    }

    /// A master write. False: refused (a full mailbox, say).
    pub fn write(&mut self, addr: u16, data: &[u8]) -> bool {
        if !self.gate(addr, data.len(), true) {
            return false;
        }
        for (k, &b) in data.iter().enumerate() {
            let a = addr as usize + k;
            if a >= MEM_SIZE {
                break;
            }
            if !read_only(a as u16) {
                self.mem[a] = b;
            }
        }
        let touches = |r: u16, n: u16| {
            let (s, e) = (addr as usize, addr as usize + data.len());
            (r as usize) < e && (r + n) as usize > s
        };
        for n in 0..SMS {
            // a sync manager switched off forgets its mailbox state
            if touches(reg::SM0 + 8 * n as u16, 8) && !self.sm(n).enabled() {
                self.set_mailbox_full(n, false);
            }
        }
        if touches(reg::RX_ERROR, 12) {
            // ETG.1000.4: a write to one of the RX error counters clears them all
            self.mem[reg::RX_ERROR as usize..reg::RX_ERROR as usize + 12].fill(0);
        }
        if touches(reg::AL_CONTROL, 2) {
            self.events.al_control = true;
        }
        if touches(reg::DC_RECV_TIME0, 4) {
            self.events.dc_latch = true;
        }
        if addr == reg::DC_SYSTEM_TIME && data.len() >= 4 {
            let mut v = [0u8; 8];
            let n = data.len().min(8);
            v[..n].copy_from_slice(&data[..n]);
            self.events.dc_system_time = Some((u64::from_le_bytes(v), n == 8));
        }
        if touches(reg::DC_SPEED_START, 2) {
            self.events.dc_loop_reset = true;
        }
        if touches(reg::DC_ACTIVATION, 1) {
            self.events.dc_activation = true;
        }
        if touches(reg::EEP_CONTROL + 1, 1) {
            self.events.eeprom_command = true;
        }
        true
    }
}

impl Default for Esc {
    fn default() -> Self {
        Esc::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rx_error_counters_count_saturate_and_clear_on_a_write() {
        let mut esc = Esc::new();
        for _ in 0..3 {
            esc.count_rx_error(false);
        }
        esc.count_rx_error(true);
        let mut out = [0u8; 12];
        assert!(esc.read(reg::RX_ERROR, &mut out));
        assert_eq!(out[0], 3, "invalid frames, port 0");
        assert_eq!(out[8], 1, "forwarded RX errors, port 0");
        for _ in 0..300 {
            esc.count_rx_error(false);
        }
        assert_eq!(esc.u8(reg::RX_ERROR), 0xFF, "the counter stops at 0xFF");
        // a write of any value to any of them clears all twelve, and is not stored
        assert!(esc.write(reg::RX_ERROR + 8, &[0x55]));
        esc.get(reg::RX_ERROR, &mut out);
        assert_eq!(out, [0u8; 12]);
        // the processing unit and PDI error counters are not cleared by that write
        esc.mem[reg::RX_ERROR as usize + 12] = 7;
        assert!(esc.write(reg::RX_ERROR, &[0]));
        assert_eq!(esc.u8(reg::RX_ERROR + 12), 7);
    }
}
