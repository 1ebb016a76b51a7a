//! Distributed clocks: the SYNC0 unit of the ESC (ETG.1000.4 / the ESC register description,
//! "SYNC signal generation") and the DC synchronisation mode of ETG.1020.
//!
//! The slave's system time is its local clock plus the offset the master writes (0x0920);
//! the master writes the start time of cyclic operation (0x0990, system time, ns) and the
//! SYNC0 cycle (0x09A0, ns) and then activates cyclic operation and SYNC0 (0x0981 bits 0
//! and 1). From then on the ESC pulses SYNC0 at `start + k * cycle`; a cycle of 0 gives one
//! pulse at the start time (single shot). Read back while active, 0x0990 is the next pulse.
//! A start time already past at activation is not waited out as a 32-bit ESC waits for its
//! clock to wrap: the first pulse is the first one of that grid after the activation.
//!
//! The drive follows SYNC0 when the master chose DC SYNC0 as the synchronisation type of
//! the outputs (0x1C32:1 = 2) before SAFE-OP; [`check`] is what the slave checks then.

use crate::esc::{reg, Esc};

/// AL status codes of DC synchronisation (ETG.1000.6 table 11).
pub mod code {
    /// Invalid DC SYNC configuration: DC SYNC0 chosen, SYNC0 not activated.
    pub const INVALID_DC_SYNC_CONFIG: u16 = 0x0030;
    /// DC SYNC0 cycle time: shorter than the slave's minimum cycle time (0x1C32:5).
    pub const DC_SYNC0_CYCLE_TIME: u16 = 0x0036;
}

/// 0x1C32:1 / 0x1C33:1: free run.
pub const SYNC_FREE_RUN: u16 = 0;
/// 0x1C32:1 / 0x1C33:1: synchronous with the SM2 / SM3 event.
pub const SYNC_SM: u16 = 1;
/// 0x1C32:1 / 0x1C33:1: DC SYNC0.
pub const SYNC_DC_SYNC0: u16 = 2;

/// 0x0981 bit 0: cyclic operation enabled.
pub const ACTIVATE_CYCLIC: u8 = 0x01;
/// 0x0981 bit 1: SYNC0 generated.
pub const ACTIVATE_SYNC0: u8 = 0x02;

/// The SYNC0 unit as activated: when it pulses, in system time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sync0 {
    /// Generating pulses.
    active: bool,
    /// The first pulse, system time, ns.
    first_ns: u64,
    /// Cycle, ns (0: a single pulse).
    cycle_ns: u32,
}

impl Sync0 {
    /// The unit as the registers of `esc` set it at a write of 0x0981, the system time then
    /// being `system_ns`: inactive unless cyclic operation and SYNC0 are both enabled.
    pub fn activate(esc: &Esc, system_ns: u64) -> Sync0 {
        let act = esc.u8(reg::DC_ACTIVATION);
        if act & (ACTIVATE_CYCLIC | ACTIVATE_SYNC0) != ACTIVATE_CYCLIC | ACTIVATE_SYNC0 {
            return Sync0::default();
        }
        let start = esc.u64(reg::DC_START_TIME);
        let cycle_ns = esc.u32(reg::DC_SYNC0_CYCLE);
        let first_ns = if start >= system_ns || cycle_ns == 0 {
            start
        } else {
            // the first pulse of the grid after now
            let k = (system_ns - start).div_ceil(u64::from(cycle_ns));
            start.saturating_add(k.saturating_mul(u64::from(cycle_ns)))
        };
        Sync0 {
            active: true,
            first_ns,
            cycle_ns,
        }
    }

    /// Generating pulses.
    pub fn active(&self) -> bool {
        self.active
    }

    /// The SYNC0 cycle, ns (0: single shot).
    pub fn cycle_ns(&self) -> u32 {
        self.cycle_ns
    }

