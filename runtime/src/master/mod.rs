//! The built-in reference CiA 402 master: what a PLC or CNC does on the bus, in a few hundred
//! lines, sans-IO like the node (frames and time in, frames out).
//!
//! It resets the node, configures its PDOs over SDO as CiA 301 prescribes (invalidate, clear,
//! map, count, validate), starts it, produces SYNC and its own heartbeat, takes the drive
//! through the CiA 402 state machine and runs a motion program: profile-position moves, or an
//! interpolator streaming cyclic synchronous positions (what a CNC's interpolator does) or
//! velocities. Every SYNC it records what the drive reported in its TPDOs, so the demo and the
//! scenarios analyse the axis exactly as an external controller would see it: from the wire.
//!
//! Positions are in the drive's user units (uu; by our factor-group default 1 um on a linear
//! axis, 0.001 deg on a rotary one), velocities in uu/s.

pub mod compensation;
pub mod contour;
pub mod line;
pub mod on_bus;
pub mod outer_loop;
pub mod sdo_client;

use crate::bus::CanFrame;
use crate::samples::Sample;
use drive_protocol::wire::{cob, EmcyFrame, Heartbeat, NmtCommand, NmtFrame};
use drive_protocol::Cia402State;
use sdo_client::{SdoClient, SdoResult};
use std::collections::VecDeque;

/// CiA 402 operation modes the master uses (0x6060 values, from the protocol's one registry).
pub use drive_protocol::cia402::mode::value::{
    CSP as MODE_CSP, CST as MODE_CST, CSV as MODE_CSV, PP as MODE_PP, PV as MODE_PV,
};

#[derive(Debug, Clone)]
pub struct MasterConfig {
    /// The drive's node ID.
    pub node_id: u8,
    /// Our own node ID for the heartbeat the drive consumes.
    pub master_id: u8,
    pub sync_period_us: u32,
    /// Our heartbeat period; the drive's consumer time (0x1016) is set to 2.5 periods.
    pub heartbeat_ms: u16,
    /// The drive's heartbeat (0x1017), ms.
    pub drive_heartbeat_ms: u16,
    /// How long any single step (SDO, state change, PP move) may take.
    pub step_timeout_us: u64,
    /// How long one SDO transfer may wait for the drive's answer.
    pub sdo_timeout_us: u64,
    /// The master closes the position loop itself in CSV ([`outer_loop`]); None: it sends
    /// its interpolator's velocity as it is.
    pub position_loop: Option<outer_loop::PositionLoop>,
}

impl Default for MasterConfig {
    fn default() -> Self {
        Self {
            node_id: 5,
            master_id: 0x7F,
            sync_period_us: 1000,
            heartbeat_ms: 100,
            drive_heartbeat_ms: 100,
            step_timeout_us: 2_000_000,
            sdo_timeout_us: 500_000,
            position_loop: None,
        }
    }
}

/// One step of a motion program.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// Select the mode (SDO 0x6060, confirmed by 0x6061) and switch on to OPERATION ENABLED.
    Enable { mode: i8 },
    /// Change the mode while enabled.
    SetMode { mode: i8 },
    /// Profile-position move (PP), absolute, waiting for target reached.
    MoveTo {
        target_uu: i32,
        velocity_uu_s: u32,
        accel_uu_s2: u32,
    },
    /// Cyclic synchronous motion (CSP/CSV): ramp the interpolator's velocity to
    /// `velocity_uu_s` with `accel_uu_s2`, then hold; the step lasts `duration_s` in all.
    Cruise {
        velocity_uu_s: f64,
        accel_uu_s2: f64,
        duration_s: f64,
    },
    /// Wait, still producing SYNC and set-points.
    Dwell { duration_s: f64 },
    /// Expedited SDO download of `len` bytes.
    WriteSdo {
        index: u16,
        sub: u8,
        value: u32,
        len: u8,
    },
    /// Stop sending our heartbeat (to test the drive's heartbeat consumer).
    StopHeartbeat,
    /// Stop producing SYNC.
    StopSync,
    /// Controlword "disable voltage".
    Disable,
}

