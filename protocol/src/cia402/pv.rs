//! Profile velocity mode (3): ramps with 0x6083/0x6084 to 0x60FF, target reached by the
//! velocity window 0x606D/0x606E, statusword bit 12 = speed is zero (0x606F/0x6070).

use super::objects as o;
use super::{Ctx, ModeOut, TimedWindow};
use crate::drive::Setpoint;

#[derive(Clone, Copy, Debug, Default)]
pub struct Pv {
    reached: TimedWindow,
    zero: TimedWindow,
}

impl Pv {
    pub fn enter(&mut self) {
        *self = Pv::default();
    }

    pub fn step(&mut self, ctx: &mut Ctx) -> ModeOut {
        let target_uu = ctx.store.i32(o::TARGET_VELOCITY) as f64;
        let target = ctx.f.vel_to_inc(target_uu);
        let max = ctx.vel_limit(f64::INFINITY);
        let target = target.clamp(-max, max);
        let limit = target != ctx.f.vel_to_inc(target_uu);
        if ctx.halt {
            ctx.axis
                .ramp_velocity(0.0, ctx.halt_dec, ctx.halt_dec, ctx.dt);
        } else {
            let acc = ctx.acc(o::PROFILE_ACC);
            let dec = ctx.acc(o::PROFILE_DEC);
            ctx.axis.ramp_velocity(target, acc, dec, ctx.dt);
        }
        // keep the generated position near the real one (no position loop in PV)
        ctx.axis.pos = ctx.act_inc;
        let win = ctx.f.vel_to_inc(ctx.store.u32(o::VEL_WINDOW) as f64);
        let goal = if ctx.halt { 0.0 } else { target };
        let inside = (goal - ctx.act_vel).abs() <= win && ctx.axis.vel == goal;
        let thr = ctx.f.vel_to_inc(ctx.store.u32(o::VEL_THRESHOLD) as f64);
        ModeOut {
            setpoint: Setpoint::Velocity {
                velocity_inc_per_s: ctx.axis.vel,
                torque_ff_permille: 0.0,
            },
            target_reached: self
                .reached
                .update(inside, ctx.now, ctx.store.u32(o::VEL_WINDOW_TIME)),
            oms12: self.zero.update(
                ctx.act_vel.abs() <= thr,
                ctx.now,
                ctx.store.u32(o::VEL_THRESHOLD_TIME),
            ),
            oms13: false,
            limit,
            position_mode: false,
        }
    }
}
