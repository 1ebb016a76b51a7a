#!/usr/bin/env python3
"""Profile position (PP) with python canopen's BaseNode402 against drive-emu, default PDOs.

    drive-emu run --iface vcan0 --node 5 &
    drive-emu eds --preset cnc1 --node 5 --real32 decimal > drive.eds   # REAL32 as python canopen reads them
    python pp.py --iface vcan0 --node 5 --eds drive.eds

Without kernel CAN (no vcan: macOS, Windows, containers) the drive serves its bus over
socketcand instead: `drive-emu run --socketcand 127.0.0.1:29536 --node 5 &`, then
`python pp.py --socketcand 127.0.0.1:29536 --node 5 --eds drive.eds`.

Resets the node and waits for its boot-up, enables it in PP, moves 5 mm (5000 um, the
default user unit is 1 um on linear axes) and back, each time waiting for "target reached"
(statusword bit 10), then disables it. Exit status 0 on success.
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


def move_to(node, target_um, timeout=30):
    node.sdo["Target position"].raw = target_um
    node.controlword = 0x0F
    node.controlword = 0x1F  # bit 4 rising edge: new set-point
    wait_for(lambda: node.statusword & 0x1000, timeout, "set-point acknowledge (bit 12)")
    node.controlword = 0x0F
    wait_for(lambda: node.statusword & 0x0400 and not node.statusword & 0x1000, timeout,
             f"target reached (bit 10) at {target_um} um")
    return node.sdo["Position actual value"].raw


def main(bus, node_id, eds):
    network = canopen.Network()
    network.connect(**bus)
    try:
        node = canopen.BaseNode402(node_id, eds)
        network.add_node(node)
        node.nmt.state = "RESET COMMUNICATION"
        node.nmt.wait_for_bootup(10)
        print(f"node {node_id} booted")
        node.setup_402_state_machine()  # reads the PDO mapping over SDO
        node.nmt.state = "OPERATIONAL"
        wait_for(lambda: node.statusword & 0x4F == 0x40, 10, "SWITCH ON DISABLED")
        node.op_mode = "PROFILED POSITION"
        node.state = "OPERATION ENABLED"
        print(f"state {node.state}, mode {node.op_mode}")
        node.sdo["Profile velocity"].raw = 20000  # um/s
        node.sdo["Profile acceleration"].raw = 200000  # um/s^2
        node.sdo["Profile deceleration"].raw = 200000
        start = node.sdo["Position actual value"].raw
        for target in (start + 5000, start):
            end = move_to(node, target)
            print(f"PP move to {target} um: target reached at {end} um")
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
