//! CiA 402 drive profile: device control (state machine, controlword, statusword), the modes
//! of operation (one file each), the factor group and the motion generators, and following
//! error monitoring. Everything runs once per tick in `Cia402::step` on the object store.
//!
//! Public: [`mode`] (0x6060 values), [`State`] (also `drive_protocol::Cia402State`),
//! [`controlword`] and [`statusword`] bits; the rest is the node's inside.

pub mod controlword;
mod csp;
mod cst;
mod csv;
pub(crate) mod factor;
mod hm;
mod ip;
pub mod mode;
pub(crate) mod objects;
mod pp;
pub(crate) mod profile;
mod pt;
mod pv;
pub(crate) mod state_machine;
pub mod statusword;
mod writes;

use crate::drive::{Drive, DriveCommand, Feedback, Setpoint};
use crate::od::Store;
use crate::quirks::Cia402Quirks;
use controlword::{BIT_FAULT_RESET, BIT_HALT};
use factor::{sat_i32, Factor};
pub use factor::{
    SiUnit, SI_DEGREE, SI_HOUR, SI_METRE, SI_MINUTE, SI_RADIAN, SI_REVOLUTION, SI_SECOND,
};
use objects as o;
use profile::Axis;
pub use state_machine::State;
use statusword as sw;
pub(crate) use writes::register_writes;

/// EMCY / 0x603F code for a following error.
pub(crate) const EMCY_FOLLOWING_ERROR: u16 = 0x8611;

/// Large finite acceleration used for "0 = no limit".
const NO_LIMIT_ACC: f64 = 1e15;

/// A condition that must hold for a time before it counts (window times).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct TimedWindow {
    since: Option<u64>,
}

impl TimedWindow {
    pub fn update(&mut self, cond: bool, now_us: u64, time_ms: u32) -> bool {
        if !cond {
            self.since = None;
            return false;
        }
        let s = *self.since.get_or_insert(now_us);
        now_us.saturating_sub(s) >= time_ms as u64 * 1000
    }
}

/// What a mode produced this tick.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ModeOut {
    pub setpoint: Setpoint,
    pub target_reached: bool,
    pub oms12: bool,
    pub oms13: bool,
    pub limit: bool,
    /// Following error is monitored (closed position loop on our demand).
    pub position_mode: bool,
}

impl Default for ModeOut {
    fn default() -> Self {
        ModeOut {
            setpoint: Setpoint::Disabled,
            target_reached: false,
            oms12: false,
            oms13: false,
            limit: false,
            position_mode: false,
        }
    }
}

/// Everything a mode needs for one tick.
pub(crate) struct Ctx<'a> {
    pub store: &'a mut Store,
    pub fb: &'a Feedback,
    pub f: Factor,
    /// Increment value that corresponds to user position 0.
    pub origin: f64,
    pub act_inc: f64,
    pub act_vel: f64,
    pub now: u64,
    pub dt: f64,
    pub cw: u16,
    /// Rising edges of the controlword this tick: against the previous tick's, and those
    /// written and overwritten since (latched when written).
    pub rising: u16,
    pub halt: bool,
    pub halt_dec: f64,
    /// Motor-encoder increments per motor revolution the drive runs with (0x608F, a
    /// placeholder replaced: `od::placeholders::running_factor_group`).
    pub inc_per_motor_rev: f64,
    pub axis: Axis,
    /// Set by homing when the home position is found.
    pub new_origin: Option<f64>,
}