impl std::fmt::Display for Step {
    /// For people: "cruise at 10000 uu/s (ramp 500000 uu/s², 4 s in all)".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Step::Enable { mode } => write!(f, "enable in {}", mode_short(*mode)),
            Step::SetMode { mode } => write!(f, "switch to {}", mode_short(*mode)),
            Step::MoveTo {
                target_uu,
                velocity_uu_s,
                accel_uu_s2,
            } => write!(
                f,
                "PP move to {target_uu} uu at {velocity_uu_s} uu/s, {accel_uu_s2} uu/s²"
            ),
            Step::Cruise {
                velocity_uu_s,
                accel_uu_s2,
                duration_s,
            } => write!(
                f,
                "cruise at {velocity_uu_s:.0} uu/s (ramp {accel_uu_s2:.0} uu/s², {duration_s} s in all)"
            ),
            Step::Dwell { duration_s } => write!(f, "dwell {duration_s} s"),
            Step::WriteSdo {
                index,
                sub,
                value,
                len,
            } => write!(f, "write {}", sdo_value_text(*index, *sub, *value, *len)),
            Step::StopHeartbeat => write!(f, "stop the master heartbeat"),
            Step::StopSync => write!(f, "stop SYNC"),
            Step::Disable => write!(f, "disable voltage"),
        }
    }
}

/// The dictionary of our drive as the master names its objects: the standard objects and
/// the emulator's at their default base (linear names).
fn reference_dictionary() -> &'static drive_protocol::od::ObjectDictionary {
    static OD: std::sync::OnceLock<drive_protocol::od::ObjectDictionary> =
        std::sync::OnceLock::new();
    OD.get_or_init(|| {
        let info = drive_protocol::DriveInfo {
            encoder_increments_per_rev: 1,
            gear_motor_revs: 1,
            gear_shaft_revs: 1,
            feed_user_units: 1,
            feed_shaft_revs: 1,
            rated_torque_mnm: 1,
            rated_current_ma: 1,
            max_motor_speed_rpm: 1,
            rotary: false,
        };
        let mut od = drive_protocol::od::ObjectDictionary::standard(&info);
        // the standard dictionary has nothing at the default base: this cannot collide
        let _ =
            crate::drive::objects::register(&mut od, crate::drive::objects::DEFAULT_BASE, false);
        od
    })
}

/// "0x2000 sub 0 (backlash_mm) = 0.05": an SDO value decoded with the object's data type from
/// our drive's dictionary (REAL32 as a number, signed as signed), raw when the object is
/// unknown.
pub fn sdo_value_text(index: u16, sub: u8, value: u32, len: u8) -> String {
    let od = reference_dictionary();
    let (name, shown) = match od.get(index, sub) {
        Some((_, e)) => {
            let raw = e.decode(&value.to_le_bytes()[..usize::from(len).clamp(1, 4)]);
            let v = e
                .number(raw)
                .map_or_else(|| format!("{value}"), |n| n.to_string());
            (format!(" ({})", e.name), v)
        }
        None => (
            String::new(),
            format!("{value:#0w$X}", w = 2 + 2 * usize::from(len)),
        ),
    };
    format!("{index:#06X} sub {sub}{name} = {shown}")
}

/// An EMCY message seen on the bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Emcy {
    pub t_us: u64,
    pub node_id: u8,
    pub code: u16,
    pub error_register: u8,
}

#[derive(Debug, Clone, PartialEq)]
enum Phase {
    Reset,
    WaitBoot { since_us: u64 },
    Configure(usize),
    Program(usize),
    Done,
    Failed(String),
}

/// Where a program step is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
enum Stage {
    /// Nothing done yet.
    #[default]
    Start,
    /// Enable / SetMode: 0x6060 written, waiting for 0x6061 to show the mode.
    WaitModeDisplay,
    /// Enable: walking the state machine to OPERATION ENABLED.
    SwitchOn,
    /// Enable / SetMode: reached; report and go on.
    Reached,
    /// MoveTo: writing profile parameter `k` (0x6081, 0x6083, 0x6084).
    PpParameter(usize),
    /// MoveTo: parameters written; give the new set-point (controlword bit 4).
    PpNewSetpoint,
    /// MoveTo: waiting for the set-point acknowledge (statusword bit 12).
    PpWaitAcknowledge,
    /// MoveTo: acknowledge seen, bit 4 cleared; waiting for target reached (bit 10).
    PpWaitTarget,
    /// Cruise / Dwell: announced, running for its duration.
    Running,
}

/// Per-step progress.
#[derive(Debug, Clone, Copy, Default)]
struct StepState {
    started_us: u64,
    stage: Stage,
    sdo_sent: bool,
}

/// A CiA 402 mode of operation (0x6060 / 0x6061) by name, e.g. "CSP (cyclic synchronous
/// position)" (the protocol's mode registry says it).
pub fn mode_name(mode: i8) -> &'static str {
    drive_protocol::cia402::mode::describe(mode)
}

