//! Interpolated position mode (7, CiA 402 "ip"): the master writes a set-point to the
//! interpolation data record 0x60C1:1 every interpolation period (0x60C2) and enables the
//! interpolation with controlword bit 4 ("enable ip mode"); the drive interpolates linearly
//! between the set-points (sub-mode 0x60C0 = 0, the only one CiA 402 defines) with the same
//! interpolator as CSP (`csp.rs`). Statusword bit 12 says "ip mode active" while bit 4 is set
//! in OPERATION ENABLED; with bit 4 clear the drive holds its position and 0x60C1:1 follows it,
//! so enabling again starts from where the axis is (no jump). Bit 13 is the following error,
//! as in CSP.

use super::objects as o;
use super::{Ctx, ModeOut};
use crate::cia402::controlword::BIT_NEW_SETPOINT as BIT_ENABLE_IP;
use crate::drive::Setpoint;

#[derive(Clone, Copy, Debug, Default)]
pub struct Ip {
    interpolator: super::csp::Csp,
    active: bool,
}

impl Ip {
    /// Entering IP holds the current position: 0x60C1:1 is set to it.
    pub fn enter(&mut self, ctx: &mut Ctx) {
        self.interpolator.enter_on(ctx, o::IP_DATA);
        self.active = false;
    }

    pub fn step(&mut self, ctx: &mut Ctx, sync_at: Option<u64>, period_us: u64) -> ModeOut {
        let enabled = ctx.cw & BIT_ENABLE_IP != 0 && !ctx.halt;
        if !enabled {
            // hold; the set-point follows the axis, so enabling starts without a jump
            self.interpolator.enter_on(ctx, o::IP_DATA);
            self.active = false;
            return ModeOut {
                setpoint: Setpoint::Position {
                    position_inc: ctx.axis.pos,
                    velocity_ff_inc_per_s: 0.0,
                    torque_ff_permille: 0.0,
                },
                target_reached: true,
                position_mode: true,
                ..ModeOut::default()
            };
        }
        self.active = true;
        let mut out = self
            .interpolator
            .step_on(ctx, o::IP_DATA, sync_at, period_us);
        out.oms12 = true; // ip mode active
        out
    }
}
