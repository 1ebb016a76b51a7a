//! The emulator (`drive-emu run`) as a process on a virtual CAN bus: what it puts on the
//! wire (candump), robustness against malformed traffic and against the interface going
//! down, a two-axis machine file and its status block on a terminal.
//!
//! Needs vcan: `./vcan-setup.sh --ifaces 2 -- cargo nextest run -p e2e --test emulator_bus`
//! (or ./test-all.sh). Node ids: 12 (candump), 13 (flood, vcan1), 14 (link down, vcan1),
//! 20/21 (machine file), 22/23 (status block). No timing assertions: in lock-step mode the
//! emulator's time only advances with the SYNCs we send, so heartbeat counts are exact
//! functions of them.

use std::process::Command;
use std::time::{Duration, Instant};

use e2e::socketcan::{CanFrame, EmbeddedFrame, ExtendedId, Socket, StandardId};
use e2e::{
    drive_emu_bin, frame, id_data, iface, nmt, open_bus, recv_matching, sdo_barrier, sdo_download,
    sdo_u32, sdo_upload, sdo_upload_within, send, temp_file, wait_bootup, Emu, Peer, SdoError,
    PEER_TIMEOUT,
};

const DEVICE_TYPE: u32 = 0x0002_0192;

/// Parse a `candump -L` line: `(ts) iface ID#DATA` -> (id, data); RTR/others -> None.
fn parse_candump(line: &str) -> Option<(u32, Vec<u8>)> {
    let f = line.split_whitespace().nth(2)?;
    let (id, data) = f.split_once('#')?;
    if data.starts_with('R') {
        return None;
    }
    let id = u32::from_str_radix(id, 16).ok()?;
    let bytes = (0..data.len() / 2)
        .map(|i| u8::from_str_radix(&data[2 * i..2 * i + 2], 16))
        .collect::<Result<Vec<u8>, _>>()
        .ok()?;
    Some((id, bytes))
}

/// Start candump on `ifname` and wait until it demonstrably receives (it has no ready
/// signal): resend a marker frame until it prints it.
fn start_candump(ifname: &str, sock: &e2e::socketcan::CanSocket, marker: u16) -> Peer {
    // line-buffered: candump's stdout is a pipe here
    let mut cmd = Command::new("stdbuf");
    cmd.args(["-oL", "candump", "-d", "-r", "4194304", "-L", ifname]);
    let mut dump = Peer::spawn("candump", cmd);
    let deadline = Instant::now() + PEER_TIMEOUT;
    let needle = format!("{marker:03X}#");
    loop {
        send(sock, marker, &[0xAA]);
        if dump
            .wait_line(&needle, Duration::from_millis(200))
            .is_some()
        {
            return dump;
        }
        assert!(
            Instant::now() < deadline,
            "candump never saw our marker frame on {ifname}"
        );
    }
}