/// The short name of a mode: "CSP", "PP", "no mode"; a mode without a name is said with its
/// kind and number, e.g. "reserved mode 5", "manufacturer-specific mode -1".
pub fn mode_short(mode: i8) -> String {
    let n = mode_name(mode);
    match n.split_once(" (") {
        Some((short, _)) => short.to_string(),
        None if mode == 0 => n.to_string(),
        None => format!("{n} {mode}"),
    }
}

/// An NMT state from its heartbeat code, e.g. "OPERATIONAL".
pub fn nmt_name(code: u8) -> &'static str {
    match code {
        0x00 => "BOOT-UP",
        0x04 => "STOPPED",
        0x05 => "OPERATIONAL",
        0x7F => "PRE-OPERATIONAL",
        _ => "UNKNOWN",
    }
}

/// What an EMCY code means: CiA 301/402's table, and this drive's own warning 0xFF01.
pub fn emcy_meaning(code: u16) -> drive_protocol::EmcyMeaning {
    use drive_protocol::{emcy_code::meaning, EmcyMeaning};
    match code {
        crate::drive::objects::EMCY_BACKLASH => EmcyMeaning::with(
            "backlash limit cycle found by the drive's detector (a warning: the drive keeps running)",
            "the axis is worn: see `drive-emu analyze` or the panel for the frequency and amplitude",
        ),
        _ => meaning(code),
    }
}

/// The short name of an EMCY code, for lists (see [`emcy_meaning`]).
pub fn emcy_name(code: u16) -> &'static str {
    emcy_meaning(code).name
}

/// `0x8130 (heartbeat / life guard error ...: make the master send ...)`, for messages that
/// stop a run.
pub fn emcy_explained(code: u16) -> String {
    let m = emcy_meaning(code);
    format!("{code:#06X} ({}: {})", m.name, m.action)
}

/// The name of the CiA 402 state a statusword shows (CiA 402 statusword masks), for
/// messages; `UNKNOWN` for a pattern that is no state. Compare [`Cia402State`]s, not names.
pub fn state_name(sw: u16) -> &'static str {
    Cia402State::from_statusword(sw).map_or("UNKNOWN", Cia402State::name)
}

/// The PDO configuration the master writes: (index, sub, value, len).
fn pdo_configuration(node: u8, sync_period_us: u32, cfg: &MasterConfig) -> Vec<(u16, u8, u32, u8)> {
    let n = u32::from(node);
    let mut w = vec![
        (0x1017, 0, u32::from(cfg.drive_heartbeat_ms), 2),
        (
            0x1016,
            1,
            (u32::from(cfg.master_id) << 16) | (u32::from(cfg.heartbeat_ms) * 5 / 2),
            4,
        ),
        (0x1006, 0, sync_period_us, 4),
        // Interpolation period for CSP: value * 10^index s.
        (0x60C2, 1, sync_period_us / 1000, 1),
        (0x60C2, 2, (-3i8) as u8 as u32, 1),
    ];
    let mut map = |comm: u16, mapping: u16, cob: u32, entries: &[u32]| {
        w.push((comm, 1, cob | 0x8000_0000, 4));
        w.push((comm, 2, 1, 1)); // synchronous, every SYNC
        w.push((mapping, 0, 0, 1));
        for (i, e) in entries.iter().enumerate() {
            w.push((mapping, i as u8 + 1, *e, 4));
        }
        w.push((mapping, 0, entries.len() as u32, 1));
        w.push((comm, 1, cob, 4));
    };
    // RPDO1: controlword + target position; RPDO2: target velocity + target torque.
    map(0x1400, 0x1600, 0x200 + n, &[0x6040_0010, 0x607A_0020]);
    map(0x1401, 0x1601, 0x300 + n, &[0x60FF_0020, 0x6071_0010]);
    // TPDO1: statusword + position actual; TPDO2: velocity + torque actual + mode display;
    // TPDO3: direct encoder + current; TPDO4: following error.
    map(0x1800, 0x1A00, 0x180 + n, &[0x6041_0010, 0x6064_0020]);
    map(
        0x1801,
        0x1A01,
        0x280 + n,
        &[0x606C_0020, 0x6077_0010, 0x6061_0008],
    );
    map(0x1802, 0x1A02, 0x380 + n, &[0x60E4_0120, 0x6078_0010]);
    map(0x1803, 0x1A03, 0x480 + n, &[0x60F4_0020]);
    w
}

