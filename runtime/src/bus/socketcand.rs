//! The run's bus served over TCP in the socketcand text protocol, for CAN tools where there is
//! no kernel CAN (macOS, Windows, WSL2, containers): python-can's `socketcand` interface (so
//! python canopen, unchanged), Kayak, and other socketcand clients.
//!
//! The protocol, server side (socketcand's raw mode; each message is `< ... >`):
//! - on connect the server says `< hi >`;
//! - the client opens the bus, `< open can0 >`, answered `< ok >`, then asks for raw mode,
//!   `< rawmode >`, answered `< ok >`;
//! - in raw mode the server sends every frame on the bus as
//!   `< frame ID SECS.USECS DATA >` (ID in hex, 3 digits standard, 8 extended; DATA the bytes
//!   in hex, run together), and the client sends `< send ID LEN B0 B1 ... >` (LEN and bytes in
//!   hex);
//! - `< echo >` is answered `< echo >`.
//!
//! Errors: before raw mode a bad command is answered `< error TEXT >` (python-can shows it in
//! the exception of its handshake). In raw mode `< error ... >` means a CAN error frame to a
//! client, so a bad line there gets no answer: it is dropped, counted and said once on stderr.
//! Remote (RTR) frames have no form in raw mode: the drive sends none, clients cannot.
//!
//! The bus: what one client sends, the drive and every other client see (not the sender, as
//! on a CAN socket); what the drive sends, every client in raw mode sees. One I/O thread
//! serves the listener and all clients with `poll`, non-blocking; the real-time loop talks
//! to it only through two lock-free queues and two wake-up sockets (one byte per batch), so
//! it never waits for a client and never allocates per frame. Each client has a bounded
//! output buffer: a client too slow to read loses frames, counted, and the others and the
//! drive go on. A client that disconnects, mid-line or not, is simply gone.

use super::{CanBus, CanFrame, RecvError, SendError};
use crossbeam::queue::ArrayQueue;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::os::fd::{AsRawFd, RawFd};
use std::os::unix::net::UnixStream;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// The bus name a client opens (`< open can0 >`).
pub const CHANNEL: &str = "can0";
/// Frames the drive may have queued for the I/O thread.
pub const TX_QUEUE_FRAMES: usize = 8192;
/// Frames from clients waiting for the drive's loop (lock-step: it may fall seconds behind).
pub const RX_QUEUE_FRAMES: usize = 16384;
/// Bytes of a client's output buffer (about 1500 frames); beyond it frames to that client are
/// dropped and counted.
pub const CLIENT_OUT_BYTES: usize = 64 * 1024;
/// Longest message accepted from a client, `<` to `>` (a CAN 2.0 `send` is under 50).
pub const MAX_LINE_BYTES: usize = 256;
/// Clients served at once; one more is told so and closed.
pub const MAX_CLIENTS: usize = 32;
/// After the `< ok >` of `< rawmode >`, frames to that client wait this long, so a client
/// that reads the `< ok >` with one `recv` (python-can) gets it alone. Nothing is lost.
pub const RAW_HOLD: Duration = Duration::from_millis(100);

/// What went wrong with one message from a client.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LineError {
    /// Not a command this server knows.
    Unknown(String),
    /// A `send` that is not `send ID LEN B0 ..`: the text says what is wrong.
    BadSend(String),
    /// A command that is not valid in this state (send before open, a second open ...).
    State(&'static str),
}

impl std::fmt::Display for LineError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LineError::Unknown(c) => write!(f, "unknown command '{c}'"),
            LineError::BadSend(why) => write!(f, "bad send: {why}"),
            LineError::State(why) => f.write_str(why),
        }
    }
}

/// A message a client sent, parsed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Command<'a> {
    Open(&'a str),
    RawMode,
    BcmMode,
    Echo,
    Send(CanFrame),
}

