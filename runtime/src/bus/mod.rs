//! The CAN bus as the runtime sees it: one trait, three implementations.
//!
//! - [`inproc::InProcBus`]: an in-process bus for tests, offline runs and the embedded demo.
//! - `socketcan::SocketCanBus`: a Linux SocketCAN interface (`can0`, `vcan0`); cargo feature
//!   `socketcan` (on by default).
//! - [`socketcand::SocketcandBus`]: the bus served over TCP in the socketcand protocol, for
//!   CAN tools where there is no kernel CAN (`run --socketcand`).
//!
//! [`live::LiveTransport`] is the one `run` chose at start. All are non-blocking and allocation-free per frame. A frame the transport cannot take
//! ([`SendError::Full`]) is retried after a bounded wait and counted; never a panic or a stall.

pub mod ethercat;
pub mod fault;
pub mod inproc;
pub mod live;
#[cfg(feature = "socketcan")]
pub mod socketcan;
pub mod socketcand;

pub use drive_protocol::CanFrame;

/// Why a frame was not sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SendError {
    /// The transmit queue is full (ENOBUFS / EAGAIN): the runtime waits for room (bounded, see
    /// [`CanBus::wait_writable`]) and counts the frame as dropped only if none comes.
    Full,
    /// The interface is down or gone: the frame is dropped; the caller keeps running.
    Down,
}

/// Why a receive failed (the caller counts it and goes on).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RecvError {
    /// The interface is down or gone.
    Down,
    /// Anything else the transport reported (error frame, truncated read).
    Other,
}

/// A non-blocking CAN endpoint.
pub trait CanBus {
    /// Queue a frame for transmission.
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError>;
    /// Queue several frames, in order, with as few system calls as the transport can (one
    /// `sendmmsg` on SocketCAN). Returns how many were taken from the front of `frames`, and
    /// why the next one was not (`None`: it may simply be retried, e.g. the transport takes
    /// at most so many at once). The default sends them one by one.
    fn send_batch(&mut self, frames: &[CanFrame]) -> (usize, Option<SendError>) {
        for (i, f) in frames.iter().enumerate() {
            if let Err(e) = self.send(f) {
                return (i, Some(e));
            }
        }
        (frames.len(), None)
    }
    /// The next received frame, `Ok(None)` when there is none now.
    fn recv(&mut self) -> Result<Option<CanFrame>, RecvError>;
    /// Wait up to `timeout_us` for a frame to arrive (lock-step mode); returns at once if one is
    /// queued. Implementations may return early.
    fn wait_readable(&mut self, timeout_us: u64);
    /// The runtime finished a tick. Transports that model time (the fault injector's delays)
    /// advance their clock here; the default does nothing.
    fn end_tick(&mut self) {}
    /// The descriptor that becomes readable when a frame arrives, so the real-time loop can
    /// wait on it together with its next deadline; `None` for transports without one.
    fn rx_fd(&self) -> Option<std::os::fd::RawFd> {
        None
    }
    /// The kernel's receive timestamp of the frame last returned by [`CanBus::recv`], ns on
    /// CLOCK_REALTIME (SO_TIMESTAMPNS); `None` when the transport does not know. Reading it
    /// costs no system call (the loop converts it with [`crate::time::Clock::realtime_to_us`]).
    fn last_rx_stamp_ns(&self) -> Option<i128> {
        None
    }
    /// Received frames the transport lost before the runtime could read them (the kernel's
    /// receive queue overflowed), cumulative since the bus was opened; 0 if it cannot tell.
    fn rx_overflows(&self) -> u64 {
        0
    }
    /// After [`SendError::Full`]: wait up to `timeout_us` for room in the transmit queue.
    /// Implementations may return early; the default returns at once.
    fn wait_writable(&mut self, timeout_us: u64) {
        let _ = timeout_us;
    }
}
