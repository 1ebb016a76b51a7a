//! The drive core's methods: the object dictionary's values and their writes (each
//! through the write hook of the service that owns the object, [`super::writes`]), the
//! EMCY bookkeeping, RPDO values, boot and reset of the dictionary. Nothing here decodes a
//! received CAN frame (that is [`super::frames`]); what the core sends it queues as
//! [`CoreOutput`]s (the boot-up, a heartbeat, an EMCY; docs/decisions/0018). What a front end
//! other than CAN calls is in [`super::access`].

use super::*;

impl<D: Drive> ObjectAccess for Access<'_, D> {
    fn read(&mut self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, u32> {
        let (slot, e) = lookup(&self.core.od, index, sub)?;
        if !e.access.readable() {
            return Err(abort::WRITE_ONLY);
        }
        match e.backing {
            Backing::Handler(tag) => self.drive.read_object(tag, index, sub, buf),
            Backing::Stored => Ok(self.core.store.read_bytes(slot, e.dtype.size(), buf)),
        }
    }

    fn check_write(&mut self, index: u16, sub: u8, size: Option<usize>) -> Result<(), u32> {
        let (_, e) = lookup(&self.core.od, index, sub)?;
        if !e.access.writable() {
            return Err(abort::READ_ONLY);
        }
        let n = e.dtype.size();
        match size {
            Some(s) if n > 0 && s > n => Err(abort::TOO_LONG),
            Some(s) if n > 0 && s < n => Err(abort::TOO_SHORT),
            Some(s) if n == 0 && s > e.capacity => Err(abort::TOO_LONG),
            _ => Ok(()),
        }
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), u32> {
        self.check_write(index, sub, Some(data.len()))?;
        let (slot, e) = lookup(&self.core.od, index, sub)?;
        if e.dtype.variable() {
            if let Backing::Handler(tag) = e.backing {
                return self.drive.write_object(tag, index, sub, data);
            }
            return if self.core.store.write_bytes(slot, data) {
                Ok(())
            } else {
                Err(abort::TOO_LONG)
            };
        }
        let raw = e.decode(data);
        if let Err(high) = e.check_limits(raw) {
            return Err(if high {
                abort::VALUE_HIGH
            } else {
                abort::VALUE_LOW
            });
        }
        if let Backing::Handler(tag) = e.backing {
            return self.drive.write_object(tag, index, sub, data);
        }
        self.core.write_stored(&ObjectWrite {
            row: slot,
            index,
            sub,
            raw,
            origin: Origin::Sdo,
        })
    }
}

impl DriveCore {
    pub(super) fn event(&mut self, e: NodeEvent) {
        if self.events.push_back(e).is_err() {
            self.events_dropped = self.events_dropped.wrapping_add(1);
        }
    }

    /// Report state changes since the last call as events.
    pub(super) fn observe(&mut self) {
        if self.cia.state != self.seen_cia {
            let from = self.seen_cia;
            self.seen_cia = self.cia.state;
            self.event(NodeEvent::Cia402State {
                from,
                to: self.cia.state,
            });
        }
        if self.nmt != self.seen_nmt {
            let from = self.seen_nmt;
            self.seen_nmt = self.nmt;
            self.event(NodeEvent::NmtState { from, to: self.nmt });
        }
    }

    pub(super) fn raise_emcy(&mut self, code: u16, info: [u8; 5], cause: Cause) {
        if self.emcy.raise(&mut self.store, code, info, cause) {
            self.event(NodeEvent::EmcyRaised { code });
        }
    }

    pub(crate) fn clear_emcy(&mut self, code: u16, cause: Cause) {
        if self.emcy.clear(&mut self.store, code, cause) {
            self.event(NodeEvent::EmcyCleared { code });
        }
    }

    /// `cause` holds no error any more: the errors only it held clear.
    pub(super) fn clear_cause(&mut self, cause: Cause) {
        for code in self.emcy.clear_cause(&mut self.store, cause) {
            self.event(NodeEvent::EmcyCleared { code });
        }
    }

    /// Every error goes (reset node).
    pub(super) fn clear_all_emcy(&mut self) {
        for code in self.emcy.active_codes() {
            self.event(NodeEvent::EmcyCleared { code });
        }
        self.emcy.reset(&mut self.store);
    }

    /// RPDO `k` arrived with a length error `code` (0 = right length): raise it once, and
    /// clear it when no RPDO holds it any more.
    pub(super) fn rpdo_length_condition(&mut self, k: usize, code: u16, len: u8) {
        let old = self.pdo.rpdo[k].len_error;
        if old == code {
            return;
        }
        self.pdo.rpdo[k].len_error = code;
        if old != 0 && !self.pdo.rpdo.iter().any(|p| p.len_error == old) {
            self.clear_emcy(old, Cause::Condition);
        }
        if code != 0 {
            let info = [k as u8 + 1, len, self.pdo.rpdo[k].len, 0, 0];
            self.raise_emcy(code, info, Cause::Condition);
        }
    }