/// One message between `<` and `>` (the brackets excluded).
pub fn parse_command(body: &str) -> Result<Command<'_>, LineError> {
    let mut words = body.split_ascii_whitespace();
    let Some(cmd) = words.next() else {
        return Err(LineError::Unknown(String::new()));
    };
    let done = |mut w: std::str::SplitAsciiWhitespace<'_>, c| match w.next() {
        None => Ok(c),
        Some(extra) => Err(LineError::Unknown(format!("{cmd} {extra}"))),
    };
    match cmd {
        "open" => match (words.next(), words.next()) {
            (Some(name), None) => Ok(Command::Open(name)),
            _ => Err(LineError::State("open takes one bus name: < open can0 >")),
        },
        "rawmode" => done(words, Command::RawMode),
        "bcmmode" => done(words, Command::BcmMode),
        "echo" => done(words, Command::Echo),
        "send" => parse_send(words).map(Command::Send),
        other => Err(LineError::Unknown(other.chars().take(40).collect())),
    }
}

/// `ID LEN B0 B1 ...` of a `send`: ID in hex (1..=3 digits standard, 8 extended), LEN 0..=8
/// and each byte in hex; as many bytes as LEN says.
fn parse_send<'a>(mut words: impl Iterator<Item = &'a str>) -> Result<CanFrame, LineError> {
    let bad = |s: String| LineError::BadSend(s);
    let id_text = words
        .next()
        .ok_or_else(|| bad("no identifier (< send ID LEN B0 .. >)".into()))?;
    let id = u32::from_str_radix(id_text, 16)
        .map_err(|_| bad(format!("identifier '{id_text}' is not hex")))?;
    let extended = match id_text.len() {
        1..=3 if id <= 0x7FF => false,
        1..=3 => return Err(bad(format!("identifier {id_text} is over 0x7FF"))),
        8 if id <= 0x1FFF_FFFF => true,
        8 => return Err(bad(format!("identifier {id_text} is over 0x1FFFFFFF"))),
        _ => {
            return Err(bad(format!(
                "identifier '{id_text}': 3 hex digits (standard) or 8 (extended)"
            )))
        }
    };
    let len_text = words.next().ok_or_else(|| bad("no length".into()))?;
    let len = u8::from_str_radix(len_text, 16)
        .ok()
        .filter(|l| *l <= 8)
        .ok_or_else(|| bad(format!("length '{len_text}' is not 0..8")))?;
    let mut data = [0u8; 8];
    let mut n = 0usize;
    for b in words {
        if n == 8 {
            return Err(bad("more than 8 data bytes".into()));
        }
        data[n] = (b.len() <= 2)
            .then(|| u8::from_str_radix(b, 16).ok())
            .flatten()
            .ok_or_else(|| bad(format!("data byte '{b}' is not 1 or 2 hex digits")))?;
        n += 1;
    }
    if n != usize::from(len) {
        return Err(bad(format!("length {len} but {n} data bytes")));
    }
    Ok(CanFrame {
        id,
        extended,
        rtr: false,
        len,
        data,
    })
}

/// `< frame ID SECS.USECS DATA >` of `frame` received at `stamp` (since the Unix epoch),
/// appended to `out`; `false` (nothing appended) for a remote frame, which raw mode cannot
/// say. No allocation once `out` has room.
pub fn format_frame(frame: &CanFrame, stamp: Duration, out: &mut Vec<u8>) -> bool {
    if frame.rtr {
        return false;
    }
    const HEX: &[u8; 16] = b"0123456789ABCDEF";
    out.extend_from_slice(b"< frame ");
    let (id, digits) = if frame.extended {
        (frame.id & 0x1FFF_FFFF, 8)
    } else {
        (frame.id & 0x7FF, 3)
    };
    for k in (0..digits).rev() {
        out.push(HEX[((id >> (4 * k)) & 0xF) as usize]);
    }
    out.push(b' ');
    push_decimal(out, stamp.as_secs(), 1);
    out.push(b'.');
    push_decimal(out, u64::from(stamp.subsec_micros()), 6);
    out.push(b' ');
    for b in &frame.data[..usize::from(frame.len.min(8))] {
        out.push(HEX[usize::from(b >> 4)]);
        out.push(HEX[usize::from(b & 0xF)]);
    }
    out.extend_from_slice(b" >");
    true
}

/// `v` in decimal, at least `width` digits (zero-padded).
fn push_decimal(out: &mut Vec<u8>, v: u64, width: usize) {
    let mut digits = [0u8; 20];
    let mut n = 0;
    let mut v = v;
    while v > 0 || n < width {
        digits[n] = b'0' + (v % 10) as u8;
        v /= 10;
        n += 1;
    }
    out.extend(digits[..n].iter().rev());
}