/// The reference master for one drive.
pub struct Master {
    cfg: MasterConfig,
    program: Vec<Step>,
    configuration: Vec<(u16, u8, u32, u8)>,
    phase: Phase,
    step: StepState,
    sdo: SdoClient,
    tx: VecDeque<CanFrame>,
    next_sync_us: u64,
    sync_on: bool,
    next_heartbeat_us: u64,
    heartbeat_on: bool,
    /// The wall clock on a real bus (`set_wall_us`): the heartbeat a drive supervises in real
    /// milliseconds goes by it. `None` offline: the master's own clock.
    wall_us: Option<u64>,
    controlword: u16,
    /// Interpolator (CSP/CSV): set-point position and velocity.
    target_uu: f64,
    velocity_uu_s: f64,
    target_torque: i16,
    mode: i8,
    /// The position loop closed by the master in CSV, if configured.
    outer: Option<outer_loop::OuterLoop>,
    latest: Sample,
    have_actual: bool,
    samples: Vec<Sample>,
    emcys: Vec<Emcy>,
    log: Vec<(u64, String)>,
}

impl Master {
    pub fn new(cfg: MasterConfig, program: Vec<Step>) -> Self {
        let configuration = pdo_configuration(cfg.node_id, cfg.sync_period_us, &cfg);
        let sdo = SdoClient::new(cfg.node_id, cfg.sdo_timeout_us);
        let outer = cfg.position_loop.map(outer_loop::OuterLoop::new);
        Self {
            outer,
            cfg,
            program,
            configuration,
            phase: Phase::Reset,
            step: StepState::default(),
            sdo,
            tx: VecDeque::new(),
            next_sync_us: 0,
            sync_on: false,
            next_heartbeat_us: 0,
            heartbeat_on: false,
            wall_us: None,
            controlword: 0,
            target_uu: 0.0,
            velocity_uu_s: 0.0,
            target_torque: 0,
            mode: 0,
            latest: Sample::default(),
            have_actual: false,
            samples: Vec::new(),
            emcys: Vec::new(),
            log: Vec::new(),
        }
    }

    pub fn config(&self) -> &MasterConfig {
        &self.cfg
    }
    pub fn samples(&self) -> &[Sample] {
        &self.samples
    }
    pub fn emcys(&self) -> &[Emcy] {
        &self.emcys
    }
    /// Timestamped messages about what the master did (for the demo's narration).
    pub fn log(&self) -> &[(u64, String)] {
        &self.log
    }
    pub fn latest(&self) -> &Sample {
        &self.latest
    }
    pub fn finished(&self) -> bool {
        matches!(self.phase, Phase::Done | Phase::Failed(_))
    }
    pub fn error(&self) -> Option<&str> {
        match &self.phase {
            Phase::Failed(e) => Some(e),
            _ => None,
        }
    }
    /// Index of the program step being executed (program.len() when done).
    pub fn current_step(&self) -> usize {
        match self.phase {
            Phase::Program(i) => i,
            Phase::Done => self.program.len(),
            _ => 0,
        }
    }

    pub fn pop_tx(&mut self) -> Option<CanFrame> {
        self.tx.pop_front()
    }

    fn say(&mut self, now_us: u64, msg: impl Into<String>) {
        self.log.push((now_us, msg.into()));
    }

    fn fail(&mut self, now_us: u64, msg: String) {
        self.say(now_us, format!("FAILED: {msg}"));
        self.phase = Phase::Failed(msg);
    }

