//! The EtherCAT wire: an AF_PACKET raw socket for EtherType 0x88A4 on one Ethernet interface
//! (a veth end, a TAP, a real NIC). Non-blocking; frames in and out without allocation. Our
//! own transmitted frames are not read back (PACKET_IGNORE_OUTGOING), so on a veth pair the
//! master sees only what the slaves return.

use std::ffi::CString;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};

/// EtherType of EtherCAT.
pub const ETHERTYPE: u16 = 0x88A4;
/// `SOL_PACKET` option: do not deliver the packets this socket's host sends (Linux 4.20).
const PACKET_IGNORE_OUTGOING: libc::c_int = 23;

/// A raw packet socket bound to one interface and EtherType 0x88A4.
#[derive(Debug)]
pub struct PacketSocket {
    fd: OwnedFd,
    ifindex: i32,
}

fn last_error(what: &str, iface: &str) -> io::Error {
    let e = io::Error::last_os_error();
    io::Error::new(e.kind(), format!("{what} on {iface}: {e}"))
}

impl PacketSocket {
    /// Open and bind to `iface` (needs CAP_NET_RAW).
    pub fn open(iface: &str) -> io::Result<PacketSocket> {
        let name = CString::new(iface)
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "interface name has a NUL"))?;
        // SAFETY: plain libc calls on a C string we own; the descriptor is owned at once.
        let ifindex = unsafe { libc::if_nametoindex(name.as_ptr()) } as i32;
        if ifindex == 0 {
            return Err(io::Error::new(
                io::ErrorKind::NotFound,
                format!("no network interface {iface}"),
            ));
        }
        let proto = ETHERTYPE.to_be();
        // SAFETY: socket(2) with constant arguments.
        let fd = unsafe {
            libc::socket(
                libc::AF_PACKET,
                libc::SOCK_RAW | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
                libc::c_int::from(proto),
            )
        };
        if fd < 0 {
            return Err(last_error("raw socket (needs CAP_NET_RAW)", iface));
        }
        // SAFETY: fd is a fresh descriptor we own.
        let fd = unsafe { OwnedFd::from_raw_fd(fd) };
        // SAFETY: a zeroed sockaddr_ll is valid; the fields are set below.
        let mut sll: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
        sll.sll_family = libc::AF_PACKET as u16;
        sll.sll_protocol = proto;
        sll.sll_ifindex = ifindex;
        // SAFETY: bind with a sockaddr_ll of its own size.
        let r = unsafe {
            libc::bind(
                fd.as_raw_fd(),
                (&sll as *const libc::sockaddr_ll).cast(),
                std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
            )
        };
        if r < 0 {
            return Err(last_error("bind", iface));
        }
        let one: libc::c_int = 1;
        // SAFETY: setsockopt with an int option.
        let r = unsafe {
            libc::setsockopt(
                fd.as_raw_fd(),
                libc::SOL_PACKET,
                PACKET_IGNORE_OUTGOING,
                (&one as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        if r < 0 {
            return Err(last_error("PACKET_IGNORE_OUTGOING (Linux >= 4.20)", iface));
        }
        Ok(PacketSocket { fd, ifindex })
    }

    /// The next frame into `buf`: its length, `Ok(None)` when none is waiting.
    pub fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        // SAFETY: recv into a buffer of its own length.
        let n = unsafe {
            libc::recv(
                self.fd.as_raw_fd(),
                buf.as_mut_ptr().cast(),
                buf.len(),
                libc::MSG_DONTWAIT | libc::MSG_TRUNC,
            )
        };
        if n < 0 {
            let e = io::Error::last_os_error();
            return match e.kind() {
                io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted => Ok(None),
                _ => Err(e),
            };
        }
        // MSG_TRUNC: the real length of a frame longer than `buf` (refused by the caller)
        Ok(Some(n as usize))
    }

    /// Send one frame (a whole Ethernet frame).
    pub fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        // SAFETY: a zeroed sockaddr_ll is valid; send a buffer of its own length.
        let mut sll: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
        sll.sll_family = libc::AF_PACKET as u16;
        sll.sll_protocol = ETHERTYPE.to_be();
        sll.sll_ifindex = self.ifindex;
        sll.sll_halen = 6;
        let n = frame.len().min(6);
        sll.sll_addr[..n].copy_from_slice(&frame[..n]);
        // SAFETY: as above.
        let r = unsafe {
            libc::sendto(
                self.fd.as_raw_fd(),
                frame.as_ptr().cast(),
                frame.len(),
                libc::MSG_DONTWAIT,
                (&sll as *const libc::sockaddr_ll).cast(),
                std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
            )
        };
        if r < 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(())
    }

    /// The descriptor that becomes readable when a frame arrives.
    pub fn fd(&self) -> RawFd {
        self.fd.as_raw_fd()
    }
}