/// Counters of the server, cumulative; read them at any time.
#[derive(Debug, Default)]
pub struct ServerStats {
    /// Clients accepted so far.
    pub clients_accepted: AtomicU64,
    /// Clients connected now.
    pub clients_now: AtomicU64,
    /// Clients refused (more than [`MAX_CLIENTS`]).
    pub clients_refused: AtomicU64,
    /// Frames clients sent onto the bus.
    pub frames_from_clients: AtomicU64,
    /// Frames the drive sent.
    pub frames_from_drive: AtomicU64,
    /// Frames not delivered to a client whose output buffer was full (a slow reader).
    pub dropped_to_slow_clients: AtomicU64,
    /// Frames from clients lost because the drive's loop had not read the ones before.
    pub rx_overflows: AtomicU64,
    /// Messages from clients that were not valid (garbage, bad `send`, too long).
    pub bad_lines: AtomicU64,
}

impl ServerStats {
    fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }

    /// One line for people: clients, frames, drops.
    pub fn summary(&self) -> String {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed);
        format!(
            "{} clients served ({} refused), {} frames from clients, {} from the drive, {} \
             dropped to slow clients, {} lost waiting for the loop, {} bad messages",
            g(&self.clients_accepted),
            g(&self.clients_refused),
            g(&self.frames_from_clients),
            g(&self.frames_from_drive),
            g(&self.dropped_to_slow_clients),
            g(&self.rx_overflows),
            g(&self.bad_lines)
        )
    }
}

struct Shared {
    /// Drive -> clients.
    tx: ArrayQueue<CanFrame>,
    /// Clients -> drive, with the arrival time (ns since the Unix epoch, CLOCK_REALTIME).
    rx: ArrayQueue<(CanFrame, i128)>,
    stats: ServerStats,
    stop: AtomicBool,
}

/// The drive's end of a socketcand server: a [`CanBus`]. Dropping it stops the server and
/// closes every client.
pub struct SocketcandBus {
    shared: Arc<Shared>,
    local_addr: SocketAddr,
    /// Written (one byte) after frames were queued for the I/O thread.
    tx_wake: UnixStream,
    /// Readable when frames from clients are queued for the drive.
    rx_wake: UnixStream,
    last_rx_stamp_ns: Option<i128>,
    thread: Option<std::thread::JoinHandle<()>>,
}

/// Why the server could not start.
#[derive(Debug)]
pub struct BindError {
    pub addr: String,
    pub source: std::io::Error,
}

impl std::fmt::Display for BindError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "cannot serve socketcand on {}: {} (give ADDR:PORT, e.g. 127.0.0.1:29536, or port 0 \
             for any free port)",
            self.addr, self.source
        )
    }
}

impl std::error::Error for BindError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.source)
    }
}

impl SocketcandBus {
    /// Listen on `addr` (`HOST:PORT`; port 0: any free one, see [`SocketcandBus::local_addr`])
    /// and start the I/O thread.
    pub fn bind(addr: &str) -> Result<Self, BindError> {
        let err = |source| BindError {
            addr: addr.to_string(),
            source,
        };
        let addrs: Vec<SocketAddr> = addr.to_socket_addrs().map_err(err)?.collect();
        let listener = TcpListener::bind(&addrs[..]).map_err(err)?;
        listener.set_nonblocking(true).map_err(err)?;
        let local_addr = listener.local_addr().map_err(err)?;
        let (tx_wake, tx_wake_io) = UnixStream::pair().map_err(err)?;
        let (rx_wake_io, rx_wake) = UnixStream::pair().map_err(err)?;
        for s in [&tx_wake, &tx_wake_io, &rx_wake_io, &rx_wake] {
            s.set_nonblocking(true).map_err(err)?;
        }
        let shared = Arc::new(Shared {
            tx: ArrayQueue::new(TX_QUEUE_FRAMES),
            rx: ArrayQueue::new(RX_QUEUE_FRAMES),
            stats: ServerStats::default(),
            stop: AtomicBool::new(false),
        });
        let io = IoThread {
            listener,
            shared: Arc::clone(&shared),
            tx_wake: tx_wake_io,
            rx_wake: rx_wake_io,
            clients: Vec::with_capacity(MAX_CLIENTS),
            line: Vec::with_capacity(128),
        };
        let thread = std::thread::Builder::new()
            .name("drive-emu-socketcand".into())
            .spawn(move || io.run())
            .map_err(err)?;
        Ok(Self {
            shared,
            local_addr,
            tx_wake,
            rx_wake,
            last_rx_stamp_ns: None,
            thread: Some(thread),
        })
    }