    /// Feed a frame received from the bus.
    pub fn handle(&mut self, frame: &CanFrame, now_us: u64) {
        if frame.extended || frame.rtr {
            return;
        }
        let n = u32::from(self.cfg.node_id);
        let d = &frame.data;
        let len = usize::from(frame.len);
        let i32_at = |o: usize| i32::from_le_bytes([d[o], d[o + 1], d[o + 2], d[o + 3]]);
        let i16_at = |o: usize| i16::from_le_bytes([d[o], d[o + 1]]);
        match frame.id {
            id if id == cob::SDO_TX + n => {
                self.sdo.handle(frame);
            }
            id if id == cob::HEARTBEAT + n
                && Heartbeat::parse(frame.payload()).is_some_and(|h| h.is_bootup()) =>
            {
                if let Phase::WaitBoot { .. } = self.phase {
                    self.say(now_us, "drive booted (boot-up message)");
                    self.phase = Phase::Configure(0);
                }
            }
            id if id == cob::EMCY + n && len >= 3 => {
                // A short EMCY (3..7 bytes) from a sloppy producer still counts; pad it.
                let mut p = [0u8; 8];
                p[..len.min(8)].copy_from_slice(&d[..len.min(8)]);
                if let Some(e) = EmcyFrame::parse(&p) {
                    self.emcys.push(Emcy {
                        t_us: now_us,
                        node_id: self.cfg.node_id,
                        code: e.code,
                        error_register: e.register,
                    })
                }
            }
            id if id == 0x180 + n && len == 6 => {
                self.latest.statusword = u16::from_le_bytes([d[0], d[1]]);
                self.latest.position_uu = i32_at(2);
                self.have_actual = true;
            }
            id if id == 0x280 + n && len == 7 => {
                self.latest.velocity_uu_s = i32_at(0);
                self.latest.torque_permille = i16_at(4);
                self.latest.mode_display = d[6] as i8;
            }
            id if id == 0x380 + n && len == 6 => {
                self.latest.direct_position_uu = i32_at(0);
                self.latest.current_permille = i16_at(4);
            }
            id if id == 0x480 + n && len == 4 => {
                self.latest.following_error_uu = i32_at(0);
            }
            _ => {}
        }
    }

    fn sdo_step(&mut self, now_us: u64, index: u16, sub: u8, value: u32, len: u8) -> Option<bool> {
        if !self.step.sdo_sent {
            let f = self.sdo.write(now_us, index, sub, value, len);
            self.tx.push_back(f);
            self.step.sdo_sent = true;
            return None;
        }
        match self.sdo.poll(now_us)? {
            SdoResult::Written | SdoResult::Read(_) => Some(true),
            SdoResult::Aborted(code) => {
                self.fail(
                    now_us,
                    format!("SDO write {index:04X}sub{sub} = {value} aborted: {code:#010X}"),
                );
                Some(false)
            }
            SdoResult::TimedOut => {
                self.fail(now_us, format!("SDO write {index:04X}sub{sub} timed out"));
                Some(false)
            }
        }
    }

    fn next_step(&mut self, now_us: u64, i: usize) {
        self.step = StepState {
            started_us: now_us,
            ..Default::default()
        };
        self.phase = if i + 1 >= self.program.len() {
            self.say(now_us, "program finished");
            Phase::Done
        } else {
            Phase::Program(i + 1)
        };
    }

    /// Advance by time: run the program, produce SYNC, RPDOs and heartbeat.
    /// On a real bus: the wall clock (us, any origin), by which the master's heartbeat goes
    /// (a drive supervises it in real milliseconds, CiA 301), while its own clock (`now_us` of
    /// `poll` / `handle`) counts its SYNC cycles so that its time-outs do not depend on the
    /// host's load.
    pub fn set_wall_us(&mut self, wall_us: u64) {
        self.wall_us = Some(wall_us);
    }

    pub fn poll(&mut self, now_us: u64) {
        match self.phase.clone() {
            Phase::Reset => {
                self.nmt(NmtCommand::ResetCommunication);
                self.say(
                    now_us,
                    format!("NMT reset communication of node {}", self.cfg.node_id),
                );
                self.phase = Phase::WaitBoot { since_us: now_us };
            }
            Phase::WaitBoot { since_us } => {
                if now_us - since_us > self.cfg.step_timeout_us {
                    self.fail(now_us, "no boot-up message from the drive".into());
                }
            }
            Phase::Configure(k) => {
                if k >= self.configuration.len() {
                    self.nmt(NmtCommand::StartRemoteNode);
                    self.say(now_us, "PDOs mapped; NMT start; SYNC and heartbeat on");
                    self.sync_on = true;
                    self.heartbeat_on = true;
                    self.next_sync_us = now_us;
                    self.next_heartbeat_us = self.wall_us.unwrap_or(now_us);
                    self.step = StepState {
                        started_us: now_us,
                        ..Default::default()
                    };
                    self.phase = if self.program.is_empty() {
                        Phase::Done
                    } else {
                        Phase::Program(0)
                    };
                } else {
                    let (index, sub, value, len) = self.configuration[k];
                    if let Some(true) = self.sdo_step(now_us, index, sub, value, len) {
                        self.step.sdo_sent = false;
                        self.phase = Phase::Configure(k + 1);
                    }
                }
            }
            Phase::Program(i) => {
                let step = self.program[i].clone();
                self.run_step(now_us, i, &step);
            }
            Phase::Done | Phase::Failed(_) => {}
        }
        self.produce(now_us);
    }

