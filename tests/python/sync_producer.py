#!/usr/bin/env python3
"""drive-emu as the SYNC producer (CiA 301 0x1005 bit 30), seen with python-can.

Usage: sync_producer.py IFACE NODE EDS
Prints READY once connected; then waits for the drive's boot-up (start the emulator after
READY), and over SDO (python canopen):
  1. 0x1019 = 4 (while 0x1006 = 0), 0x1006 = 20 ms, 0x1005 = 0x40000080: the drive's SYNC
     frames arrive on CAN-ID 0x80 with one counter byte running 1, 2, 3, 4, 1, ...;
  2. 0x1019 written while 0x1006 != 0 aborts 0x08000022, a new CAN-ID while producing
     0x06090030;
  3. operational: the synchronous TPDO2 (every SYNC) follows the drive's own SYNC;
  4. 0x1005 = 0x00000090 stops it; bit 30 again on 0x90: SYNC on 0x90, counter from 1.
The emulator runs with --lockstep and nobody else sends SYNC: the drive's SYNC runs on its
communication clock (the wall clock there), simulated time does not move (docs/master.md).
No rate is asserted. Exits non-zero with a line starting FAIL on the first failure.
"""
import sys
import time
import traceback

import can
import canopen
from canopen.sdo.exceptions import SdoAbortedError

IFACE, NODE, EDS = sys.argv[1], int(sys.argv[2]), sys.argv[3]


def fail(msg):
    print(f"FAIL: {msg}", flush=True)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)


def step(msg):
    print(f"STEP {msg}", flush=True)


def frames(bus, ids, n, timeout=30.0):
    """The next n frames with a CAN-ID in ids: (id, data)."""
    got = []
    deadline = time.monotonic() + timeout
    while len(got) < n and time.monotonic() < deadline:
        m = bus.recv(0.5)
        if m is not None and m.arbitration_id in ids:
            got.append((m.arbitration_id, bytes(m.data)))
    check(len(got) == n, f"{len(got)} of {n} frames on {[hex(i) for i in ids]}: {got}")
    return got


def drain(bus):
    while bus.recv(0) is not None:
        pass


def refused(index, value, size, code):
    try:
        node.sdo.download(index, 0, value.to_bytes(size, "little"))
    except SdoAbortedError as e:
        check(e.code == code, f"0x{index:04X} = 0x{value:X}: abort 0x{e.code:08X}, "
              f"expected 0x{code:08X}")
        return
    fail(f"0x{index:04X} = 0x{value:X} accepted, expected abort 0x{code:08X}")


def counters(got):
    check(all(len(d) == 1 for _, d in got), f"SYNC without its counter byte: {got}")
    return [d[0] for _, d in got]


def cyclic_from_1(cs, overflow):
    return cs == [(k % overflow) + 1 for k in range(len(cs))]


network = canopen.Network()
network.connect(interface="socketcan", channel=IFACE)
node = canopen.RemoteNode(NODE, EDS)
node.sdo.RESPONSE_TIMEOUT = 5.0
network.add_node(node)
listen = can.Bus(interface="socketcan", channel=IFACE)
print("READY", flush=True)

try:
    node.nmt.wait_for_bootup(60)
    node.sdo[0x1006].raw = 0
    node.sdo[0x1019].raw = 4
    node.sdo[0x1006].raw = 20000
    drain(listen)
    node.sdo[0x1005].raw = 0x40000080
    cs = counters(frames(listen, {0x80}, 10))
    # the first may have been sent before the listener drained: the sequence runs from 1
    i = cs.index(1)
    check(i < 4 and cyclic_from_1(cs[i:], 4), f"counters {cs}")
    step(f"SYNC on 0x80, counters {cs}")

    refused(0x1019, 3, 1, 0x08000022)
    refused(0x1005, 0x40000081, 4, 0x06090030)
    check(node.sdo[0x1005].raw == 0x40000080, "0x1005 unchanged")
    step("0x1019 while 0x1006 != 0: 0x08000022; a running producer's CAN-ID: 0x06090030")

    node.nmt.state = "OPERATIONAL"
    tpdo2 = 0x280 + NODE
    drain(listen)
    got = frames(listen, {0x80, tpdo2}, 12)
    first = [i for i, _ in got].index(0x80)
    pairs = [i for i, _ in got[first:first + 10]]
    check(pairs == [0x80, tpdo2] * 5, f"TPDO2 after each SYNC: {[hex(i) for i in pairs]}")
    step("operational: TPDO2 follows each of the drive's SYNCs")

    node.sdo[0x1005].raw = 0x90
    node.sdo[0x1005].raw = 0x40000090
    drain(listen)
    got = frames(listen, {0x80, 0x90}, 6)
    check(all(i == 0x90 for i, _ in got), f"SYNC moved to 0x90: {got}")
    cs = counters(got)
    i = cs.index(1)
    check(i < 4 and cyclic_from_1(cs[i:], 4), f"counters on 0x90: {cs}")
    step(f"stopped, restarted on 0x90: counters {cs}")
    print("PASS", flush=True)
except SystemExit:
    raise
except Exception:  # noqa: BLE001
    traceback.print_exc()
    fail("exception (see traceback above)")
finally:
    listen.shutdown()
    network.disconnect()
