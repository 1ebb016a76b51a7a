//! Distributed clocks: the local clock and its time control loop ([`DcClock`]), the SYNC0
//! unit of the ESC (ETG.1000.4 / the ESC register description, "SYNC signal generation")
//! and the DC synchronisation mode of ETG.1020.
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

pub use crate::esc::{DIFF_FILTER_DEPTH_DEFAULT, SPEED_COUNTER_START_DEFAULT};
/// The loop's frequency correction is held within this, ppb (a crystal's drift is tens of ppm).
pub const FREQ_CORRECTION_MAX_PPB: i64 = 500_000;
/// A frequency estimate needs at least this much of the frames' clock between the writes it
/// compares, ns (back-to-back writes only steer the phase).
pub const FREQ_ESTIMATE_MIN_NS: u64 = 50_000;
/// 0x092C's magnitude (bits 0..30).
const DIFF_MAGNITUDE: u64 = 0x7FFF_FFFF;
const PPB: i128 = 1_000_000_000;

/// The ESC's local clock and its time control loop (a model of ETG.1000.4's drift control,
/// not the ESC's gate-level arithmetic).
///
/// The local clock runs from the frames' clock (the host's, ns) at a configurable drift
/// (ppb; 0 by default: the local clock is then the frames' clock until a master steers it).
/// A master's write of the system time (0x0910, 4 or 8 bytes: ARMW / FRMW of the reference
/// clock's time, or a plain write) does not set the time: the value plus the system time
/// delay (0x0928) is compared with the local copy of the system time (local clock plus the
/// offset 0x0920, in 32 bits for a 4-byte write), and the difference (local minus received)
/// feeds the loop:
/// - the phase: the difference is slewed out, never stepped, at the rate the speed counter
///   start (0x0930) allows (10^8 / start ppb: 24.4 ppm for the default 0x1000), so the system
///   time stays monotonic;
/// - the frequency: what the difference grew by since the previous estimate, over the time
///   between them (at least [`FREQ_ESTIMATE_MIN_NS`]), corrects the clock's rate by a quarter
///   of that error per estimate, held within [`FREQ_CORRECTION_MAX_PPB`];
/// - 0x092C is the mean of the differences (a filter of depth 0x0934 bits 0..3: each write
///   moves the mean by 1/2^depth of the way), sign in bit 31 (set: the local copy is smaller
///   than the received time), magnitude in bits 0..30, as the ESC reports it.
///
/// A write of the speed counter start (0x0930) resets the loop (as SOEM's `config_init` does
/// right after its broadcast write of 0x0910). Nothing here allocates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DcClock {
    drift_ppb: i64,
    freq_ppb: i64,
    base_host_ns: u64,
    base_local_ns: u64,
    /// The difference still to slew out at the base, ns (local minus reference).
    pending_ns: i64,
    /// Slew rate, ppb.
    slew_ppb: i64,
    diff_mean_ns: i64,
    /// Start of the current frequency estimate (frames' clock) and the growth of the
    /// difference since then, ns.
    estimate_from_ns: Option<u64>,
    growth_ns: i64,
}

impl Default for DcClock {
    fn default() -> Self {
        DcClock {
            drift_ppb: 0,
            freq_ppb: 0,
            base_host_ns: 0,
            base_local_ns: 0,
            pending_ns: 0,
            slew_ppb: slew_ppb(SPEED_COUNTER_START_DEFAULT),
            diff_mean_ns: 0,
            estimate_from_ns: None,
            growth_ns: 0,
        }
    }
}

/// The slew rate the speed counter start allows, ppb (a start below 0x80 counts as 0x80).
fn slew_ppb(speed_counter_start: u16) -> i64 {
    100_000_000 / i64::from(speed_counter_start.max(0x80))
}

impl DcClock {
    /// The clock's drift against the frames' clock, ppb (+: the local clock runs fast).
    pub fn drift_ppb(&self) -> i64 {
        self.drift_ppb
    }

    /// The loop's frequency correction now, ppb.
    pub fn freq_correction_ppb(&self) -> i64 {
        self.freq_ppb
    }