/// An EtherCAT fault, as a master sees it (scenario `ethercat = "..."`, the panel).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum EcatFault {
    /// Frames lost on the way to the slave (it never sees them, nothing comes back): the next
    /// `frames` frames if non-zero, else `share` of the frames while the fault lasts.
    Lost { frames: u32, share: f64 },
    /// A late cycle: the slave holds each answered frame for `hold_us` before it returns it.
    Late { hold_us: u64 },
    /// The link is down: nothing reaches the slave, nothing answers.
    LinkDown,
    /// A corrupted datagram: `share` of the frames come back with the working counters the
    /// master sent (not incremented by any slave), so the master sees a working-counter
    /// error.
    BadWkc { share: f64 },
    /// The first slave drops out of OP to SAFE-OP with the error flag and this AL status code
    /// (ETG.1000.6), as a real slave does on a local error; applied to the slave, not the wire.
    OutOfOp { al_code: u16 },
    /// Frames corrupted on the wire before the first slave (a flipped bit: a bad frame check
    /// sequence): the next `frames` frames if non-zero, else `share` of them while the fault
    /// lasts. The slaves count them in their RX error counters (0x0300 invalid frames on the
    /// first, 0x0308 forwarded errors on the others) and process nothing; the master's port
    /// drops them, so it sees no answer.
    Corrupt { frames: u32, share: f64 },
}

impl EcatFault {
    /// For people: what the master sees.
    pub fn describe(&self) -> String {
        match *self {
            EcatFault::Lost { frames, .. } if frames > 0 => {
                format!("EtherCAT: the next {frames} frames lost (no answer)")
            }
            EcatFault::Lost { share, .. } => {
                format!("EtherCAT: {:.0} % of the frames lost", share * 100.0)
            }
            EcatFault::Late { hold_us } => format!(
                "EtherCAT: late cycle (each frame held {} ms)",
                hold_us as f64 / 1000.0
            ),
            EcatFault::LinkDown => "EtherCAT: link down (nothing answers)".into(),
            EcatFault::BadWkc { share } => format!(
                "EtherCAT: working counter not incremented in {:.0} % of the frames",
                share * 100.0
            ),
            EcatFault::OutOfOp { al_code } => {
                format!("EtherCAT: slave drops out of OP (AL status code 0x{al_code:04X})")
            }
            EcatFault::Corrupt { frames, .. } if frames > 0 => {
                format!("EtherCAT: the next {frames} frames corrupted (RX errors, no answer)")
            }
            EcatFault::Corrupt { share, .. } => format!(
                "EtherCAT: {:.0} % of the frames corrupted (RX errors, no answer)",
                share * 100.0
            ),
        }
    }
}

/// Frames held back at once by a late-cycle fault: a 1 kHz master with several frames per
/// cycle, held for up to [`MAX_HOLD_US`].
pub const HELD_FRAMES: usize = 64;
/// Longest hold of a late-cycle fault, us.
pub const MAX_HOLD_US: u64 = 1_000_000;
/// Largest frame a late-cycle fault holds (the loop's receive buffer).
pub const HELD_FRAME_LEN: usize = 1600;

/// What the fault injector did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct EcatFaultStats {
    /// Frames lost (a lost-frames fault or the link down).
    pub lost: u64,
    /// Frames held back (late cycle).
    pub held: u64,
    /// Held frames that found the hold buffer full: lost.
    pub hold_full: u64,
    /// Frames returned with their working counters not incremented.
    pub bad_wkc: u64,
    /// Frames corrupted on the wire (counted as RX errors by the slaves, not answered).
    pub corrupted: u64,
}

/// What to do with a frame the segment has answered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Answer {
    /// Send it now.
    Send,
    /// Held (late cycle) or lost: sent by [`EcatFaults::due`] later, or never.
    Kept,
}

