//! Cyclic synchronous position mode (8): a target 0x607A every SYNC, interpolated linearly
//! over the interpolation period (0x60C2; else 0x1006; else the measured SYNC interval) so the
//! position demand is smooth at the tick rate. 0x60B1 adds velocity and 0x60B2 torque
//! feed-forward. Targets are unwrapped across the I32 range. Without SYNC (none for three
//! periods, or never) a new target is taken at once. The same interpolator serves the
//! interpolated position mode (`ip.rs`), whose set-point is 0x60C1:1: the target object is
//! the caller's.

use super::objects as o;
use super::{Ctx, ModeOut};
use crate::drive::Setpoint;

#[derive(Clone, Copy, Debug, Default)]
pub struct Csp {
    prev: f64,
    next: f64,
    t_sync: u64,
    period_us: u64,
    last_raw: i32,
    target_uu: f64,
}

impl Csp {
    /// Entering CSP holds the current position: 0x607A is set to it.
    pub fn enter(&mut self, ctx: &mut Ctx) {
        self.enter_on(ctx, o::TARGET_POSITION);
    }

    /// Hold the current position, the target object `target` (a store slot) set to it.
    pub fn enter_on(&mut self, ctx: &mut Ctx, target: usize) {
        let uu = ctx.to_uu_pos(ctx.axis.pos);
        self.target_uu = uu.round();
        self.last_raw = super::factor::sat_i32(uu);
        ctx.store.set_i32(target, self.last_raw);
        self.prev = ctx.axis.pos;
        self.next = ctx.axis.pos;
        self.period_us = 0;
        self.t_sync = ctx.now;
    }

    fn eval(&self, t: u64) -> (f64, f64) {
        if self.period_us == 0 {
            return (self.next, 0.0);
        }
        let frac = (t.saturating_sub(self.t_sync) as f64 / self.period_us as f64).min(1.0);
        let v = if frac < 1.0 {
            (self.next - self.prev) / (self.period_us as f64 * 1e-6)
        } else {
            0.0
        };
        (self.prev + (self.next - self.prev) * frac, v)
    }

    pub fn step(&mut self, ctx: &mut Ctx, sync_at: Option<u64>, period_us: u64) -> ModeOut {
        self.step_on(ctx, o::TARGET_POSITION, sync_at, period_us)
    }

    /// One tick following the target object `target` (a store slot).
    pub fn step_on(
        &mut self,
        ctx: &mut Ctx,
        target: usize,
        sync_at: Option<u64>,
        period_us: u64,
    ) -> ModeOut {
        let raw = ctx.store.i32(target);
        let changed = raw != self.last_raw;
        if changed {
            self.target_uu += raw.wrapping_sub(self.last_raw) as f64;
            self.last_raw = raw;
        }
        let (uu, limited) = ctx.clamp_sw_limits(self.target_uu);
        let tgt = ctx.to_inc_pos(uu);
        if let Some(t) = sync_at {
            let (p, _) = self.eval(t);
            self.prev = p;
            self.next = tgt;
            self.t_sync = t;
            self.period_us = period_us;
        } else {
            let stale = self.period_us == 0
                || ctx.now.saturating_sub(self.t_sync) > self.period_us.saturating_mul(3);
            if stale && changed {
                self.prev = tgt;
                self.next = tgt;
                self.period_us = 0;
            }
        }
        let (pos, v) = self.eval(ctx.now);
        ctx.axis.pos = pos;
        ctx.axis.vel = v;
        let vel_off = ctx.f.vel_to_inc(ctx.store.i32(o::VEL_OFFSET) as f64);
        ModeOut {
            setpoint: Setpoint::Position {
                position_inc: pos,
                velocity_ff_inc_per_s: v + vel_off,
                torque_ff_permille: ctx.store.i32(o::TORQUE_OFFSET) as f64,
            },
            target_reached: false,
            oms12: !ctx.halt,
            oms13: false,
            limit: limited,
            position_mode: true,
        }
    }
}
