//! Cyclic synchronous torque mode (10): 0x6071 + 0x60B2 torque offset, limited by 0x6072.
//! Statusword bit 12 = drive follows the command value.

use super::objects as o;
use super::{Ctx, ModeOut};
use crate::drive::Setpoint;

pub fn step(ctx: &mut Ctx) -> ModeOut {
    let t = ctx.store.i32(o::TARGET_TORQUE) as f64 + ctx.store.i32(o::TORQUE_OFFSET) as f64;
    let max = ctx.store.u32(o::MAX_TORQUE) as f64;
    let tc = t.clamp(-max, max);
    ctx.axis.vel = ctx.act_vel;
    ctx.axis.pos = ctx.act_inc;
    ModeOut {
        setpoint: Setpoint::Torque {
            torque_permille: tc,
        },
        target_reached: false,
        oms12: !ctx.halt,
        oms13: false,
        limit: tc != t,
        position_mode: false,
    }
}