/// The capture: boot-up first, heartbeats (state 0x7F in pre-operational, 0x05 in
/// operational; on the wall clock, as a master supervises them, also in lock-step), SDO
/// answers on 0x580+n only when asked, TPDOs on 0x180../0x280../0x380../0x480.. only in
/// operational and, for the synchronous ones, exactly one per SYNC, each after a SYNC.
#[test]
fn candump_boot_heartbeat_sdo_and_tpdo_cob_ids() {
    const NODE: u8 = 12;
    const HB_MS: u16 = 10;
    const SYNCS: usize = 100; // per phase, 1 ms each in lock-step: 100 ms of drive time
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let mut dump = start_candump(&ifname, &sock, 0x7A0);

    let emu = Emu::spawn(&[
        "--iface",
        &ifname,
        "--node",
        "12",
        "--preset",
        "cnc1",
        "--lockstep",
        "--sync-period-us",
        "1000",
    ]);
    assert!(
        wait_bootup(&sock, NODE, PEER_TIMEOUT),
        "no boot-up 0x70C#00 from drive-emu; stderr:\n{}",
        emu.stderr_now()
    );
    assert_eq!(sdo_u32(&sock, NODE, 0x1000, 0), DEVICE_TYPE);
    sdo_download(&sock, NODE, 0x1017, 0, &HB_MS.to_le_bytes()).expect("write 0x1017");

    // Phase 1: pre-operational. SYNCs advance time; heartbeats 0x7F, no PDOs.
    for _ in 0..SYNCS {
        send(&sock, 0x080, &[]);
        // a little pacing so that candump keeps up (no timing is asserted)
        std::thread::sleep(Duration::from_micros(500));
    }
    // An SDO round trip after the SYNCs: all of them have been handled by now.
    assert_eq!(sdo_u32(&sock, NODE, 0x1017, 0), u32::from(HB_MS));
    let hb_id = 0x700 + u32::from(NODE);
    recv_matching(&sock, PEER_TIMEOUT, |f| id_data(f) == (hb_id, vec![0x7F]))
        .expect("a heartbeat 70C#7F in pre-operational");

    // Phase 2: operational; each SYNC answered by the synchronous TPDOs.
    nmt(&sock, 0x01, NODE);
    for i in 0..SYNCS {
        send(&sock, 0x080, &[]);
        // pace like a master: wait for the last synchronous TPDO of this SYNC
        recv_matching(&sock, PEER_TIMEOUT, |f| {
            id_data(f).0 == 0x480 + u32::from(NODE)
        })
        .unwrap_or_else(|| panic!("no TPDO4 0x48C after SYNC {i}"));
    }
    assert_eq!(sdo_u32(&sock, NODE, 0x1000, 0), DEVICE_TYPE);
    recv_matching(&sock, PEER_TIMEOUT, |f| id_data(f) == (hb_id, vec![0x05]))
        .expect("a heartbeat 70C#05 in operational");
    send(&sock, 0x7A2, &[0x02]);
    dump.wait_line("7A2#02", PEER_TIMEOUT)
        .expect("candump did not see the end marker");
    let dump_out = dump.output();
    let frames: Vec<(u32, Vec<u8>)> = dump_out.lines().filter_map(parse_candump).collect();
    drop(dump);
    emu.stop_clean();

    let node = u32::from(NODE);
    let mine = |id: u32| {
        id == 0x700 + node
            || id == 0x580 + node
            || id == 0x80 + node
            || (0x180..=0x480).step_by(0x100).any(|b| id == b + node)
    };
    // the capture from the first frame of the node on
    let first = frames
        .iter()
        .position(|(id, _)| mine(*id))
        .expect("nothing from node 12 in the capture");
    assert_eq!(
        frames[first],
        (0x700 + node, vec![0x00]),
        "the first frame of node 12 must be its boot-up 70C#00"
    );
    // In lock-step the emulator handles a batch of frames at one instant and then runs
    // the ticks the batch's SYNCs asked for: its heartbeats may follow our later frames
    // on the wire. So heartbeats are classified by their state byte, and the NMT start
    // frame splits the capture for the PDO checks (no PDO can precede it).
    let nmt_at = frames
        .iter()
        .position(|f| *f == (0, vec![0x01, NODE]))
        .expect("NMT start in the capture");
    let (pre, op) = frames.split_at(nmt_at);
    let count = |fs: &[(u32, Vec<u8>)], id: u32, data: Option<&[u8]>| {
        fs.iter()
            .filter(|(i, d)| *i == id && data.is_none_or(|x| d.as_slice() == x))
            .count()
    };
    let hb = 0x700 + node;
    let mut hist = std::collections::BTreeMap::new();
    for (id, _) in &frames {
        *hist.entry(*id).or_insert(0usize) += 1;
    }
    eprintln!("capture: {} frames, by id: {hist:X?}", frames.len());
    let seq: Vec<String> = frames
        .iter()
        .filter(|(id, _)| *id >= 0x500 || *id == 0)
        .map(|(id, d)| {
            format!(
                "{id:03X}#{}",
                d.iter().map(|b| format!("{b:02X}")).collect::<String>()
            )
        })
        .collect();
    eprintln!("sequence: {}", seq.join(" "));
    assert!(
        !dump_out.contains("DROPCOUNT"),
        "candump dropped frames (its socket overflowed); the capture is incomplete:\n{dump_out}"
    );
    // Heartbeats go by the wall clock (a master supervises them so, CiA 301), so their
    // number depends on how long the run took, not on the SYNCs: each state has some.
    let hb_pre = count(&frames, hb, Some(&[0x7F]));
    let hb_op = count(&frames, hb, Some(&[0x05]));
    assert!(hb_pre >= 1, "no heartbeat 70C#7F in pre-operational");
    assert!(hb_op >= 1, "no heartbeat 70C#05 in operational");
    assert_eq!(
        count(pre, hb, Some(&[0x05])),
        0,
        "heartbeat 70C#05 before NMT start"
    );
    let first_op_hb = frames.iter().position(|f| *f == (hb, vec![0x05])).unwrap();
    assert_eq!(
        count(&frames[first_op_hb..], hb, Some(&[0x7F])),
        0,
        "heartbeat 70C#7F after the first 70C#05"
    );
    assert_eq!(
        count(&frames, hb, None),
        1 + hb_pre + hb_op,
        "node 12 on 0x70C: one boot-up, then heartbeats 0x7F / 0x05 only"
    );
    for base in [0x180, 0x280, 0x380, 0x480] {
        assert_eq!(
            count(pre, base + node, None),
            0,
            "TPDO {:03X} in pre-operational",
            base + node
        );
    }
    // synchronous TPDOs (types 1): one per SYNC, 6 bytes (statusword + I32)
    for base in [0x280, 0x380, 0x480] {
        let id = base + node;
        assert_eq!(count(op, id, None), SYNCS, "TPDO {id:03X}: one per SYNC");
        assert!(
            op.iter()
                .filter(|(i, _)| *i == id)
                .all(|(_, d)| d.len() == 6),
            "TPDO {id:03X} is statusword + 32-bit value, 6 bytes"
        );
        // the k-th TPDO comes after the k-th SYNC
        let mut syncs = 0;
        let mut tpdos = 0;
        for (i, _) in op {
            if *i == 0x080 {
                syncs += 1;
            } else if *i == id {
                tpdos += 1;
                assert!(
                    tpdos <= syncs,
                    "TPDO {id:03X} #{tpdos} before SYNC #{tpdos}"
                );
            }
        }
    }
    // TPDO1 (event-driven, statusword + mode display): sent on entering operational
    let tpdo1 = count(op, 0x180 + node, None);
    assert!(tpdo1 >= 1, "no TPDO1 18C after NMT start");
    // SDO answers: on 0x58C only, one per request (3 uploads/downloads in pre-op + 1 in op)
    assert_eq!(
        count(&frames, 0x580 + node, None),
        4,
        "SDO answers on 0x58C"
    );
    assert_eq!(
        count(
            &frames,
            0x580 + node,
            Some(&[0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00])
        ),
        2,
        "upload of 0x1000 answered 43 00 10 00 92 01 02 00"
    );
    assert_eq!(count(&frames, 0x80 + node, None), 0, "no EMCY expected");
}