    /// The first pulse at or after system time `t_ns`; `None` when inactive, or after the
    /// single pulse of a cycle of 0.
    pub fn next_at_or_after(&self, t_ns: u64) -> Option<u64> {
        if !self.active {
            return None;
        }
        if t_ns <= self.first_ns {
            return Some(self.first_ns);
        }
        if self.cycle_ns == 0 {
            return None;
        }
        let cycle = u64::from(self.cycle_ns);
        let k = (t_ns - self.first_ns).div_ceil(cycle);
        self.first_ns.checked_add(k.checked_mul(cycle)?)
    }
}

/// The PRE-OP -> SAFE-OP check of the synchronisation type `sync_type` (0x1C32:1) against
/// the SYNC0 unit and the slave's minimum cycle time `min_cycle_ns` (0x1C32:5): DC SYNC0
/// needs SYNC0 activated (else 0x0030) with a cycle of at least the minimum (else 0x0036).
/// Free run and SM-synchronous need nothing.
pub fn check(sync_type: u16, sync0: &Sync0, min_cycle_ns: u32) -> Result<(), u16> {
    if sync_type != SYNC_DC_SYNC0 {
        return Ok(());
    }
    if !sync0.active() {
        return Err(code::INVALID_DC_SYNC_CONFIG);
    }
    if sync0.cycle_ns() < min_cycle_ns {
        return Err(code::DC_SYNC0_CYCLE_TIME);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn esc(start: u64, cycle: u32, act: u8) -> Esc {
        let mut e = Esc::new();
        e.set_u64(reg::DC_START_TIME, start);
        e.set_u32(reg::DC_SYNC0_CYCLE, cycle);
        e.set(reg::DC_ACTIVATION, &[act]);
        e
    }

    #[test]
    fn pulses_on_the_grid_of_start_and_cycle() {
        let s = Sync0::activate(&esc(5_000_000, 1_000_000, 3), 1_000_000);
        assert!(s.active());
        assert_eq!(s.next_at_or_after(0), Some(5_000_000));
        assert_eq!(s.next_at_or_after(5_000_000), Some(5_000_000));
        assert_eq!(s.next_at_or_after(5_000_001), Some(6_000_000));
        assert_eq!(s.next_at_or_after(7_999_999), Some(8_000_000));
    }

    #[test]
    fn a_start_in_the_past_begins_at_the_next_grid_point() {
        let s = Sync0::activate(&esc(1_000_000, 250_000, 3), 1_600_000);
        assert_eq!(s.next_at_or_after(0), Some(1_750_000));
    }

    #[test]
    fn inactive_without_both_bits_and_single_shot_with_cycle_zero() {
        for act in [0, 1, 2] {
            let s = Sync0::activate(&esc(5, 1000, act), 0);
            assert!(!s.active());
            assert_eq!(s.next_at_or_after(0), None);
        }
        let s = Sync0::activate(&esc(5_000, 0, 3), 0);
        assert_eq!(s.next_at_or_after(0), Some(5_000));
        assert_eq!(s.next_at_or_after(5_001), None);
    }

    #[test]
    fn the_end_of_time_does_not_overflow() {
        let s = Sync0::activate(&esc(u64::MAX - 10, 1_000_000, 3), 0);
        assert_eq!(s.next_at_or_after(u64::MAX - 5), None);
    }

    #[test]
    fn dc_sync0_needs_sync0_active_and_a_long_enough_cycle() {
        let on = Sync0::activate(&esc(0, 1_000_000, 3), 0);
        let fast = Sync0::activate(&esc(0, 50_000, 3), 0);
        let off = Sync0::default();
        assert_eq!(check(SYNC_FREE_RUN, &off, 125_000), Ok(()));
        assert_eq!(check(SYNC_SM, &off, 125_000), Ok(()));
        assert_eq!(check(SYNC_DC_SYNC0, &on, 125_000), Ok(()));
        assert_eq!(
            check(SYNC_DC_SYNC0, &off, 125_000),
            Err(code::INVALID_DC_SYNC_CONFIG)
        );
        assert_eq!(
            check(SYNC_DC_SYNC0, &fast, 125_000),
            Err(code::DC_SYNC0_CYCLE_TIME)
        );
    }
}