    fn timed_out(&self, now_us: u64) -> bool {
        now_us - self.step.started_us > self.cfg.step_timeout_us
    }

    /// Advance program step `i`: one `match` arm per [`Step`] kind; the two with a stage
    /// sequence of their own in a function each ([`Self::step_enable`],
    /// [`Self::step_move_to`]).
    fn run_step(&mut self, now_us: u64, i: usize, step: &Step) {
        match *step {
            Step::Enable { mode } => self.step_enable(now_us, i, step, mode, true),
            Step::SetMode { mode } => self.step_enable(now_us, i, step, mode, false),
            Step::MoveTo {
                target_uu,
                velocity_uu_s,
                accel_uu_s2,
            } => self.step_move_to(now_us, i, target_uu, velocity_uu_s, accel_uu_s2),
            Step::Cruise { duration_s, .. } | Step::Dwell { duration_s } => {
                if self.step.stage == Stage::Start {
                    self.step.stage = Stage::Running;
                    self.say(now_us, step.to_string());
                }
                if (now_us - self.step.started_us) as f64 >= duration_s * 1e6 {
                    self.next_step(now_us, i);
                }
            }
            Step::WriteSdo {
                index,
                sub,
                value,
                len,
            } => {
                if let Some(true) = self.sdo_step(now_us, index, sub, value, len) {
                    self.say(
                        now_us,
                        format!("wrote {}", sdo_value_text(index, sub, value, len)),
                    );
                    self.next_step(now_us, i);
                }
            }
            Step::StopHeartbeat => {
                self.heartbeat_on = false;
                self.say(now_us, "master heartbeat stopped");
                self.next_step(now_us, i);
            }
            Step::StopSync => {
                self.sync_on = false;
                self.say(now_us, "SYNC stopped");
                self.next_step(now_us, i);
            }
            Step::Disable => {
                self.controlword = 0x00;
                self.velocity_uu_s = 0.0;
                self.next_step(now_us, i);
            }
        }
    }

    /// `enable` / `set_mode` (`enable` false): the mode written and seen in its display, then
    /// (enable) fault reset, shutdown, switch on, enable operation; a timeout fails the step.
    fn step_enable(&mut self, now_us: u64, i: usize, step: &Step, mode: i8, enable: bool) {
        let sw = self.latest.statusword;
        match self.step.stage {
            Stage::Start => {
                if let Some(true) = self.sdo_step(now_us, 0x6060, 0, mode as u8 as u32, 1) {
                    self.mode = mode;
                    self.step.stage = Stage::WaitModeDisplay;
                }
            }
            Stage::WaitModeDisplay if self.latest.mode_display == mode && self.have_actual => {
                // Start from where the axis is, so enabling never jumps.
                self.target_uu = f64::from(self.latest.position_uu);
                self.velocity_uu_s = 0.0;
                self.step.stage = if enable {
                    Stage::SwitchOn
                } else {
                    Stage::Reached
                };
            }
            Stage::SwitchOn => {
                // Fault reset first if needed, then shutdown, switch on, enable.
                let state = Cia402State::from_statusword(sw);
                self.controlword = match state {
                    Some(Cia402State::Fault) => {
                        if self.controlword & 0x80 != 0 {
                            0x00
                        } else {
                            0x80
                        }
                    }
                    Some(Cia402State::SwitchOnDisabled) => 0x06,
                    Some(Cia402State::ReadyToSwitchOn) => 0x07,
                    Some(Cia402State::SwitchedOn) => 0x0F,
                    Some(Cia402State::OperationEnabled) => {
                        self.step.stage = Stage::Reached;
                        0x0F
                    }
                    _ => self.controlword,
                };
                if state != Some(Cia402State::OperationEnabled) {
                    self.target_uu = f64::from(self.latest.position_uu);
                }
            }
            Stage::Reached => {
                self.say(
                    now_us,
                    format!("drive in {} in {}", state_name(sw), mode_short(self.mode)),
                );
                self.next_step(now_us, i);
                return;
            }
            _ => {}
        }
        if self.timed_out(now_us) {
            self.fail(
                now_us,
                format!(
                    "{step} not reached: statusword {sw:#06X} ({}), mode display {}",
                    state_name(sw),
                    mode_short(self.latest.mode_display)
                ),
            );
        }
    }