    /// The address the server listens on (the port it got for port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The server's counters.
    pub fn stats(&self) -> &ServerStats {
        &self.shared.stats
    }

    fn wake_io(&self) {
        // A full wake-up socket already has a wake-up pending: nothing lost.
        let _ = (&self.tx_wake).write(&[1]);
    }
}

impl Drop for SocketcandBus {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        self.wake_io();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Read and discard everything a non-blocking wake-up socket holds.
fn drain(mut s: &UnixStream) {
    let mut buf = [0u8; 64];
    while matches!(s.read(&mut buf), Ok(n) if n > 0) {}
}

impl CanBus for SocketcandBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        let r = self.shared.tx.push(*frame).map_err(|_| SendError::Full);
        self.wake_io();
        r
    }

    /// Queue them all (as many as fit), then one wake-up of the I/O thread.
    fn send_batch(&mut self, frames: &[CanFrame]) -> (usize, Option<SendError>) {
        let mut n = 0;
        for f in frames {
            if self.shared.tx.push(*f).is_err() {
                break;
            }
            n += 1;
        }
        if n > 0 {
            self.wake_io();
        }
        (n, (n < frames.len()).then_some(SendError::Full))
    }

    fn recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        // Empty: drain the wake-up socket first, then look again, so a frame queued meanwhile
        // is either seen now or leaves the socket readable.
        let item = self.shared.rx.pop().or_else(|| {
            drain(&self.rx_wake);
            self.shared.rx.pop()
        });
        self.last_rx_stamp_ns = item.map(|(_, t)| t);
        Ok(item.map(|(f, _)| f))
    }

    fn wait_readable(&mut self, timeout_us: u64) {
        if !self.shared.rx.is_empty() {
            return;
        }
        let mut pfd = libc::pollfd {
            fd: self.rx_wake.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let ms = timeout_us.div_ceil(1000).min(i32::MAX as u64) as i32;
        // SAFETY: one valid pollfd.
        unsafe { libc::poll(&mut pfd, 1, ms) };
    }

    fn rx_fd(&self) -> Option<RawFd> {
        Some(self.rx_wake.as_raw_fd())
    }

    fn last_rx_stamp_ns(&self) -> Option<i128> {
        self.last_rx_stamp_ns
    }

    fn rx_overflows(&self) -> u64 {
        self.shared.stats.rx_overflows.load(Ordering::Relaxed)
    }

    fn wait_writable(&mut self, timeout_us: u64) {
        // The I/O thread empties the queue as fast as it is scheduled.
        std::thread::sleep(Duration::from_micros(timeout_us));
    }
}

/// Where a client is in the protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// Said hi, no bus open yet.
    New,
    /// Bus open (socketcand's broadcast manager mode): may send, sees no frames.
    Open,
    /// Raw mode: sees every frame; frames are written from `hold_until` on.
    Raw { hold_until: Instant },
}

struct Client {
    stream: TcpStream,
    peer: SocketAddr,
    mode: Mode,
    /// Bytes received, not yet a whole message.
    input: Vec<u8>,
    /// Skipping text that is not a message, up to the next `<`.
    skipping: bool,
    /// Bytes to write; `writable` of them may go now (the rest wait for the raw-mode hold).
    out: Vec<u8>,
    writable: usize,
    bad_lines: u64,
    closed: bool,
}

impl Client {
    /// Append a message; `false` if it does not fit (a slow reader): nothing appended.
    fn queue(&mut self, bytes: &[u8]) -> bool {
        if self.out.len() + bytes.len() > CLIENT_OUT_BYTES {
            return false;
        }
        self.out.extend_from_slice(bytes);
        if !matches!(self.mode, Mode::Raw { .. }) {
            self.writable = self.out.len();
        }
        true
    }

