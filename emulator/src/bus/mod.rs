//! The CAN bus as the runtime sees it: one trait, two implementations.
//!
//! - [`inproc::InProcBus`]: an in-process bus for tests, offline runs and the embedded demo.
//! - [`socketcan::SocketCanBus`]: a Linux SocketCAN interface (`can0`, `vcan0`).
//!
//! Both are non-blocking and allocation-free per frame. A frame the transport cannot take is a
//! counted drop ([`SendError::Full`]), never a panic or a stall.

pub mod fault;
pub mod inproc;
pub mod socketcan;

pub use drive_protocol::CanFrame;

/// Why a frame was not sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SendError {
    /// The transmit queue is full (ENOBUFS / EAGAIN): the frame is dropped and counted.
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
    /// The next received frame, `Ok(None)` when there is none now.
    fn recv(&mut self) -> Result<Option<CanFrame>, RecvError>;
    /// Wait up to `timeout_us` for a frame to arrive (lock-step mode); returns at once if one is
    /// queued. Implementations may return early.
    fn wait_readable(&mut self, timeout_us: u64);
    /// The runtime finished a tick. Transports that model time (the fault injector's delays)
    /// advance their clock here; the default does nothing.
    fn end_tick(&mut self) {}
}