impl Ctx<'_> {
    pub fn to_uu_pos(&self, inc: f64) -> f64 {
        self.f.to_uu(inc - self.origin)
    }
    pub fn to_inc_pos(&self, uu: f64) -> f64 {
        self.f.to_inc(uu) + self.origin
    }
    /// Clamp a user-unit target to 0x607D. Inactive when min >= max or when both are at the
    /// ends of the I32 range (the default: positions may wrap).
    pub fn clamp_sw_limits(&self, uu: f64) -> (f64, bool) {
        let lo_raw = self.store.i32(o::SW_LIMIT_MIN);
        let hi_raw = self.store.i32(o::SW_LIMIT_MAX);
        let (lo, hi) = (lo_raw as f64, hi_raw as f64);
        if lo < hi && !(lo_raw == i32::MIN && hi_raw == i32::MAX) {
            let c = uu.clamp(lo, hi);
            (c, c != uu)
        } else {
            (uu, false)
        }
    }
    /// A velocity in user units/s limited by 0x607F and 0x6080, in increments/s.
    pub fn vel_limit(&self, v_uu: f64) -> f64 {
        let v = v_uu.min(self.store.u32(o::MAX_PROFILE_VEL) as f64);
        let inc = self.f.vel_to_inc(v);
        let motor = max_motor_inc_per_s(self.store, self.inc_per_motor_rev);
        if motor > 0.0 {
            inc.min(motor)
        } else {
            inc
        }
    }
    /// An acceleration object in increments/s^2 (0 = no limit).
    pub fn acc(&self, row: usize) -> f64 {
        let a = self.store.u32(row);
        if a == 0 {
            NO_LIMIT_ACC
        } else {
            self.f.acc_to_inc(a as f64)
        }
    }
}

fn max_motor_inc_per_s(store: &Store, inc_per_motor_rev: f64) -> f64 {
    store.u32(o::MAX_MOTOR_SPEED) as f64 / 60.0 * inc_per_motor_rev
}

/// What the node hands a tick besides the store and the drive's feedback: the time of the
/// latest SYNC since the previous tick, the CSP interpolation period (0 = none), and the
/// controlword to act on: its level and the rising edges written since the last tick
/// (`quirks::ControlwordLatch`).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct TickControl {
    /// Time of the latest SYNC since the previous tick.
    pub sync_at: Option<u64>,
    /// The CSP interpolation period, us (0 = none).
    pub csp_period_us: u64,
    /// The controlword (0x6040, or with a hold time the last value that stood long enough).
    pub level: u16,
    /// Rising edges of bits 7 and 4 written since the last tick.
    pub latched: u16,
}

/// Results of one tick the node reacts to.
#[derive(Clone, Copy, Debug)]
pub(crate) struct StepOut {
    pub command: DriveCommand,
    /// A fault was entered this tick with this code (send EMCY).
    pub new_fault: Option<u16>,
    /// A fault reset succeeded (clear EMCY errors).
    pub fault_cleared: bool,
}

/// The CiA 402 layer of one node.
#[derive(Clone, Debug)]
pub(crate) struct Cia402 {
    pub state: State,
    prev_cw: u16,
    pub mode_display: i8,
    axis: Axis,
    origin: f64,
    factor: Factor,
    pp: pp::Pp,
    pv: pv::Pv,
    pt: pt::Pt,
    hm: hm::Hm,
    csp: csp::Csp,
    ip: ip::Ip,
    pending_fault: Option<u16>,
    fault_code: u16,
    fe_timer: TimedWindow,
    fe_flag: bool,
    last_now: Option<u64>,
    /// A local quick stop (communication loss) blocks transition 16 until the master has
    /// sent a quick stop itself.
    local_qs: bool,
    /// A communication loss whose reaction (0x6007 = 1) is a fault is still present (the
    /// node sets it each tick): a fault reset is refused meanwhile.
    pub comm_fault_present: bool,
    /// The vendor switches of the CiA 402 layer (docs/quirks.md).
    pub quirks: Cia402Quirks,
    /// QUICK STOP ACTIVE has been published (in a statusword) since it was entered.
    qsa_shown: bool,
    /// Manufacturer-specific statusword bits the node sets (bit 15 after a late SYNC).
    pub status_extra: u16,
    pub statusword: u16,
    pub following_error_uu: f64,
    pub position_actual_uu: i32,
    /// A following-error window 0x6065 of 0 is "off" on this device (its vendor's file says
    /// so: `DeviceDescription::following_error_window_zero_off`), as 0xFFFFFFFF is in CiA 402.
    pub fe_window_zero_off: bool,
    /// The rows of 0x60A8, 0x60A9 and 0x60AA in the store, where the dictionary has an SI
    /// unit velocity or acceleration: applied to the factor each tick
    /// ([`Factor::with_si_units`], [`Factor::with_si_acceleration`]).
    pub si_rows: Option<SiRows>,
    /// Motor-encoder increments per motor revolution the drive runs with, as of the last
    /// tick (0x608F; a placeholder a master wrote replaced by the encoder's count).
    pub inc_per_motor_rev: f64,
}

