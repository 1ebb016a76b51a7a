//! An in-process CAN bus: every frame one endpoint sends is delivered to every other endpoint,
//! in order, like a wire. Endpoints may live on different threads. The queues are lock-free
//! and sized once (`crossbeam::queue::ArrayQueue`): sending never allocates, a full receiver
//! queue drops the frame for that receiver only and counts it (as a real controller's
//! overrun would).

use super::{CanBus, CanFrame, RecvError, SendError};
use crossbeam::queue::ArrayQueue;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

struct Shared {
    queues: Vec<ArrayQueue<CanFrame>>,
    overruns: Vec<AtomicU64>,
}

/// A bus with a fixed number of endpoints, created together.
pub struct InProcBus;

impl InProcBus {
    /// Create `endpoints` connected endpoints, each with a receive queue of `capacity` frames.
    pub fn endpoints(endpoints: usize, capacity: usize) -> Vec<InProcEndpoint> {
        let shared = Arc::new(Shared {
            queues: (0..endpoints).map(|_| ArrayQueue::new(capacity)).collect(),
            overruns: (0..endpoints).map(|_| AtomicU64::new(0)).collect(),
        });
        (0..endpoints)
            .map(|index| InProcEndpoint {
                shared: Arc::clone(&shared),
                index,
            })
            .collect()
    }
}

/// One node's connection to an [`InProcBus`].
pub struct InProcEndpoint {
    shared: Arc<Shared>,
    index: usize,
}

impl InProcEndpoint {
    /// Frames lost because this endpoint's receive queue was full.
    pub fn rx_overruns(&self) -> u64 {
        self.shared.overruns[self.index].load(Ordering::Relaxed)
    }
}

impl CanBus for InProcEndpoint {
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        for (i, q) in self.shared.queues.iter().enumerate() {
            if i != self.index && q.push(*frame).is_err() {
                self.shared.overruns[i].fetch_add(1, Ordering::Relaxed);
            }
        }
        Ok(())
    }

    fn recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        Ok(self.shared.queues[self.index].pop())
    }

    fn rx_overflows(&self) -> u64 {
        self.rx_overruns()
    }

    fn wait_readable(&mut self, timeout_us: u64) {
        let deadline = std::time::Instant::now() + std::time::Duration::from_micros(timeout_us);
        while self.shared.queues[self.index].is_empty() && std::time::Instant::now() < deadline {
            std::thread::sleep(std::time::Duration::from_micros(50));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_reach_every_other_endpoint_in_order_but_not_the_sender() {
        let mut eps = InProcBus::endpoints(3, 8);
        eps[0].send(&CanFrame::new(0x181, &[1])).unwrap();
        eps[0].send(&CanFrame::new(0x181, &[2])).unwrap();
        for ep in &mut eps[1..] {
            assert_eq!(ep.recv().unwrap().unwrap().data[0], 1);
            assert_eq!(ep.recv().unwrap().unwrap().data[0], 2);
            assert_eq!(ep.recv().unwrap(), None);
        }
        assert_eq!(eps[0].recv().unwrap(), None);
    }

    #[test]
    fn a_full_receiver_drops_and_counts_without_blocking_the_sender() {
        let mut eps = InProcBus::endpoints(2, 2);
        for k in 0..5u8 {
            eps[0].send(&CanFrame::new(0x200, &[k])).unwrap();
        }
        assert_eq!(eps[1].rx_overruns(), 3);
        assert_eq!(eps[1].recv().unwrap().unwrap().data[0], 0);
    }
}