/// The wire faults in force on one EtherCAT port, on the frames' clock (us). Sans-IO and
/// deterministic (a seeded splitmix64 decides shares); everything is allocated with it, so
/// nothing on the frame path allocates.
pub struct EcatFaults {
    rng: u64,
    /// Frames still to lose, and (share, until) of a lost-share fault.
    lost_count: u32,
    lost_share: Option<(f64, Option<u64>)>,
    late: Option<(u64, Option<u64>)>,
    link_down: Option<Option<u64>>,
    bad_wkc: Option<(f64, Option<u64>)>,
    /// Frames still to corrupt, and (share, until) of a corrupt-share fault.
    corrupt_count: u32,
    corrupt_share: Option<(f64, Option<u64>)>,
    /// The frame [`EcatFaults::admit`] refused last was corrupted (not lost).
    corrupted_now: bool,
    /// Held frames: (due us, length), their bytes in `held_buf`, in order of arrival.
    held: heapless::Deque<(u64, u16), HELD_FRAMES>,
    held_buf: Box<[[u8; HELD_FRAME_LEN]; HELD_FRAMES]>,
    held_head: usize,
    /// Working counters as the master sent them (bad-wkc), per datagram of the frame.
    wkc_in: heapless::Vec<(usize, [u8; 2]), { drive_ethercat::frame::MAX_DATAGRAMS }>,
    stats: EcatFaultStats,
    /// The frames' clock as last seen ([`EcatFaults::admit`], [`EcatFaults::due`]), us.
    clock_us: u64,
}

impl EcatFaults {
    pub fn new(seed: u64) -> Self {
        Self {
            rng: seed,
            lost_count: 0,
            lost_share: None,
            late: None,
            link_down: None,
            bad_wkc: None,
            corrupt_count: 0,
            corrupt_share: None,
            corrupted_now: false,
            held: heapless::Deque::new(),
            held_buf: Box::new([[0; HELD_FRAME_LEN]; HELD_FRAMES]),
            held_head: 0,
            wkc_in: heapless::Vec::new(),
            stats: EcatFaultStats::default(),
            clock_us: 0,
        }
    }

    /// The frames' clock as the injector last saw it, us: when a fault started from the
    /// drive's cycle begins.
    pub fn clock_us(&self) -> u64 {
        self.clock_us
    }

    pub fn stats(&self) -> EcatFaultStats {
        self.stats
    }

    /// Whether any wire fault is in force (or frames are held).
    pub fn active(&self) -> bool {
        self.lost_count > 0
            || self.lost_share.is_some()
            || self.late.is_some()
            || self.link_down.is_some()
            || self.bad_wkc.is_some()
            || self.corrupt_count > 0
            || self.corrupt_share.is_some()
            || !self.held.is_empty()
    }

    /// Start `fault` at `now_us` for `over_us` (None: until [`EcatFaults::clear`]); a fault of
    /// the same kind in force is replaced. `OutOfOp` is the slave's, not the wire's: ignored.
    pub fn start(&mut self, fault: EcatFault, over_us: Option<u64>, now_us: u64) {
        let until = over_us.map(|o| now_us.saturating_add(o));
        match fault {
            EcatFault::Lost { frames, .. } if frames > 0 => self.lost_count = frames,
            EcatFault::Lost { share, .. } => self.lost_share = Some((share, until)),
            EcatFault::Late { hold_us } => self.late = Some((hold_us.min(MAX_HOLD_US), until)),
            EcatFault::LinkDown => self.link_down = Some(until),
            EcatFault::BadWkc { share } => self.bad_wkc = Some((share, until)),
            EcatFault::Corrupt { frames, .. } if frames > 0 => self.corrupt_count = frames,
            EcatFault::Corrupt { share, .. } => self.corrupt_share = Some((share, until)),
            EcatFault::OutOfOp { .. } => {}
        }
    }

    /// End every wire fault; frames already held still go out when due.
    pub fn clear(&mut self) {
        self.lost_count = 0;
        self.lost_share = None;
        self.late = None;
        self.link_down = None;
        self.bad_wkc = None;
        self.corrupt_count = 0;
        self.corrupt_share = None;
    }