/// The store rows of a dictionary's SI unit objects (UNSIGNED32 ones only).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SiRows {
    /// 0x60A8 SI unit position.
    pub position: Option<usize>,
    /// 0x60A9 SI unit velocity.
    pub velocity: Option<usize>,
    /// 0x60AA SI unit acceleration.
    pub acceleration: Option<usize>,
}

impl Cia402 {
    pub fn new(factor: Factor, quirks: Cia402Quirks) -> Cia402 {
        Cia402 {
            state: State::NotReadyToSwitchOn,
            prev_cw: 0,
            mode_display: 0,
            axis: Axis::default(),
            origin: 0.0,
            factor,
            pp: Default::default(),
            pv: Default::default(),
            pt: Default::default(),
            hm: Default::default(),
            csp: Default::default(),
            ip: Default::default(),
            pending_fault: None,
            fault_code: 0,
            fe_timer: TimedWindow::default(),
            fe_flag: false,
            last_now: None,
            local_qs: false,
            comm_fault_present: false,
            quirks,
            qsa_shown: false,
            status_extra: 0,
            statusword: 0,
            following_error_uu: 0.0,
            position_actual_uu: 0,
            fe_window_zero_off: false,
            si_rows: None,
            inc_per_motor_rev: 0.0,
        }
    }

    /// With what the device's dictionary says: a following-error window of 0 is off, the
    /// rows of its SI unit objects.
    pub(crate) fn with_device(
        mut self,
        fe_window_zero_off: bool,
        si_rows: Option<SiRows>,
    ) -> Cia402 {
        self.fe_window_zero_off = fe_window_zero_off;
        self.si_rows = si_rows;
        self
    }

    /// Request FAULT REACTION ACTIVE at the next tick (0x6007 reaction, injected fault).
    pub fn request_fault(&mut self, code: u16) {
        if !matches!(self.state, State::Fault | State::FaultReactionActive)
            && self.pending_fault.is_none()
        {
            self.pending_fault = Some(code);
        }
    }

    /// React to a lost master / lost SYNC as 0x6007 says. Returns true if it raises a fault.
    pub fn comm_loss(&mut self, store: &Store, code: u16) -> bool {
        match store.i32(o::ABORT_CONN) {
            1 if matches!(
                self.state,
                State::OperationEnabled
                    | State::QuickStopActive
                    | State::SwitchedOn
                    | State::ReadyToSwitchOn
            ) =>
            {
                self.request_fault(code);
                true
            }
            2 if matches!(
                self.state,
                State::OperationEnabled
                    | State::QuickStopActive
                    | State::SwitchedOn
                    | State::ReadyToSwitchOn
            ) =>
            {
                self.state = State::SwitchOnDisabled;
                false
            }
            3 => {
                if self.state == State::OperationEnabled {
                    self.state = State::QuickStopActive;
                    self.local_qs = true;
                } else if matches!(self.state, State::SwitchedOn | State::ReadyToSwitchOn) {
                    self.state = State::SwitchOnDisabled;
                }
                false
            }
            _ => false,
        }
    }

    fn enter_mode(&mut self, ctx: &mut Ctx, m: i8) {
        match m {
            mode::value::PP => {
                ctx.axis.vel = 0.0;
                self.pp.enter(ctx)
            }
            mode::value::PV => self.pv.enter(),
            mode::value::PT => self.pt.enter(ctx),
            mode::value::HM => {
                ctx.axis.vel = 0.0;
                self.hm.enter()
            }
            mode::value::CSP => {
                ctx.axis.vel = 0.0;
                self.csp.enter(ctx)
            }
            mode::value::IP => {
                ctx.axis.vel = 0.0;
                self.ip.enter(ctx)
            }
            _ => {}
        }
    }

