//! Smoke tests of the vcan harness: a real CAN bus is there and Rust (socketcan),
//! can-utils (candump) and python-can all see the same frames.
//!
//! Needs vcan: `./vcan-setup.sh -- cargo nextest run -p e2e --test vcan_smoke`.
//! Fails (never skips) without it. Each test uses its own CAN ids so they can run in
//! parallel on one bus.

use std::process::Command;
use std::time::{Duration, Instant};

use e2e::socketcan::Socket;
use e2e::{frame, id_data, iface, open_bus, python, recv_matching, Peer, PEER_TIMEOUT};

#[test]
fn socket_to_socket() {
    let ifname = iface(0);
    let tx = open_bus(&ifname);
    let rx = open_bus(&ifname);
    let sent = frame(0x123, &[0xDE, 0xAD, 0xBE, 0xEF]);
    tx.write_frame(&sent).expect("write_frame");
    let got = recv_matching(&rx, Duration::from_secs(5), |f| id_data(f).0 == 0x123)
        .unwrap_or_else(|| panic!("frame 0x123 not received on a second socket on {ifname}"));
    assert_eq!(id_data(&got), (0x123, vec![0xDE, 0xAD, 0xBE, 0xEF]));
}

#[test]
fn candump_sees_frame() {
    let ifname = iface(0);
    let tx = open_bus(&ifname);
    let mut cmd = Command::new("candump");
    cmd.args(["-L", "-n", "1", &format!("{ifname},321:7FF")]);
    let mut dump = Peer::spawn("candump", cmd);
    // candump gives no ready signal: resend until it has seen one (or time out).
    let deadline = Instant::now() + PEER_TIMEOUT;
    let line = loop {
        tx.write_frame(&frame(0x321, &[0x01, 0x02, 0x03]))
            .expect("write_frame");
        if let Some(l) = dump.wait_line("321#", Duration::from_millis(200)) {
            break l;
        }
        assert!(
            Instant::now() < deadline,
            "candump saw nothing on {ifname}; output:\n{}",
            dump.output()
        );
    };
    assert!(
        line.contains(&format!("{ifname} 321#010203")),
        "unexpected candump line: {line}"
    );
    assert!(
        dump.finish(Duration::from_secs(5)).success(),
        "candump -n 1 did not exit cleanly"
    );
}

const PY_PEER: &str = r#"
import sys, can
iface = sys.argv[1]
with can.Bus(interface="socketcan", channel=iface,
             can_filters=[{"can_id": 0x322, "can_mask": 0x7FF}]) as bus:
    print("READY", flush=True)
    msg = bus.recv(timeout=60)
    if msg is None:
        sys.exit("python-can: no frame 0x322 within 60 s")
    print("GOT %03X#%s" % (msg.arbitration_id, bytes(msg.data).hex().upper()), flush=True)
    bus.send(can.Message(arbitration_id=0x323, data=bytes(reversed(msg.data)), is_extended_id=False))
"#;

#[test]
fn python_can_sees_frame_and_answers() {
    let ifname = iface(0);
    let sock = open_bus(&ifname);
    let mut cmd = Command::new(python());
    cmd.args(["-c", PY_PEER, &ifname]);
    let mut peer = Peer::spawn("python-can receiver", cmd);
    peer.wait_line("READY", PEER_TIMEOUT).unwrap_or_else(|| {
        panic!(
            "python-can peer did not start (pip install -r tests/requirements.txt?); output:\n{}",
            peer.output()
        )
    });
    sock.write_frame(&frame(0x322, &[0x11, 0x22, 0x33]))
        .expect("write_frame");
    let got = peer.wait_line("GOT", PEER_TIMEOUT);
    assert_eq!(
        got.as_deref(),
        Some("GOT 322#112233"),
        "python-can output:\n{}",
        peer.output()
    );
    let answer = recv_matching(&sock, PEER_TIMEOUT, |f| id_data(f).0 == 0x323)
        .expect("no answer 0x323 from the python-can peer");
    assert_eq!(id_data(&answer), (0x323, vec![0x33, 0x22, 0x11]));
    assert!(
        peer.finish(PEER_TIMEOUT).success(),
        "python-can peer failed"
    );
}
