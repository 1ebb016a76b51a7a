//! Shared test fixtures: a simple drive model and a bus-side helper.
#![allow(dead_code)]

use drive_protocol::od::{Access, DataType, Entry, ObjectDictionary};
use drive_protocol::{
    CanFrame, Drive, DriveCommand, DriveInfo, Feedback, FrameEvent, Node, NodeConfig, Setpoint,
};

pub const ID: u8 = 5;
pub const DT_US: u64 = 1000;

/// 65536 inc per motor rev, 1:1, 10 mm screw, user unit 1 um: 6.5536 inc per um.
pub fn info() -> DriveInfo {
    DriveInfo {
        encoder_increments_per_rev: 65536,
        gear_motor_revs: 1,
        gear_shaft_revs: 1,
        feed_user_units: 10_000,
        feed_shaft_revs: 1,
        rated_torque_mnm: 5000,
        rated_current_ma: 8000,
        max_motor_speed_rpm: 3000,
        rotary: false,
    }
}

pub const INC_PER_UU: f64 = 6.5536;

/// An ideal axis with a first-order lag (position, speed) or an integrator (torque).
#[derive(Clone, Debug)]
pub struct SimDrive {
    pub pos: f64,
    pub vel: f64,
    pub dt: f64,
    pub tau: f64,
    pub fault: Option<u16>,
    pub fault_persists: bool,
    /// A fault injected through 0x2101 (held until 0 is written).
    pub injected: Option<u16>,
    pub home_switch_above: Option<f64>,
    /// Values of the objects the drive keeps itself (tag [`HANDLER_TAG`], sub-index = slot).
    pub params: [f32; 4],
    pub last: Option<DriveCommand>,
    pub commands: u64,
    pub direct_offset: f64,
    /// Extra position lag (to provoke following errors).
    pub stuck: bool,
}

impl Default for SimDrive {
    fn default() -> Self {
        SimDrive {
            pos: 0.0,
            vel: 0.0,
            dt: DT_US as f64 * 1e-6,
            tau: 0.002,
            fault: None,
            fault_persists: false,
            injected: None,
            home_switch_above: None,
            params: [0.0; 4],
            last: None,
            commands: 0,
            direct_offset: 0.0,
            stuck: false,
        }
    }
}

/// Tag of the test drive's own objects.
pub const HANDLER_TAG: u16 = 7;
/// Tag of its fault injection (0x2101, write-only U16: a non-zero code is a fault the drive
/// reports until 0 is written; a fault reset meanwhile is refused).
pub const INJECT_TAG: u16 = 8;
/// Index of the test drive's own REAL32 record (subs 1..=3, each limited to 0.0..=1.0 by the
/// drive itself).
pub const HANDLER_INDEX: u16 = 0x2200;

/// The standard dictionary plus a REAL32 record the test drive keeps itself (a handler).
pub fn od_with_handler() -> ObjectDictionary {
    let mut od = ObjectDictionary::standard(&info());
    let rec = drive_protocol::od::ObjType::Record;
    od.insert(
        Entry::member(
            HANDLER_INDEX,
            0,
            rec,
            "Drive values",
            "Highest sub-index supported",
            DataType::U8,
            Access::Const,
        )
        .with_default(drive_protocol::od::DefaultValue::Value(3)),
    )
    .unwrap();
    for sub in 1..=3u8 {
        od.insert(
            Entry::member(
                HANDLER_INDEX,
                sub,
                rec,
                "Drive values",
                format!("value {sub}"),
                DataType::Real32,
                Access::Rw,
            )
            .with_handler(HANDLER_TAG),
        )
        .unwrap();
    }
    od.insert(
        Entry::var(0x2101, "inject_fault_code", DataType::U16, Access::Wo).with_handler(INJECT_TAG),
    )
    .unwrap();
    od
}

