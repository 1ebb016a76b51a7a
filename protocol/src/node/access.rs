//! The drive core as a front end other than CAN sees it (EtherCAT CoE, say): object reads and
//! writes with the rules of an SDO transfer, PDO byte images through the mapping objects with
//! the rules of an RPDO, and one drive cycle as a SYNC makes it. Each method reuses the node's
//! own path (the SDO server's object access, the PDO engine's mapping and the RPDO checks,
//! the SYNC and the tick); none copies a rule. None allocates: fit for the real-time path.

use super::{Access, DriveCore};
use crate::cia301::emcy::Cause;
use crate::cia301::pdo::layout::{self, Param};
use crate::cia301::pdo::{compile, mapping, Direction, Pdo};
use crate::cia301::sdo::{abort, ObjectAccess};
use crate::cia301::sync::EMCY_SYNC_LOSS;
use crate::drive::Drive;
use crate::node::Clocks;
use crate::od::Store;

/// EMCY of a front end whose master's process data stopped (CiA 301 0x8250, RPDO timeout):
/// [`DriveCore::connection_lost`] on EtherCAT's SM watchdog.
pub const EMCY_RPDO_TIMEOUT: u16 = 0x8250;

impl DriveCore {
    /// Read object (`index`, `sub`) into `out` as an SDO upload does (the entry must exist
    /// and be readable; a value the drive keeps comes from [`Drive::read_object`]). Returns
    /// its length, or the CiA 301 abort code. A value longer than `out` is refused with
    /// 0x05040005 (out of memory) rather than cut.
    pub fn read_object(
        &mut self,
        index: u16,
        sub: u8,
        out: &mut [u8],
        drive: &mut impl Drive,
    ) -> Result<usize, u32> {
        let (_, e) = super::lookup(&self.od, index, sub)?;
        let size = e.dtype.size();
        if size > out.len() {
            return Err(abort::OUT_OF_MEMORY);
        }
        let mut acc = Access { core: self, drive };
        let n = acc.read(index, sub, out)?;
        // a variable-length value exactly as long as `out` may have been cut: say so
        if size == 0 && n == out.len() && self.stored_len(index, sub) > n {
            return Err(abort::OUT_OF_MEMORY);
        }
        Ok(n)
    }

    /// The stored length of a variable-length value (0 for a value the drive keeps).
    fn stored_len(&self, index: u16, sub: u8) -> usize {
        match self.od.get(index, sub) {
            Some((slot, e)) if e.backing == crate::od::Backing::Stored => {
                self.store.stored_len(slot.get())
            }
            _ => 0,
        }
    }

    /// Write `data` to object (`index`, `sub`) with exactly the rules an SDO download passes:
    /// access, size, the dictionary's limits, the drive's rules (a supported mode, the
    /// software limits, PDO parameters) and the write hooks (controlword latch, 0x1010 store,
    /// ...). Ok, or the CiA 301 abort code; a refused write changes nothing.
    pub fn write_object(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
        drive: &mut impl Drive,
    ) -> Result<(), u32> {
        let mut acc = Access { core: self, drive };
        let r = acc.write(index, sub, data);
        self.observe();
        r
    }

    /// Check a write of `size` bytes to (`index`, `sub`) before any data moves (exists,
    /// writable, fits), as the SDO server does at the start of a segmented download.
    pub fn check_write_object(
        &mut self,
        index: u16,
        sub: u8,
        size: Option<usize>,
        drive: &mut impl Drive,
    ) -> Result<(), u32> {
        let mut acc = Access { core: self, drive };
        acc.check_write(index, sub, size)
    }

    /// The mapping `mapping_index` (0x1600.. RPDO, 0x1A00.. TPDO) compiled from the values the
    /// dictionary holds now, with the PDO engine's rules (mappable, size, at most
    /// [`DriveCore::pdo_max_len`] bytes).
    fn compiled(&self, mapping_index: u16, dir: Direction) -> Result<(Pdo, usize), u32> {
        let param = match Param::of(mapping_index) {
            Some(p) if p.mapping && p.dir == dir => p,
            _ => return Err(abort::NOT_MAPPABLE),
        };
        let list = match dir {
            Direction::Rx => &self.pdo.rpdo,
            Direction::Tx => &self.pdo.tpdo,
        };
        let (k, pdo) = list
            .iter()
            .enumerate()
            .find(|(_, p)| p.number == param.number)
            .ok_or(abort::NO_OBJECT)?;
        let store: &Store = &self.store;
        let count = pdo.slots.count.map_or(0, |s| store.u32(s as usize)) as usize;
        let c = compile(
            &self.od,
            store,
            &pdo.slots,
            count,
            dir == Direction::Tx,
            self.pdo.max_len,
        )?;
        let mut p = *pdo;
        p.map = c.map;
        p.n = c.n;
        p.len = c.len;
        p.bitwise = c.bitwise;
        Ok((p, k))
    }

    /// Bytes of the PDO image that mapping `mapping_index` (0x1600.. or 0x1A00..) describes
    /// now, or the abort code of a mapping that does not compile (0x06040041 / 0x06040042)
    /// or does not exist (0x06020000).
    pub fn pdo_image_len(&self, mapping_index: u16) -> Result<usize, u32> {
        let dir = match Param::of(mapping_index) {
            Some(Param { dir, .. }) => dir,
            None => return Err(abort::NOT_MAPPABLE),
        };
        self.compiled(mapping_index, dir)
            .map(|(p, _)| p.len as usize)
    }

