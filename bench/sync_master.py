"""A SYNC master: N SYNC frames (COB-ID 0x080, no data) on IFACE, one every PERIOD s on an
absolute schedule (a SYNC that is late goes out at once, so N SYNCs take N * PERIOD however the
host schedules us; `cangen -g 1` sleeps 1 ms after each frame and falls far below 1 kHz in a
loaded user-mode Linux). Run it with `chrt -f 90` for a steady rate. Raw socket from the
standard library: no python-can import (slow in UML).

    python3 bench/sync_master.py IFACE N [PERIOD]
"""
import socket
import struct
import sys
import time

iface, n = sys.argv[1], int(sys.argv[2])
period = float(sys.argv[3]) if len(sys.argv) > 3 else 0.001
s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
s.bind((iface,))
s.setsockopt(socket.SOL_CAN_RAW, socket.CAN_RAW_FILTER, b"")  # send only
sync = struct.pack("=IB3x8s", 0x080, 0, b"")
t = time.monotonic()
late = 0
for k in range(n):
    t += period
    wait = t - time.monotonic()
    if wait > 0:
        time.sleep(wait)
    else:
        late += 1
    while True:
        try:
            s.send(sync)
            break
        except OSError:  # ENOBUFS: the interface queue is full; try again shortly
            time.sleep(period / 10)
print(f"sync_master: {n} SYNCs, {late} sent late", file=sys.stderr)
