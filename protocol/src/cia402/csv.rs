//! Cyclic synchronous velocity mode (9): 0x60FF + 0x60B1 velocity offset, 0x60B2 torque
//! offset as feed-forward. Statusword bit 12 = drive follows the command value.

use super::objects as o;
use super::{Ctx, ModeOut};
use crate::drive::Setpoint;

pub fn step(ctx: &mut Ctx) -> ModeOut {
    let v = ctx
        .f
        .vel_to_inc(ctx.store.i32(o::TARGET_VELOCITY) as f64 + ctx.store.i32(o::VEL_OFFSET) as f64);
    let max = ctx.vel_limit(f64::INFINITY);
    let vc = v.clamp(-max, max);
    ctx.axis.vel = vc;
    ctx.axis.pos = ctx.act_inc;
    ModeOut {
        setpoint: Setpoint::Velocity {
            velocity_inc_per_s: vc,
            torque_ff_permille: ctx.store.i32(o::TORQUE_OFFSET) as f64,
        },
        target_reached: false,
        oms12: !ctx.halt,
        oms13: false,
        limit: vc != v,
        position_mode: false,
    }
}