    /// The TxPDO byte image of mapping `mapping_index` (0x1A00..): the mapped values as of the
    /// last tick, packed as a TPDO carries them, into `out`. Returns the length; `out`
    /// shorter than the image: 0x05040005.
    pub fn tpdo_image(&self, mapping_index: u16, out: &mut [u8]) -> Result<usize, u32> {
        let (p, _) = self.compiled(mapping_index, Direction::Tx)?;
        let len = p.len as usize;
        if out.len() < len {
            return Err(abort::OUT_OF_MEMORY);
        }
        Ok(mapping::pack(&p, &self.store, &mut out[..len]))
    }

    /// Bytes a PDO mapping may carry (8, one CAN frame, unless the front end set more).
    pub fn pdo_max_len(&self) -> usize {
        self.pdo.max_len
    }

    /// Let a PDO mapping carry up to `bytes` (at most 255; at least 8): for a front end whose
    /// process data is not one CAN frame per PDO (EtherCAT: what its sync managers hold).
    /// The node's PDOs are rebuilt with the new limit. The CAN front end keeps 8; a PDO
    /// longer than 8 bytes is never sent or received as a CAN frame (it is cut to the values
    /// that fit), so set this only where the PDOs are not valid on CAN.
    pub fn set_pdo_max_len(&mut self, bytes: usize) {
        let c = self;
        c.pdo.max_len = bytes.clamp(mapping::CAN_MAX_LEN, usize::from(u8::MAX));
        c.pdo.refresh_all(&c.od, &c.store);
    }

    /// Apply an RxPDO byte image of mapping `mapping_index` (0x1600..) as a received RPDO is
    /// applied: each value passes the rules of an SDO write (the dictionary's limits, then the
    /// write hook of the service that owns the object: a supported mode, min <= max, the
    /// controlword latch, a homing method 0; a refused value is not written, the others are;
    /// EMCY 0x6320 is held while the RPDO carries a refused value). `data` shorter than the
    /// mapping: nothing is written, abort 0x06070013. Ok(true) when every value was taken.
    pub fn apply_rpdo_image(&mut self, mapping_index: u16, data: &[u8]) -> Result<bool, u32> {
        let (p, k) = self.compiled(mapping_index, Direction::Rx)?;
        if data.len() < p.len as usize {
            return Err(abort::TOO_SHORT);
        }
        let c = self;
        let map = &p.map[..p.n as usize];
        let ok = mapping::unpack(map, p.bitwise, &data[..p.len as usize], |row, raw| {
            c.rpdo_value(row, raw)
        });
        c.rpdo_value_condition(k, ok);
        Ok(ok)
    }

    /// Advance the drive one cycle at `clocks`, as a SYNC followed by the tick does on CAN: the
    /// cycle's time is the SYNC's (CSP interpolation, the measured interval, a SYNC loss
    /// recovered), then timers, the CiA 402 state machine and mode, and exactly one
    /// `drive.command(..)`. No CAN PDO is sent or applied (the front end moves the images).
    pub fn cycle(&mut self, clocks: Clocks, drive: &mut impl Drive) {
        self.cycle_sync(clocks);
        self.poll_with(clocks, drive);
    }

    /// The SYNC half of [`DriveCore::cycle`]: the cycle's time as a SYNC's.
    pub(super) fn cycle_sync(&mut self, clocks: Clocks) {
        let c = self;
        c.now_us = clocks.app_us;
        c.comm_us = clocks.comm_us;
        if c.nmt != crate::NmtState::Initialising {
            let s = c.sync.on_sync(clocks.app_us, 0, 0, 0);
            if s.recovered {
                c.clear_emcy(EMCY_SYNC_LOSS, Cause::Condition);
            }
            let (_, watched) = c.watchdog_period();
            c.qs.watchdog_sync(clocks.app_us, watched);
            c.pending_sync = Some(clocks.app_us);
        }
    }

    /// The front end lost its master's process data (EtherCAT: the SM watchdog took the slave
    /// out of OP): EMCY `code` raised and held as a condition until
    /// [`DriveCore::connection_restored`], and the CiA 402 reaction 0x6007 (abort connection
    /// option code: 0 none, 1 fault, 2 disable voltage, 3 quick stop), as a lost heartbeat
    /// or SYNC on CAN. Returns true when the reaction is a fault.
    pub fn connection_lost(&mut self, code: u16) -> bool {
        let c = self;
        c.raise_emcy(code, [0; 5], Cause::Condition);
        let fault = c.cia.comm_loss(&c.store, code);
        c.observe();
        fault
    }

    /// The front end's process data is back (EtherCAT: OP again): the condition EMCY `code`
    /// of [`DriveCore::connection_lost`] is cleared (a fault it led to stays until the master's
    /// fault reset, controlword bit 7).
    pub fn connection_restored(&mut self, code: u16) {
        let c = self;
        c.clear_emcy(code, Cause::Condition);
        c.observe();
    }

    /// PDO numbers (0-based: 0x1600 + n / 0x1A00 + n) the dictionary has, RPDOs then TPDOs,
    /// through `f(dir_is_tx, mapping_index)`.
    pub fn for_each_pdo_mapping(&self, mut f: impl FnMut(bool, u16)) {
        for p in &self.pdo.rpdo {
            f(false, layout::bases(Direction::Rx).1 + p.number);
        }
        for p in &self.pdo.tpdo {
            f(true, layout::bases(Direction::Tx).1 + p.number);
        }
    }
}
