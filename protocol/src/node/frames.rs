//! The CANopen-over-CAN front end: a received frame dispatched on the COB-IDs configured now
//! ([`RxTable`]) to NMT, SYNC, heartbeat, SDO, RPDO, RTR and LSS; the NMT commands. What
//! the frames ask of the drive goes to the core ([`super::drive_core`]).

use super::*;

impl Node {
    /// An NMT command for this node: a reset node resets the application and the whole
    /// dictionary, a reset communication the communication objects; the others change state.
    fn nmt_command(&mut self, cmd: NmtCommand, now_us: u64, drive: &mut impl Drive) {
        match cmd {
            NmtCommand::ResetNode => {
                // The application resets too: the drive re-initialises its axis.
                drive.reset();
                self.take_lss_node_id(true);
                let c = &mut self.core;
                c.restore_range(0x0000, 0xFFFF);
                let f = Factor::from_info(&c.info).unwrap_or(Factor {
                    inc_per_uu: 1.0,
                    vel_inc_per_uu: 1.0,
                    acc_inc_per_uu: 1.0,
                });
                c.cia = Cia402::new(f, c.quirks.cia402()).with_device(
                    c.od.device.following_error_window_zero_off,
                    si_unit_rows(&c.od),
                );
                c.cw_latch = ControlwordLatch::default();
                c.clear_all_emcy();
                self.can.sdo.reset();
                let delay = c.reset_node_delay_us;
                c.start_boot(now_us, false, delay);
            }
            NmtCommand::ResetCommunication => {
                self.take_lss_node_id(false);
                let c = &mut self.core;
                c.restore_range(0x1000, 0x1FFF);
                // 0x1001 / 0x1003 keep what the drive is still in FAULT for
                let before = c.emcy.active_codes();
                c.emcy.reset_communication(&mut c.store);
                for code in before {
                    if !c.emcy.is_active(code) {
                        c.event(NodeEvent::EmcyCleared { code });
                    }
                }
                self.can.sdo.reset();
                let delay = c.reset_comm_delay_us;
                c.start_boot(now_us, true, delay);
            }
            _ => {
                let c = &mut self.core;
                let next = nmt::next_state(cmd);
                if next == NmtState::Operational && c.nmt != NmtState::Operational {
                    c.pdo.restart();
                }
                if next != NmtState::Operational {
                    self.sdo_reset_if_stopped(next);
                }
                self.core.nmt = next;
            }
        }
    }

    fn sdo_reset_if_stopped(&mut self, next: NmtState) {
        if next == NmtState::Stopped {
            self.can.sdo.reset();
        }
    }

    /// Handle one received frame.
    pub fn handle(&mut self, frame: &CanFrame, now_us: u64, drive: &mut impl Drive) -> FrameEvent {
        self.handle_with(frame, Clocks::same(now_us), 0, drive)
    }

    /// Handle one received frame that arrived `late_us` before `now_us` (a runtime that read it
    /// late says so): a SYNC handled after its synchronous window (0x1007) closed sends no
    /// synchronous TPDOs. Everything else is as [`Node::handle`].
    pub fn handle_late(
        &mut self,
        frame: &CanFrame,
        now_us: u64,
        late_us: u64,
        drive: &mut impl Drive,
    ) -> FrameEvent {
        self.handle_with(frame, Clocks::same(now_us), late_us, drive)
    }

    /// [`Node::handle_late`] with two clocks ([`Clocks`]): a lock-step runtime gives the wall
    /// clock as the communication clock.
    pub fn handle_with(
        &mut self,
        frame: &CanFrame,
        clocks: Clocks,
        late_us: u64,
        drive: &mut impl Drive,
    ) -> FrameEvent {
        let ev = self.handle_frame(frame, clocks, late_us, drive);
        if let Some(t) = self.can.sdo.take_finished() {
            self.core.event(NodeEvent::SdoTransfer(t));
        }
        self.core.observe();
        ev
    }