    /// One tick, in stages: read the inputs, enter a fault the drive or a reaction raised,
    /// apply the controlword's transition, run what the state does (the mode of operation
    /// in OPERATION ENABLED, the stop ramps elsewhere), monitor the following error, then
    /// compose the statusword and publish the actual values. `control`: the SYNC, the CSP
    /// period and the controlword of this tick.
    pub fn step(
        &mut self,
        store: &mut Store,
        fb: &Feedback,
        now_us: u64,
        control: TickControl,
        drive: &mut impl Drive,
    ) -> StepOut {
        let (sync_at, csp_period_us) = (control.sync_at, control.csp_period_us);
        let input = self.read_inputs(store, fb, now_us, control, drive.info());
        let mut out = StepOut {
            command: DriveCommand {
                setpoint: Setpoint::Disabled,
                max_torque_permille: store.u32(o::MAX_TORQUE) as f64,
                max_velocity_inc_per_s: max_motor_inc_per_s(store, self.inc_per_motor_rev),
            },
            new_fault: None,
            fault_cleared: false,
        };
        self.enter_raised_fault(store, fb, &mut out);
        if self.state == State::NotReadyToSwitchOn {
            // automatic transitions 0 / 1
            self.state = State::SwitchOnDisabled;
        }
        let was = self.state;
        let deferred = self.apply_controlword(store, &input, drive, &mut out);

        let requested = store.i32(o::MODE) as i8;
        let mut ctx = self.context(store, fb, &input, now_us);
        self.track_axis(&mut ctx, &input, was, requested);
        let mut mo = self.run_state(&mut ctx, deferred, requested, sync_at, csp_period_us);
        if !self.state.enabled() {
            mo.setpoint = Setpoint::Disabled;
            mo.position_mode = false;
        }
        if let Some(org) = ctx.new_origin {
            self.origin = org;
            ctx.origin = org;
        }
        let fe_uu = self.monitor_following_error(&mut ctx, &mut mo, &input, now_us, &mut out);
        self.statusword = self.compose_statusword(&mo);
        self.publish_actual_values(ctx.store, fb, &input, ctx.axis.pos, fe_uu);
        ctx.store
            .set_i32(o::TORQUE_DEMAND, torque_demand_permille(&mo.setpoint, fb));
        self.axis = ctx.axis;
        self.prev_cw = input.cw;
        out.command.setpoint = mo.setpoint;
        out
    }

    /// Stage 1: the tick's time step, the factor group (0x608F, 0x6091, 0x6092, if valid;
    /// a placeholder encoder resolution a master wrote runs as the drive's encoder count,
    /// `od::placeholders::running_factor_group`), the actual position and speed the loops
    /// use, and the controlword 0x6040.
    fn read_inputs(
        &mut self,
        store: &Store,
        fb: &Feedback,
        now_us: u64,
        control: TickControl,
        info: crate::drive::DriveInfo,
    ) -> TickInput {
        let dt = match self.last_now {
            Some(l) => (now_us.saturating_sub(l) as f64 * 1e-6).min(0.1),
            None => 0.0,
        };
        self.last_now = Some(now_us);
        let [enc, enc_revs, gear_motor, gear_shaft, feed, feed_revs] =
            crate::od::placeholders::running_factor_group(
                [
                    store.u32(o::ENC_INC),
                    store.u32(o::ENC_REVS),
                    store.u32(o::GEAR_MOTOR),
                    store.u32(o::GEAR_SHAFT),
                    store.u32(o::FEED),
                    store.u32(o::FEED_REVS),
                ],
                info.encoder_increments_per_rev,
            );
        self.inc_per_motor_rev = enc as f64 / enc_revs.max(1) as f64;
        if let Some(f) =
            Factor::from_objects(enc, enc_revs, gear_motor, gear_shaft, feed, feed_revs)
        {
            self.factor = match self.si_rows {
                Some(rows) => {
                    let revs = enc_revs.max(1) as f64;
                    let shaft = gear_shaft.max(1) as f64;
                    let inc_per_shaft_rev = enc as f64 / revs * gear_motor as f64 / shaft;
                    let pos = rows.position.map(|r| store.u32(r));
                    let f = match rows.velocity {
                        Some(v) => f.with_si_units(pos, store.u32(v), inc_per_shaft_rev).0,
                        None => f,
                    };
                    match rows.acceleration {
                        Some(a) => {
                            f.with_si_acceleration(pos, store.u32(a), inc_per_shaft_rev)
                                .0
                        }
                        None => f,
                    }
                }
                None => f,
            };
        }
        let act_inc = if fb.position_from_direct {
            fb.direct_position_inc
        } else {
            fb.motor_position_inc
        } as f64;
        let act_vel = if fb.motor_velocity_inc_per_s.is_finite() {
            fb.motor_velocity_inc_per_s
        } else {
            0.0
        };
        let cw = control.level;
        if cw & 0x04 == 0 {
            self.local_qs = false;
        }
        TickInput {
            dt,
            act_inc,
            act_vel,
            cw,
            rising: (cw & !self.prev_cw) | control.latched,
        }
    }