impl Drive for SimDrive {
    fn info(&self) -> DriveInfo {
        info()
    }
    fn feedback(&self) -> Feedback {
        Feedback {
            motor_position_inc: self.pos.round() as i64,
            direct_position_inc: (self.pos + self.direct_offset).round() as i64,
            position_from_direct: false,
            motor_velocity_inc_per_s: self.vel,
            velocity_demand_inc_per_s: self.vel,
            torque_permille: 0.0,
            current_permille: 0.0,
            home_switch: self.home_switch_above.is_some_and(|h| self.pos >= h),
            negative_limit_switch: false,
            positive_limit_switch: false,
            drive_fault: self.fault.or(self.injected),
        }
    }
    fn command(&mut self, c: &DriveCommand) {
        self.commands += 1;
        self.last = Some(*c);
        let a = 1.0 - (-self.dt / self.tau).exp();
        if self.stuck {
            self.vel = 0.0;
            return;
        }
        match c.setpoint {
            Setpoint::Disabled => {
                self.vel *= 0.5;
                self.pos += self.vel * self.dt;
            }
            Setpoint::Position { position_inc, .. } => {
                let new = self.pos + (position_inc - self.pos) * a;
                self.vel = (new - self.pos) / self.dt;
                self.pos = new;
            }
            Setpoint::Velocity {
                velocity_inc_per_s, ..
            } => {
                self.vel += (velocity_inc_per_s - self.vel) * a;
                self.pos += self.vel * self.dt;
            }
            Setpoint::Torque { torque_permille } => {
                self.vel += torque_permille * 100.0 * self.dt;
                self.pos += self.vel * self.dt;
            }
        }
    }
    fn read_object(
        &mut self,
        tag: u16,
        _index: u16,
        sub: u8,
        out: &mut [u8],
    ) -> Result<usize, u32> {
        assert_eq!(tag, HANDLER_TAG, "a tag the test drive reads");
        let v = self.params.get(sub as usize).ok_or(0x0609_0011u32)?;
        out[..4].copy_from_slice(&v.to_le_bytes());
        Ok(4)
    }
    fn write_object(&mut self, tag: u16, _index: u16, sub: u8, data: &[u8]) -> Result<(), u32> {
        if tag == INJECT_TAG {
            let code = u16::from_le_bytes([data[0], data[1]]);
            self.injected = (code != 0).then_some(code);
            return Ok(());
        }
        assert_eq!(tag, HANDLER_TAG, "a tag the test drive never registered");
        let v = f32::from_le_bytes(data.try_into().map_err(|_| 0x0607_0010u32)?);
        if !(0.0..=1.0).contains(&v) {
            return Err(if v > 1.0 { 0x0609_0031 } else { 0x0609_0032 });
        }
        *self.params.get_mut(sub as usize).ok_or(0x0609_0011u32)? = v;
        Ok(())
    }
    fn reset_fault(&mut self) -> bool {
        if self.fault_persists || self.injected.is_some() {
            return false;
        }
        self.fault = None;
        true
    }
}

/// A node with LSS: node-ID `node_id` (255: non-configured), LSS serial number `serial`
/// (0x1018:4), boot delay, power-on bit timing, store written by the application or not.
pub fn lss_config(
    node_id: u8,
    serial: u32,
    boot_delay_us: u64,
    bit_timing_index: u8,
    store_external: bool,
) -> NodeConfig {
    let mut od = od_with_handler();
    od.set_default(
        0x1018,
        4,
        drive_protocol::od::DefaultValue::Value(serial as u64),
    )
    .unwrap();
    let mut cfg = NodeConfig::new(node_id, info())
        .with_od(od)
        .with_boot_delay_us(boot_delay_us);
    cfg.lss = Some(drive_protocol::LssConfig {
        bit_timing_index,
        store_external,
    });
    cfg
}

/// A node, its drive and the bus as the master sees it.
pub struct Bench {
    pub node: Node,
    pub drive: SimDrive,
    pub now: u64,
    /// Frames the node sent, oldest first.
    pub tx: Vec<CanFrame>,
}

pub fn f(id: u32, data: &[u8]) -> CanFrame {
    CanFrame::new(id, data)
}

impl Bench {
    pub fn new() -> Bench {
        Bench::with_id(ID)
    }

    pub fn with_id(id: u8) -> Bench {
        Bench::with_config(NodeConfig::new(id, info()).with_od(od_with_handler()))
    }

    /// A bench whose node has a boot delay for its resets; its power-on boot is complete.
    pub fn with_boot_delay(delay_us: u64) -> Bench {
        let cfg = NodeConfig::new(ID, info())
            .with_od(od_with_handler())
            .with_boot_delay_us(delay_us);
        let mut b = Bench::with_config(cfg);
        b.node.finish_boot(0);
        b.drain();
        b
    }