    /// RPDO `k` carried only acceptable values (`ok`) or not: EMCY 0x6320 held meanwhile.
    pub(super) fn rpdo_value_condition(&mut self, k: usize, ok: bool) {
        if self.pdo.rpdo[k].value_error != ok {
            return;
        }
        self.pdo.rpdo[k].value_error = !ok;
        if ok {
            if !self.pdo.rpdo.iter().any(|p| p.value_error) {
                self.clear_emcy(EMCY_RPDO_VALUE, Cause::Condition);
            }
        } else {
            self.raise_emcy(EMCY_RPDO_VALUE, [k as u8 + 1, 0, 0, 0, 0], Cause::Condition);
        }
    }

    /// A reconfigured (or reset) RPDO starts without errors: they are reported again.
    pub(crate) fn rpdo_conditions_reset(&mut self, k: usize) {
        self.rpdo_length_condition(k, 0, 0);
        self.rpdo_value_condition(k, true);
    }

    pub(super) fn emit(&mut self, o: CoreOutput) {
        emit(&mut self.out, &mut self.out_dropped, o);
    }

    /// A write to a stored object whose type and dictionary limits were checked, from an SDO
    /// download or an RPDO: the hook of the service that owns the object ([`WriteHooks`])
    /// checks it and applies its side effects; the value is stored unless the hook applied
    /// it itself. A refused write changes nothing.
    pub(crate) fn write_stored(&mut self, w: &ObjectWrite) -> Result<(), u32> {
        if let Some(hook) = self.hooks.for_row(w.row, w.index) {
            if hook(self, w)? == Verdict::Applied {
                return Ok(());
            }
        }
        self.store.set(w.row, w.raw);
        Ok(())
    }

    /// One value of a received RPDO for the store row `row`: the dictionary's limits, then
    /// [`DriveCore::write_stored`] as for an SDO write. Whether it was taken.
    pub(super) fn rpdo_value(&mut self, row: usize, raw: u64) -> bool {
        let e = self.od.entry(Slot::at(row));
        if e.check_limits(raw).is_err() {
            return false;
        }
        let w = ObjectWrite {
            row,
            index: e.index,
            sub: e.sub,
            raw,
            origin: Origin::Rpdo,
        };
        self.write_stored(&w).is_ok()
    }

    /// Apply received data to RPDO `k`'s mapped objects, each value through
    /// [`DriveCore::rpdo_value`]. Whether every value was taken (for
    /// [`DriveCore::rpdo_value_condition`]).
    pub(super) fn apply_rpdo(&mut self, k: usize, data: &[u8]) -> bool {
        let (map, n, len, bitwise) = self.pdo.rpdo[k].rx_map();
        let Some(data) = data.get(..len) else {
            return false;
        };
        mapping::unpack(&map[..n], bitwise, data, |row, raw| {
            self.rpdo_value(row, raw)
        })
    }

    /// An SDO answer to a request at `now_us`: sent now or after the vendor's delay.
    pub(super) fn sdo_answer(&mut self, f: CanFrame, now_us: u64) {
        match self.qs.sdo_answer(&self.quirks, f, now_us) {
            SdoAnswer::Now(f) => self.emit(CoreOutput::CanOnly(f)),
            SdoAnswer::Queued => {}
            SdoAnswer::Dropped => self.out_dropped = self.out_dropped.wrapping_add(1),
        }
    }

    /// The period `sync_watchdog` watches, us (0: none), and whether the drive is in a
    /// watched state (OPERATION ENABLED in one of its modes).
    pub(super) fn watchdog_period(&self) -> (u64, bool) {
        let Some(w) = &self.quirks.sync_watchdog else {
            return (0, false);
        };
        let watched =
            self.cia.state == State::OperationEnabled && w.modes.contains(&self.cia.mode_display);
        let cycle = u64::from(self.store.u32(R_1006));
        let period = match w.period_from {
            WatchdogPeriod::Interpolation => match interpolation_period_us(&self.store) {
                0 => cycle,
                p => p,
            },
            WatchdogPeriod::CommunicationCycle => cycle,
        };
        (period, watched)
    }

    pub(super) fn refresh_all(&mut self) {
        for k in 0..self.pdo.rpdo.len() {
            self.rpdo_conditions_reset(k);
        }
        self.pdo.refresh_all(&self.od, &self.store);
        for i in 0..4 {
            let e = self.store.u32(R_1016 + i);
            self.hbc.configure(i, e);
        }
    }

