//! Loop statistics: ticks, overruns and a wake-up lateness histogram. Recording is
//! allocation-free (the histogram is sized once, up front).

use hdrhistogram::Histogram;
use std::fmt;

/// The statistics a node publishes in its statistics object (the emulator's record at base +
/// 0x100, `drive::objects`), sub-index 1.. in this order. `sync_lock_state`: 0 free-running,
/// 1 acquiring, 2 locked to SYNC; `sync_phase_error_us`: smoothed magnitude of the SYNC's
/// arrival minus the loop's prediction; `sync_period_us`: the SYNC period the loop measured;
/// `tx_full_waits`: times the transport's transmit queue was full and the loop waited for
/// room; `sync_window_missed`: synchronous TPDOs not sent because the 0x1007 window had
/// closed; `rx_overflows`: frames the kernel dropped because the receive queue of the
/// runtime's socket was full (SO_RXQ_OVFL, cumulative; a lock-step drive that lost SYNCs
/// there says so here).
#[rustfmt::skip]
pub const STATS_NAMES: [&str; 13] = [
    "ticks", "overruns", "lateness_p50_us", "lateness_p99_us", "lateness_max_us",
    "dropped_tx_frames", "node_tx_queue_overflows", "sync_lock_state", "sync_phase_error_us",
    "sync_period_us", "tx_full_waits", "sync_window_missed", "rx_overflows",
];

/// Values of the statistics object, in [`STATS_NAMES`] order.
pub type StatsValues = [u32; STATS_NAMES.len()];

/// Largest lateness the histogram resolves; later wake-ups are clamped to it.
const MAX_TRACKED_US: u64 = 10_000_000;

#[derive(Debug, Clone)]
pub struct LoopStats {
    pub period_us: u64,
    pub ticks: u64,
    /// Ticks whose work finished after the next tick's deadline.
    pub overruns: u64,
    /// Ticks skipped because the loop fell more than the catch-up limit behind.
    pub skipped_ticks: u64,
    /// Frames the transport refused (full transmit queue, interface down).
    pub tx_dropped: u64,
    /// Receive errors (interface down, bad frames from the socket).
    pub rx_errors: u64,
    /// Frames the kernel dropped because the receive queue was full (cumulative).
    pub rx_overflows: u64,
    /// Times the transport's transmit queue was full and the loop waited for room.
    pub tx_full_waits: u64,
    /// SYNCs received.
    pub syncs: u64,
    /// SYNC phase lock: state (0 free-running, 1 acquiring, 2 locked), smoothed magnitude of
    /// the phase error and the measured SYNC period, microseconds.
    pub sync_lock_state: u32,
    pub sync_phase_error_us: u64,
    pub sync_period_us: u64,
    lateness_us: Histogram<u64>,
    work_us: Histogram<u64>,
}

/// A snapshot for printing and for the node's statistics object.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct StatsSummary {
    pub period_us: u64,
    pub ticks: u64,
    pub overruns: u64,
    pub skipped_ticks: u64,
    pub tx_dropped: u64,
    pub rx_errors: u64,
    pub rx_overflows: u64,
    pub tx_full_waits: u64,
    pub syncs: u64,
    pub sync_lock_state: u32,
    pub sync_phase_error_us: u64,
    pub sync_period_us: u64,
    pub lateness_p50_us: u64,
    pub lateness_p99_us: u64,
    pub lateness_max_us: u64,
    pub work_p50_us: u64,
    pub work_p99_us: u64,
    pub work_max_us: u64,
}

impl LoopStats {
    pub fn new(period_us: u64) -> Self {
        let hist = || {
            Histogram::<u64>::new_with_bounds(1, MAX_TRACKED_US, 3)
                .expect("static histogram bounds are valid")
        };
        Self {
            period_us,
            ticks: 0,
            overruns: 0,
            skipped_ticks: 0,
            tx_dropped: 0,
            rx_errors: 0,
            rx_overflows: 0,
            tx_full_waits: 0,
            syncs: 0,
            sync_lock_state: 0,
            sync_phase_error_us: 0,
            sync_period_us: 0,
            lateness_us: hist(),
            work_us: hist(),
        }
    }

    /// Record one tick: how late it woke and how long its work took.
    pub fn record_tick(&mut self, lateness_us: u64, work_us: u64) {
        self.ticks += 1;
        self.lateness_us
            .saturating_record(lateness_us.min(MAX_TRACKED_US));
        self.work_us.saturating_record(work_us.min(MAX_TRACKED_US));
        if lateness_us + work_us > self.period_us {
            self.overruns += 1;
        }
    }