    /// Write what may go now, non-blocking; a write error closes the client.
    fn flush(&mut self, now: Instant) {
        if let Mode::Raw { hold_until } = self.mode {
            if now >= hold_until {
                self.writable = self.out.len();
            }
        }
        while self.writable > 0 {
            match self.stream.write(&self.out[..self.writable]) {
                Ok(0) => {
                    self.closed = true;
                    return;
                }
                Ok(n) => {
                    self.out.drain(..n);
                    self.writable -= n;
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(_) => {
                    self.closed = true;
                    return;
                }
            }
        }
    }

    fn wants_write(&self) -> bool {
        self.writable > 0
    }

    fn is_raw(&self) -> bool {
        matches!(self.mode, Mode::Raw { .. })
    }
}

struct IoThread {
    listener: TcpListener,
    shared: Arc<Shared>,
    tx_wake: UnixStream,
    rx_wake: UnixStream,
    clients: Vec<Client>,
    /// Scratch for one formatted frame.
    line: Vec<u8>,
}

fn now_since_epoch() -> Duration {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap_or_default()
}

impl IoThread {
    fn run(mut self) {
        let mut pfds: Vec<libc::pollfd> = Vec::with_capacity(MAX_CLIENTS + 2);
        while !self.shared.stop.load(Ordering::Acquire) {
            pfds.clear();
            for fd in [self.listener.as_raw_fd(), self.tx_wake.as_raw_fd()] {
                pfds.push(libc::pollfd {
                    fd,
                    events: libc::POLLIN,
                    revents: 0,
                });
            }
            let now = Instant::now();
            let mut timeout_ms: i32 = 200;
            for c in &self.clients {
                let mut events = libc::POLLIN;
                if c.wants_write() {
                    events |= libc::POLLOUT;
                }
                if let Mode::Raw { hold_until } = c.mode {
                    if c.out.len() > c.writable {
                        let left = hold_until.saturating_duration_since(now);
                        timeout_ms = timeout_ms.min(left.as_millis() as i32 + 1);
                    }
                }
                pfds.push(libc::pollfd {
                    fd: c.stream.as_raw_fd(),
                    events,
                    revents: 0,
                });
            }
            // SAFETY: `pfds` is a valid array of pollfd of the length given.
            unsafe { libc::poll(pfds.as_mut_ptr(), pfds.len() as libc::nfds_t, timeout_ms) };
            if pfds[1].revents != 0 {
                drain(&self.tx_wake);
            }
            self.forward_drive_frames();
            for (i, pfd) in pfds[2..].iter().enumerate() {
                if pfd.revents & (libc::POLLIN | libc::POLLHUP | libc::POLLERR) != 0 {
                    self.read_client(i);
                }
            }
            let now = Instant::now();
            for c in &mut self.clients {
                c.flush(now);
            }
            self.drop_closed();
            if pfds[0].revents != 0 {
                self.accept();
            }
        }
    }

    /// Every frame the drive queued, to every client in raw mode.
    fn forward_drive_frames(&mut self) {
        let mut n = 0;
        let stamp = now_since_epoch();
        while let Some(f) = self.shared.tx.pop() {
            n += 1;
            self.line.clear();
            if format_frame(&f, stamp, &mut self.line) {
                let mut dropped = 0;
                for c in self.clients.iter_mut().filter(|c| c.is_raw()) {
                    if !c.queue(&self.line) {
                        dropped += 1;
                    }
                }
                ServerStats::add(&self.shared.stats.dropped_to_slow_clients, dropped);
            }
        }
        ServerStats::add(&self.shared.stats.frames_from_drive, n);
    }