    /// The CAN-ID EMCYs go out on: 0x1014's, or $NODEID + 0x80 for the 0 of a device whose
    /// file means that by it (`DeviceDescription::emcy_cob_id_zero_predefined`).
    pub(super) fn emcy_can_id(&self) -> u32 {
        let id = self.store.u32(R_1014) & 0x7FF;
        if id == 0 && self.od.device.emcy_cob_id_zero_predefined {
            0x80 + u32::from(self.node_id)
        } else {
            id
        }
    }

    pub(super) fn emcy_allowed(&self) -> bool {
        matches!(self.nmt, NmtState::PreOperational | NmtState::Operational)
            && self.store.u32(R_1014) & 0x8000_0000 == 0
            && !self.qs.not_ready()
    }

    /// Report a communication event without keeping it active (history + EMCY frame).
    pub(super) fn report(&mut self, code: u16, info: [u8; 5]) {
        if self.emcy.report(&mut self.store, code, info) {
            self.event(NodeEvent::EmcyRaised { code });
            self.event(NodeEvent::EmcyCleared { code });
        }
    }

    /// Begin a boot: at once without a boot delay (`delay_us`), else initialising (silent,
    /// deaf) until the delay has passed ([`Node::poll`] or [`Node::finish_boot`] completes
    /// it).
    pub(super) fn start_boot(&mut self, now_us: u64, keeps_app: bool, delay_us: u64) {
        self.qs.on_reset();
        if delay_us == 0 {
            self.boot_now(now_us);
        } else {
            self.nmt = NmtState::Initialising;
            self.boot_due_us = Some(now_us.saturating_add(delay_us));
            self.boot_keeps_app = keeps_app;
        }
    }

    pub(super) fn boot_now(&mut self, now_us: u64) {
        self.boot_due_us = None;
        self.boot_keeps_app = false;
        if self.node_id == UNCONFIGURED_NODE_ID {
            // CiA 305: no node-ID, no boot-up; the node stays initialising and answers LSS
            // only (as Lely's NMT does; CANopenNode skips the other services).
            return;
        }
        self.nmt = NmtState::PreOperational;
        self.refresh_all();
        self.sync = SyncConsumer::default();
        self.sync_producer = Default::default();
        self.pending_sync = None;
        self.hb_lost = false;
        self.hb.restart(now_us, self.store.u32(R_1017) as u16);
        self.emit(CoreOutput::Bootup);
        self.qs.on_bootup(&self.quirks, now_us);
    }

    pub(super) fn restore_range(&mut self, lo: u16, hi: u16) {
        let serial = self.store.raw(R_SERIAL);
        if self.has_saved {
            self.store.copy_range(&self.saved, &self.od, lo, hi);
        } else {
            self.store.reset_range(&self.od, lo, hi, self.node_id);
        }
        // The serial number (0x1018:4, $NODEID in the standard dictionary) is part of the
        // LSS address: it stays what it was at power-on when LSS changes the node-ID.
        self.store.set(R_SERIAL, serial);
    }
}

/// The interpolation time period 0x60C2 (value x 10^index s), us; 0 when not set.
pub(super) fn interpolation_period_us(store: &Store) -> u64 {
    let v = store.u32(o402::IP_VALUE) as u64;
    let i = store.i32(o402::IP_INDEX);
    if v > 0 && (-6..=0).contains(&i) {
        let mut p = v;
        for _ in 0..(i + 6) {
            p *= 10;
        }
        return p;
    }
    0
}

/// The CSP interpolation period: 0x60C2, else 0x1006, else the measured SYNC interval.
pub(super) fn csp_period_us(store: &Store, measured_us: u64) -> u64 {
    let p = interpolation_period_us(store);
    if p > 0 {
        return p;
    }
    let c = store.u32(R_1006) as u64;
    if c > 0 {
        c
    } else {
        measured_us
    }
}

/// The rows of a dictionary's SI unit objects 0x60A8, 0x60A9 and 0x60AA (a vendor's file may
/// have them; the CiA 402 layer applies 0x60A9 and 0x60AA where it can), `None` without
/// 0x60A9 and 0x60AA.
pub(super) fn si_unit_rows(od: &ObjectDictionary) -> Option<crate::cia402::SiRows> {
    let row = |index: u16| {
        od.get(index, 0)
            .filter(|(_, e)| e.dtype == crate::od::DataType::U32)
            .map(|(s, _)| s.get())
    };
    let rows = crate::cia402::SiRows {
        position: row(0x60A8),
        velocity: row(0x60A9),
        acceleration: row(0x60AA),
    };
    (rows.velocity.is_some() || rows.acceleration.is_some()).then_some(rows)
}