    /// `move_to`: the profile parameters written by SDO (0x6081, 0x6083, 0x6084), the new
    /// set-point handshake (bit 4, acknowledge bit 12), then target reached (bit 10); a
    /// timeout fails the step with where the axis stood.
    fn step_move_to(
        &mut self,
        now_us: u64,
        i: usize,
        target_uu: i32,
        velocity_uu_s: u32,
        accel_uu_s2: u32,
    ) {
        let sw = self.latest.statusword;
        let sdo = [
            (0x6081, velocity_uu_s),
            (0x6083, accel_uu_s2),
            (0x6084, accel_uu_s2),
        ];
        match self.step.stage {
            Stage::Start | Stage::PpParameter(_) => {
                let k = match self.step.stage {
                    Stage::PpParameter(k) => k,
                    _ => 0,
                };
                let (idx, v) = sdo[k];
                if let Some(true) = self.sdo_step(now_us, idx, 0, v, 4) {
                    self.step.sdo_sent = false;
                    self.step.stage = if k + 1 < sdo.len() {
                        Stage::PpParameter(k + 1)
                    } else {
                        Stage::PpNewSetpoint
                    };
                }
            }
            Stage::PpNewSetpoint => {
                self.target_uu = f64::from(target_uu);
                self.controlword = 0x0F | 0x10; // new set-point
                self.step.stage = Stage::PpWaitAcknowledge;
            }
            Stage::PpWaitAcknowledge if sw & 0x1000 != 0 => {
                self.controlword = 0x0F; // acknowledge seen: clear bit 4
                self.step.stage = Stage::PpWaitTarget;
            }
            Stage::PpWaitTarget if sw & 0x1000 == 0 && sw & 0x0400 != 0 => {
                self.say(now_us, format!("PP move to {target_uu} uu: target reached"));
                self.next_step(now_us, i);
                return;
            }
            _ => {}
        }
        if self.timed_out(now_us) {
            // Where the axis stood: a worn axis hunts around the target, wider than
            // the drive's position window 0x6067, and never sets bit 10.
            let at = self.samples.last().map_or(String::new(), |s| {
                format!(
                    " in {:.1} s: position {} uu, {} uu off, statusword {:#06X}",
                    self.cfg.step_timeout_us as f64 * 1e-6,
                    s.position_uu,
                    i64::from(s.position_uu) - i64::from(target_uu),
                    s.statusword
                )
            });
            self.fail(
                now_us,
                format!("PP move to {target_uu} uu: target not reached{at}"),
            );
        }
    }

    /// Commanded interpolator velocity for the current step, with its ramp rate.
    fn interpolator_command(&self) -> Option<(f64, f64)> {
        match self.phase {
            Phase::Program(i) => match self.program[i] {
                Step::Cruise {
                    velocity_uu_s,
                    accel_uu_s2,
                    ..
                } => Some((velocity_uu_s, accel_uu_s2)),
                _ => None,
            },
            _ => None,
        }
    }

    fn produce(&mut self, now_us: u64) {
        let n = u32::from(self.cfg.node_id);
        let hb_now = self.wall_us.unwrap_or(now_us);
        if self.heartbeat_on && hb_now >= self.next_heartbeat_us {
            let hb = Heartbeat { state: 0x05 };
            self.tx.push_back(CanFrame::new(
                cob::HEARTBEAT + u32::from(self.cfg.master_id),
                &hb.emit(),
            ));
            // on the period's grid; after a stall, one heartbeat and on from now
            let period = u64::from(self.cfg.heartbeat_ms) * 1000;
            self.next_heartbeat_us = (self.next_heartbeat_us + period).max(hb_now);
        }
        if !(self.sync_on && now_us >= self.next_sync_us) {
            return;
        }
        let dt = f64::from(self.cfg.sync_period_us) * 1e-6;
        self.next_sync_us += u64::from(self.cfg.sync_period_us);
        // The interpolator: ramp towards the commanded velocity, integrate the position.
        if let Some((v_cmd, accel)) = self.interpolator_command() {
            let dv = (v_cmd - self.velocity_uu_s).clamp(-accel * dt, accel * dt);
            self.velocity_uu_s += dv;
        }
        if self.mode == MODE_CSP || self.mode == MODE_CSV {
            self.target_uu += self.velocity_uu_s * dt;
        }
        // Record what the drive reported for the previous cycle, with the set-point it had.
        let mut s = self.latest;
        s.t_s = Sample::t_s_of_us(now_us);
        s.target_uu = self.target_uu;
        s.setpoint_velocity_uu_s = self.velocity_uu_s;
        // The master's own position loop (CSV): the velocity it sends answers the position
        // the drive reported; its reference is the set position.
        let mut velocity_cmd = self.velocity_uu_s;
        if let Some(ol) = self.outer.as_mut() {
            let x = match ol.config.encoder {
                outer_loop::LoopEncoder::Direct => self.latest.direct_position_uu,
                outer_loop::LoopEncoder::Motor => self.latest.position_uu,
            };
            let enabled = self.mode == MODE_CSV
                && Cia402State::from_statusword(self.latest.statusword)
                    == Some(Cia402State::OperationEnabled);
            velocity_cmd = ol.command(self.velocity_uu_s, dt, f64::from(x), enabled);
            if let Some(r) = ol.reference_uu() {
                s.target_uu = r;
            }
        }
        self.samples.push(s);

        let pos = (self.target_uu.round() as i64).clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        let mut r1 = [0u8; 6];
        r1[..2].copy_from_slice(&self.controlword.to_le_bytes());
        r1[2..].copy_from_slice(&pos.to_le_bytes());
        self.tx.push_back(CanFrame::new(0x200 + n, &r1));
        let vel = velocity_cmd.round() as i32;
        let mut r2 = [0u8; 6];
        r2[..4].copy_from_slice(&vel.to_le_bytes());
        r2[4..].copy_from_slice(&self.target_torque.to_le_bytes());
        self.tx.push_back(CanFrame::new(0x300 + n, &r2));
        self.tx.push_back(CanFrame::new(cob::SYNC, &[]));
    }

