//! Profile position mode (1): set-point handshake (controlword bit 4 new set-point, statusword
//! bit 12 acknowledge), change set immediately (bit 5), relative (bit 6), one buffered
//! set-point, trapezoid from 0x6081/0x6083/0x6084 limited by 0x607F, software limits 0x607D,
//! target reached by 0x6067/0x6068.

use super::controlword::{BIT_CHANGE_IMMEDIATELY, BIT_NEW_SETPOINT, BIT_RELATIVE};
use super::objects as o;
use super::{Ctx, ModeOut, TimedWindow};
use crate::drive::Setpoint;

#[derive(Clone, Copy, Debug, Default)]
pub struct Pp {
    /// Current target, user units (unwrapped) and increments.
    target_uu: f64,
    target_inc: f64,
    buffered: Option<(f64, f64)>,
    /// 0x607D clamped the current / the buffered target: statusword bit 11 (internal limit
    /// active) stays set while such a target is in force.
    target_limited: bool,
    buffered_limited: bool,
    moving: bool,
    ack: bool,
    reached: TimedWindow,
}

impl Pp {
    pub fn enter(&mut self, ctx: &Ctx) {
        self.target_inc = ctx.axis.pos;
        self.target_uu = ctx.to_uu_pos(ctx.axis.pos);
        self.buffered = None;
        self.target_limited = false;
        self.buffered_limited = false;
        self.moving = false;
        self.ack = false;
        self.reached = TimedWindow::default();
    }

    pub fn step(&mut self, ctx: &mut Ctx) -> ModeOut {
        let mut out = ModeOut::default();
        let rising = ctx.rising & BIT_NEW_SETPOINT != 0;
        if rising {
            let raw = ctx.store.i32(o::TARGET_POSITION) as f64;
            let base = if ctx.cw & BIT_RELATIVE != 0 {
                match self.buffered {
                    Some((uu, _)) => uu,
                    None => self.target_uu,
                }
            } else {
                0.0
            };
            let (uu, limited) = ctx.clamp_sw_limits(base + raw);
            let inc = ctx.to_inc_pos(uu);
            if !self.moving || ctx.cw & BIT_CHANGE_IMMEDIATELY != 0 {
                self.target_uu = uu;
                self.target_inc = inc;
                self.target_limited = limited;
                self.buffered = None;
                self.buffered_limited = false;
                self.moving = true;
                self.ack = true;
            } else if self.buffered.is_none() {
                self.buffered = Some((uu, inc));
                self.buffered_limited = limited;
                self.ack = true;
            }
        }
        // a pulse written within one tick is acknowledged for one statusword
        if ctx.cw & BIT_NEW_SETPOINT == 0 && !rising {
            self.ack = false;
        }
        let reached_now;
        if ctx.halt {
            let standing = ctx.axis.stop(ctx.halt_dec, ctx.dt);
            reached_now = standing;
        } else {
            if self.moving {
                let vmax = ctx.vel_limit(ctx.store.u32(o::PROFILE_VEL) as f64);
                let acc = ctx.acc(o::PROFILE_ACC);
                let dec = ctx.acc(o::PROFILE_DEC);
                if ctx.axis.move_to(self.target_inc, vmax, acc, dec, ctx.dt) {
                    if let Some((uu, inc)) = self.buffered.take() {
                        self.target_uu = uu;
                        self.target_inc = inc;
                        self.target_limited = self.buffered_limited;
                        self.buffered_limited = false;
                    } else {
                        self.moving = false;
                    }
                }
            }
            let window = ctx.f.to_inc(ctx.store.u32(o::POS_WINDOW) as f64);
            let inside = !self.moving && (self.target_inc - ctx.act_inc).abs() <= window;
            reached_now = self
                .reached
                .update(inside, ctx.now, ctx.store.u32(o::POS_WINDOW_TIME));
        }
        out.target_reached = reached_now;
        out.limit = self.target_limited || self.buffered_limited;
        out.oms12 = self.ack;
        out.position_mode = true;
        out.setpoint = Setpoint::Position {
            position_inc: ctx.axis.pos,
            velocity_ff_inc_per_s: ctx.axis.vel,
            torque_ff_permille: 0.0,
        };
        out
    }
}
