//! The emulator (`drive-emu run`) as a process on a virtual CAN bus: what it puts on the
//! wire (candump), robustness against malformed traffic and against the interface going
//! down, and a two-axis machine file.
//!
//! Needs vcan: `./vcan-setup.sh --ifaces 2 -- cargo nextest run -p e2e --test emulator_bus`
//! (or ./test-all.sh). Node ids: 12 (candump), 13 (flood, vcan1), 14 (link down, vcan1),
//! 20/21 (machine file). No timing assertions: in lock-step mode the emulator's time only
//! advances with the SYNCs we send, so heartbeat counts are exact functions of them.

use std::process::Command;
use std::time::{Duration, Instant};

use e2e::socketcan::{
    CanFrame, CanRemoteFrame, EmbeddedFrame, ExtendedId, Socket, StandardId,
};
use e2e::{
    frame, id_data, iface, nmt, open_bus, recv_matching, sdo_download, sdo_u32, sdo_upload,
    send, temp_file, wait_bootup, Emu, Peer, SdoError, PEER_TIMEOUT,
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
        if dump.wait_line(&needle, Duration::from_millis(200)).is_some() {
            return dump;
        }
        assert!(Instant::now() < deadline, "candump never saw our marker frame on {ifname}");
    }
}

/// The capture: boot-up first, heartbeats (state 0x7F in pre-operational, 0x05 in
/// operational) with counts fixed by the SYNCs sent (lock-step), SDO answers on 0x580+n
/// only when asked, TPDOs on 0x180../0x280../0x380../0x480.. only in operational and, for
/// the synchronous ones, exactly one per SYNC, each after a SYNC.
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

    // Phase 2: operational; each SYNC answered by the synchronous TPDOs.
    nmt(&sock, 0x01, NODE);
    for i in 0..SYNCS {
        send(&sock, 0x080, &[]);
        // pace like a master: wait for the last synchronous TPDO of this SYNC
        recv_matching(&sock, PEER_TIMEOUT, |f| id_data(f).0 == 0x480 + u32::from(NODE))
            .unwrap_or_else(|| panic!("no TPDO4 0x48C after SYNC {i}"));
    }
    assert_eq!(sdo_u32(&sock, NODE, 0x1000, 0), DEVICE_TYPE);
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
        .map(|(id, d)| format!("{id:03X}#{}", d.iter().map(|b| format!("{b:02X}")).collect::<String>()))
        .collect();
    eprintln!("sequence: {}", seq.join(" "));
    // 100 ms of drive time at a 10 ms period: 10 heartbeats, +-1 for where the period
    // starts relative to the SDO write.
    assert!(
        !dump_out.contains("DROPCOUNT"),
        "candump dropped frames (its socket overflowed); the capture is incomplete:\n{dump_out}"
    );
    // 100 ms of drive time per phase at a 10 ms period: 10 heartbeats, +-1 for where the
    // period starts relative to the SDO write and to the NMT start.
    let hb_pre = count(&frames, hb, Some(&[0x7F]));
    let hb_op = count(&frames, hb, Some(&[0x05]));
    assert!(
        (9..=11).contains(&hb_pre),
        "{hb_pre} heartbeats 70C#7F for {SYNCS} SYNCs of 1 ms at {HB_MS} ms"
    );
    assert!(
        (9..=11).contains(&hb_op),
        "{hb_op} heartbeats 70C#05 for {SYNCS} SYNCs of 1 ms at {HB_MS} ms"
    );
    assert_eq!(count(pre, hb, Some(&[0x05])), 0, "heartbeat 70C#05 before NMT start");
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
        assert_eq!(count(pre, base + node, None), 0, "TPDO {:03X} in pre-operational", base + node);
    }
    // synchronous TPDOs (types 1): one per SYNC, 6 bytes (statusword + I32)
    for base in [0x280, 0x380, 0x480] {
        let id = base + node;
        assert_eq!(count(op, id, None), SYNCS, "TPDO {id:03X}: one per SYNC");
        assert!(
            op.iter().filter(|(i, _)| *i == id).all(|(_, d)| d.len() == 6),
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
                assert!(tpdos <= syncs, "TPDO {id:03X} #{tpdos} before SYNC #{tpdos}");
            }
        }
    }
    // TPDO1 (event-driven, statusword + mode display): sent on entering operational
    let tpdo1 = count(op, 0x180 + node, None);
    assert!(tpdo1 >= 1, "no TPDO1 18C after NMT start");
    // SDO answers: on 0x58C only, one per request (3 uploads/downloads in pre-op + 1 in op)
    assert_eq!(count(&frames, 0x580 + node, None), 4, "SDO answers on 0x58C");
    assert_eq!(
        count(&frames, 0x580 + node, Some(&[0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00])),
        2,
        "upload of 0x1000 answered 43 00 10 00 92 01 02 00"
    );
    assert_eq!(count(&frames, 0x80 + node, None), 0, "no EMCY expected");
}

