//! Homing mode (6). Methods:
//! - 35 and 37: the current position is home (position actual becomes 0x607C).
//! - 19 / 20: home switch (Feedback.home_switch). The search runs at 0x6099 sub 1 towards the
//!   switch edge: 19 moves positive while the switch is inactive (negative while active), 20
//!   the opposite. Home is where the switch changes state.
//! - 33 / 34: index pulse of the motor encoder, searched at 0x6099 sub 2 in negative (33) or
//!   positive (34) direction. The index is where the motor position crosses a multiple of
//!   0x608F sub 1 increments.
//!
//! Accelerations use 0x609A. After the home is found the axis stops with 0x609A and the
//! position actual at home equals the home offset 0x607C. Statusword bit 12 = homing attained,
//! bit 13 = homing error (unsupported method), bit 10 = target reached (standing).

use super::controlword::BIT_HOMING_START;
use super::objects as o;
use super::{Ctx, ModeOut};
use crate::drive::Setpoint;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
enum Phase {
    #[default]
    Idle,
    Switch {
        dir: f64,
        start_level: bool,
    },
    Index {
        dir: f64,
        start_rev: i64,
    },
    Stopping,
    Done,
    Error,
}

#[derive(Clone, Copy, Debug, Default)]
pub struct Hm {
    phase: Phase,
    attained: bool,
}

impl Hm {
    pub fn enter(&mut self) {
        self.phase = Phase::Idle;
        self.attained = false;
    }

    /// Returns the mode output; sets `ctx.new_origin` when home is found.
    pub fn step(&mut self, ctx: &mut Ctx) -> ModeOut {
        let start = ctx.rising & BIT_HOMING_START != 0;
        let res = (ctx.inc_per_motor_rev.round() as i64).max(1);
        let home_offset_inc = ctx.f.to_inc(ctx.store.i32(o::HOME_OFFSET) as f64);
        if start {
            self.attained = false;
            let method = ctx.store.i32(o::HOMING_METHOD) as i8;
            let sw = ctx.fb.home_switch;
            self.phase = match method {
                35 | 37 => {
                    ctx.new_origin = Some(ctx.act_inc - home_offset_inc);
                    self.attained = true;
                    Phase::Done
                }
                19 => Phase::Switch {
                    dir: if sw { -1.0 } else { 1.0 },
                    start_level: sw,
                },
                20 => Phase::Switch {
                    dir: if sw { 1.0 } else { -1.0 },
                    start_level: sw,
                },
                33 => Phase::Index {
                    dir: -1.0,
                    start_rev: ctx.fb.motor_position_inc.div_euclid(res),
                },
                34 => Phase::Index {
                    dir: 1.0,
                    start_rev: ctx.fb.motor_position_inc.div_euclid(res),
                },
                _ => Phase::Error,
            };
        } else if ctx.cw & BIT_HOMING_START == 0
            && matches!(self.phase, Phase::Switch { .. } | Phase::Index { .. })
        {
            // homing interrupted
            self.phase = Phase::Stopping;
        }
        let acc = ctx.acc(o::HOMING_ACC);
        match self.phase {
            _ if ctx.halt => {
                ctx.axis.stop(ctx.halt_dec, ctx.dt);
            }
            Phase::Switch { dir, start_level } => {
                if ctx.fb.home_switch != start_level {
                    ctx.new_origin = Some(ctx.act_inc - home_offset_inc);
                    self.attained = true;
                    self.phase = Phase::Stopping;
                    ctx.axis.stop(acc, ctx.dt);
                } else {
                    let v = ctx
                        .f
                        .vel_to_inc(ctx.store.u32(o::HOMING_SPEED_SWITCH) as f64);
                    ctx.axis.ramp_velocity(dir * v, acc, acc, ctx.dt);
                }
            }
            Phase::Index { dir, start_rev } => {
                let m = ctx.fb.motor_position_inc;
                let rev = m.div_euclid(res);
                if rev != start_rev {
                    // crossed the index at rev*res (positive) or start_rev*res (negative)
                    let index_inc = if rev > start_rev {
                        rev * res
                    } else {
                        start_rev * res
                    };
                    let home_act = ctx.act_inc - (m - index_inc) as f64;
                    ctx.new_origin = Some(home_act - home_offset_inc);
                    self.attained = true;
                    self.phase = Phase::Stopping;
                    ctx.axis.stop(acc, ctx.dt);
                } else {
                    let v = ctx.f.vel_to_inc(ctx.store.u32(o::HOMING_SPEED_ZERO) as f64);
                    ctx.axis.ramp_velocity(dir * v, acc, acc, ctx.dt);
                }
            }
            Phase::Stopping => {
                if ctx.axis.stop(acc, ctx.dt) {
                    self.phase = Phase::Done;
                }
            }
            Phase::Idle | Phase::Done | Phase::Error => {
                ctx.axis.vel = 0.0;
            }
        }
        let standing = ctx.axis.vel == 0.0;
        ModeOut {
            setpoint: Setpoint::Position {
                position_inc: ctx.axis.pos,
                velocity_ff_inc_per_s: ctx.axis.vel,
                torque_ff_permille: 0.0,
            },
            target_reached: standing
                && matches!(self.phase, Phase::Idle | Phase::Done | Phase::Error),
            oms12: self.attained && self.phase == Phase::Done,
            oms13: self.phase == Phase::Error,
            limit: false,
            position_mode: true,
        }
    }
}
