//! The socketcand transport (`run --socketcand`) on its own, with plain TCP clients and no
//! python: the handshake, frames both ways (standard and extended), several clients on one
//! bus, bad input (dropped, counted, the bus goes on), a client that disconnects mid-message,
//! a client that never reads (its frames dropped and counted, the drive never waits), and the
//! drive's side allocation-free per frame.

use drive_emu::bus::socketcand::{SocketcandBus, CHANNEL};
use drive_emu::bus::{CanBus, CanFrame};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.try_with(Cell::get).unwrap_or(false) {
            let _ = ALLOCS.try_with(|a| a.set(a.get() + 1));
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.try_with(Cell::get).unwrap_or(false) {
            let _ = ALLOCS.try_with(|a| a.set(a.get() + 1));
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations `f` made on this thread.
fn allocations(f: impl FnOnce()) -> u64 {
    ALLOCS.with(|a| a.set(0));
    COUNTING.with(|c| c.set(true));
    f();
    COUNTING.with(|c| c.set(false));
    ALLOCS.with(Cell::get)
}

/// Long enough for a loaded machine; only a broken server waits this long.
const PATIENCE: Duration = Duration::from_secs(60);

fn server() -> SocketcandBus {
    SocketcandBus::bind("127.0.0.1:0").expect("bind on a free port")
}

/// A socketcand client speaking the protocol by hand.
struct Client {
    s: TcpStream,
    buf: Vec<u8>,
}

impl Client {
    fn connect(bus: &SocketcandBus) -> Client {
        let s = TcpStream::connect(bus.local_addr()).expect("connect");
        s.set_read_timeout(Some(PATIENCE)).unwrap();
        Client { s, buf: Vec::new() }
    }

    /// Connected, bus open, raw mode.
    fn raw(bus: &SocketcandBus) -> Client {
        let mut c = Client::connect(bus);
        assert_eq!(c.next(), "< hi >");
        c.say(&format!("< open {CHANNEL} >"));
        assert_eq!(c.next(), "< ok >");
        c.say("< rawmode >");
        assert_eq!(c.next(), "< ok >");
        c
    }

    fn say(&mut self, text: &str) {
        self.s.write_all(text.as_bytes()).expect("write");
    }

    /// The next message `< ... >` from the server.
    fn next(&mut self) -> String {
        loop {
            if let Some(end) = self.buf.iter().position(|&b| b == b'>') {
                let msg: Vec<u8> = self.buf.drain(..=end).collect();
                let text = String::from_utf8(msg).expect("ASCII from the server");
                return text.trim_start().to_string();
            }
            let mut chunk = [0u8; 4096];
            let n = self
                .s
                .read(&mut chunk)
                .expect("the server said nothing in time");
            assert!(n > 0, "the server closed the connection");
            self.buf.extend_from_slice(&chunk[..n]);
        }
    }

    /// The next `< frame .. >`, as (id text, data text).
    fn next_frame(&mut self) -> (String, String) {
        let msg = self.next();
        let parts: Vec<&str> = msg.split(' ').collect();
        // "<", "frame", ID, SECS.USECS, DATA, ">"
        assert_eq!(parts.len(), 6, "not a frame: {msg:?}");
        assert_eq!(parts[1], "frame", "{msg:?}");
        let (secs, usecs) = parts[3].split_once('.').expect("SECS.USECS");
        assert!(secs.parse::<u64>().unwrap() > 1_600_000_000, "{msg:?}");
        assert_eq!(usecs.len(), 6, "{msg:?}");
        (parts[2].to_string(), parts[4].to_string())
    }
}

/// The next frame a client sent onto the bus, as the drive reads it.
fn drive_recv(bus: &mut SocketcandBus) -> CanFrame {
    let deadline = Instant::now() + PATIENCE;
    loop {
        if let Some(f) = bus.recv().expect("recv") {
            return f;
        }
        assert!(Instant::now() < deadline, "no frame reached the drive");
        bus.wait_readable(100_000);
    }
}

fn wait_until(what: &str, mut pred: impl FnMut() -> bool) {
    let deadline = Instant::now() + PATIENCE;
    while !pred() {
        assert!(Instant::now() < deadline, "timeout waiting for {what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn handshake_then_standard_and_extended_frames_both_ways() {
    let mut bus = server();
    let mut c = Client::raw(&bus);
    c.say("< send 605 8 40 41 60 0 0 0 0 0 >");
    let f = drive_recv(&mut bus);
    assert_eq!(f, CanFrame::new(0x605, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]));
    assert!(bus.last_rx_stamp_ns().is_some(), "no arrival time");
    c.say("< send 1ABCDEF0 3 1 2 ff >");
    let f = drive_recv(&mut bus);
    assert!(f.extended);
    assert_eq!((f.id, f.payload()), (0x1ABC_DEF0, &[1, 2, 0xFF][..]));

    bus.send(&CanFrame::new(
        0x585,
        &[0x43, 0x41, 0x60, 0, 0x37, 0x02, 0, 0],
    ))
    .unwrap();
    assert_eq!(
        c.next_frame(),
        ("585".to_string(), "4341600037020000".to_string())
    );
    let ext = CanFrame {
        id: 0x18FF_0005,
        extended: true,
        ..CanFrame::new(0, &[9])
    };
    let sync = CanFrame::new(0x80, &[]);
    assert_eq!(bus.send_batch(&[ext, sync]), (2, None));
    assert_eq!(c.next_frame(), ("18FF0005".to_string(), "09".to_string()));
    assert_eq!(c.next_frame(), ("080".to_string(), String::new()));
    c.say("< echo >");
    assert_eq!(c.next(), "< echo >");
    assert_eq!(bus.stats().bad_lines.load(Ordering::Relaxed), 0);
}

#[test]
fn two_clients_share_the_bus_and_a_sender_does_not_hear_itself() {
    let mut bus = server();
    let mut a = Client::raw(&bus);
    let mut b = Client::raw(&bus);
    a.say("< send 000 2 1 5 >");
    assert_eq!(drive_recv(&mut bus), CanFrame::new(0, &[1, 5]));
    assert_eq!(b.next_frame(), ("000".to_string(), "0105".to_string()));
    b.say("< send 705 1 7f >");
    assert_eq!(drive_recv(&mut bus), CanFrame::new(0x705, &[0x7F]));
    // The drive's next frame is what each hears next: A heard B's, B not its own.
    bus.send(&CanFrame::new(0x185, &[0xAA])).unwrap();
    assert_eq!(a.next_frame(), ("705".to_string(), "7F".to_string()));
    assert_eq!(a.next_frame(), ("185".to_string(), "AA".to_string()));
    assert_eq!(b.next_frame(), ("185".to_string(), "AA".to_string()));
    assert_eq!(bus.stats().clients_now.load(Ordering::Relaxed), 2);
}

#[test]
fn bad_input_is_answered_before_raw_mode_and_dropped_and_counted_in_it() {
    let mut bus = server();
    let mut c = Client::connect(&bus);
    assert_eq!(c.next(), "< hi >");
    c.say("< send 123 0 >");
    assert!(c.next().contains("open the bus first"));
    c.say("< open vcan9 >");
    let e = c.next();
    assert!(e.starts_with("< error") && e.contains(CHANNEL), "{e}");
    c.say("< rawmode >");
    assert!(c.next().starts_with("< error"));
    c.say("< open can0 >");
    assert_eq!(c.next(), "< ok >");
    c.say("< fly >");
    assert!(c.next().contains("unknown command 'fly'"));
    c.say("< rawmode >");
    assert_eq!(c.next(), "< ok >");
    let before = bus.stats().bad_lines.load(Ordering::Relaxed);
    assert_eq!(before, 4);
    // In raw mode: none of these reaches the drive or gets an answer.
    let long = format!("< send {} >", "0 ".repeat(300));
    for bad in [
        "hello ",
        "< send 800 0 >",
        "< send 123 2 01 >",
        "< send 123 1 100 >",
        "< send 12345 0 >",
        "< fly >",
        "< send 123 1 01",
        long.as_str(),
    ] {
        c.say(bad);
    }
    c.s.write_all(b"< send \xff\xfe 1 00 >").unwrap();
    c.say("< open can0 >");
    c.say("< send 123 1 AA >");
    assert_eq!(drive_recv(&mut bus), CanFrame::new(0x123, &[0xAA]));
    assert_eq!(bus.recv().unwrap(), None, "a bad message reached the drive");
    wait_until("the bad messages counted", || {
        bus.stats().bad_lines.load(Ordering::Relaxed) == before + 10
    });
    // No answer was written: the next thing the client hears is the drive's frame.
    bus.send(&CanFrame::new(0x181, &[1])).unwrap();
    assert_eq!(c.next_frame(), ("181".to_string(), "01".to_string()));
}

#[test]
fn a_client_that_disconnects_mid_message_is_forgotten() {
    let mut bus = server();
    let mut a = Client::raw(&bus);
    let mut b = Client::raw(&bus);
    a.say("< send 12");
    drop(a);
    wait_until("the client gone", || {
        bus.stats().clients_now.load(Ordering::Relaxed) == 1
    });
    b.say("< send 123 0 >");
    assert_eq!(drive_recv(&mut bus), CanFrame::new(0x123, &[]));
    assert_eq!(bus.recv().unwrap(), None);
    bus.send(&CanFrame::new(0x701, &[5])).unwrap();
    assert_eq!(b.next_frame(), ("701".to_string(), "05".to_string()));
    // And a new client is served as the first was.
    let mut c = Client::raw(&bus);
    c.say("< send 001 1 2 >");
    assert_eq!(drive_recv(&mut bus), CanFrame::new(1, &[2]));
    assert_eq!(bus.stats().bad_lines.load(Ordering::Relaxed), 0);
}

#[test]
fn a_client_that_never_reads_loses_frames_counted_and_the_drive_never_waits_for_it() {
    let mut bus = server();
    let _slow = Client::raw(&bus); // never reads again
    let fast = Client::raw(&bus);
    let reader = std::thread::spawn(move || {
        let mut fast = fast;
        loop {
            let (id, _) = fast.next_frame();
            if id == "7FF" {
                return;
            }
        }
    });
    // 15 MB of text per client: more than the kernel's socket buffers and the server's.
    let frames = [CanFrame::new(0x181, &[1, 2, 3, 4, 5, 6, 7, 8]); 64];
    let mut queued = 0u64;
    while queued < 500_000 {
        let (n, _) = bus.send_batch(&frames);
        queued += n as u64;
        if n < frames.len() {
            // The I/O thread's queue is full: as the runtime, wait a little (bounded).
            bus.wait_writable(50);
        }
    }
    wait_until("frames to the slow client dropped", || {
        bus.stats().dropped_to_slow_clients.load(Ordering::Relaxed) > 0
    });
    // The fast client still gets the bus: the end marker until it has heard one.
    let deadline = Instant::now() + PATIENCE;
    while !reader.is_finished() {
        assert!(Instant::now() < deadline, "the reading client starved");
        let _ = bus.send(&CanFrame::new(0x7FF, &[]));
        std::thread::sleep(Duration::from_millis(20));
    }
    reader.join().unwrap();
    assert!(bus.stats().frames_from_drive.load(Ordering::Relaxed) >= 500_000);
}

#[test]
fn the_drives_side_does_not_allocate_per_frame() {
    let mut bus = server();
    let mut c = Client::raw(&bus);
    for k in 0..100u8 {
        c.say(&format!("< send 200 1 {k:x} >"));
    }
    wait_until("the frames queued for the drive", || {
        bus.stats().frames_from_clients.load(Ordering::Relaxed) == 100
    });
    let frames = [CanFrame::new(0x181, &[1, 2]); 8];
    let mut got = 0;
    let n = allocations(|| {
        while let Ok(Some(_)) = bus.recv() {
            got += 1;
        }
        for _ in 0..100 {
            let _ = bus.send_batch(&frames);
            let _ = bus.send(&frames[0]);
        }
        bus.wait_readable(0);
    });
    assert_eq!(got, 100);
    assert_eq!(n, 0, "allocations on the drive's side");
}
