//! Heartbeat producer (0x1017) and consumer (0x1016).
//!
//! Near the end of the clock's range a period or timeout that would end after `u64::MAX` us
//! never ends (no deadline, never due): see `Node::poll_at`.

use crate::cia301::emcy::Cause;
use crate::cia301::sdo::abort;
use crate::node::writes::{ObjectWrite, Verdict, WriteHooks};
use crate::node::DriveCore;
use crate::od::idx;

/// Producer: sends the NMT state every 0x1017 ms.
#[derive(Clone, Copy, Debug)]
pub struct Producer {
    /// `None`: beyond the end of the clock's range (never due).
    next_due_us: Option<u64>,
}

impl Default for Producer {
    /// Due at once (until a boot restarts it).
    fn default() -> Self {
        Producer {
            next_due_us: Some(0),
        }
    }
}

impl Producer {
    /// Restart the period (boot, or 0x1017 written).
    pub fn restart(&mut self, now_us: u64, period_ms: u16) {
        self.next_due_us = now_us.checked_add(period_ms as u64 * 1000);
    }

    /// When the next heartbeat is due (us), `None` when the producer is off.
    pub fn deadline_us(&self, period_ms: u16) -> Option<u64> {
        if period_ms == 0 {
            return None;
        }
        self.next_due_us
    }

    /// True when a heartbeat is due now.
    pub fn due(&mut self, now_us: u64, period_ms: u16) -> bool {
        if period_ms == 0 {
            return false;
        }
        let Some(due) = self.next_due_us.filter(|&d| now_us >= d) else {
            return false;
        };
        let p = period_ms as u64 * 1000;
        // Keep the grid; once a whole period was missed, restart from now (the next beat on
        // the grid would be due already: one heartbeat per poll, never two at one instant).
        self.next_due_us = if now_us - due >= p {
            now_us.checked_add(p)
        } else {
            due.checked_add(p)
        };
        true
    }
}

#[derive(Clone, Copy, Debug, Default)]
struct Slot {
    node: u8,
    time_ms: u16,
    last_us: u64,
    /// Monitoring starts at the first heartbeat received.
    armed: bool,
}

/// Consumer: up to four monitored producers. A timeout is reported once, then monitoring
/// waits for the next heartbeat of that node.
#[derive(Clone, Copy, Debug, Default)]
pub struct Consumer {
    slots: [Slot; 4],
}

impl Consumer {
    /// Configure slot `i` (0..4) from a 0x1016 entry.
    pub fn configure(&mut self, i: usize, entry: u32) {
        if let Some(s) = self.slots.get_mut(i) {
            s.node = (entry >> 16) as u8;
            s.time_ms = entry as u16;
            s.armed = false;
        }
    }

    /// A heartbeat (or boot-up) from `node` arrived.
    pub fn on_heartbeat(&mut self, node: u8, now_us: u64) {
        for s in self.slots.iter_mut() {
            if s.time_ms != 0 && s.node == node && node != 0 && node < 128 {
                s.last_us = now_us;
                s.armed = true;
            }
        }
    }

    /// Returns the node id of a producer that just timed out.
    pub fn poll(&mut self, now_us: u64) -> Option<u8> {
        for s in self.slots.iter_mut() {
            if s.armed && now_us.saturating_sub(s.last_us) > s.time_ms as u64 * 1000 {
                s.armed = false;
                return Some(s.node);
            }
        }
        None
    }

    /// When the first monitored producer times out (us), if any is being watched.
    pub fn deadline_us(&self) -> Option<u64> {
        self.slots
            .iter()
            .filter(|s| s.armed && s.time_ms != 0)
            .filter_map(|s| s.last_us.checked_add(s.time_ms as u64 * 1000 + 1))
            .min()
    }

    /// Whether `node` is configured for monitoring in some 0x1016 entry (non-zero time).
    pub fn is_monitoring(&self, node: u8) -> bool {
        self.slots.iter().any(|s| s.node == node && s.time_ms != 0)
    }
}

/// CiA 301: two 0x1016 entries with a non-zero time may not monitor the same node.
pub fn conflicts(entries: &[u32; 4], i: usize, new: u32) -> bool {
    let node = (new >> 16) as u8;
    let t = new as u16;
    if t == 0 || node == 0 {
        return false;
    }
    entries
        .iter()
        .enumerate()
        .any(|(k, &e)| k != i && (e >> 16) as u8 == node && e as u16 != 0)
}

/// The heartbeat objects whose writes the producer and consumer rule: 0x1016 (consumer
/// entries) and 0x1017 (producer time).
pub(crate) fn register_writes(t: &mut WriteHooks) {
    t.register(0x1016, 0x1016, write_consumer);
    t.register(0x1017, 0x1017, write_producer);
}

/// 0x1016:1..=4: an entry that monitors a node another entry monitors with a time is refused
/// (CiA 301 7.5.2.32); the consumer restarts that entry (it waits for a first heartbeat
/// again): a loss it reported is over, the fault it caused stays until the fault reset.
fn write_consumer(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    let Some(i) = (w.sub as usize).checked_sub(1).filter(|&i| i < 4) else {
        return Ok(Verdict::Store);
    };
    let first = idx(0x1016, 1);
    let mut entries = [0u32; 4];
    for (k, e) in entries.iter_mut().enumerate() {
        *e = c.store.u32(first + k);
    }
    if conflicts(&entries, i, w.raw as u32) {
        return Err(abort::PARAM_INCOMPATIBLE);
    }
    c.hbc.configure(i, w.raw as u32);
    if c.hb_lost {
        c.hb_lost = false;
        c.clear_emcy(crate::node::EMCY_HEARTBEAT, Cause::Condition);
    }
    Ok(Verdict::Store)
}

/// 0x1017: the producer restarts its period with the new time.
fn write_producer(c: &mut DriveCore, w: &ObjectWrite) -> Result<Verdict, u32> {
    c.hb.restart(c.comm_us, w.raw as u16);
    Ok(Verdict::Store)
}