    /// A frame, dispatched on what it is for this node ([`RxTable::classify`] on the COB-IDs
    /// configured now) to one function per service, once the NMT and quirk states that hear
    /// little have had their say.
    fn handle_frame(
        &mut self,
        frame: &CanFrame,
        clocks: Clocks,
        late_us: u64,
        drive: &mut impl Drive,
    ) -> FrameEvent {
        self.core.now_us = clocks.app_us;
        self.core.comm_us = clocks.comm_us;
        // everything a frame times here is communication: resets (boot delay), heartbeats,
        // SDO, RTR answers; a SYNC is the exception (on_sync takes both)
        let now_us = clocks.comm_us;
        let rx = self.rx_table().classify(frame);
        match rx {
            Rx::Other => return FrameEvent::Ignored,
            Rx::Sync | Rx::Rpdo => {}
            // may change the node-ID or the EMCY COB-ID: what is queued is framed first
            _ => self.frame_queued(),
        }
        if rx == Rx::Lss {
            return self.lss_frame(frame, now_us, drive);
        }
        if let Some(ev) = self.hard_of_hearing(frame, now_us, drive) {
            return ev;
        }
        let nmt = self.core.nmt;
        match rx {
            Rx::Nmt => self.nmt_frame(frame, now_us, drive),
            Rx::Sync => self.core.on_sync(frame.len, frame.data[0], clocks, late_us),
            Rx::Heartbeat(node) => {
                self.heartbeat_in(node, now_us);
                FrameEvent::Handled
            }
            _ if nmt == NmtState::Stopped => FrameEvent::Ignored,
            Rx::Sdo => self.sdo_frame(frame, now_us, drive),
            _ if nmt != NmtState::Operational => FrameEvent::Ignored,
            Rx::Rpdo => self.rpdo_frame(frame),
            Rx::Rtr => self.rtr_frame(frame, now_us),
            Rx::Other | Rx::Lss => FrameEvent::Ignored,
        }
    }

    /// The COB-IDs this node receives on, as configured now.
    fn rx_table(&self) -> RxTable {
        RxTable {
            sync: self.sync_cob(),
            sdo_rx: cob::SDO_RX + self.core.node_id as u32,
            lss: self.core.boot_due_us.is_none() && self.can.lss.is_some(),
        }
    }

    /// The SYNC COB-ID (0x1005, 11 bits).
    fn sync_cob(&self) -> u32 {
        self.core.store.u32(R_1005) & 0x7FF
    }

    /// The states that hear little (LSS aside): non-configured, booting, not ready after
    /// boot-up. `Some`: the frame's fate there; `None`: the node hears it.
    fn hard_of_hearing(
        &mut self,
        frame: &CanFrame,
        now_us: u64,
        drive: &mut impl Drive,
    ) -> Option<FrameEvent> {
        if self.lss_unconfigured() {
            // Non-configured: silent but for LSS; a broadcast NMT reset still resets it.
            return Some(match nmt::decode(frame, 0) {
                Some(cmd @ (NmtCommand::ResetNode | NmtCommand::ResetCommunication)) => {
                    self.nmt_command(cmd, now_us, drive);
                    FrameEvent::Handled
                }
                _ => FrameEvent::Ignored,
            });
        }
        let is_sync = frame.id == self.sync_cob() && !frame.rtr;
        if self.core.nmt == NmtState::Initialising {
            // Deaf while booting, but a SYNC still tells a lock-step runtime time goes on.
            if self.core.boot_due_us.is_some() && is_sync {
                return Some(FrameEvent::Sync { counter: None });
            }
            return Some(FrameEvent::Ignored);
        }
        if self.core.qs.not_ready() {
            // not_ready_after_bootup (docs/quirks.md 3.6): only a reset is heard; a SYNC still
            // tells a lock-step runtime that time goes on
            return Some(match nmt::decode(frame, self.core.node_id) {
                Some(cmd @ (NmtCommand::ResetNode | NmtCommand::ResetCommunication))
                    if frame.id == 0 =>
                {
                    self.nmt_command(cmd, now_us, drive);
                    FrameEvent::Handled
                }
                _ if is_sync => FrameEvent::Sync { counter: None },
                _ => FrameEvent::Ignored,
            });
        }
        None
    }

