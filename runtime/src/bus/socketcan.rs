//! SocketCAN transport (`can0`, `vcan0`) through the `socketcan` crate.
//!
//! Non-blocking: a read that finds nothing returns `Ok(None)`; a full transmit queue (ENOBUFS,
//! EAGAIN) is [`SendError::Full`]; an interface that goes down (ENETDOWN, ENODEV, ENXIO) is
//! [`SendError::Down`] / [`RecvError::Down`]. The socket stays bound through a down/up cycle of
//! the interface, so the runtime simply keeps simulating, counts what it could not send and
//! resumes when the link is back. `link_up()` tells the status line which state we are in.

use super::{CanBus, CanFrame, RecvError, SendError};
use socketcan::frame::can_frame_default;
use socketcan::{CanSocket, Socket};
use std::os::fd::AsRawFd;

const CAN_EFF_FLAG: u32 = 0x8000_0000;
const CAN_RTR_FLAG: u32 = 0x4000_0000;
const CAN_ERR_FLAG: u32 = 0x2000_0000;
const CAN_EFF_MASK: u32 = 0x1FFF_FFFF;
const CAN_SFF_MASK: u32 = 0x7FF;

/// Why the interface could not be opened, with the advice a user needs.
#[derive(Debug)]
pub struct OpenError {
    pub iface: String,
    pub source: std::io::Error,
    /// The interface exists but is not a CAN interface: its link type (ARPHRD_*, from
    /// `/sys/class/net/IFACE/type`; CAN is 280).
    pub not_can: Option<u32>,
}

/// ARPHRD_CAN: the link type of can0, vcan0, slcan0 (`/sys/class/net/IFACE/type`).
pub const ARPHRD_CAN: u32 = 280;

/// The link type of a network interface from sysfs: `None` when there is no such entry (no
/// such interface, or no sysfs). Needs no CAN support in the kernel: a kernel without CAN
/// and a CAN socket bound to a non-CAN interface both say ENODEV, for an interface that
/// exists.
pub fn link_type(iface: &str) -> Option<u32> {
    if iface.is_empty() || iface.contains('/') || iface == "." || iface == ".." {
        return None;
    }
    let text = std::fs::read_to_string(format!("/sys/class/net/{iface}/type")).ok()?;
    text.trim().parse().ok()
}

fn link_type_name(t: u32) -> &'static str {
    match t {
        1 => ", Ethernet",
        772 => ", loopback",
        65534 => ", no link layer (tun, wireguard)",
        _ => "",
    }
}

impl std::fmt::Display for OpenError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(t) = self.not_can {
            return write!(
                f,
                "cannot open CAN interface {0}: {0} exists but is not a CAN interface (link \
                 type {t}{1}; CAN interfaces such as can0 and vcan0 have type {ARPHRD_CAN}: \
                 `ip -details link show` lists them; a virtual one: sudo ./vcan-setup.sh)",
                self.iface,
                link_type_name(t)
            );
        }
        let errno = match self.source.raw_os_error() {
            // Opening looks the interface up first, so a kernel without CAN says ENODEV too.
            Some(libc::ENODEV) if !kernel_has_can() => Some(libc::EAFNOSUPPORT),
            other => other,
        };
        let hint = match errno {
            Some(libc::EAFNOSUPPORT) => {
                " (this kernel has no CAN support; run inside user-mode Linux with \
                 ./vcan-setup.sh -- COMMAND, or use the embedded demo: drive-emu demo)"
            }
            Some(libc::ENODEV) => {
                " (no such interface; create it with: sudo ./vcan-setup.sh, or \
                 ip link add dev vcan0 type vcan && ip link set up vcan0)"
            }
            _ => "",
        };
        write!(
            f,
            "cannot open CAN interface {}: {}{}",
            self.iface, self.source, hint
        )
    }
}