/// xorshift64*: a reproducible stream of garbage without a dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n).map(|_| self.next() as u8).collect()
    }
}

/// SDO upload after a disturbance. A garbage SDO may have left a transfer open; in a block
/// download the server takes every frame but an abort for a sub-block segment (CiA 301: they
/// carry no command specifier), so, as a master that lost track does, abort first. Then the
/// node must answer at the first try (an abort of a stale transfer counts) and give the right
/// value within three. The first answer may take a while: the drive handles its receive queue
/// in bus order, and on a busy host the flood may still be in it (no request is resent).
fn sdo_answers_after(sock: &e2e::socketcan::CanSocket, node: u8) {
    send(
        sock,
        0x600 + u16::from(node),
        &[0x80, 0, 0, 0, 0x00, 0x00, 0x00, 0x08], // abort, 0x08000000 general error
    );
    let first = sdo_upload_within(sock, node, 0x1000, 0, PEER_TIMEOUT);
    assert_ne!(
        first,
        Err(SdoError::Timeout),
        "node {node}: no SDO answer at all"
    );
    let mut last = first.clone();
    for _ in 0..3 {
        if last == Ok(DEVICE_TYPE.to_le_bytes().to_vec()) {
            if first != last {
                eprintln!("note: first SDO upload after the disturbance gave {first:?}");
            }
            return;
        }
        last = sdo_upload(sock, node, 0x1000, 0);
    }
    panic!("node {node}: SDO upload of 0x1000 gave {first:?} then {last:?}");
}

