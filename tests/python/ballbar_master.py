#!/usr/bin/env python3
"""A python-can master that interpolates the ballbar's circle (ISO 230-4, both ways) on two
CiA 402 drives in CSP, as a CNC does, and logs the bus in `candump -L` format, for
`drive-emu analyze --ballbar` (issue 31, item 3). Not our reference master: the plan is
written here from ISO 230-4 and docs/ballbar.md (arc-in and arc-out of 90 deg, the feed ramped
by a raised cosine over at most 0.5 s, 0.5 s dwells, CW first then CCW back).

    ballbar_master.py (--iface vcan0 | --socketcand HOST:PORT) --nodes 5,6 \
        --radius-mm 10 --feed-mm-min 1000 --sync-ms 1 --log capture.log

The drives are expected in lock-step (`run --lockstep`): the master sends both set-points
(RPDO2: controlword, target position 0x607A in um) and then SYNC, and waits for the drives'
synchronous answers before the next SYNC, so a slow python keeps the drives' time exact.
The log holds every frame the master sends and receives, with its time stamp.
"""
import argparse
import math
import struct
import sys
import time

import can

SYNC = 0x80


def plan(radius, feed, overrun=math.pi / 2, dwell=0.5):
    """(duration, f(t) -> (x, y)) of the circular test about (0, 0), in mm and s."""
    ramp = min(2.0 * radius * overrun / 3.0 / feed, 0.5)
    length = radius * (2 * math.pi + 2 * overrun)
    pass_s = length / feed + ramp

    def path(t):
        up = lambda t: 0.5 * feed * (t - ramp / math.pi * math.sin(math.pi * t / ramp))
        if t < ramp:
            return up(t)
        if t <= pass_s - ramp:
            return 0.5 * feed * ramp + feed * (t - ramp)
        return length - up(pass_s - t)

    def point(angle):
        return radius * math.cos(angle), radius * math.sin(angle)

    def at(t):
        for sign, t0, start in ((-1.0, dwell, overrun), (1.0, 2 * dwell + pass_s, -overrun)):
            if t0 <= t < t0 + pass_s:
                return point(start + sign * path(t - t0) / radius)
        # at rest: before the CW pass and after the CCW pass at its start (the CCW pass ends
        # where the CW pass began), between the passes at the CW pass's end
        if t < dwell or t >= 2 * dwell + 2 * pass_s:
            return point(overrun)
        return point(-overrun)

    return 3 * dwell + 2 * pass_s, at


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    bus_arg = ap.add_mutually_exclusive_group(required=True)
    bus_arg.add_argument("--iface")
    bus_arg.add_argument("--socketcand", metavar="HOST:PORT")
    ap.add_argument("--nodes", default="5,6")
    ap.add_argument("--radius-mm", type=float, default=10.0)
    ap.add_argument("--feed-mm-min", type=float, default=1000.0)
    ap.add_argument("--sync-ms", type=float, default=1.0)
    ap.add_argument("--log", required=True)
    a = ap.parse_args()
    nodes = [int(n) for n in a.nodes.split(",")]
    if a.iface:
        bus = can.Bus(interface="socketcan", channel=a.iface, receive_own_messages=False)
    else:
        host, port = a.socketcand.rsplit(":", 1)
        bus = can.Bus(interface="socketcand", host=host, port=int(port), channel="can0")
    log = can.CanutilsLogWriter(a.log, channel="can0")

    def send(cob, data):
        msg = can.Message(arbitration_id=cob, data=data, is_extended_id=False)
        bus.send(msg)
        msg.timestamp = time.time()
        log.on_message_received(msg)

    def recv(timeout):
        msg = bus.recv(timeout)
        if msg is not None:
            log.on_message_received(msg)
        return msg

    def sdo(node, index, sub, fmt, value):
        data = struct.pack(fmt, value)
        cs = 0x23 | ((4 - len(data)) << 2)
        send(0x600 + node, bytes([cs, index & 0xFF, index >> 8, sub]) + data + bytes(4 - len(data)))
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:
            m = recv(0.5)
            if m is not None and m.arbitration_id == 0x580 + node:
                if m.data[0] != 0x60:
                    sys.exit(f"node {node}: SDO write {index:04X}sub{sub} refused: {m.data.hex()}")
                return
        sys.exit(f"node {node}: no SDO answer to {index:04X}sub{sub}")

    def read_position(node):
        send(0x600 + node, bytes([0x40, 0x64, 0x60, 0, 0, 0, 0, 0]))
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:
            m = recv(0.5)
            if m is not None and m.arbitration_id == 0x580 + node and m.data[0] & 0xE0 == 0x40:
                return struct.unpack("<i", bytes(m.data[4:8]))[0]
        sys.exit(f"node {node}: no answer to the position read")

    period = a.sync_ms / 1000.0
    duration, at = plan(a.radius_mm, a.feed_mm_min / 60.0)
    time.sleep(0.3)
    send(0x000, bytes([0x82, 0]))  # reset communication, all nodes
    booted = set()
    deadline = time.monotonic() + 10
    while booted != set(nodes) and time.monotonic() < deadline:
        m = recv(0.5)
        if m is not None and m.arbitration_id - 0x700 in nodes and bytes(m.data) == b"\x00":
            booted.add(m.arbitration_id - 0x700)
    if booted != set(nodes):
        sys.exit(f"boot-up seen from {sorted(booted)}, not {nodes}")
    x0 = {}
    for n in nodes:
        sdo(n, 0x60C2, 1, "<B", int(round(a.sync_ms)))
        sdo(n, 0x60C2, 2, "<b", -3)
        sdo(n, 0x6060, 0, "<b", 8)  # CSP
        x0[n] = read_position(n)
    send(0x000, bytes([0x01, 0]))  # start
    cw = 0x06
    syncs = 0
    # where the axes stand is the circle's start point (at(0)): the centre follows from it
    start = at(0.0)
    centre = {n: x0[n] / 1000.0 - start[k] for k, n in enumerate(nodes)}

    def cycle(t, control):
        nonlocal syncs
        xy = at(t)
        for k, n in enumerate(nodes):
            um = int(round((centre[n] + xy[k]) * 1000.0))
            send(0x300 + n, struct.pack("<Hi", control, um))
        send(SYNC, b"")
        syncs += 1
        # the drives' synchronous answers (TPDO1 statusword, TPDO2 statusword + position)
        answered = set()
        deadline = time.monotonic() + 2
        while answered != set(nodes) and time.monotonic() < deadline:
            m = recv(0.5)
            if m is not None and m.arbitration_id - 0x280 in nodes:
                answered.add(m.arbitration_id - 0x280)
        if answered != set(nodes):
            sys.exit(f"SYNC {syncs}: answers from {sorted(answered)} only")
        return m

    # enable: shutdown, switch on, enable operation, 50 cycles each at the start point
    for cw in (0x06, 0x07, 0x0F):
        for _ in range(50):
            cycle(0.0, cw)
    t0_sync = syncs
    n_cycles = int(math.ceil(duration / period))
    for i in range(n_cycles + 1):
        cycle(i * period, 0x0F)
    for _ in range(20):
        cycle(duration, 0x0F)
    for n in nodes:
        send(0x300 + n, struct.pack("<Hi", 0x06, 0))
    log.stop()
    bus.shutdown()
    print(f"ballbar_master: {syncs} SYNCs, the circle from SYNC {t0_sync}, {duration:.3f} s")


if __name__ == "__main__":
    main()
