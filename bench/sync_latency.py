"""SYNC -> TPDO response latency of a running drive-emu over a CAN interface.

Sends N SYNC frames (one every PERIOD s) and, for each, measures the time from the kernel's
transmit echo of the SYNC to the arrival of the drive's first synchronous TPDO (0x280 + node),
both kernel receive timestamps. Prints p50/p99/max in microseconds.

    python3 bench/sync_latency.py IFACE NODE [N] [PERIOD]
"""
import sys
import time

import can

iface, node = sys.argv[1], int(sys.argv[2])
n = int(sys.argv[3]) if len(sys.argv) > 3 else 2000
period = float(sys.argv[4]) if len(sys.argv) > 4 else 0.002
bus = can.Bus(interface="socketcan", channel=iface, receive_own_messages=True)
# NMT start so that TPDOs flow.
bus.send(can.Message(arbitration_id=0x000, data=[0x01, node], is_extended_id=False))
time.sleep(0.2)
lat = []
for _ in range(n):
    bus.send(can.Message(arbitration_id=0x080, data=[], is_extended_id=False))
    t_sync = None
    deadline = time.monotonic() + 0.1
    while time.monotonic() < deadline:
        m = bus.recv(timeout=0.05)
        if m is None:
            continue
        if m.arbitration_id == 0x080 and t_sync is None:
            t_sync = m.timestamp
        elif m.arbitration_id == 0x280 + node and t_sync is not None:
            lat.append((m.timestamp - t_sync) * 1e6)
            break
    time.sleep(period)
bus.shutdown()
if not lat:
    sys.exit("no TPDO answered a SYNC")
lat.sort()
q = lambda p: lat[min(len(lat) - 1, int(p * len(lat)))]
print(f"SYNC->TPDO over {iface}: n={len(lat)} p50 {q(0.5):.0f} us, p99 {q(0.99):.0f} us, max {lat[-1]:.0f} us")