impl std::error::Error for OpenError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        // Not a CAN interface: no system call failed, the message says it all.
        self.not_can.is_none().then_some(&self.source as _)
    }
}

/// True if this kernel can open a raw CAN socket at all.
pub fn kernel_has_can() -> bool {
    // SAFETY: plain socket(2) call; the descriptor is closed at once.
    let fd = unsafe { libc::socket(libc::AF_CAN, libc::SOCK_RAW, libc::CAN_RAW) };
    if fd >= 0 {
        // SAFETY: `fd` is a descriptor we own.
        unsafe { libc::close(fd) };
        true
    } else {
        false
    }
}

/// A non-blocking raw CAN socket bound to one interface.
pub struct SocketCanBus {
    socket: CanSocket,
    link_up: bool,
    /// Kernel receive timestamp of the last received frame, ns, CLOCK_REALTIME, if known.
    last_rx_stamp_ns: Option<i128>,
    /// Frames the kernel dropped on this socket's full receive queue (SO_RXQ_OVFL), summed
    /// from its wrapping 32-bit counter.
    rx_overflows: RxOverflows,
}

impl SocketCanBus {
    pub fn open(iface: &str) -> Result<Self, OpenError> {
        let err = |source| OpenError {
            iface: iface.to_string(),
            source,
            not_can: None,
        };
        if let Some(t) = link_type(iface).filter(|&t| t != ARPHRD_CAN) {
            return Err(OpenError {
                not_can: Some(t),
                ..err(std::io::Error::from_raw_os_error(libc::ENODEV))
            });
        }
        let socket = CanSocket::open(iface).map_err(err)?;
        socket.set_nonblocking(true).map_err(err)?;
        set_receive_buffer(&socket, RECEIVE_BUFFER_BYTES);
        enable_rx_timestamps(socket.as_raw_fd());
        enable_rx_overflow_count(socket.as_raw_fd());
        Ok(Self {
            socket,
            link_up: true,
            last_rx_stamp_ns: None,
            rx_overflows: RxOverflows::default(),
        })
    }

    /// False after a send or receive found the interface down, until traffic flows again.
    pub fn link_up(&self) -> bool {
        self.link_up
    }
}

/// Receive buffer asked for: tens of thousands of frames (a frame costs about 1 KiB of buffer
/// in the kernel), so a loop that stalls or falls behind for seconds (a loaded or virtualised
/// host) reads them late instead of losing them. With 4 MiB a lock-step drive on a loaded host
/// lost SYNCs (e2e reference_master). The kernel's default (~200 KiB) holds a few hundred.
pub const RECEIVE_BUFFER_BYTES: i32 = 32 << 20;

/// Ask for a receive buffer of `bytes`: SO_RCVBUFFORCE where permitted (CAP_NET_ADMIN), else
/// SO_RCVBUF (capped by net.core.rmem_max). Neither failing matters: the default still works.
/// Returns the size the kernel granted.
pub fn set_receive_buffer(socket: &CanSocket, bytes: i32) -> i32 {
    let fd = socket.as_raw_fd();
    let _ = set_socket_int(fd, libc::SO_RCVBUFFORCE, bytes)
        || set_socket_int(fd, libc::SO_RCVBUF, bytes);
    let mut granted: libc::c_int = 0;
    let mut glen = std::mem::size_of::<libc::c_int>() as libc::socklen_t;
    // SAFETY: getsockopt into a c_int of the size we pass.
    unsafe {
        libc::getsockopt(
            fd,
            libc::SOL_SOCKET,
            libc::SO_RCVBUF,
            (&mut granted as *mut libc::c_int).cast(),
            &mut glen,
        )
    };
    granted
}

