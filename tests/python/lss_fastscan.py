#!/usr/bin/env python3
"""python-canopen's LssMaster (pinned, tests/requirements.txt) gives non-configured drives
their node-IDs.

Usage: lss_fastscan.py (--iface IFACE | --pipe) FIRST_NODE IDENTITY...
IDENTITY is `VENDOR,PRODUCT,REVISION,SERIAL` (0x1018:1..4) of each non-configured drive on
the bus. --iface: a SocketCAN interface (drive-emu on vcan0). --pipe: frames on stdin and
stdout, one per line, `F <id hex> <data hex>` (a test harness runs the nodes; other stdout
lines are this script's report). For each drive, in LSS address order (the order fastscan
finds them), with node-ID FIRST_NODE, FIRST_NODE + 1, ...:
  1. nothing answers SDO at that node-ID, no boot-up;
  2. fast_scan() finds exactly this drive: its four identity parts;
  3. inquire_node_id() is 0xFF (non-configured); inquire_lss_address() gives the identity;
  4. configure_node_id(n), store_configuration() (error code 0 each, else LssError);
  5. switch state global to waiting: the drive boots as n (boot-up on 0x700+n) and answers
     SDO there (0x1000 device type, 0x1018:4 serial number);
then:
  6. switch state selective by the first drive's identity answers, inquire_node_id() is its
     node-ID;
  7. configured drives take no part in fastscan: fast_scan() finds nobody.
Prints READY once connected, STEP lines, PASS at the end; exits non-zero with a line starting
with FAIL on the first failure. python canopen waits 0.5 s for each LSS answer (and fastscan
takes a missing answer for a 1 bit); that is raised to 1.5 s here because user-mode Linux or a
loaded host can be slow. No timing is asserted.
"""
import queue
import struct
import sys
import threading
import time
import traceback

import can
import canopen
from canopen import lss

lss.LssMaster.RESPONSE_TIMEOUT = 1.5
OUT_LOCK = threading.Lock()


def say(line):
    with OUT_LOCK:
        print(line, flush=True)


def fail(msg):
    say(f"FAIL: {msg}")
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)


def step(msg):
    say(f"STEP {msg}")


class PipeBus(can.BusABC):
    """Frames as lines: `F <id hex> <data hex>` out on stdout, in on stdin."""

    def __init__(self):
        self._rx = queue.Queue()
        self.channel_info = "pipe"
        threading.Thread(target=self._reader, daemon=True).start()
        super().__init__(channel="pipe")

    def _reader(self):
        for line in sys.stdin:
            parts = line.split()
            if len(parts) >= 2 and parts[0] == "F":
                data = bytes.fromhex(parts[2]) if len(parts) > 2 else b""
                self._rx.put(can.Message(arbitration_id=int(parts[1], 16), data=data,
                                         is_extended_id=False))

    def send(self, msg, timeout=None):
        say(f"F {msg.arbitration_id:X} {bytes(msg.data).hex()}")

    def _recv_internal(self, timeout):
        try:
            return self._rx.get(timeout=timeout), False
        except queue.Empty:
            return None, False


def main():
    args = sys.argv[1:]
    if args[0] == "--pipe":
        network = canopen.Network(PipeBus())
        network.connect()
        args = args[1:]
    elif args[0] == "--iface":
        network = canopen.Network()
        network.connect(interface="socketcan", channel=args[1])
        args = args[2:]
    else:
        sys.exit(__doc__)
    first = int(args[0])
    drives = sorted([int(x, 0) for x in a.split(",")] for a in args[1:])
    say("READY")
    try:
        for k, identity in enumerate(drives):
            configure(network, first + k, identity)
        n0, id0 = first, drives[0]
        check(network.lss.send_switch_state_selective(*id0), "no answer to switch selective")
        check(network.lss.inquire_node_id() == n0, "inquire_node_id() after the boot")
        network.lss.send_switch_state_global(network.lss.WAITING_STATE)
        step("switch state selective by identity; inquire_node_id() = its node-ID")
        found, lss_id = network.lss.fast_scan()
        check(not found, f"a configured drive answered fastscan: {lss_id}")
        step("configured drives ignore fastscan")
        say("PASS")
    except SystemExit:
        raise
    except Exception:
        traceback.print_exc(file=sys.stderr)
        fail("exception")
    finally:
        network.disconnect()


def configure(network, n, identity):
    node = canopen.RemoteNode(n, canopen.ObjectDictionary())
    node.sdo.RESPONSE_TIMEOUT = 1.0
    network.add_node(node)
    bootups = []
    network.subscribe(0x700 + n, lambda can_id, data, ts: bootups.append(bytes(data)))

    # ---- 1. non-configured: silent
    try:
        node.sdo.upload(0x1000, 0)
        fail(f"an SDO answer at node {n} before any node-ID was given")
    except canopen.SdoCommunicationError:
        pass
    check(not bootups, f"a heartbeat at 0x{0x700 + n:X} before the node-ID: {bootups}")
    step(f"node {n}: nobody there yet")

    # ---- 2. fastscan
    t0 = time.monotonic()
    found, lss_id = network.lss.fast_scan()
    check(found, "fast_scan() found no drive")
    check(lss_id == identity, f"fast_scan() found {lss_id}, expected {identity}")
    step(f"fast_scan found {[hex(x) for x in lss_id]} in {time.monotonic() - t0:.1f} s")

    # ---- 3. inquiries (the drive is in configuration state now)
    check(network.lss.inquire_node_id() == 0xFF, "inquire_node_id() of a non-configured drive")
    parts = [
        network.lss.inquire_lss_address(cs)
        for cs in (lss.CS_INQUIRE_VENDOR_ID, lss.CS_INQUIRE_PRODUCT_CODE,
                   lss.CS_INQUIRE_REVISION_NUMBER, lss.CS_INQUIRE_SERIAL_NUMBER)
    ]
    check(parts == identity, f"inquire_lss_address: {parts}, expected {identity}")
    step("inquiries: node-ID 0xFF, identity as found")

    # ---- 4. configure and store
    network.lss.configure_node_id(n)
    network.lss.store_configuration()
    step(f"configure_node_id({n}) and store_configuration() accepted")

    # ---- 5. back to waiting: the drive boots as n
    network.lss.send_switch_state_global(network.lss.WAITING_STATE)
    node.nmt.wait_for_bootup(10)
    check(bootups and bootups[0] == b"\x00", f"boot-up on 0x{0x700 + n:X}: {bootups}")
    device_type = struct.unpack("<I", node.sdo.upload(0x1000, 0))[0]
    check(device_type & 0xFFFF == 402, f"0x1000 = 0x{device_type:08X}: not a CiA 402 device")
    serial = struct.unpack("<I", node.sdo.upload(0x1018, 4))[0]
    check(serial == identity[3], f"0x1018:4 = {serial}, the LSS serial number is {identity[3]}")
    step(f"booted as node {n}, SDO answered (0x1000 = 0x{device_type:08X})")


if __name__ == "__main__":
    main()