/// Malformed traffic, a fixed number of frames: random standard ids and lengths, RTR frames,
/// extended ids, garbage SDO requests to the node, NMT frames with bad lengths. The
/// emulator must stay up, answer SDO afterwards and exit 0 on SIGTERM without a panic.
#[test]
fn flood_of_malformed_frames_does_not_hurt() {
    const NODE: u8 = 13;
    // A count, not a duration: the same flood however busy the host is (bounded in time only
    // by the generous PEER_TIMEOUT per frame refused in a row).
    const FLOOD_FRAMES: u64 = 20_000;
    let ifname = iface(1);
    let sock = open_bus(&ifname);
    let mut emu = Emu::spawn(&["--iface", &ifname, "--node", "13", "--preset", "cnc1"]);
    assert!(
        wait_bootup(&sock, NODE, PEER_TIMEOUT),
        "no boot-up from node 13"
    );
    assert_eq!(sdo_u32(&sock, NODE, 0x1000, 0), DEVICE_TYPE);

    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let (mut sent, mut refused) = (0u64, 0u64);
    let mut kinds = [0u64; 6];
    let mut last_sent = Instant::now();
    while sent < FLOOD_FRAMES {
        assert!(
            last_sent.elapsed() < PEER_TIMEOUT,
            "the socket refused every frame for {PEER_TIMEOUT:?}"
        );
        let kind = rng.below(6) as usize;
        let len = rng.below(9) as usize;
        let f: CanFrame = match kind {
            // random standard id, random length
            0 => CanFrame::new(
                StandardId::new(rng.below(0x800) as u16).unwrap(),
                &rng.bytes(len),
            ),
            // remote frames, also on the node's own COB-IDs
            1 => {
                let id = if rng.below(2) == 0 {
                    rng.below(0x800) as u16
                } else {
                    [0x18D, 0x28D, 0x58D, 0x60D, 0x70D, 0x000, 0x080][rng.below(7) as usize]
                };
                CanFrame::new_remote(StandardId::new(id).unwrap(), len)
            }
            // extended ids (some whose low 11 bits are the node's COB-IDs)
            2 => {
                let raw = if rng.below(2) == 0 {
                    rng.below(1 << 29) as u32
                } else {
                    (rng.below(1 << 18) as u32) << 11 | 0x60D
                };
                CanFrame::new(ExtendedId::new(raw).unwrap(), &rng.bytes(len))
            }
            // SDO requests with garbage (random command specifier, index, length)
            3 => {
                let mut d = rng.bytes(len);
                if len >= 4 && rng.below(2) == 0 {
                    // a plausible index so the garbage reaches the object dictionary
                    let idx: u16 = [
                        0x1000, 0x1017, 0x1600, 0x1A00, 0x1800, 0x6040, 0x607A, 0x2000, 0x2101,
                        0x1008,
                    ][rng.below(10) as usize];
                    d[1..3].copy_from_slice(&idx.to_le_bytes());
                }
                CanFrame::new(StandardId::new(0x60D).unwrap(), &d)
            }
            // NMT with wrong lengths (never the 2 bytes of a real command)
            4 => {
                let l = [0usize, 1, 3, 4, 5, 8][rng.below(6) as usize];
                let mut d = rng.bytes(l);
                if l >= 2 && rng.below(2) == 0 {
                    d[1] = NODE;
                }
                CanFrame::new(StandardId::new(0x000).unwrap(), &d)
            }
            // SYNC with odd lengths, EMCY/heartbeat look-alikes with our node id
            _ => {
                let id =
                    [0x080, 0x08D, 0x70D, 0x58D, 0x20D, 0x30D, 0x40D, 0x50D][rng.below(8) as usize];
                CanFrame::new(StandardId::new(id).unwrap(), &rng.bytes(len))
            }
        }
        .expect("valid frame");
        kinds[kind] += 1;
        match sock.write_frame(&f) {
            Ok(()) => {
                sent += 1;
                last_sent = Instant::now();
            }
            Err(_) => {
                // ENOBUFS: the queue is full; let it drain
                refused += 1;
                std::thread::sleep(Duration::from_micros(200));
            }
        }
        if sent % 512 == 0 {
            assert!(
                emu.alive(),
                "drive-emu died during the flood; stderr:\n{}",
                emu.stderr_now()
            );
        }
    }
    eprintln!("flood: {sent} frames sent ({refused} refused by the socket), by kind {kinds:?}");
    assert!(
        emu.alive(),
        "drive-emu died during the flood; stderr:\n{}",
        emu.stderr_now()
    );

    // The drive answers the flood in bus order (an abort per garbage SDO, EMCYs): read its
    // answers until it has been quiet for 500 ms, so the SDO check below is not one frame in
    // a burst this socket may not keep up with (its receive queue full, a frame dropped: in
    // user-mode Linux one CPU runs the drive and this test). Bounded: a drive that never
    // goes quiet is checked all the same.
    let quiet = Duration::from_millis(500);
    let t0 = Instant::now();
    let mut last_heard = Instant::now();
    let mut heard = 0u64;
    while last_heard.elapsed() < quiet && t0.elapsed() < PEER_TIMEOUT {
        if recv_matching(&sock, quiet, |_| true).is_some() {
            heard += 1;
            last_heard = Instant::now();
        }
    }
    eprintln!("after the flood: {heard} frames from the drive, then quiet");
    // The flood may have stopped the node (NMT garbage): back to pre-operational, then SDO.
    nmt(&sock, 0x80, NODE);
    sdo_answers_after(&sock, NODE);
    assert_eq!(
        sdo_u32(&sock, NODE, 0x1018, 4),
        u32::from(NODE),
        "serial number = node id"
    );
    assert!(emu.alive());
    emu.stop_clean();
}

