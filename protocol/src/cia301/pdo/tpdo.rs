//! TPDO transmission: at SYNC (types 0, 1..=240, sampling for 252), on RTR (252, 253), and
//! event-driven (254, 255) limited by the inhibit time and refreshed by the event timer.

use super::{layout, send, Pdo, PdoEngine, TransmissionType};
use crate::frame::CanFrame;
use crate::od::Store;

impl PdoEngine {
    /// At SYNC in operational.
    ///
    /// With `window_closed` (the SYNC was handled after the synchronous window 0x1007 closed)
    /// synchronous TPDOs are not sent (CiA 301); returns how many were held back.
    pub fn on_sync(
        &mut self,
        store: &Store,
        now_us: u64,
        window_closed: bool,
        out: &mut impl FnMut(CanFrame),
    ) -> u32 {
        let mut missed = 0;
        let mut emit = |p: &mut _, out: &mut _| {
            if window_closed {
                missed += 1;
            } else {
                send(p, store, now_us, out);
            }
        };
        for p in self.tpdo.iter_mut() {
            if !p.valid {
                continue;
            }
            match p.ttype {
                TransmissionType::SyncAcyclic if p.changed(store) => emit(p, out),
                TransmissionType::SyncCyclic(n) => {
                    p.sync_count = p.sync_count.saturating_add(1);
                    if p.sync_count >= n {
                        p.sync_count = 0;
                        emit(p, out);
                    }
                }
                TransmissionType::RtrSync => {
                    let mut d = [0u8; 8];
                    p.pack(store, &mut d);
                    p.sampled = d;
                }
                _ => {}
            }
        }
        missed
    }

    /// A remote frame in operational: answer it if a TPDO of type 252/253 has its
    /// identifier (252 with the data sampled at the last SYNC). Returns whether one did.
    pub fn on_rtr(
        &mut self,
        store: &Store,
        frame: &CanFrame,
        now_us: u64,
        out: &mut impl FnMut(CanFrame),
    ) -> bool {
        for p in self.tpdo.iter_mut() {
            // COB-ID bit 30 set: "no RTR allowed on this PDO" (CiA 301 7.5.2.35)
            let rtr_allowed = p.cob & super::COB_NO_RTR == 0;
            if !(p.valid && rtr_allowed && frame.rtr && p.id() == frame.id && p.ttype.is_rtr()) {
                continue;
            }
            if p.ttype == TransmissionType::RtrSync {
                out(CanFrame::new(
                    p.id(),
                    &p.sampled[..usize::from(p.len).min(p.sampled.len())],
                ));
            } else {
                send(p, store, now_us, out);
            }
            return true;
        }
        false
    }

    /// Event-driven TPDOs, every poll in operational: send on change once the inhibit time
    /// has passed, and when the event timer expires.
    pub fn poll_events(&mut self, store: &Store, now_us: u64, out: &mut impl FnMut(CanFrame)) {
        for p in self.tpdo.iter_mut() {
            if !p.valid || !p.ttype.is_event() {
                continue;
            }
            let (inhibit, timer) = timers_us(store, p);
            let inhibit_ok = passed(p.last_tx_us, inhibit, now_us);
            let timer_due = timer > 0 && passed(p.last_tx_us, timer, now_us);
            if inhibit_ok && (p.changed(store) || timer_due) {
                send(p, store, now_us, out);
            }
        }
    }

    /// When event-driven TPDO `k` next needs a look: its event timer, or the end of its
    /// inhibit time when its data changed meanwhile; `now_us` when it never sent.
    pub fn deadline_us(&self, store: &Store, k: usize, now_us: u64) -> Option<u64> {
        let p = &self.tpdo[k];
        if !p.valid || !p.ttype.is_event() {
            return None;
        }
        let Some(last) = p.last_tx_us else {
            return Some(now_us);
        };
        let (inhibit, timer) = timers_us(store, p);
        // a time beyond the end of the clock's range never comes (`checked_add`)
        let mut at = if timer > 0 {
            last.checked_add(timer.max(inhibit))
        } else {
            None
        };
        if p.changed(store) {
            if let Some(t) = last.checked_add(inhibit) {
                at = Some(at.map_or(t, |a| a.min(t)));
            }
        }
        at
    }
}

/// Whether `dt_us` has passed since `since` (always when nothing was sent yet; never when
/// `since + dt_us` is beyond the end of the clock's range, nor while the clock is before
/// `since`).
fn passed(since: Option<u64>, dt_us: u64, now_us: u64) -> bool {
    since.is_none_or(|l| l.checked_add(dt_us).is_some_and(|t| now_us >= t))
}

/// Inhibit time and event timer of a TPDO, us.
fn timers_us(store: &Store, p: &Pdo) -> (u64, u64) {
    (
        p.comm_value(store, layout::INHIBIT_TIME) as u64 * 100,
        p.comm_value(store, layout::EVENT_TIMER) as u64 * 1000,
    )
}
