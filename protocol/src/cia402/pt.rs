//! Profile torque mode (4): the torque demand 0x6074 ramps to the target torque 0x6071
//! (per mille of the rated torque 0x6076, limited by 0x6072) at the torque slope 0x6087 (per
//! mille per second; 0 = a step), 0x6088 torque profile type 0 = linear ramp (the only one).
//! Halt (controlword bit 8) ramps the demand to 0 at the same slope. Statusword bit 10
//! (target reached) once the demand has reached its goal (the target, or 0 while halted);
//! bits 12 and 13 are reserved in this mode. The speed limit the drive applies in every
//! mode (0x6080) holds here too: the motor's torque folds back at it.

use super::objects as o;
use super::{Ctx, ModeOut};
use crate::drive::Setpoint;

#[derive(Clone, Copy, Debug, Default)]
pub struct Pt {
    /// The torque demand 0x6074, per mille of the rated torque.
    demand_permille: f64,
}

impl Pt {
    /// Enter the mode: the ramp starts from the torque the motor gives now (0 after an
    /// enable; a mode change on the fly does not jump).
    pub fn enter(&mut self, ctx: &Ctx) {
        let t = ctx.fb.torque_permille;
        self.demand_permille = if t.is_finite() { t } else { 0.0 };
    }

    pub fn step(&mut self, ctx: &mut Ctx) -> ModeOut {
        let target = ctx.store.i32(o::TARGET_TORQUE) as f64;
        let max = ctx.store.u32(o::MAX_TORQUE) as f64;
        let clamped = target.clamp(-max, max);
        let goal = if ctx.halt { 0.0 } else { clamped };
        let slope_permille_per_s = ctx.store.u32(o::TORQUE_SLOPE) as f64;
        self.demand_permille = if slope_permille_per_s == 0.0 {
            goal
        } else {
            let step = slope_permille_per_s * ctx.dt;
            let d = self.demand_permille;
            if (goal - d).abs() <= step {
                goal
            } else {
                d + step.copysign(goal - d)
            }
        };
        // no position or velocity loop in this mode: the generator follows the motor
        ctx.axis.vel = ctx.act_vel;
        ctx.axis.pos = ctx.act_inc;
        ModeOut {
            setpoint: Setpoint::Torque {
                torque_permille: self.demand_permille,
            },
            target_reached: self.demand_permille == goal,
            oms12: false,
            oms13: false,
            limit: clamped != target,
            position_mode: false,
        }
    }
}
