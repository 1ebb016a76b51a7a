"""SYNC -> TPDO and SDO upload latency of a running drive-emu over a CAN interface.

Sends N SYNC frames (one every PERIOD s); for each, the time from the kernel's transmit echo of
the SYNC to the arrival of the drive's first synchronous TPDO (0x280 + node); and every tenth
period an SDO upload of 0x1000, from the echo of the request to the answer (0x580 + node). All
times are kernel receive timestamps. Prints p50/p99/max in microseconds.

    python3 bench/sync_latency.py IFACE NODE [N] [PERIOD] [LABEL] [--map-tpdo2]

--map-tpdo2: first make TPDO2 synchronous over SDO (CiA 301: 0x1801 COB-ID 0x280 + node,
transmission type 1, 0x1A01 mapping the error register 0x1001), for a generic CANopen device
whose TPDO2 is off or event-driven (CANopenNode's canopend with its example object dictionary).
"""
import sys
import time

import can

map_tpdo2 = "--map-tpdo2" in sys.argv
args = [a for a in sys.argv if a != "--map-tpdo2"]
iface, node = args[1], int(args[2])
n = int(args[3]) if len(args) > 3 else 2000
period = float(args[4]) if len(args) > 4 else 0.001
label = args[5] if len(args) > 5 else "drive-emu"
bus = can.Bus(interface="socketcan", channel=iface, receive_own_messages=True)


def sdo_download(index, sub, value, size):
    cmd = {1: 0x2F, 2: 0x2B, 4: 0x23}[size]
    data = [cmd, index & 0xFF, index >> 8, sub] + list(value.to_bytes(4, "little"))
    bus.send(can.Message(arbitration_id=0x600 + node, data=data, is_extended_id=False))
    deadline = time.monotonic() + 2.0
    while time.monotonic() < deadline:
        m = bus.recv(timeout=0.1)
        if m is not None and m.arbitration_id == 0x580 + node:
            if m.data[0] != 0x60:
                sys.exit(f"SDO write {index:04X}:{sub} refused: {bytes(m.data).hex()}")
            return
    sys.exit(f"SDO write {index:04X}:{sub}: no answer")


if map_tpdo2:
    sdo_download(0x1801, 1, 0x8000_0280 + node, 4)  # off while it is changed
    sdo_download(0x1A01, 0, 0, 1)
    sdo_download(0x1A01, 1, 0x1001_0008, 4)
    sdo_download(0x1A01, 0, 1, 1)
    sdo_download(0x1801, 2, 1, 1)  # synchronous, every SYNC
    sdo_download(0x1801, 1, 0x0000_0280 + node, 4)
# NMT start so that TPDOs flow.
bus.send(can.Message(arbitration_id=0x000, data=[0x01, node], is_extended_id=False))
time.sleep(0.3)
while bus.recv(timeout=0.01) is not None:
    pass


def round_trip(req_id, req_data, ans_id):
    bus.send(can.Message(arbitration_id=req_id, data=req_data, is_extended_id=False))
    t_req = None
    deadline = time.monotonic() + 0.2
    while time.monotonic() < deadline:
        m = bus.recv(timeout=0.05)
        if m is None:
            continue
        if m.arbitration_id == req_id and t_req is None:
            t_req = m.timestamp
        elif m.arbitration_id == ans_id and t_req is not None:
            return (m.timestamp - t_req) * 1e6
    return None


sync_lat, sdo_lat = [], []
for k in range(n):
    lat = round_trip(0x080, [], 0x280 + node)
    if lat is not None:
        sync_lat.append(lat)
    time.sleep(period)
    if k % 10 == 5:
        lat = round_trip(0x600 + node, [0x40, 0x00, 0x10, 0, 0, 0, 0, 0], 0x580 + node)
        if lat is not None:
            sdo_lat.append(lat)
        time.sleep(period)
bus.shutdown()
if not sync_lat or not sdo_lat:
    sys.exit("no answers")


def q(v, p):
    v = sorted(v)
    return v[min(len(v) - 1, int(p * len(v)))]


print(
    f"{label}: SYNC->TPDO n={len(sync_lat)} p50 {q(sync_lat, .5):.0f} us p99 {q(sync_lat, .99):.0f} us"
    f" | SDO upload n={len(sdo_lat)} p50 {q(sdo_lat, .5):.0f} us p99 {q(sdo_lat, .99):.0f} us"
)
