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
pub(crate) mod objects;
mod pp;
pub(crate) mod profile;
mod pv;
pub(crate) mod state_machine;
pub mod statusword;

use crate::drive::{Drive, DriveCommand, Feedback, Setpoint};
use crate::od::Store;
use controlword::BIT_HALT;
use factor::{sat_i32, Factor};
use objects as o;
use profile::Axis;
pub use state_machine::State;
use statusword as sw;

/// Modes of operation (0x6060 values).
pub mod mode {
    /// No mode selected.
    pub const NONE: i8 = 0;
    /// Profile position mode.
    pub const PP: i8 = 1;
    /// Profile velocity mode.
    pub const PV: i8 = 3;
    /// Homing mode.
    pub const HM: i8 = 6;
    /// Cyclic synchronous position mode.
    pub const CSP: i8 = 8;
    /// Cyclic synchronous velocity mode.
    pub const CSV: i8 = 9;
    /// Cyclic synchronous torque mode.
    pub const CST: i8 = 10;
    /// Whether the drive supports `m`.
    pub fn supported(m: i8) -> bool {
        matches!(m, NONE | PP | PV | HM | CSP | CSV | CST)
    }
}

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
    pub prev_cw: u16,
    pub halt: bool,
    pub halt_dec: f64,
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
        let inc = self.f.to_inc(v);
        let motor = max_motor_inc_per_s(self.store);
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
            self.f.to_inc(a as f64)
        }
    }
}

fn max_motor_inc_per_s(store: &Store) -> f64 {
    let revs = store.u32(o::ENC_REVS).max(1) as f64;
    store.u32(o::MAX_MOTOR_SPEED) as f64 / 60.0 * store.u32(o::ENC_INC) as f64 / revs
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
    hm: hm::Hm,
    csp: csp::Csp,
    pending_fault: Option<u16>,
    fault_code: u16,
    fe_timer: TimedWindow,
    fe_flag: bool,
    last_now: Option<u64>,
    /// A local quick stop (communication loss) blocks transition 16 until the master has
    /// sent a quick stop itself.
    local_qs: bool,
    pub statusword: u16,
    pub following_error_uu: f64,
    pub position_actual_uu: i32,
}

