#!/usr/bin/env python3
"""Profile velocity (PV) with python canopen's BaseNode402 against drive-emu, default PDOs.

    drive-emu run --iface vcan0 --node 5 &
    drive-emu eds --preset cnc1 --node 5 --real32 decimal > drive.eds   # REAL32 as python canopen reads them
    python pv.py --iface vcan0 --node 5 --eds drive.eds

Without kernel CAN (no vcan: macOS, Windows, containers) the drive serves its bus over
socketcand instead: `drive-emu run --socketcand 127.0.0.1:29536 --node 5 &`, then
`python pv.py --socketcand 127.0.0.1:29536 --node 5 --eds drive.eds`.

Resets the node, enables it in PV, runs at 10 mm/s (10000 um/s) until "target reached"
(statusword bit 10: the speed is within the velocity window), then at 0 again, then disables
it. Exit status 0 on success.
"""
import argparse
import time

import canopen

# BaseNode402's own timeouts (0.2 s for the next TPDO, 0.4 s per state step) assume a quiet
# real-time host; a loaded machine or user-mode Linux stalls longer than that at times.
canopen.BaseNode402.TIMEOUT_CHECK_TPDO = 2.0
canopen.BaseNode402.TIMEOUT_SWITCH_OP_MODE = 5.0
canopen.BaseNode402.TIMEOUT_SWITCH_STATE_SINGLE = 3.0
canopen.BaseNode402.TIMEOUT_SWITCH_STATE_FINAL = 10.0


def wait_for(pred, timeout, what):
    deadline = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > deadline:
            raise TimeoutError(f"timeout ({timeout} s) waiting for {what}")
        time.sleep(0.01)


def main(bus, node_id, eds, velocity_um_s=10000):
    network = canopen.Network()
    network.connect(**bus)
    try:
        node = canopen.BaseNode402(node_id, eds)
        network.add_node(node)
        node.nmt.state = "RESET COMMUNICATION"
        node.nmt.wait_for_bootup(10)
        print(f"node {node_id} booted")
        node.setup_402_state_machine()
        node.nmt.state = "OPERATIONAL"
        wait_for(lambda: node.statusword & 0x4F == 0x40, 10, "SWITCH ON DISABLED")
        node.op_mode = "PROFILED VELOCITY"
        node.state = "OPERATION ENABLED"
        print(f"state {node.state}, mode {node.op_mode}")
        node.sdo["Profile acceleration"].raw = 100000  # um/s^2
        node.sdo["Profile deceleration"].raw = 100000
        for v in (velocity_um_s, 0):
            node.sdo["Target velocity"].raw = v
            time.sleep(0.05)  # let the ramp start before looking at bit 10
            wait_for(lambda: node.statusword & 0x0400, 30, f"velocity {v} um/s reached (bit 10)")
            actual = node.sdo["Velocity actual value"].raw
            print(f"PV at {v} um/s: velocity actual {actual} um/s")
        node.state = "SWITCH ON DISABLED"
        node.nmt.state = "PRE-OPERATIONAL"
    finally:
        network.disconnect()


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    where = ap.add_mutually_exclusive_group()
    where.add_argument("--iface", default="vcan0", help="SocketCAN interface (default vcan0)")
    where.add_argument("--socketcand", metavar="HOST:PORT",
                       help="the drive's socketcand server (drive-emu run --socketcand)")
    ap.add_argument("--node", type=int, default=5)
    ap.add_argument("--eds", required=True)
    a = ap.parse_args()
    if a.socketcand:
        host, _, port = a.socketcand.rpartition(":")
        bus = {"interface": "socketcand", "host": host, "port": int(port), "channel": "can0"}
    else:
        bus = {"interface": "socketcan", "channel": a.iface}
    main(bus, a.node, a.eds)
