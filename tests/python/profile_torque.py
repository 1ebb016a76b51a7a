#!/usr/bin/env python3
"""python-canopen (pinned, tests/requirements.txt) runs drive-emu in profile torque mode.

Usage: profile_torque.py IFACE NODE EDS
Prints READY once connected; then waits for the drive's boot-up (start the emulator after
READY), and:
  1. 0x6502 offers PT (bit 3); BaseNode402 to OPERATION ENABLED with SYNC running, then
     op_mode "PROFILED TORQUE" (0x6061 = 4);
  2. target torque 0x6071 = +TORQUE at the slope 0x6087: the demand 0x6074 reaches it with
     statusword bit 10, the actual torque 0x6077 follows (same sign, at least half of it) and
     the actual velocity 0x606C rises;
  3. 0x6071 = -TORQUE: the actual torque turns negative and the velocity falls;
  4. halt (controlword bit 8): the demand ramps to 0, bit 10 once there; then disabled.
The emulator runs in lock-step with our SYNC (--lockstep --sync-period-us 10000): the drive's
time advances 10 ms per SYNC. Waits have generous time-outs (user-mode Linux is slow); no
timing is asserted. Exits non-zero with a line starting FAIL on the first failure.
"""
import sys
import time
import traceback

import canopen

IFACE, NODE, EDS = sys.argv[1], int(sys.argv[2]), sys.argv[3]
SYNC_PERIOD = 0.01
TORQUE = 200  # per mille of the rated torque
SLOPE = 2000  # per mille per second: 0.1 s to TORQUE


def fail(msg):
    print(f"FAIL: {msg}", flush=True)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)


def step(msg):
    print(f"STEP {msg}", flush=True)


def wait_for(pred, timeout, what):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return
        time.sleep(0.02)
    fail(f"timeout ({timeout} s) waiting for {what() if callable(what) else what}")


canopen.BaseNode402.TIMEOUT_SWITCH_STATE_SINGLE = 3.0
canopen.BaseNode402.TIMEOUT_SWITCH_STATE_FINAL = 10.0
canopen.BaseNode402.TIMEOUT_SWITCH_OP_MODE = 5.0
canopen.BaseNode402.TIMEOUT_CHECK_TPDO = 2.0

network = canopen.Network()
network.connect(interface="socketcan", channel=IFACE)
node = canopen.BaseNode402(NODE, EDS)
node.sdo.RESPONSE_TIMEOUT = 5.0
network.add_node(node)
print("READY", flush=True)


def sdo(index):
    return node.sdo[index].raw


def state_text():
    return (f"0x6041 = 0x{sdo(0x6041):04X}, 0x6074 = {sdo(0x6074)}, 0x6077 = {sdo(0x6077)}, "
            f"0x606C = {sdo(0x606C)}")


try:
    node.nmt.wait_for_bootup(60)
    check(sdo(0x6502) & 0x8, f"0x6502 = 0x{sdo(0x6502):X}: no profile torque (bit 3)")
    node.tpdo.read()
    node.tpdo[1].event_timer = 50
    node.tpdo[1].save()
    node.setup_402_state_machine()
    node.nmt.state = "OPERATIONAL"
    network.sync.start(SYNC_PERIOD)
    wait_for(lambda: node.statusword & 0x4F == 0x40, 10,
             lambda: f"SWITCH ON DISABLED (statusword 0x{node.statusword:04X})")
    node.sdo[0x6087].raw = SLOPE
    node.sdo[0x6071].raw = 0
    node.op_mode = "PROFILED TORQUE"
    check(sdo(0x6061) == 4, f"0x6061 = {sdo(0x6061)} after op_mode PROFILED TORQUE")
    node.state = "OPERATION ENABLED"
    check(node.state == "OPERATION ENABLED", f"state {node.state}")
    step(f"PT, OPERATION ENABLED: {state_text()}")

    v0 = sdo(0x606C)
    node.sdo[0x6071].raw = TORQUE
    wait_for(lambda: sdo(0x6074) == TORQUE and sdo(0x6041) & 0x400, 30,
             lambda: f"the demand at {TORQUE} with target reached: {state_text()}")
    wait_for(lambda: sdo(0x6077) >= TORQUE // 2, 30,
             lambda: f"actual torque following +{TORQUE}: {state_text()}")
    wait_for(lambda: sdo(0x606C) > v0 + 1000, 30,
             lambda: f"velocity rising from {v0}: {state_text()}")
    step(f"+{TORQUE} per mille: {state_text()}")

    v1 = sdo(0x606C)
    node.sdo[0x6071].raw = -TORQUE
    wait_for(lambda: sdo(0x6077) <= -TORQUE // 2, 30,
             lambda: f"actual torque following -{TORQUE}: {state_text()}")
    wait_for(lambda: sdo(0x606C) < v1 - 1000, 30,
             lambda: f"velocity falling from {v1}: {state_text()}")
    step(f"-{TORQUE} per mille: {state_text()}")

    node.controlword = 0x010F  # halt
    wait_for(lambda: sdo(0x6074) == 0 and sdo(0x6041) & 0x400, 30,
             lambda: f"halt: the demand at 0 with target reached: {state_text()}")
    step(f"halt: {state_text()}")
    node.controlword = 0x0006
    wait_for(lambda: sdo(0x6041) & 0x6F == 0x21, 10,
             lambda: f"READY TO SWITCH ON: {state_text()}")
    print("PASS", flush=True)
except SystemExit:
    raise
except Exception:  # noqa: BLE001
    traceback.print_exc()
    fail("exception (see traceback above)")
finally:
    try:
        network.sync.stop()
    except Exception:  # noqa: BLE001
        pass
    network.disconnect()
