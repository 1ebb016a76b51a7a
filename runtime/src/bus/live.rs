//! The bus of a live run (`drive-emu run`), chosen at start: a SocketCAN interface
//! (`--iface`), a socketcand server (`--socketcand`), or an in-process endpoint (the typed
//! API's `LiveBusSpec::InProcess`, a test's master on the other end).

use super::inproc::InProcEndpoint;
use super::socketcand::SocketcandBus;
use super::{CanBus, CanFrame, RecvError, SendError};

/// One of the transports, behind one [`CanBus`].
pub enum LiveTransport {
    #[cfg(feature = "socketcan")]
    SocketCan(super::socketcan::SocketCanBus),
    Socketcand(SocketcandBus),
    InProcess(InProcEndpoint),
}

/// `$bus.$call` on whichever transport this is.
macro_rules! each {
    ($self:expr, $b:ident => $e:expr) => {
        match $self {
            #[cfg(feature = "socketcan")]
            LiveTransport::SocketCan($b) => $e,
            LiveTransport::Socketcand($b) => $e,
            LiveTransport::InProcess($b) => $e,
        }
    };
}

impl LiveTransport {
    /// False while a SocketCAN interface is down; the others are always up.
    pub fn link_up(&self) -> bool {
        match self {
            #[cfg(feature = "socketcan")]
            LiveTransport::SocketCan(b) => b.link_up(),
            LiveTransport::Socketcand(_) | LiveTransport::InProcess(_) => true,
        }
    }

    /// The socketcand server, if that is the transport.
    pub fn socketcand(&self) -> Option<&SocketcandBus> {
        match self {
            LiveTransport::Socketcand(b) => Some(b),
            _ => None,
        }
    }
}

impl CanBus for LiveTransport {
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        each!(self, b => b.send(frame))
    }
    fn send_batch(&mut self, frames: &[CanFrame]) -> (usize, Option<SendError>) {
        each!(self, b => b.send_batch(frames))
    }
    fn recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        each!(self, b => b.recv())
    }
    fn wait_readable(&mut self, timeout_us: u64) {
        each!(self, b => b.wait_readable(timeout_us))
    }
    fn end_tick(&mut self) {
        each!(self, b => b.end_tick())
    }
    fn rx_fd(&self) -> Option<std::os::fd::RawFd> {
        each!(self, b => b.rx_fd())
    }
    fn last_rx_stamp_ns(&self) -> Option<i128> {
        each!(self, b => b.last_rx_stamp_ns())
    }
    fn rx_overflows(&self) -> u64 {
        each!(self, b => b.rx_overflows())
    }
    fn wait_writable(&mut self, timeout_us: u64) {
        each!(self, b => b.wait_writable(timeout_us))
    }
}