    /// Stage 2 (transition 13): a fault the drive reports or a reaction requested enters
    /// FAULT REACTION ACTIVE, sets 0x603F and asks the node for an EMCY.
    fn enter_raised_fault(&mut self, store: &mut Store, fb: &Feedback, out: &mut StepOut) {
        let fault = fb.drive_fault.or(self.pending_fault.take());
        if let Some(code) = fault {
            if !matches!(self.state, State::Fault | State::FaultReactionActive) {
                self.state = State::FaultReactionActive;
                self.fault_code = code;
                store.set_u32(o::ERROR_CODE, code as u32);
                out.new_fault = Some(code);
            }
        }
    }

    /// Stage 3: the transitions the controlword asks for, in the order written: a fault
    /// reset (a rising edge of bit 7 this tick, or one latched since the last), then the
    /// command of the controlword's level (0x0080 then 0x0006 written within one tick are
    /// transitions 15 and 2). Returns the state to enter once the axis has stopped when 0x605C
    /// / 0x605B ask for a ramp before disabling (transitions 5 and 8).
    fn apply_controlword(
        &mut self,
        store: &mut Store,
        input: &TickInput,
        drive: &mut impl Drive,
        out: &mut StepOut,
    ) -> Option<State> {
        let cw = input.cw;
        if input.rising & BIT_FAULT_RESET != 0 && self.state == State::Fault {
            // CiA 402: fault reset only when no fault is present (a supervised condition
            // that faulted the drive, or the drive's own); refused, the drive stays in FAULT
            // with its one error and sends nothing
            if !self.comm_fault_present && drive.reset_fault() {
                self.state = State::SwitchOnDisabled;
                self.fault_code = 0;
                self.fe_flag = false;
                store.set_u32(o::ERROR_CODE, 0);
                out.fault_cleared = true;
            }
        }
        // the level alone (the edge was handled above)
        let cmd = controlword::decode(cw, cw | BIT_FAULT_RESET);
        let qs_opt = store.i32(o::QS_OPTION) as i16;
        let (mut next, mut n) = state_machine::transition(self.state, cmd, qs_opt)?;
        if n == 4 && self.quirks.enable_requires_mode && store.i32(o::MODE) == 0 {
            // enable_requires_mode (docs/quirks.md 3.1): no OPERATION ENABLED without a mode;
            // from READY TO SWITCH ON, "3+4" does 3 only
            if self.state != State::ReadyToSwitchOn {
                return None;
            }
            (next, n) = (State::SwitchedOn, 3);
        }
        match n {
            5 if store.i32(o::DISABLE_OP_OPTION) == 1 => return Some(next),
            8 if store.i32(o::SHUTDOWN_OPTION) == 1 => return Some(next),
            16 if self.local_qs => {}
            _ => self.state = next,
        }
        None
    }