    /// Set the drift from frames' time `host_ns` on (the past is kept).
    pub fn set_drift_ppb(&mut self, host_ns: u64, drift_ppb: i64) {
        self.rebase(host_ns);
        self.drift_ppb = drift_ppb.clamp(-(PPB as i64) / 2, PPB as i64 / 2);
    }

    /// (time to slew the pending difference out, direction -1 / 0 / +1 of the local clock)
    fn ramp(&self) -> (u64, i128) {
        if self.pending_ns == 0 || self.slew_ppb == 0 {
            return (0, 0);
        }
        let t = i128::from(self.pending_ns.unsigned_abs()) * PPB / i128::from(self.slew_ppb);
        (
            u64::try_from(t).unwrap_or(u64::MAX),
            -i128::from(self.pending_ns.signum()),
        )
    }

    /// The local clock at frames' time `host_ns` (not before the last write: earlier times
    /// count as that one).
    pub fn local_ns(&self, host_ns: u64) -> u64 {
        let dt = host_ns.saturating_sub(self.base_host_ns);
        let (ramp_ns, dir) = self.ramp();
        let rate = i128::from(self.drift_ppb + self.freq_ppb);
        let phase = if dt >= ramp_ns {
            -i128::from(self.pending_ns)
        } else {
            dir * i128::from(dt) * i128::from(self.slew_ppb) / PPB
        };
        let dt = i128::from(dt);
        let local = i128::from(self.base_local_ns) + dt + dt * rate / PPB + phase;
        local.clamp(0, i128::from(u64::MAX)) as u64
    }

    /// The frames' time at which the local clock reads `local_ns` (the first at or after,
    /// to a nanosecond; before the last write: that far before it).
    pub fn host_ns(&self, local_ns: u64) -> u64 {
        if local_ns <= self.base_local_ns {
            return self
                .base_host_ns
                .saturating_sub(self.base_local_ns - local_ns);
        }
        let rate = i128::from(self.drift_ppb + self.freq_ppb);
        let (ramp_ns, dir) = self.ramp();
        let ramp_end_local = self.local_ns(self.base_host_ns.saturating_add(ramp_ns));
        let ceil = |num: i128, den: i128| (num + den - 1) / den.max(1);
        let dt = if dir != 0 && local_ns <= ramp_end_local {
            let k = PPB + rate + dir * i128::from(self.slew_ppb);
            ceil(i128::from(local_ns - self.base_local_ns) * PPB, k)
        } else {
            let past = i128::from(local_ns) - i128::from(ramp_end_local);
            i128::from(ramp_ns) + ceil(past * PPB, PPB + rate)
        };
        let host = i128::from(self.base_host_ns) + dt.max(0);
        host.clamp(0, i128::from(u64::MAX)) as u64
    }

    /// Move the base to `host_ns` (what was slewed since is no longer pending).
    fn rebase(&mut self, host_ns: u64) {
        if host_ns <= self.base_host_ns {
            return;
        }
        let local = self.local_ns(host_ns);
        let (ramp_ns, dir) = self.ramp();
        let dt = host_ns - self.base_host_ns;
        let slewed = if dt >= ramp_ns {
            -self.pending_ns
        } else {
            (dir * i128::from(dt) * i128::from(self.slew_ppb) / PPB) as i64
        };
        self.pending_ns += slewed;
        self.base_local_ns = local;
        self.base_host_ns = host_ns;
    }

    /// A write of the speed counter start (0x0930): the loop starts over at that bandwidth.
    pub fn reset(&mut self, host_ns: u64, speed_counter_start: u16) {
        self.rebase(host_ns);
        self.freq_ppb = 0;
        self.pending_ns = 0;
        self.diff_mean_ns = 0;
        self.estimate_from_ns = None;
        self.growth_ns = 0;
        self.slew_ppb = slew_ppb(speed_counter_start);
    }