    fn nmt(&mut self, command: NmtCommand) {
        let f = NmtFrame {
            command,
            node: self.cfg.node_id,
        };
        self.tx.push_back(CanFrame::new(cob::NMT, &f.emit()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_code_the_drive_raises_is_explained() {
        use crate::drive::axis_drive as ad;
        for code in [
            ad::ERROR_SENSOR,
            ad::ERROR_OVERCURRENT,
            ad::ERROR_MOTOR_I2T,
            ad::ERROR_OVERSPEED,
            ad::ERROR_POSITION_RANGE,
            ad::ERROR_PHYSICS,
            crate::drive::objects::EMCY_BACKLASH,
            0x8130, // heartbeat consumer (drive_protocol's node)
        ] {
            let text = emcy_explained(code);
            assert!(text.starts_with(&format!("{code:#06X} (")), "{text}");
            assert!(
                !text.contains("see the drive's manual"),
                "{code:#06X}: {text}"
            );
        }
        assert!(emcy_name(0xFF01).contains("backlash"));
        assert!(emcy_explained(0xFF77).contains("manufacturer-specific"));
    }

    #[test]
    fn statusword_decoding_follows_the_standard_masks() {
        assert_eq!(state_name(0x0250), "SWITCH ON DISABLED");
        assert_eq!(state_name(0x0231), "READY TO SWITCH ON");
        assert_eq!(state_name(0x0233), "SWITCHED ON");
        assert_eq!(state_name(0x0237), "OPERATION ENABLED");
        assert_eq!(state_name(0x0217), "QUICK STOP ACTIVE");
        assert_eq!(state_name(0x0208), "FAULT");
        assert_eq!(state_name(0x021F), "FAULT REACTION ACTIVE");
    }

    #[test]
    fn pdo_configuration_follows_the_cia301_remap_order() {
        let w = pdo_configuration(5, 1000, &MasterConfig::default());
        let pos = |e: (u16, u8, u32, u8)| w.iter().position(|x| *x == e).unwrap();
        // TPDO1: invalidate, clear, map, count, validate.
        let inval = pos((0x1800, 1, 0x8000_0185, 4));
        let clear = pos((0x1A00, 0, 0, 1));
        let entry = pos((0x1A00, 1, 0x6041_0010, 4));
        let count = pos((0x1A00, 0, 2, 1));
        let valid = pos((0x1800, 1, 0x185, 4));
        assert!(inval < clear && clear < entry && entry < count && count < valid);
    }

    #[test]
    fn master_starts_with_reset_and_waits_for_boot() {
        let mut m = Master::new(MasterConfig::default(), vec![]);
        m.poll(0);
        let f = m.pop_tx().unwrap();
        assert_eq!((f.id, f.len, f.data[0], f.data[1]), (0, 2, 0x82, 5));
        m.poll(3_000_000);
        assert!(m.error().unwrap().contains("boot-up"));
    }
}