    /// The context the modes run in this tick.
    fn context<'a>(
        &self,
        store: &'a mut Store,
        fb: &'a Feedback,
        input: &TickInput,
        now_us: u64,
    ) -> Ctx<'a> {
        let halt_opt = store.i32(o::HALT_OPTION);
        let mut ctx = Ctx {
            store,
            fb,
            f: self.factor,
            origin: self.origin,
            act_inc: input.act_inc,
            act_vel: input.act_vel,
            now: now_us,
            dt: input.dt,
            cw: input.cw,
            rising: input.rising,
            halt: false,
            halt_dec: 0.0,
            inc_per_motor_rev: self.inc_per_motor_rev,
            axis: self.axis,
            new_origin: None,
        };
        ctx.halt_dec = if halt_opt == 1 {
            ctx.acc(o::PROFILE_DEC)
        } else {
            ctx.acc(o::QS_DEC)
        };
        ctx
    }

    /// Stage 4: the demand follows the actual axis while disabled; entering OPERATION
    /// ENABLED starts the requested mode from where the axis stands.
    fn track_axis(&mut self, ctx: &mut Ctx, input: &TickInput, was: State, requested: i8) {
        if !self.state.enabled() {
            ctx.axis = Axis {
                pos: input.act_inc,
                vel: input.act_vel,
            };
        }
        if self.state == State::OperationEnabled && was != State::OperationEnabled {
            self.mode_display = self.mode_to_run(requested, input.cw);
            if was != State::QuickStopActive {
                ctx.axis = Axis {
                    pos: input.act_inc,
                    vel: 0.0,
                };
            }
            self.enter_mode(ctx, self.mode_display);
        }
    }

    /// The mode 0x6061 takes when 0x6060 asks for `requested`: it, unless
    /// `mode_change_blocked_by_halt` keeps the mode in force while bit 8 is set (3.2).
    fn mode_to_run(&self, requested: i8, cw: u16) -> i8 {
        if self.quirks.mode_change_blocked_by_halt && cw & BIT_HALT != 0 {
            self.mode_display
        } else {
            requested
        }
    }

    /// Stage 5: what the state does this tick: the mode of operation (or the ramp of a
    /// deferred disable) in OPERATION ENABLED, the stop ramps of QUICK STOP ACTIVE (0x605A)
    /// and FAULT REACTION ACTIVE (0x605E), nothing elsewhere.
    fn run_state(
        &mut self,
        ctx: &mut Ctx,
        deferred: Option<State>,
        requested: i8,
        sync_at: Option<u64>,
        csp_period_us: u64,
    ) -> ModeOut {
        match self.state {
            State::OperationEnabled => match deferred {
                Some(next) => self.ramp_then_disable(ctx, next),
                None => self.run_mode(ctx, requested, sync_at, csp_period_us),
            },
            State::QuickStopActive => self.quick_stop(ctx),
            State::FaultReactionActive => self.fault_reaction(ctx),
            _ => {
                self.mode_display = self.mode_to_run(requested, ctx.cw);
                ModeOut::default()
            }
        }
    }

    /// Transitions 5 / 8 with option code 1: ramp down on 0x6084, then enter `next`.
    fn ramp_then_disable(&mut self, ctx: &mut Ctx, next: State) -> ModeOut {
        let dec = ctx.acc(o::PROFILE_DEC);
        let standing = ctx.axis.stop(dec, ctx.dt);
        if standing {
            self.state = next;
            return ModeOut::default();
        }
        ModeOut {
            setpoint: hold(&ctx.axis),
            position_mode: true,
            ..ModeOut::default()
        }
    }

    /// The mode of operation: switch to a newly requested mode, then run it.
    fn run_mode(
        &mut self,
        ctx: &mut Ctx,
        requested: i8,
        sync_at: Option<u64>,
        csp_period_us: u64,
    ) -> ModeOut {
        let requested = self.mode_to_run(requested, ctx.cw);
        if requested != self.mode_display {
            self.mode_display = requested;
            self.enter_mode(ctx, requested);
        }
        ctx.halt = ctx.cw & BIT_HALT != 0
            && mode::Mode::from_value(self.mode_display).is_some_and(|m| m.halts());
        match self.mode_display {
            mode::value::PP => self.pp.step(ctx),
            mode::value::PV => self.pv.step(ctx),
            mode::value::PT => self.pt.step(ctx),
            mode::value::HM => self.hm.step(ctx),
            mode::value::CSP => self.csp.step(ctx, sync_at, csp_period_us),
            mode::value::IP => self.ip.step(ctx, sync_at, csp_period_us),
            mode::value::CSV => csv::step(ctx),
            mode::value::CST => cst::step(ctx),
            _ => {
                let standing = ctx.axis.stop(ctx.acc(o::QS_DEC), ctx.dt);
                ModeOut {
                    setpoint: hold(&ctx.axis),
                    target_reached: standing,
                    position_mode: true,
                    ..ModeOut::default()
                }
            }
        }
    }

    /// QUICK STOP ACTIVE: ramp on 0x6084 or 0x6085 as 0x605A says; options 1..=4 then go to
    /// SWITCH ON DISABLED, 5..=8 stay and hold; option 0 disables at once. The automatic
    /// transition 12 waits until a statusword has shown QUICK STOP ACTIVE (CiA 402: it is a
    /// state with its own statusword), unless `quick_stop_skips_active_state` (3.12).
    fn quick_stop(&mut self, ctx: &mut Ctx) -> ModeOut {
        let qs_opt = ctx.store.i32(o::QS_OPTION) as i16;
        let may_leave = self.qsa_shown || self.quirks.quick_stop_skips_active_state;
        let dec = match qs_opt {
            1 | 5 => ctx.acc(o::PROFILE_DEC),
            _ => ctx.acc(o::QS_DEC),
        };
        let mut mo = ModeOut::default();
        if qs_opt == 0 {
            if may_leave {
                self.state = State::SwitchOnDisabled;
            }
        } else {
            let standing = ctx.axis.stop(dec, ctx.dt);
            mo.setpoint = hold(&ctx.axis);
            mo.position_mode = true;
            mo.target_reached = standing;
            if standing && (1..=4).contains(&qs_opt) && may_leave {
                self.state = State::SwitchOnDisabled;
                mo.setpoint = Setpoint::Disabled;
            }
        }
        mo
    }

    /// FAULT REACTION ACTIVE: ramp as 0x605E says (0: disable at once), then FAULT.
    fn fault_reaction(&mut self, ctx: &mut Ctx) -> ModeOut {
        let opt = ctx.store.i32(o::FAULT_OPTION);
        let dec = if opt == 1 {
            ctx.acc(o::PROFILE_DEC)
        } else {
            ctx.acc(o::QS_DEC)
        };
        let mut mo = ModeOut::default();
        if opt == 0 || ctx.axis.stop(dec, ctx.dt) {
            self.state = State::Fault;
        } else {
            mo.setpoint = hold(&ctx.axis);
        }
        mo
    }

    /// Stage 6: following error (0x60F4) against the window 0x6065 for the time 0x6066 in
    /// the position modes; over it, a fault 0x8611 and the axis held where it is. Returns
    /// the following error in user units.
    fn monitor_following_error(
        &mut self,
        ctx: &mut Ctx,
        mo: &mut ModeOut,
        input: &TickInput,
        now_us: u64,
        out: &mut StepOut,
    ) -> f64 {
        let fe_inc = if mo.position_mode {
            ctx.axis.pos - input.act_inc
        } else {
            0.0
        };
        let fe_uu = self.factor.to_uu(fe_inc);
        let window = ctx.store.u32(o::FE_WINDOW);
        let off = window == u32::MAX || (window == 0 && self.fe_window_zero_off);
        let over = mo.position_mode && !off && fe_uu.abs() > window as f64;
        if self
            .fe_timer
            .update(over, now_us, ctx.store.u32(o::FE_TIME))
            && self.state == State::OperationEnabled
        {
            self.fe_flag = true;
            self.state = State::FaultReactionActive;
            self.fault_code = EMCY_FOLLOWING_ERROR;
            ctx.store
                .set_u32(o::ERROR_CODE, EMCY_FOLLOWING_ERROR as u32);
            out.new_fault = Some(EMCY_FOLLOWING_ERROR);
            // hold where the axis is
            ctx.axis = Axis {
                pos: input.act_inc,
                vel: input.act_vel,
            };
            mo.setpoint = hold(&ctx.axis);
        }
        self.following_error_uu = fe_uu;
        fe_uu
    }

    /// Stage 7: statusword 0x6041 from the state and what the mode reported (and the bits a
    /// vendor switch hides or adds).
    fn compose_statusword(&mut self, mo: &ModeOut) -> u16 {
        self.qsa_shown = self.state == State::QuickStopActive;
        let mut s = sw::state_bits(self.state) | sw::BIT_REMOTE;
        let oe = self.state == State::OperationEnabled;
        if (oe || self.state == State::QuickStopActive) && mo.target_reached {
            s |= sw::BIT_TARGET_REACHED;
        }
        if mo.limit {
            s |= sw::BIT_INTERNAL_LIMIT;
        }
        if oe {
            if mo.oms12 {
                s |= sw::BIT_OMS12;
            }
            if mo.oms13 {
                s |= sw::BIT_OMS13;
            }
        }
        if self.fe_flag
            && matches!(
                self.mode_display,
                mode::value::PP | mode::value::CSP | mode::value::IP
            )
        {
            s |= sw::BIT_OMS13;
        }
        if self.mode_display == mode::value::HM {
            s &= !self.quirks.homing_hidden_bits;
        }
        s | self.status_extra
    }

    /// Stage 8: the statusword, mode display and actual values (0x6062..0x6078, 0x60E4,
    /// 0x60F4, 0x60FD) into the object store, in user units through the factor group.
    fn publish_actual_values(
        &mut self,
        st: &mut Store,
        fb: &Feedback,
        input: &TickInput,
        demand_inc: f64,
        fe_uu: f64,
    ) {
        let f = self.factor;
        let origin = self.origin;
        let to_uu = |inc: f64| f.to_uu(inc - origin);
        let act_vel = input.act_vel;
        self.position_actual_uu = sat_i32(to_uu(input.act_inc));
        st.set_u32(o::STATUSWORD, self.statusword as u32);
        st.set_i32(o::MODE_DISPLAY, self.mode_display as i32);
        st.set_i32(o::POS_DEMAND, sat_i32(to_uu(demand_inc)));
        st.set_i32(o::POS_INTERNAL, fb.motor_position_inc as i32);
        st.set_i32(o::POS_ACTUAL, self.position_actual_uu);
        st.set_i32(o::VEL_SENSOR, sat_i32(act_vel));
        st.set_i32(
            o::VEL_DEMAND,
            sat_i32(f.vel_to_uu(fb.velocity_demand_inc_per_s)),
        );
        st.set_i32(o::VEL_ACTUAL, sat_i32(f.vel_to_uu(act_vel)));
        st.set_i32(
            o::TORQUE_ACTUAL,
            sat_i32(fb.torque_permille).clamp(-32768, 32767),
        );
        st.set_i32(
            o::CURRENT_ACTUAL,
            sat_i32(fb.current_permille).clamp(-32768, 32767),
        );
        st.set_i32(o::DIRECT_POS, sat_i32(to_uu(fb.direct_position_inc as f64)));
        st.set_i32(o::FE_ACTUAL, sat_i32(fe_uu));
        st.set_u32(
            o::DIGITAL_INPUTS,
            fb.negative_limit_switch as u32
                | (fb.positive_limit_switch as u32) << 1
                | (fb.home_switch as u32) << 2,
        );
    }
}

/// What a tick reads before anything changes.
struct TickInput {
    /// Seconds since the previous tick (0 at the first, at most 0.1).
    dt: f64,
    /// Actual position, increments, from the encoder that closes the position loop.
    act_inc: f64,
    /// Motor speed, increments/s (0 if the drive reported a non-finite value).
    act_vel: f64,
    /// Controlword (its level this tick).
    cw: u16,
    /// Its rising edges this tick (against the last tick's, and latched since).
    rising: u16,
}

/// 0x6074 torque demand: the mode's torque set-point (PT's ramp, CST's target), 0 while
/// disabled, else the torque the drive's loops ask of the motor (its actual torque).
fn torque_demand_permille(setpoint: &Setpoint, fb: &Feedback) -> i32 {
    let t = match setpoint {
        Setpoint::Torque { torque_permille } => *torque_permille,
        Setpoint::Disabled => 0.0,
        _ => fb.torque_permille,
    };
    sat_i32(t).clamp(-32768, 32767)
}

fn hold(a: &Axis) -> Setpoint {
    Setpoint::Position {
        position_inc: a.pos,
        velocity_ff_inc_per_s: a.vel,
        torque_ff_permille: 0.0,
    }
}
