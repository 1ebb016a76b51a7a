#!/usr/bin/env python3
"""A python canopen master over python-can's socketcand interface against
`drive-emu run --socketcand`: no kernel CAN. Boots the drive (NMT reset, boot-up seen), NMT
states, enables and moves it in profile position (PP) and in cyclic synchronous position
(CSP, with the master's SYNC), reads the loop statistics 0x2100. Prints what it saw as one
JSON line last (emulator/tests/socketcand_run.rs checks it); exits non-zero on any
failure.

    drive-emu run --socketcand 127.0.0.1:29536 --node 5 &
    drive-emu eds --preset cnc1 --node 5 --real32 decimal > drive.eds
    python3 socketcand_master.py --port 29536 --node 5 --eds drive.eds
"""
import argparse
import json
import time

import canopen

# BaseNode402's own timeouts assume a quiet real-time host; a loaded machine stalls longer.
canopen.BaseNode402.TIMEOUT_CHECK_TPDO = 5.0
canopen.BaseNode402.TIMEOUT_SWITCH_OP_MODE = 10.0
canopen.BaseNode402.TIMEOUT_SWITCH_STATE_SINGLE = 5.0
canopen.BaseNode402.TIMEOUT_SWITCH_STATE_FINAL = 20.0

PATIENCE_S = 60.0  # only a drive that does not answer waits this long
CSP_PERIOD_S = 0.01


def wait_for(pred, what, timeout=PATIENCE_S):
    deadline = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > deadline:
            raise TimeoutError(f"timeout ({timeout} s) waiting for {what}")
        time.sleep(0.005)


def u32(node, index, sub):
    return int.from_bytes(node.sdo.upload(index, sub), "little")


def pp_move(node, target_um):
    """PP: new set-point (controlword bit 4, rising), wait for target reached (bit 10)."""
    node.sdo["Target position"].raw = target_um
    node.controlword = 0x0F  # bit 4 low
    node.controlword = 0x1F  # new set-point, absolute, immediately
    wait_for(lambda: node.statusword & 0x1000, "set-point acknowledge (statusword bit 12)")
    node.controlword = 0x0F
    wait_for(lambda: node.statusword & 0x0400 and not node.statusword & 0x1000,
             f"target reached (statusword bit 10) at {target_um} um")
    return node.sdo["Position actual value"].raw


def main(a):
    seen = {}
    network = canopen.Network()
    network.connect(interface="socketcand", host=a.host, port=a.port, channel=a.channel)
    try:
        node = canopen.BaseNode402(a.node, a.eds)
        network.add_node(node)
        node.sdo.RESPONSE_TIMEOUT = 5.0
        # boot: an NMT reset and the boot-up it brings
        node.nmt.state = "RESET COMMUNICATION"
        node.nmt.wait_for_bootup(PATIENCE_S)
        seen["bootup"] = True
        seen["nmt_after_bootup"] = node.nmt.state
        print(f"node {a.node} booted: {node.nmt.state}", flush=True)

        # the loop statistics, twice: the tick count grows
        ticks = u32(node, 0x2100, 1)
        wait_for(lambda: u32(node, 0x2100, 1) > ticks, "0x2100:1 (ticks) to grow")
        seen["stats_ticks"] = u32(node, 0x2100, 1)
        seen["stats_overruns"] = u32(node, 0x2100, 2)

        # PP: enable, a move out and back
        node.setup_402_state_machine()  # reads the PDO mapping over SDO
        node.nmt.state = "OPERATIONAL"
        wait_for(lambda: node.statusword & 0x4F == 0x40, "SWITCH ON DISABLED")
        seen["nmt_operational"] = node.nmt.state
        node.op_mode = "PROFILED POSITION"
        node.state = "OPERATION ENABLED"
        seen["pp_state"] = node.state
        node.sdo["Profile velocity"].raw = 20000  # um/s
        node.sdo["Profile acceleration"].raw = 200000  # um/s^2
        node.sdo["Profile deceleration"].raw = 200000
        start = node.sdo["Position actual value"].raw
        seen["pp_target_um"] = start + 5000
        seen["pp_reached_um"] = pp_move(node, start + 5000)
        print(f"PP: {start} -> {seen['pp_reached_um']} um", flush=True)
        node.state = "SWITCH ON DISABLED"

        # CSP: a ramp streamed with RPDO2 + SYNC, as a CNC interpolator does
        node.sdo[0x60C2][1].raw = 10  # interpolation period 10 * 10^-3 s
        node.sdo[0x60C2][2].raw = -3
        rpdo2 = node.rpdo[2]
        start = node.sdo["Position actual value"].raw
        rpdo2["Controlword"].raw = 0x0F
        rpdo2["Target position"].raw = start
        node.op_mode = "CYCLIC SYNCHRONOUS POSITION"
        node.state = "OPERATION ENABLED"
        seen["csp_state"] = node.state
        tpdo2 = node.tpdo[2]
        target = start
        next_t = time.monotonic()
        for k in range(150):
            if k < 100:
                target += 10  # 10 um per 10 ms: 1 mm/s for 1 s, then hold
            rpdo2["Target position"].raw = target
            rpdo2.transmit()
            network.sync.transmit()
            next_t += CSP_PERIOD_S
            time.sleep(max(0.0, next_t - time.monotonic()))
        # TPDO2 is synchronous: one more SYNC, and it answers with the position
        network.sync.transmit()
        tpdo2.wait_for_reception(PATIENCE_S)
        seen["csp_target_um"] = target
        seen["csp_tpdo_um"] = tpdo2["Position actual value"].raw
        seen["csp_actual_um"] = node.sdo["Position actual value"].raw
        print(f"CSP: {start} -> {seen['csp_actual_um']} um (set-point {target})", flush=True)
        node.state = "SWITCH ON DISABLED"
        node.nmt.state = "PRE-OPERATIONAL"
        seen["nmt_end"] = node.nmt.state
    finally:
        network.disconnect()
    print(json.dumps(seen), flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--channel", default="can0")
    ap.add_argument("--node", type=int, default=5)
    ap.add_argument("--eds", required=True)
    main(ap.parse_args())
