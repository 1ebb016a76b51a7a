//! The node's timers and the drive cycle: the communication timers (SDO time-out, boot
//! delay, heartbeats, event-driven TPDOs, EMCY inhibit) and one CiA 402 tick with its SYNC
//! supervision. The SDO time-out is the CAN front end's ([`Node`]); the rest is the drive
//! core's ([`DriveCore::poll_with`]).

use super::*;

impl Node {
    /// Timers, the CiA 402 state machine and mode, and exactly one `drive.command(..)`.
    pub fn poll(&mut self, now_us: u64, drive: &mut impl Drive) {
        self.poll_with(Clocks::same(now_us), drive);
    }

    /// [`Node::poll`] with two clocks ([`Clocks`]).
    pub fn poll_with(&mut self, clocks: Clocks, drive: &mut impl Drive) {
        self.sdo_timer(clocks.comm_us);
        self.core.timers_and_drive(clocks, drive);
        self.finish_call();
    }

    /// The communication timers alone, at `comm_us` on the communication clock: SDO
    /// time-out, a boot whose delay is over, the heartbeat producer and consumer, event-driven
    /// TPDOs, EMCYs held by their inhibit time. No CiA 402 cycle, no command to the drive: a
    /// lock-step runtime calls it between SYNCs, when [`Node::poll_at_comm`] says.
    pub fn poll_comm(&mut self, comm_us: u64, drive: &mut impl Drive) {
        let _ = drive;
        self.sdo_timer(comm_us);
        self.core.comm_timers(comm_us);
        self.finish_call();
    }

    /// Advance the drive one cycle at `clocks`, as [`DriveCore::cycle`] (a SYNC's time and
    /// the tick, no CAN PDO), with the CAN front end's timers and transmit queue.
    pub fn cycle(&mut self, clocks: Clocks, drive: &mut impl Drive) {
        self.core.cycle_sync(clocks);
        self.poll_with(clocks, drive);
    }

    /// The SDO server's time-out: its abort frames.
    fn sdo_timer(&mut self, comm_us: u64) {
        let mut outv: heapless::Vec<[u8; 8], 2> = heapless::Vec::new();
        self.can.sdo.poll(comm_us, &mut |f| {
            let _ = outv.push(f);
        });
        let tx_cob = cob::SDO_TX + self.core.node_id as u32;
        for f in outv {
            self.send(CanFrame::new(tx_cob, &f));
        }
    }

    /// After a call: a finished SDO transfer and state changes as events.
    fn finish_call(&mut self) {
        if let Some(t) = self.can.sdo.take_finished() {
            self.core.event(NodeEvent::SdoTransfer(t));
        }
        self.core.observe();
    }
}

impl DriveCore {
    /// Timers, the CiA 402 state machine and mode, and exactly one `drive.command(..)`; what
    /// is to be sent goes to [`DriveCore::take_output`].
    pub fn poll(&mut self, now_us: u64, drive: &mut impl Drive) {
        self.poll_with(Clocks::same(now_us), drive);
    }

    /// [`DriveCore::poll`] with two clocks ([`Clocks`]).
    pub fn poll_with(&mut self, clocks: Clocks, drive: &mut impl Drive) {
        self.timers_and_drive(clocks, drive);
        self.observe();
    }

    /// The communication timers of [`Node::poll_comm`] but the SDO time-out.
    fn comm_timers(&mut self, comm_us: u64) {
        self.comm_us = comm_us;
        self.comm_timers_before(comm_us);
        if self.nmt != NmtState::Initialising {
            self.comm_timers_after(comm_us);
        }
    }

    /// The boot after its delay, the heartbeat producer and consumer.
    fn comm_timers_before(&mut self, comm_us: u64) {
        if self.nmt == NmtState::Initialising && self.boot_due_us.is_some_and(|due| comm_us >= due)
        {
            self.boot_now(comm_us);
        }
        if self.nmt == NmtState::Initialising {
            return;
        }
        // the vendor switches' heartbeats and delayed SDO answers
        let (qs, quirks) = (&mut self.qs, &self.quirks);
        let (out, dropped) = (&mut self.out, &mut self.out_dropped);
        if qs.poll_comm(quirks, comm_us, self.node_id, self.nmt as u8, &mut |f| {
            emit(out, dropped, CoreOutput::CanOnly(f))
        }) {
            self.hb.restart(comm_us, self.store.u32(R_1017) as u16);
        }
        if self.qs.not_ready() {
            return;
        }
        // heartbeat producer
        if self.hb.due(comm_us, self.store.u32(R_1017) as u16) {
            self.emit(CoreOutput::Heartbeat {
                state: self.nmt as u8,
            });
        }
        self.sync_produce(comm_us);
        // heartbeat consumer: every producer whose time is up (one EMCY, for the first)
        let mut lost = None;
        while let Some(n) = self.hbc.poll(comm_us) {
            lost.get_or_insert(n);
        }
        if let Some(n) = lost {
            self.hb_lost = true;
            self.raise_emcy(EMCY_HEARTBEAT, [n, 0, 0, 0, 0], Cause::Condition);
            self.cia.comm_loss(&self.store, EMCY_HEARTBEAT);
        }
    }

