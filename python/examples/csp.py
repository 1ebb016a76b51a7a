#!/usr/bin/env python3
"""Cyclic synchronous position (CSP) with python canopen's BaseNode402 against drive-emu.

    drive-emu run --iface vcan0 --node 5 &
    drive-emu eds --preset cnc1 --node 5 --real32 decimal > drive.eds   # REAL32 as python canopen reads them
    python csp.py --iface vcan0 --node 5 --eds drive.eds

Without kernel CAN (no vcan: macOS, Windows, containers) the drive serves its bus over
socketcand instead: `drive-emu run --socketcand 127.0.0.1:29536 --node 5 &`, then
`python csp.py --socketcand 127.0.0.1:29536 --node 5 --eds drive.eds`.

Default PDOs, no remap: RPDO2 (controlword + target position) is synchronous, applied at the
next SYNC; TPDO2 (statusword + position actual) comes with every SYNC. The master streams a
position ramp, 10 um per 10 ms cycle (1 mm/s), for 1 s: each cycle it sends RPDO2 and a SYNC,
as a CNC interpolator does. Then it checks the axis followed and disables the drive.
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

PERIOD_S = 0.01


def wait_for(pred, timeout, what):
    deadline = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > deadline:
            raise TimeoutError(f"timeout ({timeout} s) waiting for {what}")
        time.sleep(0.01)


def main(bus, node_id, eds, cycles=100, step_um=10):
    network = canopen.Network()
    network.connect(**bus)
    try:
        node = canopen.BaseNode402(node_id, eds)
        network.add_node(node)
        node.nmt.state = "RESET COMMUNICATION"
        node.nmt.wait_for_bootup(10)
        print(f"node {node_id} booted")
        node.setup_402_state_machine()
        node.sdo[0x60C2][1].raw = 10  # interpolation period 10 * 10^-3 s
        node.sdo[0x60C2][2].raw = -3
        node.nmt.state = "OPERATIONAL"
        wait_for(lambda: node.statusword & 0x4F == 0x40, 10, "SWITCH ON DISABLED")
        rpdo2 = node.rpdo[2]
        start = node.sdo["Position actual value"].raw
        # RPDO2 carries the controlword too: keep it at "enable operation"
        rpdo2["Controlword"].raw = 0x0F
        rpdo2["Target position"].raw = start
        node.op_mode = "CYCLIC SYNCHRONOUS POSITION"
        node.state = "OPERATION ENABLED"
        print(f"state {node.state}, mode {node.op_mode}")
        target = start
        next_t = time.monotonic()
        for _ in range(cycles):
            target += step_um
            rpdo2["Target position"].raw = target
            rpdo2.transmit()
            network.sync.transmit()
            next_t += PERIOD_S
            time.sleep(max(0.0, next_t - time.monotonic()))
        for _ in range(50):  # hold the last set-point while the axis settles
            rpdo2.transmit()
            network.sync.transmit()
            time.sleep(PERIOD_S)
        tpdo2 = node.tpdo[2]
        tpdo2.wait_for_reception(5)
        actual = node.sdo["Position actual value"].raw
        print(f"CSP ramp {start} -> {target} um: position actual {actual} um, "
              f"TPDO2 position {tpdo2['Position actual value'].raw} um")
        if abs(actual - target) > 100:
            raise RuntimeError(f"the axis did not follow: {actual} um, set-point {target} um")
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
