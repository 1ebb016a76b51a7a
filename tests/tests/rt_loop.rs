//! The real-time loop (`drive-emu run` without `--lockstep`) on a virtual CAN bus: frames are
//! answered on arrival, the synchronous window 0x1007 is kept, and a drive stalled by the host
//! (SIGSTOP) loses no frame: every SYNC of the burst gets its TPDO set, for every axis.
//!
//! Needs vcan: `./vcan-setup.sh -- cargo nextest run -p e2e --test rt_loop` (or ./test-all.sh).
//! Node ids: 30 (on arrival), 31 (0x1007), 40-55 (16 axes). No timing assertions: UML's
//! scheduling noise is milliseconds; the tests assert order, counts and the drive's counters.

use std::os::fd::AsRawFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use e2e::socketcan::{CanSocket, Socket};
use e2e::{
    id_data, iface, nmt, open_bus, recv_matching, sdo_download, sdo_u32, send, temp_file,
    wait_bootup, Emu, PEER_TIMEOUT,
};

/// A listener that keeps up with a burst: a 64 MiB receive buffer (SO_RCVBUFFORCE as root in
/// UML, else whatever SO_RCVBUF grants).
fn listener(ifname: &str) -> CanSocket {
    let s = open_bus(ifname);
    let bytes: libc::c_int = 64 << 20;
    for opt in [libc::SO_RCVBUFFORCE, libc::SO_RCVBUF] {
        // SAFETY: setsockopt on our own socket with a c_int value.
        let rc = unsafe {
            libc::setsockopt(
                s.as_raw_fd(),
                libc::SOL_SOCKET,
                opt,
                (&bytes as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        if rc == 0 {
            break;
        }
    }
    s
}

fn frame_id(f: &e2e::socketcan::CanFrame) -> u32 {
    id_data(f).0
}

/// A SYNC is answered with its TPDO set (TPDO2-4, all synchronous by default) before the master
/// sends the next one, and an SDO request between SYNCs is answered before the next SYNC too:
/// the master here waits for each answer before it goes on, with a tick of 4 ms (250 Hz) in the
/// drive, so nothing waits for a tick. Causality and counts, no clock.
#[test]
fn realtime_drive_answers_sync_and_sdo_on_arrival() {
    const NODE: u8 = 30;
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let emu = Emu::spawn(&["--iface", &ifname, "--node", "30", "--tick-hz", "250"]);
    assert!(wait_bootup(&sock, NODE, PEER_TIMEOUT), "no boot-up");
    nmt(&sock, 1, NODE);
    let tpdo = [
        0x280 + NODE as u32,
        0x380 + NODE as u32,
        0x480 + NODE as u32,
    ];
    let mut round_trips = Vec::new();
    for k in 0..200 {
        let t0 = Instant::now();
        send(&sock, 0x080, &[]);
        let mut seen = [false; 3];
        while !seen.iter().all(|&s| s) {
            let f = recv_matching(&sock, PEER_TIMEOUT, |f| tpdo.contains(&frame_id(f)))
                .unwrap_or_else(|| panic!("SYNC {k}: TPDO set incomplete: {seen:?}"));
            let i = tpdo.iter().position(|&c| c == frame_id(&f)).unwrap();
            assert!(
                !seen[i],
                "SYNC {k}: TPDO {:03X} twice before the next SYNC",
                tpdo[i]
            );
            seen[i] = true;
        }
        round_trips.push(t0.elapsed());
        if k % 10 == 0 {
            assert_eq!(
                sdo_u32(&sock, NODE, 0x1000, 0),
                0x0002_0192,
                "SDO between SYNCs"
            );
        }
    }
    round_trips.sort();
    // Reported, not asserted (UML timing).
    eprintln!(
        "SYNC -> full TPDO set round trip (4 ms tick): p50 {:?}, max {:?}",
        round_trips[round_trips.len() / 2],
        round_trips.last().unwrap()
    );
    emu.stop_clean();
}

/// 0x1007: with a 20 ms synchronous window, the SYNCs a stalled drive (SIGSTOP, 1 s) reads late
/// get no synchronous TPDO (counted in 0x2100 sub 12); SYNCs handled in time are answered.
#[test]
fn synchronous_window_1007_drops_tpdos_of_late_syncs() {
    const NODE: u8 = 31;
    const BURST: usize = 300;
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let emu = Emu::spawn(&["--iface", &ifname, "--node", "31"]);
    assert!(wait_bootup(&sock, NODE, PEER_TIMEOUT), "no boot-up");
    sdo_download(&sock, NODE, 0x1007, 0, &20_000u32.to_le_bytes()).expect("0x1007 write");
    assert_eq!(sdo_u32(&sock, NODE, 0x1007, 0), 20_000);
    nmt(&sock, 1, NODE);
    let tpdo2 = 0x280 + NODE as u32;
    // In time: stop-and-wait SYNCs are answered.
    let mut answered = 0;
    for _ in 0..20 {
        send(&sock, 0x080, &[]);
        if recv_matching(&sock, Duration::from_secs(5), |f| frame_id(f) == tpdo2).is_some() {
            answered += 1;
        }
    }
    assert!(
        answered >= 15,
        "only {answered} of 20 SYNCs answered in time"
    );
    // SAFETY: kill(2) on our own child.
    unsafe { libc::kill(emu.pid(), libc::SIGSTOP) };
    for _ in 0..BURST {
        send(&sock, 0x080, &[]);
        std::thread::sleep(Duration::from_micros(2000));
    }
    std::thread::sleep(Duration::from_millis(500));
    // SAFETY: as above.
    unsafe { libc::kill(emu.pid(), libc::SIGCONT) };
    // Count the TPDO2s the burst got (an SDO round trip marks the end of the backlog).
    let mut late_answers = 0;
    let marker = sdo_u32(&sock, NODE, 0x1000, 0);
    assert_eq!(marker, 0x0002_0192);
    while recv_matching(&sock, Duration::from_millis(300), |f| frame_id(f) == tpdo2).is_some() {
        late_answers += 1;
    }
    // Let the loop publish 0x2100 (every 256 ticks), then read the count of missed TPDOs.
    std::thread::sleep(Duration::from_millis(600));
    let missed = sdo_u32(&sock, NODE, 0x2100, 12);
    assert!(
        missed >= 3 * (BURST as u32 - 20),
        "0x2100:12 = {missed} synchronous TPDOs missed for {BURST} late SYNCs"
    );
    assert!(
        late_answers <= 20,
        "{late_answers} TPDO2 sent for {BURST} SYNCs read up to 1 s late with a 20 ms window"
    );
    emu.stop_clean();
}

/// 16 axes in one real-time process; the master sends a SYNC every millisecond for 3 s and the
/// drive is stopped (SIGSTOP) for a second in the middle. Every node sent exactly one TPDO2,
/// TPDO3 and TPDO4 per SYNC, in order (each set after its SYNC, before the next SYNC's set),
/// and the drive counted no dropped frame (0x2100 subs 6 and 7, the exit statistics).
#[test]
fn sixteen_axes_lose_no_frame_after_a_stall() {
    const FIRST: u8 = 40;
    const AXES: u8 = 16;
    let ifname = iface(0);
    let mut toml = String::from("tick_hz = 1000\n");
    for n in FIRST..FIRST + AXES {
        toml += &format!("[[axis]]\nnode_id = {n}\npreset = \"cnc1\"\n");
    }
    let machine = temp_file("sixteen.toml", &toml);
    let sock = open_bus(&ifname);
    let listen = listener(&ifname);
    let emu = Emu::spawn(&["--iface", &ifname, "--config", machine.to_str().unwrap()]);
    for n in FIRST..FIRST + AXES {
        assert!(
            wait_bootup(&sock, n, PEER_TIMEOUT),
            "no boot-up from node {n}"
        );
    }
    nmt(&sock, 1, 0);
    // Wait until every node is operational: a SYNC gets node FIRST+15's TPDO2.
    let last = 0x280 + u32::from(FIRST + AXES - 1);
    let mut operational = false;
    for _ in 0..100 {
        send(&sock, 0x080, &[]);
        if recv_matching(&sock, Duration::from_millis(200), |f| frame_id(f) == last).is_some() {
            operational = true;
            break;
        }
    }
    assert!(operational, "the axes never answered a SYNC");
    std::thread::sleep(Duration::from_millis(100));
    // From here the listener counts. Drain what came before for a bounded time (the bus is
    // never quiet: TPDO1's event timer sends on every node).
    let drain_until = Instant::now() + Duration::from_millis(300);
    while Instant::now() < drain_until {
        let _ = recv_matching(&listen, Duration::from_millis(20), |_| true);
    }
    let done = Arc::new(AtomicBool::new(false));
    let counter = {
        let done = Arc::clone(&done);
        std::thread::spawn(move || {
            // per node: [tpdo2, tpdo3, tpdo4] counts, and order violations
            let mut counts = vec![[0u64; 3]; AXES as usize];
            let mut syncs = 0u64;
            let mut disorder = Vec::new();
            let quiet_needed = Duration::from_secs(2);
            let mut last_frame = Instant::now();
            listen
                .set_read_timeout(Duration::from_millis(50))
                .expect("timeout");
            loop {
                // Checked before every read, not only on a read timeout: TPDO1's event timer
                // keeps the bus busy, so reads rarely time out.
                if done.load(Ordering::Relaxed) && last_frame.elapsed() > quiet_needed {
                    break;
                }
                if let Ok(f) = listen.read_frame() {
                    let id = frame_id(&f);
                    if id == 0x080 {
                        last_frame = Instant::now();
                        syncs += 1;
                        continue;
                    }
                    let (base, node) = (id & !0x7F, (id & 0x7F) as u8);
                    if !(FIRST..FIRST + AXES).contains(&node) {
                        continue;
                    }
                    let k = match base {
                        0x280 => 0,
                        0x380 => 1,
                        0x480 => 2,
                        _ => continue,
                    };
                    // quiet = no SYNC and no synchronous TPDO (event-driven ones go on)
                    last_frame = Instant::now();
                    let c = &mut counts[(node - FIRST) as usize];
                    c[k] += 1;
                    // The n-th TPDO of a kind answers the n-th SYNC: never ahead of it.
                    if c[k] > syncs && disorder.len() < 10 {
                        disorder.push((node, id, c[k], syncs));
                    }
                }
            }
            (counts, syncs, disorder)
        })
    };
    let start = Instant::now();
    let mut sent = 0u64;
    let mut stopped = false;
    let mut resumed = false;
    while start.elapsed() < Duration::from_secs(3) {
        if sock.write_frame(&e2e::frame(0x080, &[])).is_ok() {
            sent += 1;
        }
        let t = start.elapsed();
        if !stopped && t > Duration::from_secs(1) {
            // SAFETY: kill(2) on our own child.
            unsafe { libc::kill(emu.pid(), libc::SIGSTOP) };
            stopped = true;
        }
        if !resumed && t > Duration::from_secs(2) {
            // SAFETY: as above.
            unsafe { libc::kill(emu.pid(), libc::SIGCONT) };
            resumed = true;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    if !resumed {
        // SAFETY: as above.
        unsafe { libc::kill(emu.pid(), libc::SIGCONT) };
    }
    // The backlog is answered: an SDO round trip to the last node comes after it. A fresh
    // socket with a large buffer: `sock` overflowed with the 3 s of TPDOs nobody read on it.
    drop(sock);
    let sock = listener(&ifname);
    let mut answered = false;
    for _ in 0..6 {
        if e2e::sdo_upload(&sock, FIRST + AXES - 1, 0x1000, 0).is_ok() {
            answered = true;
            break;
        }
    }
    if !answered {
        done.store(true, Ordering::Relaxed);
        let exit = emu.stop();
        panic!("no SDO answer after the burst; drive-emu:\n{}", exit.stderr);
    }
    done.store(true, Ordering::Relaxed);
    let (counts, syncs, disorder) = counter.join().expect("listener thread");
    assert_eq!(syncs, sent, "the listener saw every SYNC we sent");
    for (i, c) in counts.iter().enumerate() {
        let node = FIRST + i as u8;
        assert_eq!(
            *c, [sent; 3],
            "node {node}: TPDO2/3/4 counts for {sent} SYNCs (1 s of them sent to a stopped drive)"
        );
    }
    assert!(disorder.is_empty(), "TPDO ahead of its SYNC: {disorder:?}");
    std::thread::sleep(Duration::from_millis(600));
    let sock = listener(&ifname);
    for n in [FIRST, FIRST + AXES - 1] {
        assert_eq!(sdo_u32(&sock, n, 0x2100, 6), 0, "node {n}: dropped frames");
        assert_eq!(
            sdo_u32(&sock, n, 0x2100, 7),
            0,
            "node {n}: node queue overflows"
        );
    }
    let exit = emu.stop_clean();
    assert!(exit.stderr.contains("tx dropped 0,"), "{}", exit.stderr);
}