    /// A master wrote `received_ns` (`wide`: 8 bytes, else the low 32 bits) to the system
    /// time at frames' time `host_ns`; `offset_ns` (0x0920) and `delay_ns` (0x0928) as now,
    /// `filter_depth` 0x0934 bits 0..3. Returns 0x092C's new value.
    pub fn received(
        &mut self,
        host_ns: u64,
        received_ns: u64,
        wide: bool,
        (offset_ns, delay_ns): (u64, u32),
        filter_depth: u8,
    ) -> u32 {
        self.rebase(host_ns);
        let local_system = self.base_local_ns.wrapping_add(offset_ns);
        let received = received_ns.wrapping_add(u64::from(delay_ns));
        let diff = if wide {
            local_system.wrapping_sub(received) as i64
        } else {
            i64::from((local_system as u32).wrapping_sub(received as u32) as i32)
        };
        // what the difference grew by since the last write, beyond what was still pending
        self.growth_ns = self
            .growth_ns
            .saturating_add(diff.saturating_sub(self.pending_ns));
        match self.estimate_from_ns {
            None => {
                self.estimate_from_ns = Some(host_ns);
                self.growth_ns = 0;
            }
            Some(from) if host_ns.saturating_sub(from) >= FREQ_ESTIMATE_MIN_NS => {
                let span = i128::from(host_ns - from);
                let error_ppb = i128::from(self.growth_ns) * PPB / span;
                let step = (error_ppb / 4).clamp(-PPB, PPB) as i64;
                self.freq_ppb =
                    (self.freq_ppb - step).clamp(-FREQ_CORRECTION_MAX_PPB, FREQ_CORRECTION_MAX_PPB);
                self.estimate_from_ns = Some(host_ns);
                self.growth_ns = 0;
            }
            Some(_) => {}
        }
        self.pending_ns = diff;
        let depth = u32::from(filter_depth & 0x0F);
        self.diff_mean_ns += (diff - self.diff_mean_ns) / (1i64 << depth);
        self.diff_register()
    }

    /// 0x092C: the mean difference, sign in bit 31 (set: the local copy is smaller than the
    /// received time), magnitude in bits 0..30 (held at its largest).
    pub fn diff_register(&self) -> u32 {
        let m = self.diff_mean_ns.unsigned_abs().min(DIFF_MAGNITUDE) as u32;
        if self.diff_mean_ns < 0 {
            m | 0x8000_0000
        } else {
            m
        }
    }
}

/// 0x092C as a signed difference, ns (local minus received).
pub fn diff_from_register(v: u32) -> i64 {
    let m = i64::from(v & 0x7FFF_FFFF);
    if v & 0x8000_0000 != 0 {
        -m
    } else {
        m
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
    fn the_local_clock_drifts_and_maps_back_to_the_frames_clock() {
        let mut c = DcClock::default();
        assert_eq!(c.local_ns(123_456), 123_456, "no drift: the frames' clock");
        c.set_drift_ppb(1_000_000, 50_000);
        assert_eq!(c.local_ns(1_000_000), 1_000_000);
        assert_eq!(c.local_ns(1_001_000_000), 1_001_050_000, "50 ppm over 1 s");
        // a difference being slewed out: the local clock stays monotonic and maps back
        c.received(2_000_000, 1_900_000, true, (0, 0), 0);
        let mut last = 0;
        for t in (2_000_000..40_000_000).step_by(777_777) {
            let l = c.local_ns(t);
            assert!(l >= last);
            last = l;
            let h = c.host_ns(l);
            assert!(h.abs_diff(t) <= 1, "{t} -> {l} -> {h}");
        }
    }

    #[test]
    fn a_4_byte_write_compares_the_low_32_bits_and_the_register_has_a_sign_bit() {
        let mut c = DcClock::default();
        let now = 0x1_0000_0100u64;
        // the low 32 bits of the local time are 0x100; 0x200 received: 256 ns behind
        let reg = c.received(now, 0x200, false, (0, 0), 0);
        assert_eq!(reg, 0x8000_0000 | 0x100);
        assert_eq!(diff_from_register(reg), -256);
        // the delay counts to the received time; a filter of depth 2 moves a quarter of the way
        let mut c = DcClock::default();
        assert_eq!(c.received(now, now - 1000, true, (0, 200), 2), 200);
        c.reset(now, SPEED_COUNTER_START_DEFAULT);
        assert_eq!(c.diff_register(), 0);
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