/// Set the socket-level (SOL_SOCKET) option `opt` to the int `value` on `fd`; true if the
/// kernel took it.
fn set_socket_int(fd: libc::c_int, opt: libc::c_int, value: libc::c_int) -> bool {
    // SAFETY: setsockopt on a descriptor we own, with a valid c_int option value and its size.
    unsafe {
        libc::setsockopt(
            fd,
            libc::SOL_SOCKET,
            opt,
            (&value as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        ) == 0
    }
}

/// Ask the kernel to stamp every received frame (SO_TIMESTAMPNS, CLOCK_REALTIME), so the loop
/// knows when a frame arrived even if it read it late (after a stall). Failing is harmless: the
/// frame is then taken to have arrived when it was read.
fn enable_rx_timestamps(fd: libc::c_int) {
    set_socket_int(fd, libc::SO_TIMESTAMPNS, 1);
}

/// Ask the kernel to attach its count of frames dropped on this socket (receive queue full)
/// to the frames received after a drop (SO_RXQ_OVFL), so a drive that lost frames in the
/// kernel can say so. Failing is harmless: the count then stays 0.
fn enable_rx_overflow_count(fd: libc::c_int) {
    set_socket_int(fd, libc::SO_RXQ_OVFL, 1);
}

/// The kernel's drop counter (a wrapping u32, cumulative for the socket) as a u64 total.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct RxOverflows {
    last_raw: u32,
    total: u64,
}

impl RxOverflows {
    /// The kernel reported `raw` drops so far with a received frame.
    fn update(&mut self, raw: u32) {
        self.total += u64::from(raw.wrapping_sub(self.last_raw));
        self.last_raw = raw;
    }
}

/// What the kernel attached to a received frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct RxMeta {
    /// Receive timestamp, ns, CLOCK_REALTIME (SO_TIMESTAMPNS).
    stamp_ns: Option<i128>,
    /// The socket's cumulative drop count (SO_RXQ_OVFL).
    drops: Option<u32>,
}

/// One non-blocking `recvmsg` of a `can_frame` with its receive timestamp (ns, CLOCK_REALTIME)
/// and the kernel's drop count. No allocation: the frame and the control messages live on the
/// stack.
fn recv_stamped(fd: libc::c_int) -> std::io::Result<(libc::can_frame, RxMeta)> {
    let mut raw = can_frame_default();
    let mut iov = libc::iovec {
        iov_base: (&mut raw as *mut libc::can_frame).cast(),
        iov_len: std::mem::size_of::<libc::can_frame>(),
    };
    // u64 words keep the control buffer aligned for cmsghdr.
    let mut control = [0u64; 16];
    // SAFETY: msghdr is plain data; zeroed is a valid empty header.
    let mut msg: libc::msghdr = unsafe { std::mem::zeroed() };
    msg.msg_iov = &mut iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control.as_mut_ptr().cast();
    msg.msg_controllen = std::mem::size_of_val(&control) as _;
    // SAFETY: msg points at valid, live buffers of the sizes given.
    let n = unsafe { libc::recvmsg(fd, &mut msg, libc::MSG_DONTWAIT) };
    if n < 0 {
        return Err(std::io::Error::last_os_error());
    }
    if (n as usize) < std::mem::size_of::<libc::can_frame>() {
        return Err(std::io::Error::from(std::io::ErrorKind::UnexpectedEof));
    }
    Ok((raw, parse_control(&msg)))
}

/// The timestamp and drop count among the control messages of a received `msg`.
fn parse_control(msg: &libc::msghdr) -> RxMeta {
    let mut meta = RxMeta::default();
    // SAFETY: walking the control messages the kernel wrote into the buffer `msg` points at,
    // as cmsg(3) says; each payload is read unaligned at its advertised type.
    unsafe {
        let mut c = libc::CMSG_FIRSTHDR(msg);
        while !c.is_null() {
            if (*c).cmsg_level == libc::SOL_SOCKET {
                match (*c).cmsg_type {
                    libc::SCM_TIMESTAMPNS => {
                        let ts =
                            std::ptr::read_unaligned(libc::CMSG_DATA(c).cast::<libc::timespec>());
                        meta.stamp_ns =
                            Some(ts.tv_sec as i128 * 1_000_000_000 + ts.tv_nsec as i128);
                    }
                    libc::SO_RXQ_OVFL => {
                        meta.drops =
                            Some(std::ptr::read_unaligned(libc::CMSG_DATA(c).cast::<u32>()));
                    }
                    _ => {}
                }
            }
            c = libc::CMSG_NXTHDR(msg, c);
        }
    }
    meta
}