    fn accept(&mut self) {
        loop {
            match self.listener.accept() {
                Ok((stream, peer)) => {
                    if stream.set_nonblocking(true).is_err() {
                        continue;
                    }
                    let _ = stream.set_nodelay(true);
                    if self.clients.len() >= MAX_CLIENTS {
                        ServerStats::add(&self.shared.stats.clients_refused, 1);
                        let _ = (&stream).write(b"< error too many clients >");
                        continue;
                    }
                    let mut c = Client {
                        stream,
                        peer,
                        mode: Mode::New,
                        input: Vec::with_capacity(MAX_LINE_BYTES),
                        skipping: false,
                        out: Vec::with_capacity(CLIENT_OUT_BYTES),
                        writable: 0,
                        bad_lines: 0,
                        closed: false,
                    };
                    c.queue(b"< hi >");
                    c.flush(Instant::now());
                    self.clients.push(c);
                    ServerStats::add(&self.shared.stats.clients_accepted, 1);
                    self.shared
                        .stats
                        .clients_now
                        .store(self.clients.len() as u64, Ordering::Relaxed);
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return,
                // A connection that went away before it was accepted, or out of descriptors:
                // try again at the next wake-up.
                Err(_) => return,
            }
        }
    }

    fn drop_closed(&mut self) {
        let before = self.clients.len();
        self.clients.retain(|c| !c.closed);
        if self.clients.len() != before {
            self.shared
                .stats
                .clients_now
                .store(self.clients.len() as u64, Ordering::Relaxed);
        }
    }

    /// Read what client `i` sent and act on each whole message.
    fn read_client(&mut self, i: usize) {
        let mut buf = [0u8; 4096];
        loop {
            let c = &mut self.clients[i];
            if c.closed {
                return;
            }
            match c.stream.read(&mut buf) {
                Ok(0) => {
                    c.closed = true;
                    return;
                }
                Ok(n) => self.take_input(i, &buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(_) => {
                    self.clients[i].closed = true;
                    return;
                }
            }
        }
    }

    /// Split `bytes` into messages `< ... >`. Text between messages other than white space
    /// is a bad message (up to the next `<`), as is one longer than [`MAX_LINE_BYTES`] or one
    /// cut short by the next `<`.
    fn take_input(&mut self, i: usize, bytes: &[u8]) {
        let mut frames_to_drive = 0;
        for &b in bytes {
            let c = &mut self.clients[i];
            if c.skipping {
                if b == b'<' {
                    c.skipping = false;
                    c.input.push(b);
                }
                continue;
            }
            if c.input.is_empty() {
                if b == b'<' {
                    c.input.push(b);
                } else if !b.is_ascii_whitespace() {
                    c.skipping = true;
                    self.bad_line(i, "text outside < >".into());
                }
                continue;
            }
            match b {
                b'>' => {
                    let mut msg = std::mem::take(&mut c.input);
                    if self.handle_message(i, &msg[1..]) {
                        frames_to_drive += 1;
                    }
                    msg.clear();
                    self.clients[i].input = msg;
                }
                b'<' => {
                    c.input.clear();
                    c.input.push(b);
                    self.bad_line(i, "a message without its >".into());
                }
                _ if c.input.len() >= MAX_LINE_BYTES => {
                    c.input.clear();
                    c.skipping = true;
                    self.bad_line(i, format!("a message longer than {MAX_LINE_BYTES} bytes"));
                }
                _ => c.input.push(b),
            }
        }
        if frames_to_drive > 0 {
            let _ = (&self.rx_wake).write(&[1]);
        }
    }

    /// A bad message from client `i`: counted; said to the client before raw mode, on
    /// stderr (once per client) in raw mode.
    fn bad_line(&mut self, i: usize, why: String) {
        ServerStats::add(&self.shared.stats.bad_lines, 1);
        let c = &mut self.clients[i];
        c.bad_lines += 1;
        if c.is_raw() {
            if c.bad_lines == 1 {
                eprintln!(
                    "drive-emu: socketcand client {}: {why} (dropped; further bad messages \
                     from it are only counted)",
                    c.peer
                );
            }
        } else {
            let reply = format!("< error {} >", why.replace(['<', '>'], ""));
            c.queue(reply.as_bytes());
        }
    }

    /// Act on one message (between `<` and `>`) from client `i`; true if a frame went to the
    /// drive.
    fn handle_message(&mut self, i: usize, body: &[u8]) -> bool {
        let Ok(text) = std::str::from_utf8(body) else {
            self.bad_line(i, "not ASCII".into());
            return false;
        };
        let mode = self.clients[i].mode;
        match (parse_command(text), mode) {
            (Ok(Command::Open(name)), Mode::New) => {
                if name == CHANNEL {
                    self.clients[i].mode = Mode::Open;
                    self.clients[i].queue(b"< ok >");
                } else {
                    let why = format!("no bus '{name}': this server serves {CHANNEL}");
                    self.bad_line(i, why);
                }
                false
            }
            (Ok(Command::Open(_)), _) => {
                self.bad_line(i, "a bus is open already".into());
                false
            }
            (Ok(Command::RawMode), Mode::Open | Mode::Raw { .. }) => {
                let c = &mut self.clients[i];
                c.queue(b"< ok >");
                c.mode = Mode::Raw {
                    hold_until: Instant::now() + RAW_HOLD,
                };
                false
            }
            (Ok(Command::BcmMode), Mode::Open | Mode::Raw { .. }) => {
                let c = &mut self.clients[i];
                c.mode = Mode::Open;
                c.queue(b"< ok >");
                false
            }
            (Ok(Command::Echo), _) => {
                self.clients[i].queue(b"< echo >");
                false
            }
            (Ok(Command::Send(f)), Mode::Open | Mode::Raw { .. }) => {
                self.bus_frame(i, &f);
                true
            }
            (Ok(_), Mode::New) => {
                self.bad_line(i, "open the bus first: < open can0 >".into());
                false
            }
            (Err(e), _) => {
                self.bad_line(i, e.to_string());
                false
            }
        }
    }

    /// A frame client `from` sent: to the drive and to every other client in raw mode.
    fn bus_frame(&mut self, from: usize, f: &CanFrame) {
        let stamp = now_since_epoch();
        let stats = &self.shared.stats;
        ServerStats::add(&stats.frames_from_clients, 1);
        if self.shared.rx.push((*f, stamp.as_nanos() as i128)).is_err() {
            ServerStats::add(&stats.rx_overflows, 1);
        }
        self.line.clear();
        if format_frame(f, stamp, &mut self.line) {
            for (k, c) in self.clients.iter_mut().enumerate() {
                if k != from && c.is_raw() && !c.queue(&self.line) {
                    ServerStats::add(&stats.dropped_to_slow_clients, 1);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn send_parses_standard_extended_and_empty_frames() {
        assert_eq!(
            parse_command("send 605 8 40 41 60 0 0 0 0 0"),
            Ok(Command::Send(CanFrame::new(
                0x605,
                &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]
            )))
        );
        assert_eq!(
            parse_command(" send 080 0 "),
            Ok(Command::Send(CanFrame::new(0x80, &[])))
        );
        let Ok(Command::Send(f)) = parse_command("send 1ABCDEF0 2 ff 1") else {
            panic!("not parsed");
        };
        assert!(f.extended);
        assert_eq!(
            (f.id, f.len, &f.data[..2]),
            (0x1ABC_DEF0, 2, &[0xFF, 1][..])
        );
    }

    #[test]
    fn bad_sends_say_what_is_wrong() {
        for (line, needle) in [
            ("send", "no identifier"),
            ("send xyz 1 00", "not hex"),
            ("send 800 0", "over 0x7FF"),
            ("send 3FFFFFFF 0", "over 0x1FFFFFFF"),
            ("send 12345 0", "3 hex digits"),
            ("send 123", "no length"),
            ("send 123 9", "not 0..8"),
            ("send 123 2 01", "length 2 but 1"),
            ("send 123 1 01 02", "length 1 but 2"),
            ("send 123 1 100", "1 or 2 hex digits"),
            ("send 123 8 0 0 0 0 0 0 0 0 0", "more than 8"),
        ] {
            match parse_command(line) {
                Err(e) => assert!(e.to_string().contains(needle), "{line}: {e}"),
                Ok(c) => panic!("{line}: parsed as {c:?}"),
            }
        }
        assert!(matches!(parse_command("fly"), Err(LineError::Unknown(_))));
        assert!(matches!(parse_command(""), Err(LineError::Unknown(_))));
        assert!(parse_command("rawmode now").is_err());
    }

    #[test]
    fn frames_are_formatted_as_python_can_reads_them() {
        let mut out = Vec::new();
        let t = Duration::new(1_700_000_000, 5_000);
        assert!(format_frame(
            &CanFrame::new(0x1, &[0xAB, 0x01]),
            t,
            &mut out
        ));
        assert_eq!(
            std::str::from_utf8(&out).unwrap(),
            "< frame 001 1700000000.000005 AB01 >"
        );
        out.clear();
        let ext = CanFrame {
            id: 0x1ABC_DEF0,
            extended: true,
            ..CanFrame::new(0, &[])
        };
        assert!(format_frame(&ext, Duration::ZERO, &mut out));
        assert_eq!(
            std::str::from_utf8(&out).unwrap(),
            "< frame 1ABCDEF0 0.000000  >"
        );
        out.clear();
        assert!(!format_frame(&CanFrame::remote(0x705, 1), t, &mut out));
        assert!(out.is_empty());
    }
}