    pub fn summary(&self) -> StatsSummary {
        let q = |h: &Histogram<u64>, p: f64| {
            if h.is_empty() {
                0
            } else {
                h.value_at_quantile(p)
            }
        };
        StatsSummary {
            period_us: self.period_us,
            ticks: self.ticks,
            overruns: self.overruns,
            skipped_ticks: self.skipped_ticks,
            tx_dropped: self.tx_dropped,
            rx_errors: self.rx_errors,
            rx_overflows: self.rx_overflows,
            tx_full_waits: self.tx_full_waits,
            syncs: self.syncs,
            sync_lock_state: self.sync_lock_state,
            sync_phase_error_us: self.sync_phase_error_us,
            sync_period_us: self.sync_period_us,
            lateness_p50_us: q(&self.lateness_us, 0.5),
            lateness_p99_us: q(&self.lateness_us, 0.99),
            lateness_max_us: if self.lateness_us.is_empty() {
                0
            } else {
                self.lateness_us.max()
            },
            work_p50_us: q(&self.work_us, 0.5),
            work_p99_us: q(&self.work_us, 0.99),
            work_max_us: if self.work_us.is_empty() {
                0
            } else {
                self.work_us.max()
            },
        }
    }
}

impl StatsSummary {
    /// The summary for people; a lock-step loop (its time is the SYNCs themselves) has no SYNC
    /// phase lock, so it says "lock-step" there instead of "free-running, SYNC phase error 0".
    pub fn text(&self, lockstep: bool) -> String {
        let mut out = String::new();
        let _ = self.write(&mut out, lockstep);
        out
    }

    fn write(&self, f: &mut impl fmt::Write, lockstep: bool) -> fmt::Result {
        write!(
            f,
            "ticks {} at {} us, overruns {}, skipped {}, lateness p50/p99/max {}/{}/{} us, \
             work p50/p99/max {}/{}/{} us, tx dropped {}, rx errors {}, rx overflow {}, tx full waits {}, \
             SYNCs {}, ",
            self.ticks,
            self.period_us,
            self.overruns,
            self.skipped_ticks,
            self.lateness_p50_us,
            self.lateness_p99_us,
            self.lateness_max_us,
            self.work_p50_us,
            self.work_p99_us,
            self.work_max_us,
            self.tx_dropped,
            self.rx_errors,
            self.rx_overflows,
            self.tx_full_waits,
            self.syncs,
        )?;
        if lockstep {
            return f.write_str("lock-step");
        }
        write!(
            f,
            "{}, SYNC phase error {} us, SYNC period {} us",
            lock_name(self.sync_lock_state),
            self.sync_phase_error_us,
            self.sync_period_us
        )
    }
}

impl fmt::Display for StatsSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.write(f, false)
    }
}

/// The lock state's name for people (status line, exit summary).
pub fn lock_name(code: u32) -> &'static str {
    match code {
        2 => "SYNC-locked",
        1 => "acquiring SYNC",
        _ => "free-running",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lock_step_summary_names_no_phase_lock() {
        let mut st = LoopStats::new(1000);
        st.syncs = 603;
        let s = st.summary();
        let free = s.text(false);
        assert!(free.contains("free-running, SYNC phase error"), "{free}");
        let ls = s.text(true);
        assert!(
            ls.starts_with("ticks ") && ls.ends_with("SYNCs 603, lock-step"),
            "{ls}"
        );
        assert!(
            !ls.contains("free-running") && !ls.contains("phase error"),
            "{ls}"
        );
    }

    #[test]
    fn overrun_when_lateness_plus_work_exceeds_period() {
        let mut s = LoopStats::new(1000);
        s.record_tick(10, 500);
        s.record_tick(600, 500);
        s.record_tick(0, 1200);
        assert_eq!(s.ticks, 3);
        assert_eq!(s.overruns, 2);
        let sum = s.summary();
        assert!(sum.lateness_max_us >= 600 && sum.lateness_max_us < 610);
        assert!(sum.lateness_p50_us <= 11);
    }

    #[test]
    fn huge_lateness_is_clamped_not_lost() {
        let mut s = LoopStats::new(1000);
        s.record_tick(u64::MAX / 2, 0);
        assert_eq!(s.ticks, 1);
        assert!(s.summary().lateness_max_us >= MAX_TRACKED_US - MAX_TRACKED_US / 100);
    }
}