fn is_down(e: &std::io::Error) -> bool {
    matches!(
        e.raw_os_error(),
        Some(libc::ENETDOWN) | Some(libc::ENODEV) | Some(libc::ENXIO) | Some(libc::ENETUNREACH)
    )
}

/// Our frame to the kernel's `can_frame`.
pub fn to_raw(frame: &CanFrame) -> libc::can_frame {
    let mut raw = can_frame_default();
    raw.can_id = if frame.extended {
        (frame.id & CAN_EFF_MASK) | CAN_EFF_FLAG
    } else {
        frame.id & CAN_SFF_MASK
    };
    if frame.rtr {
        raw.can_id |= CAN_RTR_FLAG;
    }
    raw.can_dlc = frame.len.min(8);
    raw.data = frame.data;
    raw
}

/// The kernel's `can_frame` to ours; error frames are not CAN traffic and give `None`.
pub fn from_raw(raw: &libc::can_frame) -> Option<CanFrame> {
    if raw.can_id & CAN_ERR_FLAG != 0 {
        return None;
    }
    let extended = raw.can_id & CAN_EFF_FLAG != 0;
    Some(CanFrame {
        id: if extended {
            raw.can_id & CAN_EFF_MASK
        } else {
            raw.can_id & CAN_SFF_MASK
        },
        extended,
        rtr: raw.can_id & CAN_RTR_FLAG != 0,
        len: raw.can_dlc.min(8),
        data: raw.data,
    })
}

/// Frames one `sendmmsg` takes at most (its arrays live on the stack).
pub const SEND_BATCH_MAX: usize = 64;

impl SocketCanBus {
    fn send_result(&mut self, result: std::io::Result<()>) -> Result<(), SendError> {
        match result {
            Ok(()) => {
                self.link_up = true;
                Ok(())
            }
            Err(e) if is_down(&e) => {
                self.link_up = false;
                Err(SendError::Down)
            }
            // ENOBUFS, EAGAIN and anything else: the frame is lost, the loop goes on.
            Err(_) => Err(SendError::Full),
        }
    }
}

impl CanBus for SocketCanBus {
    /// Up to [`SEND_BATCH_MAX`] frames in one `sendmmsg` (one system call, where a `write` per
    /// frame costs one each: expensive in user-mode Linux and under a hypervisor). No
    /// allocation: the frames, their iovecs and message headers are on the stack.
    fn send_batch(&mut self, frames: &[CanFrame]) -> (usize, Option<SendError>) {
        let n = frames.len().min(SEND_BATCH_MAX);
        if n == 0 {
            return (0, None);
        }
        let mut raw = [can_frame_default(); SEND_BATCH_MAX];
        // SAFETY: iovec and mmsghdr are plain data; all-zero is a valid (empty) value.
        let mut iov: [libc::iovec; SEND_BATCH_MAX] = unsafe { std::mem::zeroed() };
        // SAFETY: as above.
        let mut msgs: [libc::mmsghdr; SEND_BATCH_MAX] = unsafe { std::mem::zeroed() };
        for i in 0..n {
            raw[i] = to_raw(&frames[i]);
            iov[i].iov_base = (&mut raw[i] as *mut libc::can_frame).cast();
            iov[i].iov_len = std::mem::size_of::<libc::can_frame>();
            msgs[i].msg_hdr.msg_iov = &mut iov[i];
            msgs[i].msg_hdr.msg_iovlen = 1;
        }
        // SAFETY: `n` valid message headers, each pointing at one valid iovec of one whole
        // can_frame, all alive for the call.
        let rc = unsafe { libc::sendmmsg(self.socket.as_raw_fd(), msgs.as_mut_ptr(), n as _, 0) };
        if rc < 0 {
            let e = std::io::Error::last_os_error();
            return (0, self.send_result(Err(e)).err());
        }
        // Fewer than `n` taken: the next one failed; the caller's retry reports why.
        self.link_up = true;
        (rc as usize, None)
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        let raw = to_raw(frame);
        // SAFETY: writing one whole can_frame from a valid stack value.
        let n = unsafe {
            libc::write(
                self.socket.as_raw_fd(),
                (&raw as *const libc::can_frame).cast(),
                std::mem::size_of::<libc::can_frame>(),
            )
        };
        let result = if n == std::mem::size_of::<libc::can_frame>() as isize {
            Ok(())
        } else if n < 0 {
            Err(std::io::Error::last_os_error())
        } else {
            Err(std::io::Error::from(std::io::ErrorKind::WriteZero))
        };
        self.send_result(result)
    }