    /// A bench whose node is built from `cfg` (booted at 0).
    pub fn with_config(cfg: NodeConfig) -> Bench {
        let mut node = Node::new(cfg).unwrap();
        node.boot(0);
        let mut b = Bench {
            node,
            drive: SimDrive::default(),
            now: 0,
            tx: Vec::new(),
        };
        b.drain();
        b
    }

    pub fn id(&self) -> u32 {
        self.node.node_id() as u32
    }

    pub fn drain(&mut self) {
        while let Some(f) = self.node.pop_tx() {
            self.tx.push(f);
        }
    }

    pub fn take(&mut self) -> Vec<CanFrame> {
        self.drain();
        std::mem::take(&mut self.tx)
    }

    /// Frames with a given COB-ID taken so far (and removes nothing).
    pub fn sent(&self, id: u32) -> Vec<CanFrame> {
        self.tx.iter().filter(|f| f.id == id).copied().collect()
    }

    pub fn tick(&mut self) {
        self.now = self.now.saturating_add(DT_US);
        self.node.poll(self.now, &mut self.drive);
        self.drain();
    }

    pub fn ticks(&mut self, n: usize) {
        for _ in 0..n {
            self.tick();
        }
    }

    /// Advance time to `t_us` in ticks.
    pub fn run_until(&mut self, t_us: u64) {
        while self.now + DT_US <= t_us {
            self.tick();
        }
    }

    pub fn send(&mut self, fr: CanFrame) -> FrameEvent {
        let e = self.node.handle(&fr, self.now, &mut self.drive);
        self.drain();
        e
    }

    pub fn nmt(&mut self, cs: u8, target: u8) -> FrameEvent {
        self.send(f(0, &[cs, target]))
    }

    pub fn start(&mut self) {
        let id = self.id() as u8;
        self.nmt(1, id);
    }

    pub fn sync(&mut self) -> FrameEvent {
        self.send(f(0x80, &[]))
    }

    /// Send a raw SDO request and return the response frame(s).
    pub fn sdo_raw(&mut self, req: [u8; 8]) -> Vec<CanFrame> {
        self.take();
        self.send(f(0x600 + self.id(), &req));
        let id = 0x580 + self.id();
        self.take().into_iter().filter(|f| f.id == id).collect()
    }

    pub fn sdo_write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), u32> {
        assert!(data.len() <= 4 && !data.is_empty());
        let i = index.to_le_bytes();
        let mut req = [
            0x23 | (((4 - data.len()) as u8) << 2),
            i[0],
            i[1],
            sub,
            0,
            0,
            0,
            0,
        ];
        req[4..4 + data.len()].copy_from_slice(data);
        let r = self.sdo_raw(req);
        assert_eq!(r.len(), 1, "one response to an expedited download");
        let d = r[0].data;
        assert_eq!(&d[1..4], &[i[0], i[1], sub], "multiplexer echoed");
        match d[0] {
            0x60 => Ok(()),
            0x80 => Err(u32::from_le_bytes([d[4], d[5], d[6], d[7]])),
            x => panic!("unexpected response {x:#x}"),
        }
    }

    pub fn w8(&mut self, index: u16, sub: u8, v: u8) -> Result<(), u32> {
        self.sdo_write(index, sub, &[v])
    }
    pub fn w16(&mut self, index: u16, sub: u8, v: u16) -> Result<(), u32> {
        self.sdo_write(index, sub, &v.to_le_bytes())
    }
    pub fn w32(&mut self, index: u16, sub: u8, v: u32) -> Result<(), u32> {
        self.sdo_write(index, sub, &v.to_le_bytes())
    }

    /// Read with expedited or segmented upload.
    pub fn sdo_read(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, u32> {
        let i = index.to_le_bytes();
        let r = self.sdo_raw([0x40, i[0], i[1], sub, 0, 0, 0, 0]);
        assert_eq!(r.len(), 1);
        let d = r[0].data;
        if d[0] == 0x80 {
            return Err(u32::from_le_bytes([d[4], d[5], d[6], d[7]]));
        }
        assert_eq!(&d[1..4], &[i[0], i[1], sub]);
        if d[0] & 0x02 != 0 {
            let n = if d[0] & 1 != 0 {
                4 - ((d[0] >> 2) & 3) as usize
            } else {
                4
            };
            return Ok(d[4..4 + n].to_vec());
        }
        let size = u32::from_le_bytes([d[4], d[5], d[6], d[7]]) as usize;
        let mut out = Vec::new();
        let mut t = 0u8;
        loop {
            let r = self.sdo_raw([0x60 | t, 0, 0, 0, 0, 0, 0, 0]);
            let d = r[0].data;
            if d[0] == 0x80 {
                return Err(u32::from_le_bytes([d[4], d[5], d[6], d[7]]));
            }
            assert_eq!(d[0] & 0x10, t, "toggle");
            let n = 7 - ((d[0] >> 1) & 7) as usize;
            out.extend_from_slice(&d[1..1 + n]);
            if d[0] & 1 != 0 {
                break;
            }
            t ^= 0x10;
        }
        assert_eq!(out.len(), size);
        Ok(out)
    }

    pub fn r32(&mut self, index: u16, sub: u8) -> u32 {
        let v = self.sdo_read(index, sub).expect("read");
        let mut b = [0u8; 4];
        b[..v.len()].copy_from_slice(&v);
        u32::from_le_bytes(b)
    }

    pub fn ri32(&mut self, index: u16, sub: u8) -> i32 {
        let v = self.sdo_read(index, sub).expect("read");
        match v.len() {
            1 => v[0] as i8 as i32,
            2 => i16::from_le_bytes([v[0], v[1]]) as i32,
            _ => i32::from_le_bytes([v[0], v[1], v[2], v[3]]),
        }
    }

    pub fn cw(&mut self, v: u16) {
        self.w16(0x6040, 0, v).unwrap();
    }

    pub fn statusword(&mut self) -> u16 {
        self.r32(0x6041, 0) as u16
    }

    /// Enable operation in `mode` via SDO (shutdown, switch on, enable).
    pub fn enable(&mut self, mode: i8) {
        self.w8(0x6060, 0, mode as u8).unwrap();
        self.cw(0x06);
        self.tick();
        self.cw(0x07);
        self.tick();
        self.cw(0x0F);
        self.tick();
        assert_eq!(self.node.statusword() & 0x6F, 0x27, "operation enabled");
    }

    /// EMCY codes sent so far.
    pub fn emcys(&self) -> Vec<u16> {
        self.sent(0x80 + self.id())
            .iter()
            .map(|f| u16::from_le_bytes([f.data[0], f.data[1]]))
            .collect()
    }
}