/// `ip link set IFACE down` and up again under a running emulator: it keeps running,
/// answers SDO when the link is back, and its statistics show the trouble (dropped TX
/// frames or receive errors; no exact numbers asserted).
#[test]
fn link_down_and_up_is_survived() {
    const NODE: u8 = 14;
    let ifname = iface(1);
    let sock = open_bus(&ifname);
    let mut emu = Emu::spawn(&["--iface", &ifname, "--node", "14", "--preset", "cnc1"]);
    assert!(
        wait_bootup(&sock, NODE, PEER_TIMEOUT),
        "no boot-up from node 14"
    );
    // heartbeats every 10 ms: the emulator has something to send while the link is down
    sdo_download(&sock, NODE, 0x1017, 0, &10u16.to_le_bytes()).expect("write 0x1017");
    assert!(
        recv_matching(&sock, PEER_TIMEOUT, |f| id_data(f) == (0x70E, vec![0x7F])).is_some(),
        "no heartbeat 70E#7F"
    );
    drop(sock);

    let ip = |state: &str| {
        let out = Command::new("ip")
            .args(["link", "set", &ifname, state])
            .output()
            .expect("run ip(8)");
        assert!(
            out.status.success(),
            "ip link set {ifname} {state}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    ip("down");
    std::thread::sleep(Duration::from_secs(1));
    let alive_while_down = emu.alive();
    ip("up");
    assert!(
        alive_while_down,
        "drive-emu died with the link down; stderr:\n{}",
        emu.stderr_now()
    );

    let sock = open_bus(&ifname);
    assert!(
        recv_matching(&sock, PEER_TIMEOUT, |f| id_data(f) == (0x70E, vec![0x7F])).is_some(),
        "no heartbeat 70E#7F after the link came back; stderr:\n{}",
        emu.stderr_now()
    );
    sdo_answers_after(&sock, NODE);
    // give the loop time to refresh 0x2100 (every 256 ticks), then read it (reported only)
    std::thread::sleep(Duration::from_millis(600));
    let dropped_obj = sdo_u32(&sock, NODE, 0x2100, 6);
    assert!(emu.alive());
    let exit = emu.stop_clean();
    let stat = |name: &str| -> u64 {
        let s = &exit.stderr;
        let at = s
            .find(name)
            .unwrap_or_else(|| panic!("no `{name}` in the statistics:\n{s}"));
        s[at + name.len()..]
            .split(|c: char| !c.is_ascii_digit())
            .find(|t| !t.is_empty())
            .and_then(|t| t.parse().ok())
            .unwrap_or_else(|| panic!("no number after `{name}`:\n{s}"))
    };
    let (tx_dropped, rx_errors) = (stat("tx dropped "), stat("rx errors "));
    eprintln!(
        "link down/up: tx dropped {tx_dropped}, rx errors {rx_errors}, 0x2100:6 = {dropped_obj}"
    );
    assert!(
        tx_dropped + rx_errors > 0,
        "the statistics show no trace of the link being down:\n{}",
        exit.stderr
    );
}

/// Two axes in one process from a machine file: both boot and answer SDO, each with its
/// own node id and preset.
#[test]
fn machine_file_with_two_axes() {
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let cfg = temp_file(
        "two-axes.toml",
        "tick_hz = 1000\n\n[[axis]]\nnode_id = 20\npreset = \"cnc1\"\n\n[[axis]]\nnode_id = 21\npreset = \"cnc3\"\n",
    );
    let emu = Emu::spawn(&["--iface", &ifname, "--config", cfg.to_str().unwrap()]);
    let mut booted = [false; 2];
    let deadline = Instant::now() + PEER_TIMEOUT;
    while booted != [true, true] && Instant::now() < deadline {
        if let Some(f) = recv_matching(&sock, Duration::from_millis(200), |f| {
            let (id, d) = id_data(f);
            (id == 0x714 || id == 0x715) && d == [0x00]
        }) {
            booted[(id_data(&f).0 - 0x714) as usize] = true;
        }
    }
    assert_eq!(
        booted,
        [true, true],
        "boot-up 714#00 / 715#00; stderr:\n{}",
        emu.stderr_now()
    );
    for node in [20u8, 21] {
        assert_eq!(
            sdo_u32(&sock, node, 0x1000, 0),
            DEVICE_TYPE,
            "node {node} 0x1000"
        );
        assert_eq!(
            sdo_u32(&sock, node, 0x1018, 4),
            u32::from(node),
            "node {node} serial"
        );
    }
    // cnc1 is a linear axis (10 mm lead screw: feed in um), cnc3 a rotary table (feed in
    // 0.001 deg per revolution of the driving shaft): different factor groups.
    let feed20 = sdo_u32(&sock, 20, 0x6092, 1);
    let feed21 = sdo_u32(&sock, 21, 0x6092, 1);
    eprintln!("feed constants: node 20 {feed20}, node 21 {feed21}");
    assert_ne!(
        feed20, feed21,
        "both axes report the same feed constant: one preset for both?"
    );
    emu.stop_clean();
}

/// On a terminal, `run` draws a status block with one line per axis: its node ID, NMT state,
/// CiA 402 state and mode by name. The drive runs under `script` (a pseudo-terminal, as a
/// user's shell gives it); node 22 is started and put in CSP over SDO, node 23 is left alone,
/// so each line must show its own axis.
#[test]
fn status_block_names_every_axis_on_a_terminal() {
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let cfg = temp_file(
        "status-two-axes.toml",
        "tick_hz = 1000\n\n[[axis]]\nnode_id = 22\npreset = \"cnc1\"\n\n[[axis]]\nnode_id = 23\npreset = \"cnc3\"\n",
    );
    let cmdline = format!(
        "exec {} run --rt-priority 0 --no-mlock --iface {ifname} --config {}",
        drive_emu_bin().display(),
        cfg.display()
    );
    let mut cmd = Command::new("script");
    // -q quiet, -f flush, -e the command's exit status, -c the command; no typescript file.
    cmd.args(["-qfec", &cmdline, "/dev/null"]);
    let mut term = Peer::spawn("script drive-emu run", cmd);
    assert!(
        wait_bootup(&sock, 23, PEER_TIMEOUT),
        "no boot-up from node 23; terminal:\n{}",
        term.output()
    );
    nmt(&sock, 0x01, 22);
    sdo_download(&sock, 22, 0x6060, 0, &[8]).expect("0x6060 = 8 (CSP) on node 22");
    // Node 22's line once it shows CSP, then node 23's line of the same block.
    let l22 = term
        .wait_line("CSP", PEER_TIMEOUT)
        .unwrap_or_else(|| panic!("no status line with CSP; terminal:\n{}", term.output()));
    let l23 = term
        .wait_line("node 23", PEER_TIMEOUT)
        .unwrap_or_else(|| panic!("no status line for node 23; terminal:\n{}", term.output()));
    for (line, want) in [
        (
            &l22,
            ["node 22 ", " OPERATIONAL ", "SWITCH ON DISABLED", "CSP"],
        ),
        (
            &l23,
            [
                "node 23 ",
                "PRE-OPERATIONAL",
                "SWITCH ON DISABLED",
                "no mode",
            ],
        ),
    ] {
        for w in want {
            assert!(
                line.contains(w),
                "{w:?} missing in the status line {line:?}"
            );
        }
        assert!(
            !line.contains("mode 8") && !line.contains('{'),
            "a number or Debug text in {line:?}"
        );
    }
    // One axis a line: the other node's ID is not on it.
    assert!(!l22.contains("node 23") && !l23.contains("node 22"));
    eprintln!("status block lines:\n{l22:?}\n{l23:?}");
    // SIGTERM to the drive (`script` would kill it 2 s after passing a SIGTERM on, and stop
    // relaying its output first): it stops cleanly and prints its statistics.
    let drive = child_of(term.pid()).expect("the drive as the child of script");
    // SAFETY: kill(2) on the drive we started (through script).
    unsafe { libc::kill(drive, libc::SIGTERM) };
    let stopped = term.wait_line("drive-emu: stopped.", PEER_TIMEOUT);
    let out = term.output();
    let status = term.finish(PEER_TIMEOUT);
    assert!(
        stopped.is_some() && status.success(),
        "drive-emu under script: exit {status} after SIGTERM; terminal:\n{out}"
    );
}

/// The process whose parent is `parent` (from /proc/PID/stat), waited for up to PEER_TIMEOUT.
fn child_of(parent: u32) -> Option<libc::pid_t> {
    let deadline = Instant::now() + PEER_TIMEOUT;
    while Instant::now() < deadline {
        for e in std::fs::read_dir("/proc").ok()?.flatten() {
            let Ok(stat) = std::fs::read_to_string(e.path().join("stat")) else {
                continue;
            };
            // pid (comm) state ppid ...: comm may hold spaces, so read after its ')'.
            let ppid = stat
                .rsplit_once(')')
                .and_then(|(_, rest)| rest.split_whitespace().nth(1))
                .and_then(|p| p.parse::<u32>().ok());
            if ppid == Some(parent) {
                return e.file_name().to_str()?.parse().ok();
            }
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    None
}

/// A drive that stalls (here: SIGSTOP, as a loaded or virtualised host does to it for a
/// moment) reads the frames that came meanwhile when it runs again, and loses none: its
/// socket asks for a receive buffer of thousands of frames. In lock-step every SYNC is one
/// tick, so the tick count proves it.
#[test]
fn a_stalled_drive_loses_no_frame() {
    const NODE: u8 = 15;
    const BURST: usize = 2000;
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let emu = Emu::spawn(&["--iface", &ifname, "--node", "15", "--lockstep"]);
    assert!(
        wait_bootup(&sock, NODE, PEER_TIMEOUT),
        "no boot-up from node 15"
    );
    assert_eq!(sdo_u32(&sock, NODE, 0x1000, 0), DEVICE_TYPE);
    // SAFETY: kill(2) on our own child.
    unsafe { libc::kill(emu.pid(), libc::SIGSTOP) };
    let mut sent = 0;
    while sent < BURST {
        if sock.write_frame(&frame(0x080, &[])).is_ok() {
            sent += 1;
        } else {
            std::thread::sleep(Duration::from_micros(100));
        }
    }
    // SAFETY: as above.
    unsafe { libc::kill(emu.pid(), libc::SIGCONT) };
    // An SDO round trip after the burst: every SYNC before it has been read.
    sdo_barrier(&sock, NODE);
    let exit = emu.stop_clean();
    let ticks = exit.ticks();
    assert_eq!(
        ticks, BURST as u64,
        "ticks after {BURST} SYNCs sent to a stopped drive"
    );
}