    fn recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        self.last_rx_stamp_ns = None;
        match recv_stamped(self.socket.as_raw_fd()) {
            Ok((raw, meta)) => {
                self.link_up = true;
                self.last_rx_stamp_ns = meta.stamp_ns;
                if let Some(drops) = meta.drops {
                    self.rx_overflows.update(drops);
                }
                Ok(from_raw(&raw))
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => Ok(None),
            Err(e) if is_down(&e) => {
                self.link_up = false;
                Err(RecvError::Down)
            }
            Err(_) => Err(RecvError::Other),
        }
    }

    fn wait_readable(&mut self, timeout_us: u64) {
        let mut pfd = libc::pollfd {
            fd: self.socket.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        // poll(2) takes milliseconds; round up so a short wait still waits.
        let ms = timeout_us.div_ceil(1000).min(i32::MAX as u64) as i32;
        // SAFETY: one valid pollfd.
        unsafe { libc::poll(&mut pfd, 1, ms) };
    }

    fn rx_fd(&self) -> Option<std::os::fd::RawFd> {
        Some(self.socket.as_raw_fd())
    }

    fn last_rx_stamp_ns(&self) -> Option<i128> {
        self.last_rx_stamp_ns
    }

    fn rx_overflows(&self) -> u64 {
        self.rx_overflows.total
    }

    fn wait_writable(&mut self, timeout_us: u64) {
        // A full CAN transmit queue (ENOBUFS, the interface's qdisc) does not clear POLLOUT,
        // so poll cannot say when room comes: sleep the bounded time and let the caller retry.
        let ts = libc::timespec {
            tv_sec: (timeout_us / 1_000_000) as libc::time_t,
            tv_nsec: ((timeout_us % 1_000_000) * 1000) as libc::c_long,
        };
        // SAFETY: valid relative timespec; the remainder may be null.
        unsafe { libc::clock_nanosleep(libc::CLOCK_MONOTONIC, 0, &ts, std::ptr::null_mut()) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_drop_counter_is_summed_across_its_wrap() {
        let mut o = RxOverflows::default();
        o.update(0);
        o.update(3);
        o.update(3);
        assert_eq!(o.total, 3);
        o.update(u32::MAX);
        o.update(2); // the kernel's u32 wrapped: 3 more drops
        assert_eq!(o.total, u64::from(u32::MAX) + 3);
    }

    /// The same `recvmsg` path on a socket this kernel has (UDP on loopback; SO_RXQ_OVFL and
    /// SO_TIMESTAMPNS are socket-level options, as on a CAN socket): flood a small receive
    /// buffer, then every datagram sent is either read or counted as dropped by the kernel.
    #[test]
    fn receive_overflow_count_and_timestamp_come_with_each_frame() {
        use std::net::UdpSocket;
        use std::os::fd::AsRawFd;
        let rx = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let tx = UdpSocket::bind("127.0.0.1:0").expect("bind");
        assert!(set_socket_int(rx.as_raw_fd(), libc::SO_RCVBUF, 4096));
        enable_rx_timestamps(rx.as_raw_fd());
        enable_rx_overflow_count(rx.as_raw_fd());
        let frame = [0u8; std::mem::size_of::<libc::can_frame>()];
        const SENT: u64 = 2000;
        for _ in 0..SENT {
            tx.send_to(&frame, rx.local_addr().unwrap()).expect("send");
        }
        let mut read = 0u64;
        let mut counter = RxOverflows::default();
        while let Ok((_, meta)) = recv_stamped(rx.as_raw_fd()) {
            read += 1;
            assert!(meta.stamp_ns.is_some(), "no receive timestamp");
            // The kernel attaches the count once there is one (dropcount > 0).
            if let Some(drops) = meta.drops {
                counter.update(drops);
            }
        }
        assert!(read > 0 && read < SENT, "read {read} of {SENT}");
        // The count rides on frames queued after the drops: one more, now that there is room.
        tx.send_to(&frame, rx.local_addr().unwrap()).expect("send");
        let (_, meta) = recv_stamped(rx.as_raw_fd()).expect("the frame after the drops");
        counter.update(meta.drops.expect("no SO_RXQ_OVFL count after drops"));
        assert_eq!(
            read + counter.total,
            SENT,
            "read {read}, dropped {}",
            counter.total
        );
    }

    #[test]
    fn raw_conversion_round_trips_standard_extended_and_rtr() {
        for f in [
            CanFrame {
                id: 0x605,
                extended: false,
                rtr: false,
                len: 8,
                data: [0x40, 0x41, 0x60, 0, 0, 0, 0, 0],
            },
            CanFrame {
                id: 0x1ABC_DEF0,
                extended: true,
                rtr: false,
                len: 3,
                data: [1, 2, 3, 0, 0, 0, 0, 0],
            },
            CanFrame {
                id: 0x705,
                extended: false,
                rtr: true,
                len: 1,
                data: [0; 8],
            },
        ] {
            assert_eq!(from_raw(&to_raw(&f)), Some(f));
        }
    }

    #[test]
    fn error_frames_are_not_traffic() {
        let mut raw = can_frame_default();
        raw.can_id = CAN_ERR_FLAG | 0x4;
        raw.can_dlc = 8;
        assert_eq!(from_raw(&raw), None);
    }

    #[test]
    fn an_interface_that_is_not_can_is_named_so() {
        // lo exists on every Linux machine and is a loopback (772), not CAN.
        assert_eq!(link_type("lo"), Some(772));
        let msg = match SocketCanBus::open("lo") {
            Ok(_) => panic!("lo opened as a CAN interface"),
            Err(e) => e.to_string(),
        };
        for needle in [
            "lo exists but is not a CAN interface",
            "772",
            "loopback",
            "280",
        ] {
            assert!(msg.contains(needle), "`{needle}` missing: {msg}");
        }
        assert!(!msg.contains("No such device"), "{msg}");
        assert_eq!(link_type("nosuchcan9"), None);
        assert_eq!(link_type("../lo"), None);
    }

    #[test]
    fn opening_without_can_support_explains_what_to_do() {
        // On a kernel without CAN this is EAFNOSUPPORT, with CAN but no such interface ENODEV:
        // both must produce an actionable message, never a panic.
        match SocketCanBus::open("nosuchcan9") {
            Ok(_) => panic!("an interface named nosuchcan9 should not exist"),
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.contains("nosuchcan9"), "{msg}");
                assert!(
                    msg.contains("vcan-setup.sh") || msg.contains("cannot open"),
                    "{msg}"
                );
            }
        }
    }
}