    /// End the faults whose time is over at `now_us`.
    fn expire(&mut self, now_us: u64) {
        let over = |until: Option<u64>| until.is_some_and(|u| now_us >= u);
        if self.lost_share.is_some_and(|(_, u)| over(u)) {
            self.lost_share = None;
        }
        if self.late.is_some_and(|(_, u)| over(u)) {
            self.late = None;
        }
        if self.link_down.is_some_and(over) {
            self.link_down = None;
        }
        if self.bad_wkc.is_some_and(|(_, u)| over(u)) {
            self.bad_wkc = None;
        }
        if self.corrupt_share.is_some_and(|(_, u)| over(u)) {
            self.corrupt_share = None;
        }
    }

    /// splitmix64: uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        self.rng = self.rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A frame arrived at `now_us`: whether the slaves see it (false: lost on the way, the
    /// link down or a lost-frames fault). When they do, `frame`'s working counters are noted
    /// for a bad-wkc fault.
    pub fn admit(&mut self, frame: &[u8], now_us: u64) -> bool {
        self.wkc_in.clear();
        self.clock_us = now_us;
        self.corrupted_now = false;
        if !self.active() {
            return true;
        }
        self.expire(now_us);
        if self.link_down.is_some() {
            self.stats.lost += 1;
            return false;
        }
        if self.lost_count > 0 {
            self.lost_count -= 1;
            self.stats.lost += 1;
            return false;
        }
        if let Some((share, _)) = self.lost_share {
            if self.uniform() < share {
                self.stats.lost += 1;
                return false;
            }
        }
        let corrupt = if self.corrupt_count > 0 {
            self.corrupt_count -= 1;
            true
        } else {
            self.corrupt_share
                .is_some_and(|(share, _)| self.uniform() < share)
        };
        if corrupt {
            self.stats.corrupted += 1;
            self.corrupted_now = true;
            return false;
        }
        if let Some((share, _)) = self.bad_wkc {
            if self.uniform() < share {
                if let Ok(d) = drive_ethercat::frame::Datagrams::<
                    { drive_ethercat::frame::MAX_DATAGRAMS },
                >::parse(frame)
                {
                    for g in &d.list {
                        let w = g.wkc();
                        let _ = self.wkc_in.push((w, [frame[w], frame[w + 1]]));
                    }
                }
            }
        }
        true
    }

    /// Whether the frame [`EcatFaults::admit`] refused last was corrupted on the wire (the
    /// slaves count it as an RX error: `drive_ethercat::Segment::frame_corrupted`), not lost.
    pub fn corrupted(&self) -> bool {
        self.corrupted_now
    }

    /// The slaves answered `frame` (admitted at `now_us`): restore the working counters of a
    /// bad-wkc fault, hold it for a late cycle. [`Answer::Send`]: send it now.
    pub fn answer(&mut self, frame: &mut [u8], now_us: u64) -> Answer {
        if !self.wkc_in.is_empty() {
            for &(w, v) in &self.wkc_in {
                if w + 1 < frame.len() {
                    frame[w..w + 2].copy_from_slice(&v);
                }
            }
            self.wkc_in.clear();
            self.stats.bad_wkc += 1;
        }
        let Some((hold_us, _)) = self.late else {
            return Answer::Send;
        };
        if self.held.is_full() || frame.len() > HELD_FRAME_LEN {
            self.stats.hold_full += 1;
            return Answer::Kept;
        }
        let slot = (self.held_head + self.held.len()) % HELD_FRAMES;
        self.held_buf[slot][..frame.len()].copy_from_slice(frame);
        let _ = self
            .held
            .push_back((now_us.saturating_add(hold_us), frame.len() as u16));
        self.stats.held += 1;
        Answer::Kept
    }

    /// When the next held frame is due, us.
    pub fn next_due_us(&self) -> Option<u64> {
        self.held.front().map(|&(due, _)| due)
    }

    /// Send the held frames due at `now_us`, in order, with `send`.
    pub fn due(&mut self, now_us: u64, mut send: impl FnMut(&[u8])) {
        self.clock_us = now_us;
        while let Some(&(due, len)) = self.held.front() {
            if due > now_us {
                break;
            }
            self.held.pop_front();
            send(&self.held_buf[self.held_head][..usize::from(len)]);
            self.held_head = (self.held_head + 1) % HELD_FRAMES;
        }
    }
}
