#!/usr/bin/env python3
"""A python canopen master for the panel's browser test on vcan (tests/tests/panel_vcan.rs).

Resets node 5, starts SYNC (10 ms), enables it in profile position with BaseNode402, then, in steps the test
paces with files in --dir (`go-N`): moves to each --targets position and prints
`{"at": TARGET, "position": 0x6064 over SDO}` once the axis stands there; after the last
target it reads the backlash 0x2000 (REAL32, mm) over SDO every 0.2 s and prints
`{"backlash_mm": V}` whenever it changes, until `done` appears. One JSON line per event.
"""
import argparse
import json
import os
import socket
import struct
import sys
import time

import canopen

# Generous: inside user-mode Linux this python shares one CPU with the drive, a browser and
# `drive-emu analyze`; a state change once waited more than 10 s there (the test asserts what
# the page and the SDO reads show, not how fast).
canopen.BaseNode402.TIMEOUT_CHECK_TPDO = 5.0
canopen.BaseNode402.TIMEOUT_SWITCH_OP_MODE = 15.0
canopen.BaseNode402.TIMEOUT_SWITCH_STATE_SINGLE = 10.0
canopen.BaseNode402.TIMEOUT_SWITCH_STATE_FINAL = 30.0


SO_MEMINFO = 55        # linux/socket.h: getsockopt -> u32[SK_MEMINFO_VARS]
SK_MEMINFO_DROPS = 8   # frames the socket dropped (receive buffer full)


def socket_drops(network):
    """Frames this master's CAN socket dropped since it opened (its receive buffer was full)."""
    raw = network.bus.socket.getsockopt(socket.SOL_SOCKET, SO_MEMINFO, 4 * 9)
    return struct.unpack("<9I", raw)[SK_MEMINFO_DROPS]


SO_RCVBUFFORCE = 33    # asm-generic/socket.h


def widen_receive_buffer(network, nbytes=16 << 20):
    """Give this master's CAN socket room for tens of seconds of frames. Inside user-mode
    Linux this python shares one CPU with the drive and a browser; starved for seconds, it
    lost the drive's SDO answer from its full receive queue (the default 208 KiB holds about
    a second of this bus) and timed out, with the answer on the bus. The drive's own socket
    asks for the same (emulator/src/bus/socketcan.rs)."""
    sock = network.bus.socket
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, nbytes)  # root (CI, UML)
    except OSError:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, nbytes)  # capped by rmem_max


def say(**kv):
    print(json.dumps(kv), flush=True)


def wait_for(pred, timeout, what):
    deadline = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > deadline:
            raise TimeoutError(f"timeout ({timeout} s) waiting for {what}")
        time.sleep(0.01)


def move_to(node, target, timeout=60):
    node.sdo["Target position"].raw = target
    node.controlword = 0x0F
    node.controlword = 0x1F
    wait_for(lambda: node.statusword & 0x1000, timeout, "set-point acknowledge")
    node.controlword = 0x0F
    wait_for(lambda: node.statusword & 0x0400 and not node.statusword & 0x1000, timeout,
             f"target reached at {target}")
    # Standing still: two reads 0.2 s apart agree.
    last = None
    while True:
        p = node.sdo["Position actual value"].raw
        if p == last:
            return p
        last = p
        time.sleep(0.2)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--iface", default="vcan0")
    ap.add_argument("--node", type=int, default=5)
    ap.add_argument("--eds", required=True)
    ap.add_argument("--dir", required=True)
    ap.add_argument("--targets", default="20000,-5000")
    a = ap.parse_args()
    network = canopen.Network()
    network.connect(interface="socketcan", channel=a.iface)
    widen_receive_buffer(network)
    try:
        node = canopen.BaseNode402(a.node, a.eds)
        network.add_node(node)
        # python canopen's 0.3 s is too short for a drive and a browser on one busy CPU
        # (user-mode Linux beside a loaded host); the test asserts what is shown, not timing.
        node.sdo.RESPONSE_TIMEOUT = 10.0
        # An unanswered request is sent again (python canopen's own retry; PLC function
        # blocks do the same), twice at most: in CI this python, the drive, a browser and
        # `drive-emu analyze` share user-mode Linux's one CPU beside a busy host, and a read
        # once waited more than RESPONSE_TIMEOUT. A drive that never answers still fails.
        node.sdo.MAX_RETRIES = 3
        node.nmt.state = "RESET COMMUNICATION"
        node.nmt.wait_for_bootup(10)
        node.setup_402_state_machine()
        node.nmt.state = "OPERATIONAL"
        # SYNC every 10 ms: the drive's synchronous TPDOs (position, velocity, direct
        # encoder) then go out, so a capture of the bus holds samples `analyze` can read.
        network.sync.start(0.01)
        wait_for(lambda: node.statusword & 0x4F == 0x40, 10, "SWITCH ON DISABLED")
        node.op_mode = "PROFILED POSITION"
        node.state = "OPERATION ENABLED"
        node.sdo["Profile velocity"].raw = 20000
        node.sdo["Profile acceleration"].raw = 200000
        node.sdo["Profile deceleration"].raw = 200000
        say(enabled=node.state)
        for i, target in enumerate(int(t) for t in a.targets.split(",")):
            wait_for(lambda: os.path.exists(os.path.join(a.dir, f"go-{i}")), 300, f"go-{i}")
            say(at=target, position=move_to(node, target))
        last = None
        while not os.path.exists(os.path.join(a.dir, "done")):
            raw = node.sdo.upload(0x2000, 0)
            v = round(struct.unpack("<f", raw)[0], 6)
            if v != last:
                say(backlash_mm=v)
                last = v
            time.sleep(0.2)
        node.state = "SWITCH ON DISABLED"
        network.sync.stop()
    except canopen.SdoCommunicationError:
        say(error="sdo", socket_drops=socket_drops(network))
        raise
    finally:
        network.disconnect()
    return 0


if __name__ == "__main__":
    sys.exit(main())