    /// NMT module control (COB-ID 0) addressed to this node or to all.
    fn nmt_frame(&mut self, frame: &CanFrame, now_us: u64, drive: &mut impl Drive) -> FrameEvent {
        match nmt::decode(frame, self.core.node_id) {
            Some(cmd) => {
                self.nmt_command(cmd, now_us, drive);
                FrameEvent::Handled
            }
            None => FrameEvent::Ignored,
        }
    }

    /// An SDO request to this node's server (pre-operational and operational).
    fn sdo_frame(&mut self, frame: &CanFrame, now_us: u64, drive: &mut impl Drive) -> FrameEvent {
        if frame.rtr || frame.len != 8 {
            return FrameEvent::Ignored;
        }
        let in_block = self.can.sdo.expects_block_segment();
        let c = &mut self.core;
        if c.qs.sdo_request(&c.quirks, &frame.data, in_block) == SdoGate::Drop {
            return FrameEvent::Handled;
        }
        let mut outv: heapless::Vec<[u8; 8], 16> = heapless::Vec::new();
        let mut acc = Access {
            core: &mut self.core,
            drive,
        };
        self.can
            .sdo
            .handle(&frame.data, now_us, &mut acc, &mut |f| {
                let _ = outv.push(f);
            });
        let tx_cob = cob::SDO_TX + self.core.node_id as u32;
        for f in outv {
            self.core.sdo_answer(CanFrame::new(tx_cob, &f), now_us);
        }
        FrameEvent::Handled
    }

    /// A data frame in operational: an RPDO if one is configured on its COB-ID.
    fn rpdo_frame(&mut self, frame: &CanFrame) -> FrameEvent {
        let c = &mut self.core;
        match c.pdo.receive(frame) {
            RxOutcome::NotRpdo => FrameEvent::Ignored,
            RxOutcome::Received {
                k,
                len,
                length_code,
                apply,
            } => {
                let ok = apply.then(|| c.apply_rpdo(k, &frame.data));
                c.rpdo_length_condition(k, length_code, len);
                if let Some(ok) = ok {
                    c.rpdo_value_condition(k, ok);
                }
                FrameEvent::Handled
            }
        }
    }

    /// A remote frame in operational: the TPDO configured on its COB-ID, if it may answer.
    fn rtr_frame(&mut self, frame: &CanFrame, now_us: u64) -> FrameEvent {
        if self.core.quirks.tpdo_rtr_unsupported.is_some() {
            // no remote frames answered (docs/quirks.md 3.10)
            return FrameEvent::Ignored;
        }
        let c = &mut self.core;
        let (out, dropped) = (&mut c.out, &mut c.out_dropped);
        if c.pdo.on_rtr(&c.store, frame, now_us, &mut |f| {
            emit(out, dropped, CoreOutput::CanOnly(f))
        }) {
            return FrameEvent::Handled;
        }
        FrameEvent::Ignored
    }

    /// Non-configured (node-ID 0xFF) and not booting: only LSS is served.
    fn lss_unconfigured(&self) -> bool {
        self.core.node_id == UNCONFIGURED_NODE_ID && self.core.boot_due_us.is_none()
    }