impl Cia402 {
    pub fn new(factor: Factor) -> Cia402 {
        Cia402 {
            state: State::NotReadyToSwitchOn,
            prev_cw: 0,
            mode_display: 0,
            axis: Axis::default(),
            origin: 0.0,
            factor,
            pp: Default::default(),
            pv: Default::default(),
            hm: Default::default(),
            csp: Default::default(),
            pending_fault: None,
            fault_code: 0,
            fe_timer: TimedWindow::default(),
            fe_flag: false,
            last_now: None,
            local_qs: false,
            statusword: 0,
            following_error_uu: 0.0,
            position_actual_uu: 0,
        }
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
            mode::PP => {
                ctx.axis.vel = 0.0;
                self.pp.enter(ctx)
            }
            mode::PV => self.pv.enter(),
            mode::HM => {
                ctx.axis.vel = 0.0;
                self.hm.enter()
            }
            mode::CSP => {
                ctx.axis.vel = 0.0;
                self.csp.enter(ctx)
            }
            _ => {}
        }
    }

    /// One tick. `sync_at`: time of the latest SYNC since the previous tick;
    /// `csp_period_us`: the CSP interpolation period (0 = none).
    pub fn step(
        &mut self,
        store: &mut Store,
        fb: &Feedback,
        now_us: u64,
        sync_at: Option<u64>,
        csp_period_us: u64,
        drive: &mut impl Drive,
    ) -> StepOut {
        let dt = match self.last_now {
            Some(l) => (now_us.saturating_sub(l) as f64 * 1e-6).min(0.1),
            None => 0.0,
        };
        self.last_now = Some(now_us);
        if let Some(f) = Factor::from_objects(
            store.u32(o::ENC_INC),
            store.u32(o::ENC_REVS),
            store.u32(o::GEAR_MOTOR),
            store.u32(o::GEAR_SHAFT),
            store.u32(o::FEED),
            store.u32(o::FEED_REVS),
        ) {
            self.factor = f;
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
        let cw = store.u32(o::CONTROLWORD) as u16;
        let cmd = controlword::decode(cw, self.prev_cw);
        let mut out = StepOut {
            command: DriveCommand {
                setpoint: Setpoint::Disabled,
                max_torque_permille: store.u32(o::MAX_TORQUE) as f64,
                max_velocity_inc_per_s: max_motor_inc_per_s(store),
            },
            new_fault: None,
            fault_cleared: false,
        };
        if cw & 0x04 == 0 {
            self.local_qs = false;
        }

        // ---- faults (transition 13) ----
        let fault = fb.drive_fault.or(self.pending_fault.take());
        if let Some(code) = fault {
            if !matches!(self.state, State::Fault | State::FaultReactionActive) {
                self.state = State::FaultReactionActive;
                self.fault_code = code;
                store.set(o::ERROR_CODE, code as u32);
                out.new_fault = Some(code);
            }
        }
        // ---- automatic transitions 0 / 1 ----
        if self.state == State::NotReadyToSwitchOn {
            self.state = State::SwitchOnDisabled;
        }
        // ---- command transitions ----
        let qs_opt = store.i32(o::QS_OPTION) as i16;
        let mut deferred: Option<(State, f64)> = None;
        let was = self.state;
        if let Some((next, n)) = state_machine::transition(self.state, cmd, qs_opt) {
            match n {
                15 => {
                    if drive.reset_fault() {
                        self.state = next;
                        self.fault_code = 0;
                        self.fe_flag = false;
                        store.set(o::ERROR_CODE, 0);
                        out.fault_cleared = true;
                    }
                }
                5 if store.i32(o::DISABLE_OP_OPTION) == 1 => deferred = Some((next, 0.0)),
                8 if store.i32(o::SHUTDOWN_OPTION) == 1 => deferred = Some((next, 0.0)),
                16 if self.local_qs => {}
                _ => self.state = next,
            }
        }

        let requested = store.i32(o::MODE) as i8;
        let halt_opt = store.i32(o::HALT_OPTION);
        let mut ctx = Ctx {
            store,
            fb,
            f: self.factor,
            origin: self.origin,
            act_inc,
            act_vel,
            now: now_us,
            dt,
            cw,
            prev_cw: self.prev_cw,
            halt: false,
            halt_dec: 0.0,
            axis: self.axis,
            new_origin: None,
        };
        ctx.halt_dec = if halt_opt == 1 {
            ctx.acc(o::PROFILE_DEC)
        } else {
            ctx.acc(o::QS_DEC)
        };
        let entered_oe = self.state == State::OperationEnabled && was != State::OperationEnabled;
        if !self.state.enabled() {
            ctx.axis = Axis {
                pos: act_inc,
                vel: act_vel,
            };
        }
        if entered_oe {
            self.mode_display = requested;
            if was != State::QuickStopActive {
                ctx.axis = Axis {
                    pos: act_inc,
                    vel: 0.0,
                };
            }
            self.enter_mode(&mut ctx, requested);
        }

        let mut mo = ModeOut::default();
        match self.state {
            State::OperationEnabled => {
                if let Some((_, ref mut d)) = deferred {
                    *d = ctx.acc(o::PROFILE_DEC);
                    let standing = ctx.axis.stop(*d, dt);
                    mo.setpoint = hold(&ctx.axis);
                    mo.position_mode = true;
                    if standing {
                        self.state = deferred.map(|(s, _)| s).unwrap_or(self.state);
                        mo.setpoint = Setpoint::Disabled;
                        mo.position_mode = false;
                    }
                } else {
                    if requested != self.mode_display {
                        self.mode_display = requested;
                        self.enter_mode(&mut ctx, requested);
                    }
                    ctx.halt = cw & BIT_HALT != 0
                        && matches!(self.mode_display, mode::PP | mode::PV | mode::HM);
                    mo = match self.mode_display {
                        mode::PP => self.pp.step(&mut ctx),
                        mode::PV => self.pv.step(&mut ctx),
                        mode::HM => self.hm.step(&mut ctx),
                        mode::CSP => self.csp.step(&mut ctx, sync_at, csp_period_us),
                        mode::CSV => csv::step(&mut ctx),
                        mode::CST => cst::step(&mut ctx),
                        _ => {
                            let standing = ctx.axis.stop(ctx.acc(o::QS_DEC), dt);
                            ModeOut {
                                setpoint: hold(&ctx.axis),
                                target_reached: standing,
                                position_mode: true,
                                ..ModeOut::default()
                            }
                        }
                    };
                }
            }
            State::QuickStopActive => {
                let dec = match qs_opt {
                    1 | 5 => ctx.acc(o::PROFILE_DEC),
                    _ => ctx.acc(o::QS_DEC),
                };
                if qs_opt == 0 {
                    self.state = State::SwitchOnDisabled;
                } else {
                    let standing = ctx.axis.stop(dec, dt);
                    mo.setpoint = hold(&ctx.axis);
                    mo.position_mode = true;
                    mo.target_reached = standing;
                    if standing && (1..=4).contains(&qs_opt) {
                        self.state = State::SwitchOnDisabled;
                        mo.setpoint = Setpoint::Disabled;
                    }
                }
            }
            State::FaultReactionActive => {
                let opt = ctx.store.i32(o::FAULT_OPTION);
                let dec = if opt == 1 {
                    ctx.acc(o::PROFILE_DEC)
                } else {
                    ctx.acc(o::QS_DEC)
                };
                if opt == 0 || ctx.axis.stop(dec, dt) {
                    self.state = State::Fault;
                } else {
                    mo.setpoint = hold(&ctx.axis);
                }
            }
            _ => {
                self.mode_display = requested;
            }
        }
        if !self.state.enabled() {
            mo.setpoint = Setpoint::Disabled;
            mo.position_mode = false;
        }
        if let Some(org) = ctx.new_origin {
            self.origin = org;
            ctx.origin = org;
        }

        // ---- following error ----
        let fe_inc = if mo.position_mode {
            ctx.axis.pos - act_inc
        } else {
            0.0
        };
        let fe_uu = self.factor.to_uu(fe_inc);
        let window = ctx.store.u32(o::FE_WINDOW);
        let over = mo.position_mode && window != u32::MAX && fe_uu.abs() > window as f64;
        if self
            .fe_timer
            .update(over, now_us, ctx.store.u32(o::FE_TIME))
            && self.state == State::OperationEnabled
        {
            self.fe_flag = true;
            self.state = State::FaultReactionActive;
            self.fault_code = EMCY_FOLLOWING_ERROR;
            ctx.store.set(o::ERROR_CODE, EMCY_FOLLOWING_ERROR as u32);
            out.new_fault = Some(EMCY_FOLLOWING_ERROR);
            // hold where the axis is
            ctx.axis = Axis {
                pos: act_inc,
                vel: act_vel,
            };
            mo.setpoint = hold(&ctx.axis);
        }
        self.following_error_uu = fe_uu;

        // ---- statusword ----
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
        if self.fe_flag && matches!(self.mode_display, mode::PP | mode::CSP) {
            s |= sw::BIT_OMS13;
        }
        self.statusword = s;

        // ---- actual values ----
        let st = &mut *ctx.store;
        let f = self.factor;
        let to_uu = |inc: f64| f.to_uu(inc - self.origin);
        self.position_actual_uu = sat_i32(to_uu(act_inc));
        st.set(o::STATUSWORD, s as u32);
        st.set_i32(o::MODE_DISPLAY, self.mode_display as i32);
        st.set_i32(o::POS_DEMAND, sat_i32(to_uu(ctx.axis.pos)));
        st.set_i32(o::POS_INTERNAL, fb.motor_position_inc as i32);
        st.set_i32(o::POS_ACTUAL, self.position_actual_uu);
        st.set_i32(o::VEL_SENSOR, sat_i32(act_vel));
        st.set_i32(
            o::VEL_DEMAND,
            sat_i32(f.to_uu(fb.velocity_demand_inc_per_s)),
        );
        st.set_i32(o::VEL_ACTUAL, sat_i32(f.to_uu(act_vel)));
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
        st.set(
            o::DIGITAL_INPUTS,
            fb.negative_limit_switch as u32
                | (fb.positive_limit_switch as u32) << 1
                | (fb.home_switch as u32) << 2,
        );
        self.axis = ctx.axis;
        self.prev_cw = cw;
        out.command.setpoint = mo.setpoint;
        out
    }
}

fn hold(a: &Axis) -> Setpoint {
    Setpoint::Position {
        position_inc: a.pos,
        velocity_ff_inc_per_s: a.vel,
        torque_ff_permille: 0.0,
    }
}
