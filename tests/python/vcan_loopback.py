#!/usr/bin/env python3
"""Send one frame on a vcan interface with python-can and receive it on a second bus.

Usage: vcan_loopback.py [IFACE]   (default: $DRIVE_EMU_VCAN or vcan0)
Run it where vcan exists, e.g. ./vcan-setup.sh -- python3 tests/python/vcan_loopback.py
"""
import os
import sys

import can
import canopen  # noqa: F401  (checks the pinned CANopen stack is importable here too)

iface = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("DRIVE_EMU_VCAN", "vcan0")
with can.Bus(interface="socketcan", channel=iface) as tx, can.Bus(
    interface="socketcan", channel=iface
) as rx:
    msg = can.Message(arbitration_id=0x601, data=[0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0],
                      is_extended_id=False)
    tx.send(msg)
    got = rx.recv(timeout=2.0)
    if got is None:
        sys.exit(f"FAIL: nothing received on {iface} within 2 s")
    if got.arbitration_id != msg.arbitration_id or bytes(got.data) != bytes(msg.data):
        sys.exit(f"FAIL: received {got}, sent {msg}")
    print(f"OK python-can {can.__version__} canopen {canopen.__version__} on {iface}: {got}")
