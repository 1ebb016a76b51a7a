//! What a client that connects late gets first: the stream's recent past.
//!
//! A page opened on a run that has been going for a minute draws the span it shows at once
//! (not a fraction of a second that grows), its spectrum and verdict are there without waiting
//! for the next analysis, and its EMCY log shows what happened before. The history keeps the
//! last [`HISTORY_S`] seconds of `samples` messages (the longest span the page offers), at
//! most [`HISTORY_MAX_BYTES`] of them, the latest `spectrum` per axis, the latest `stats`, and
//! the last [`EVENTS_KEPT`] events (`emcy`, `injection`, `recording`). The messages are the
//! very ones sent live (shared, not copied), so a client reads the past as it would have read
//! it then.

use super::rate::PERIOD_MS;
use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;

/// One message of the stream: its type (the SSE event name) and its JSON text.
#[derive(Debug)]
pub struct Message {
    pub kind: &'static str,
    pub json: String,
}

/// Seconds of `samples` kept for a client that connects (the page's longest span).
pub const HISTORY_S: u64 = 60;
/// Most bytes of `samples` kept (a run of many axes keeps less than [`HISTORY_S`]).
pub const HISTORY_MAX_BYTES: usize = 16 << 20;
/// Events (`emcy`, `injection`, `recording`) kept.
pub const EVENTS_KEPT: usize = 64;

/// The stream's recent past (see the module's text).
#[derive(Debug, Default)]
pub struct History {
    samples: VecDeque<Arc<Message>>,
    samples_bytes: usize,
    events: VecDeque<Arc<Message>>,
    spectra: BTreeMap<u64, Arc<Message>>,
    stats: Option<Arc<Message>>,
}

impl History {
    /// Keep `m` if it is a kind the history keeps; `axis` is the message's axis (spectra).
    pub fn keep(&mut self, m: &Arc<Message>, axis: Option<u64>) {
        match m.kind {
            "samples" => {
                self.samples.push_back(Arc::clone(m));
                self.samples_bytes += m.json.len();
                let max_messages = (HISTORY_S * 1000 / PERIOD_MS) as usize;
                while self.samples.len() > max_messages || self.samples_bytes > HISTORY_MAX_BYTES {
                    match self.samples.pop_front() {
                        Some(old) => self.samples_bytes -= old.json.len(),
                        None => break,
                    }
                }
            }
            "spectrum" => {
                self.spectra.insert(axis.unwrap_or(0), Arc::clone(m));
            }
            "stats" => self.stats = Some(Arc::clone(m)),
            "emcy" | "injection" | "recording" => {
                self.events.push_back(Arc::clone(m));
                if self.events.len() > EVENTS_KEPT {
                    self.events.pop_front();
                }
            }
            _ => {}
        }
    }

    /// What a new client is sent after `hello`, oldest first: the events, the samples, then
    /// the latest spectrum of each axis and the latest statistics.
    pub fn replay(&self) -> VecDeque<Arc<Message>> {
        self.events
            .iter()
            .chain(&self.samples)
            .chain(self.spectra.values())
            .chain(&self.stats)
            .cloned()
            .collect()
    }

    /// Seconds of samples kept now, and their bytes (for tests and the client table).
    pub fn samples_kept(&self) -> (usize, usize) {
        (self.samples.len(), self.samples_bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg(kind: &'static str, n: usize) -> Arc<Message> {
        Arc::new(Message {
            kind,
            json: "x".repeat(n),
        })
    }

    #[test]
    fn keeps_the_last_span_of_samples_within_its_byte_budget() {
        let mut h = History::default();
        let per_s = (1000 / PERIOD_MS) as usize;
        for _ in 0..(HISTORY_S as usize + 10) * per_s {
            h.keep(&msg("samples", 100), None);
        }
        assert_eq!(h.samples_kept().0, HISTORY_S as usize * per_s);
        // Large messages: the byte budget rules.
        for _ in 0..100 {
            h.keep(&msg("samples", HISTORY_MAX_BYTES / 10), None);
        }
        let (n, bytes) = h.samples_kept();
        assert!(
            bytes <= HISTORY_MAX_BYTES && n <= 10,
            "{n} messages, {bytes} bytes"
        );
    }

    #[test]
    fn replays_events_samples_then_the_latest_spectrum_per_axis_and_stats() {
        let mut h = History::default();
        h.keep(&msg("hello", 1), None);
        h.keep(&msg("emcy", 1), None);
        h.keep(&msg("samples", 2), None);
        h.keep(&msg("spectrum", 3), Some(0));
        h.keep(&msg("spectrum", 4), Some(0));
        h.keep(&msg("spectrum", 5), Some(1));
        h.keep(&msg("stats", 6), None);
        h.keep(&msg("stats", 7), None);
        let r: Vec<(&str, usize)> = h.replay().iter().map(|m| (m.kind, m.json.len())).collect();
        assert_eq!(
            r,
            [
                ("emcy", 1),
                ("samples", 2),
                ("spectrum", 4),
                ("spectrum", 5),
                ("stats", 7)
            ]
        );
        for _ in 0..EVENTS_KEPT + 5 {
            h.keep(&msg("injection", 1), None);
        }
        assert_eq!(
            h.replay()
                .iter()
                .filter(|m| m.kind != "samples" && m.kind != "spectrum" && m.kind != "stats")
                .count(),
            EVENTS_KEPT
        );
    }
}