    /// Whether the node is the SYNC producer now: 0x1005 bit 30 with a period 0x1006, in
    /// pre-operational or operational (CiA 301: no SYNC in stopped).
    pub(super) fn sync_producing(&self) -> bool {
        matches!(self.nmt, NmtState::PreOperational | NmtState::Operational)
            && !self.qs.not_ready()
            && crate::cia301::sync::produces(self.store.u32(R_1005), self.store.u32(R_1006))
    }

    /// The SYNC producer: a SYNC due at `comm_us` is sent (on 0x1005's CAN-ID, with its
    /// counter), then acted on as a received one (synchronous RPDOs applied, synchronous
    /// TPDOs sent after it), at the application time of the last cycle.
    fn sync_produce(&mut self, comm_us: u64) {
        let active = self.sync_producing();
        let (period, overflow) = (self.store.u32(R_1006), self.store.u32(R_1019) as u8);
        let Some(counter) = self.sync_producer.poll(active, comm_us, period, overflow) else {
            return;
        };
        let can_id = self.store.u32(R_1005) & 0x7FF;
        let data: &[u8] = match &counter {
            Some(c) => core::slice::from_ref(c),
            None => &[],
        };
        self.emit(CoreOutput::CanOnly(CanFrame::new(can_id, data)));
        let clocks = Clocks {
            app_us: self.now_us,
            comm_us,
        };
        self.on_sync(data.len() as u8, counter.unwrap_or(0), clocks, 0);
    }

    fn timers_and_drive(&mut self, clocks: Clocks, drive: &mut impl Drive) {
        let now_us = clocks.app_us;
        self.now_us = now_us;
        self.comm_us = clocks.comm_us;
        let fb = drive.feedback();
        self.comm_timers_before(clocks.comm_us);
        let c = self;
        if c.nmt == NmtState::Initialising && !c.boot_keeps_app {
            drive.command(&crate::drive::DriveCommand {
                setpoint: crate::drive::Setpoint::Disabled,
                max_torque_permille: 0.0,
                max_velocity_inc_per_s: 0.0,
            });
            return;
        }
        // SYNC supervision
        if c.nmt == NmtState::Operational && c.sync.poll(now_us, c.store.u32(R_1006)) {
            c.raise_emcy(EMCY_SYNC_LOSS, [0; 5], Cause::Condition);
            c.cia.comm_loss(&c.store, EMCY_SYNC_LOSS);
        }
        // the vendor's SYNC watchdog (docs/quirks.md 3.13): a fault whatever 0x6007 says
        let (wd_period, watched) = c.watchdog_period();
        if let Some(code) = c.qs.watchdog_poll(&c.quirks, now_us, watched, wd_period) {
            c.cia.request_fault(code);
        }
        // CiA 402 (a lost master or SYNC whose reaction is a fault blocks the fault reset)
        c.cia.comm_fault_present = (c.hb_lost || c.sync.lost) && c.store.i32(o402::ABORT_CONN) == 1;
        c.cia.status_extra = if c.qs.late_sync { 0x8000 } else { 0 };
        let period = csp_period_us(&c.store, c.sync.interval_us);
        let sync_at = c.pending_sync.take();
        let (level, latched) = c.cw_latch.for_tick(
            c.store.u32(o402::CONTROLWORD) as u16,
            clocks.comm_us,
            c.quirks.controlword_min_hold,
        );
        let control = crate::cia402::TickControl {
            sync_at,
            csp_period_us: period,
            level,
            latched,
        };
        let out = c.cia.step(&mut c.store, &fb, now_us, control, drive);
        if let Some(code) = out.new_fault {
            c.raise_emcy(code, [0; 5], Cause::Fault);
        }
        if out.fault_cleared {
            // errors a supervision still holds (master still lost) stay active
            c.clear_cause(Cause::Fault);
        }
        drive.command(&out.command);
        if c.nmt != NmtState::Initialising {
            c.comm_timers_after(clocks.comm_us);
        }
    }

    /// Event-driven TPDOs (with the values of the last CiA 402 cycle) and EMCYs held by their
    /// inhibit time, on the communication clock.
    fn comm_timers_after(&mut self, comm_us: u64) {
        if self.nmt == NmtState::Operational {
            let (out, dropped) = (&mut self.out, &mut self.out_dropped);
            self.pdo.poll_events(&self.store, comm_us, &mut |f| {
                emit(out, dropped, CoreOutput::CanOnly(f))
            });
        }
        if self.emcy_allowed() {
            let inhibit = self.store.u32(R_1015) as u16;
            while let Some(d) = self.emcy.next(comm_us, inhibit) {
                self.emit(CoreOutput::Emcy(d));
            }
        }
    }
}
