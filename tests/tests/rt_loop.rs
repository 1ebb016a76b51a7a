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

use e2e::socketcan::{CanFilter, CanSocket, Socket, SocketOptions};
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
        assert_eq!(
            sdo_u32(&sock, n, 0x2100, 13),
            0,
            "node {n}: frames the kernel dropped on the drive's receive queue"
        );
    }
    let exit = emu.stop_clean();
    assert!(exit.stderr.contains("tx dropped 0,"), "{}", exit.stderr);
    assert!(exit.stderr.contains("rx overflow 0,"), "{}", exit.stderr);
}

/// A deterministic pseudo-random number in [-1, 1) (xorshift; the test needs no crate for it).
fn unit_noise(seed: &mut u64) -> f64 {
    *seed ^= *seed << 13;
    *seed ^= *seed >> 7;
    *seed ^= *seed << 17;
    (*seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// The q-quantile (0..=1) of a sorted slice.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// Quantiles of the intervals between the SYNCs sent, for failure messages.
fn sync_intervals(sent_at: &[(Instant, f64)]) -> String {
    let mut iv: Vec<f64> = sent_at
        .windows(2)
        .map(|w| (w[1].0 - w[0].0).as_secs_f64() * 1e6)
        .collect();
    if iv.is_empty() {
        return "(none)".into();
    }
    iv.sort_by(f64::total_cmp);
    let q: Vec<String> = [0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 0.99]
        .iter()
        .map(|&p| format!("p{} {:.0}", (p * 100.0) as u32, quantile(&iv, p)))
        .collect();
    format!("{} us ({} of them)", q.join(", "), iv.len())
}

/// SYNC phase lock seen by a master: the drive runs CSV at a constant 100 mm/s in the real-time
/// loop (`run`, 250 Hz tick); the master sends SYNC every 4 ms (+500 ppm: its clock is not the
/// drive's) with a uniform jitter J of +-0.8 ms (20 %), and reads the position actual value 0x6064 from
/// TPDO2 after each SYNC. The drive locks (0x2100:8 = 2) and its position increments follow
/// the nominal cycle: the drive samples at its phase-locked control cycle, one cycle per SYNC,
/// not at the jittered arrival.
///
/// What sampling at arrival would give: the interval between SYNCs k-1 and k is
/// `T + j_k - j_{k-1}`, with `j` uniform in [-J, J]: a triangular spread over [-2J, 2J], of
/// which only `1 - (1.5J / 2J)^2 = 44 %` lie within +-J/2 (400 us) of the nominal period. The
/// test judges the intervals between SYNCs the master sent within its injected jitter (the
/// loaded host's scheduler holds some back by milliseconds and then sends a bunch; those are
/// reported, not judged): 10 points more of their position increments than of the SYNC
/// intervals as sent (sampling at arrival) lie within +-J/2 of one cycle of travel, and the
/// median increment is the nominal 4 ms of travel within 3 %. Measured in a loaded 2-core UML:
/// 74-89 % against 53-56 % at arrival (100 % in the PLL's unit simulation of a loaded
/// master); the margin is low because the scheduler's stalls and bunches also move the lock
/// (a re-acquisition over a stall has measured a 55 ms period), see the follow-up.
/// (4 ms, not 1 ms: in a loaded UML a 1 kHz SYNC with this listener starved the drive of CPU,
/// its loop fell seconds behind the bus and skipped ticks, which says nothing about the lock.)
#[test]
fn jittered_sync_gives_smooth_position_in_realtime_mode() {
    const NODE: u8 = 33;
    const PERIOD_US: f64 = 4000.0;
    const DRIFT_PPM: f64 = 500.0;
    const JITTER_US: f64 = 800.0;
    const SPEED_UU_S: i32 = 100_000; // 1 uu = 1 um: 100 mm/s, 400 uu per SYNC
    const MEASURE_SYNCS: usize = 1500;
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let emu = Emu::spawn(&[
        "--iface",
        &ifname,
        "--node",
        "33",
        "--preset",
        "cnc1",
        "--tick-hz",
        "250",
    ]);
    assert!(wait_bootup(&sock, NODE, PEER_TIMEOUT), "no boot-up");
    // This socket only takes SDO answers: a default receive queue filled with the SYNCs and
    // TPDOs of the 200 ms between two reads drops the answer (seen in UML).
    sock.set_filters(&[CanFilter::new(0x580 + u32::from(NODE), 0x7FF)])
        .expect("CAN_RAW_FILTER");
    // CSV, interpolation period 4 ms, then enable and hold a constant target velocity.
    sdo_download(&sock, NODE, 0x60C2, 1, &[4]).expect("0x60C2:1");
    sdo_download(&sock, NODE, 0x60C2, 2, &[(-3i8) as u8]).expect("0x60C2:2");
    sdo_download(&sock, NODE, 0x6060, 0, &[9]).expect("0x6060 = CSV");
    nmt(&sock, 1, NODE);
    // Shutdown, switch on, enable operation: each once the drive's cycle took the last one.
    for (cw, want) in [(0x06u16, 0x21u32), (0x07, 0x23), (0x0F, 0x27)] {
        sdo_download(&sock, NODE, 0x6040, 0, &cw.to_le_bytes()).expect("controlword");
        let t0 = Instant::now();
        let mut sw = 0;
        while t0.elapsed() < PEER_TIMEOUT {
            sw = sdo_u32(&sock, NODE, 0x6041, 0);
            if sw & 0x6F == want {
                break;
            }
        }
        assert_eq!(
            sw & 0x6F,
            want,
            "controlword {cw:#06X}: statusword {sw:#06X}"
        );
    }
    sdo_download(&sock, NODE, 0x60FF, 0, &SPEED_UU_S.to_le_bytes()).expect("0x60FF");

    // Opened before the first SYNC, so its SYNC count is the master's.
    let listen = listener(&ifname);
    // The master's SYNC thread: an absolute schedule, each SYNC jittered independently.
    let stop = Arc::new(AtomicBool::new(false));
    let sent = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    // Consecutive SYNC pairs the scheduler sent within the injected jitter (a live count, to
    // measure long enough on a busy host; the judgement below recounts them).
    let on_time = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let master = {
        let (stop, sent, on_time, ifname) = (
            Arc::clone(&stop),
            Arc::clone(&sent),
            Arc::clone(&on_time),
            ifname.clone(),
        );
        std::thread::spawn(move || {
            let s = open_bus(&ifname);
            let mut seed = 0x9e37_79b9_7f4a_7c15u64;
            let t0 = Instant::now() + Duration::from_millis(10);
            let mut sent_at = Vec::new();
            let mut k = 0u64;
            let mut last_on_time = false;
            while !stop.load(Ordering::Relaxed) {
                k += 1;
                let nominal_us = k as f64 * PERIOD_US * (1.0 + DRIFT_PPM * 1e-6);
                let jitter_us = JITTER_US * unit_noise(&mut seed);
                let at_us = nominal_us + jitter_us;
                let at = t0 + Duration::from_micros(at_us as u64);
                let now = Instant::now();
                if at > now {
                    std::thread::sleep(at - now);
                }
                // A SYNC the scheduler held back is still sent: the drive must cope.
                while s.write_frame(&e2e::frame(0x080, &[])).is_err() {
                    std::thread::sleep(Duration::from_micros(100));
                }
                // When it went out, and how far from its jitter-free time.
                let out = Instant::now();
                let offset_us = out.duration_since(t0).as_secs_f64() * 1e6 - nominal_us;
                let held_us = offset_us - jitter_us;
                let now_on_time = held_us.abs() <= JITTER_US / 2.0;
                if now_on_time && last_on_time {
                    on_time.fetch_add(1, Ordering::Relaxed);
                }
                last_on_time = now_on_time;
                sent_at.push((out, offset_us));
                sent.fetch_add(1, Ordering::Relaxed);
            }
            sent_at
        })
    };
    // The listener: the position of every TPDO2 (the n-th answers the n-th SYNC: TPDO2 is
    // synchronous, one per SYNC, in order) and the SYNCs it saw.
    let listening = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            let tpdo2 = 0x280 + u32::from(NODE);
            let mut positions: Vec<i32> = Vec::new();
            let mut syncs = 0u64;
            listen
                .set_read_timeout(Duration::from_millis(50))
                .expect("timeout");
            // Quiet: no SYNC and no TPDO2 (TPDO1's event timer keeps the bus busy, so the
            // check comes before every read, not on a read timeout).
            let mut last_frame = Instant::now();
            loop {
                if stop.load(Ordering::Relaxed) && last_frame.elapsed() > Duration::from_millis(500)
                {
                    break;
                }
                if let Ok(f) = listen.read_frame() {
                    let (id, data) = id_data(&f);
                    if id == 0x080 {
                        syncs += 1;
                        last_frame = Instant::now();
                    } else if id == tpdo2 && data.len() >= 6 {
                        let pos = i32::from_le_bytes(data[2..6].try_into().unwrap());
                        positions.push(pos);
                        last_frame = Instant::now();
                    }
                }
            }
            (positions, syncs)
        })
    };

    // Wait (bounded) for the lock; 0x2100 is refreshed every 256 ticks.
    let wait_lock = Instant::now();
    let mut lock = 0;
    while wait_lock.elapsed() < PEER_TIMEOUT {
        lock = match e2e::sdo_upload(&sock, NODE, 0x2100, 8) {
            Ok(d) if d.len() == 4 => u32::from_le_bytes(d.try_into().unwrap()),
            other => {
                stop.store(true, Ordering::Relaxed);
                let iv = sync_intervals(&master.join().expect("master thread"));
                let exit = emu.stop();
                panic!(
                    "0x2100:8 upload {other:?} after {:?} waiting; SYNC intervals sent {iv}; \
                     drive-emu: {}",
                    wait_lock.elapsed(),
                    exit.stderr
                );
            }
        };
        if lock == 2 {
            break;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    let from_sync = sent.load(Ordering::Relaxed) as u64;
    let on_time_from = on_time.load(Ordering::Relaxed);
    if lock != 2 {
        let (err, period) = (
            sdo_u32(&sock, NODE, 0x2100, 9),
            sdo_u32(&sock, NODE, 0x2100, 10),
        );
        stop.store(true, Ordering::Relaxed);
        let iv = sync_intervals(&master.join().expect("master thread"));
        panic!(
            "0x2100:8 sync lock state never 2 (locked); phase error {err} us, period {period} \
             us; SYNC intervals sent {iv}"
        );
    }
    // Measure over the next MEASURE_SYNCS SYNCs, and on a busy host longer: until a quarter
    // of them came as pairs within the injected jitter (at most 8x as many SYNCs; a bounded
    // wait on the master's count).
    let wait_measure = Instant::now();
    loop {
        let n = sent.load(Ordering::Relaxed) as u64 - from_sync;
        let pairs = on_time.load(Ordering::Relaxed) - on_time_from;
        if n >= MEASURE_SYNCS as u64
            && (pairs >= MEASURE_SYNCS / 4 || n >= 8 * MEASURE_SYNCS as u64)
        {
            break;
        }
        assert!(
            wait_measure.elapsed() < 20 * PEER_TIMEOUT,
            "the master could not send {MEASURE_SYNCS} SYNCs ({n} sent, {pairs} pairs on time)"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let measured = sent.load(Ordering::Relaxed) - from_sync as usize;
    let lock_end = sdo_u32(&sock, NODE, 0x2100, 8);
    let period_seen = sdo_u32(&sock, NODE, 0x2100, 10);
    let phase_err = sdo_u32(&sock, NODE, 0x2100, 9);
    stop.store(true, Ordering::Relaxed);
    let sent_at = master.join().expect("master thread");
    let (positions, syncs_seen) = listening.join().expect("listener thread");
    let exit = emu.stop_clean();

    assert_eq!(
        syncs_seen,
        sent_at.len() as u64,
        "the listener saw every SYNC"
    );
    assert_eq!(
        positions.len() as u64,
        syncs_seen,
        "one TPDO2 per SYNC (a real-time drive answers every SYNC)"
    );
    // Increments between the TPDO2s of consecutive SYNCs, inside the measuring window, as
    // the sampling interval they correspond to (us at the nominal speed).
    let nominal_uu = f64::from(SPEED_UU_S) * PERIOD_US * 1e-6;
    let (lo, hi) = (from_sync as usize, from_sync as usize + measured);
    let inc_us =
        |i: usize| f64::from(positions[i].wrapping_sub(positions[i - 1])) / nominal_uu * PERIOD_US;
    let sent_us = |i: usize| (sent_at[i].0 - sent_at[i - 1].0).as_secs_f64() * 1e6;
    let master_period_us = PERIOD_US * (1.0 + DRIFT_PPM * 1e-6);
    let smooth = |x: f64, m: f64| (x - m).abs() <= JITTER_US / 2.0;
    let mut all: Vec<f64> = (lo + 1..hi).map(inc_us).collect();
    all.sort_by(f64::total_cmp);
    // The SYNCs the master sent within its injected jitter (offset from the median offset:
    // the scheduler's median delay is common to all): for the intervals between two such
    // SYNCs, sampling at arrival gives the triangular spread (44 % smooth); a locked cycle
    // gives one control cycle each. SYNCs the loaded host held back further are outside what
    // the test injected (and a SYNC that arrives after the drive's next cycle rightly gets
    // that cycle's sample), so they are reported, not judged.
    let mut offsets: Vec<f64> = sent_at[lo..hi].iter().map(|s| s.1).collect();
    offsets.sort_by(f64::total_cmp);
    let median_offset = quantile(&offsets, 0.5);
    let in_band = |i: usize| (sent_at[i].1 - median_offset).abs() <= JITTER_US;
    let band: Vec<usize> = (lo + 1..hi)
        .filter(|&i| in_band(i) && in_band(i - 1))
        .collect();
    let frac = |n: usize, d: usize| n as f64 / d.max(1) as f64;
    let pos_smooth = frac(
        band.iter()
            .filter(|&&i| smooth(inc_us(i), PERIOD_US))
            .count(),
        band.len(),
    );
    let arrival_smooth = frac(
        band.iter()
            .filter(|&&i| smooth(sent_us(i), master_period_us))
            .count(),
        band.len(),
    );
    let all_smooth = frac(
        all.iter().filter(|&&x| smooth(x, PERIOD_US)).count(),
        all.len(),
    );
    let all_arrival = frac(
        (lo + 1..hi)
            .filter(|&i| smooth(sent_us(i), master_period_us))
            .count(),
        hi - lo - 1,
    );
    let actual_period_us =
        (sent_at[hi - 1].0 - sent_at[lo].0).as_secs_f64() * 1e6 / (hi - lo - 1) as f64;
    eprintln!(
        "phase lock: 0x2100 at the end: lock state {lock_end}, period {period_seen} us (master \
         {actual_period_us:.1} us), phase error {phase_err} us. Position increments (us of \
         travel) p5/p25/p50/p75/p95 {:.0}/{:.0}/{:.0}/{:.0}/{:.0}. Within +-{:.0} us of the \
         period: SYNCs sent within the injected jitter ({} intervals): position {:.1} %, \
         arrival {:.1} % (theory 43.8 %); all {} intervals: position {:.1} %, arrival {:.1} %. \
         SYNC intervals sent: {}",
        quantile(&all, 0.05),
        quantile(&all, 0.25),
        quantile(&all, 0.5),
        quantile(&all, 0.75),
        quantile(&all, 0.95),
        JITTER_US / 2.0,
        band.len(),
        100.0 * pos_smooth,
        100.0 * arrival_smooth,
        all.len(),
        100.0 * all_smooth,
        100.0 * all_arrival,
        sync_intervals(&sent_at[lo..hi]),
    );
    assert!(
        (quantile(&all, 0.5) - PERIOD_US).abs() <= 0.03 * PERIOD_US,
        "median position increment {:.0} us of travel at {SPEED_UU_S} uu/s, nominal {PERIOD_US} us",
        quantile(&all, 0.5)
    );
    assert!(
        band.len() >= MEASURE_SYNCS / 5,
        "only {} of {measured} SYNC intervals within the injected jitter: the host is too busy to test",
        band.len()
    );
    assert!(
        pos_smooth >= arrival_smooth + 0.10,
        "only {:.1} % of the position increments within +-{} us of the cycle for SYNCs within \
         the injected jitter (sampling at arrival: {:.1} %)",
        100.0 * pos_smooth,
        JITTER_US / 2.0,
        100.0 * arrival_smooth
    );
    assert!(exit.stderr.contains("tx dropped 0,"), "{}", exit.stderr);
}