    /// An LSS request (COB-ID 0x7E5), in every NMT state once booted (as Lely and
    /// CANopenNode) and while non-configured.
    fn lss_frame(&mut self, frame: &CanFrame, now_us: u64, drive: &mut impl Drive) -> FrameEvent {
        let Some(lss) = self.can.lss.as_mut() else {
            return FrameEvent::Ignored;
        };
        let out = lss.handle(frame);
        if let Some(f) = out.response {
            self.send(f);
        }
        match out.event {
            Some(LssEvent::ResetCommunication { .. }) => {
                // CiA 305: a non-configured node given a node-ID boots with it when switched
                // back to waiting.
                self.nmt_command(NmtCommand::ResetCommunication, now_us, drive);
            }
            Some(LssEvent::StoreRequested {
                node_id,
                bit_timing_index,
            }) => {
                if self.can.lss_store_external {
                    self.can.lss_store = Some(LssStore {
                        node_id,
                        bit_timing_index,
                    });
                } else if let Some(f) = self.can.lss.as_mut().and_then(|l| l.store_done(true)) {
                    self.send(f);
                }
            }
            Some(LssEvent::ActivateBitTiming {
                table_index,
                switch_delay_ms,
            }) => self.can.lss_bit_timing_activated = Some((table_index, switch_delay_ms)),
            _ => {}
        }
        FrameEvent::Handled
    }

    fn heartbeat_in(&mut self, id_low: u8, now_us: u64) {
        let node = id_low & 0x7F;
        let c = &mut self.core;
        if c.hbc.is_monitoring(node) {
            c.hbc.on_heartbeat(node, now_us);
            if c.hb_lost {
                c.hb_lost = false;
                c.clear_emcy(EMCY_HEARTBEAT, Cause::Condition);
            }
        }
    }
}

impl DriveCore {
    /// A SYNC, handled `late_us` after it arrived (the runtime read it late). Synchronous TPDOs
    /// are sampled and queued now, unless the synchronous window (0x1007, non-zero) has
    /// already closed: then CiA 301 says they are not sent (counted in 0x2100).
    ///
    /// The SYNC's data length and first byte (the counter) are what the consumer checks
    /// (EMCY 0x8240 on a wrong length, 0x1019).
    pub(super) fn on_sync(
        &mut self,
        sync_len: u8,
        sync_byte0: u8,
        clocks: Clocks,
        late_us: u64,
    ) -> FrameEvent {
        let now_us = clocks.app_us;
        let window_us = u64::from(self.store.u32(R_1007));
        let window_closed = window_us > 0 && late_us > window_us;
        let overflow = self.store.u32(R_1019) as u8;
        if let Some(l) = self.quirks.late_sync_statusword_bit15 {
            // a SYNC later than the period 0x1006 allows (docs/quirks.md 3.14)
            let period = u64::from(self.store.u32(R_1006));
            self.qs.late_sync = period != 0
                && self.sync.last_us.is_some_and(|last| {
                    now_us.saturating_sub(last) > period + u64::from(l.late_tolerance_us)
                });
        }
        let (_, watched) = self.watchdog_period();
        self.qs.watchdog_sync(now_us, watched);
        let s = self.sync.on_sync(now_us, sync_len, sync_byte0, overflow);
        if s.length_error && self.emcy_allowed() {
            self.report(EMCY_SYNC_LENGTH, [sync_len, 0, 0, 0, 0]);
        }
        if s.recovered {
            // the supervision is satisfied again; a fault it caused stays until reset
            self.clear_emcy(EMCY_SYNC_LOSS, Cause::Condition);
        }
        self.pending_sync = Some(now_us);
        if self.nmt == NmtState::Operational {
            for k in 0..self.pdo.rpdo.len() {
                if let Some(data) = self.pdo.take_sync_rpdo(k) {
                    let ok = self.apply_rpdo(k, &data);
                    self.rpdo_value_condition(k, ok);
                }
            }
            let (out, dropped) = (&mut self.out, &mut self.out_dropped);
            let missed = self
                .pdo
                .on_sync(&self.store, clocks.comm_us, window_closed, &mut |f| {
                    emit(out, dropped, CoreOutput::CanOnly(f))
                });
            self.sync_window_missed = self.sync_window_missed.wrapping_add(missed);
        }
        self.event(NodeEvent::Sync { counter: s.counter });
        FrameEvent::Sync { counter: s.counter }
    }
}