/// Every vendor switch on (docs/quirks.md), with parameters that let the cycle run: the
/// switches' hooks (SDO gate and delay queue, controlword latch and hold, SYNC watchdog and
/// lateness, the boot's heartbeats and ready deadline) do not allocate either.
pub fn every_switch() -> drive_protocol::Quirks {
    use drive_protocol::quirks::*;
    Quirks {
        enable_requires_mode: true,
        mode_change_blocked_by_halt: true,
        homing_status_bits_missing: Some(HomingBitsMissing {
            target_reached: true,
            attained: true,
        }),
        homing_method_zero: HomingMethodZero::Ignore,
        bootup_then_heartbeat: Some(BootupThenHeartbeat {
            first_heartbeat_after_bootup_us: 100,
            heartbeat_ms_default: 10,
        }),
        not_ready_after_bootup: Some(NotReadyAfterBootup {
            ready_after_ms: 20,
            initialising_heartbeat_ms: 5,
        }),
        sdo_response_delay: Some(SdoResponseDelay {
            delay_ms: 1,
            late_delay_ms: 3,
            late_every: 4,
        }),
        sdo_first_upload_dropped: Some(SdoFirstUploadDropped {
            objects: ObjectList::parse(&["0x6041:0", "0x1000:0"]).unwrap(),
            count: 2,
        }),
        pdo_remap_lenient: true,
        tpdo_rtr_unsupported: Some(TpdoRtrUnsupported {
            abort_code: 0x0609_0030,
        }),
        controlword_min_hold: Some(ControlwordMinHold { hold_us: 500 }),
        quick_stop_skips_active_state: true,
        sync_watchdog: Some(SyncWatchdog {
            missed_periods: 100.0,
            period_from: WatchdogPeriod::Interpolation,
            modes: [7i8, 8].into_iter().collect(),
            emcy_code: 0x8100,
        }),
        late_sync_statusword_bit15: Some(LateSyncBit15 {
            late_tolerance_us: 200,
        }),
        unmappable_objects: Some(ObjectList::parse(&["0x6077:0"]).unwrap()),
        sdo_silent_objects: Some(ObjectList::parse(&["0x1800-0x1803:5"]).unwrap()),
    }
}
