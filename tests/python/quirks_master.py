#!/usr/bin/env python3
"""python canopen (pinned, tests/requirements.txt) trips over the vendor switches of
`drive-emu run --profile / --quirk` (docs/quirks.md) as the users of the issue threads did on
the real drives, and does not with the switch off.

Usage: quirks_master.py --iface IFACE --node N --bin DRIVE_EMU CASE

For CASE, the drive is started twice with drive_emu_testing's DriveEmu (python/): once with
the case's switch on, once without; the same master code runs against both, and the script
asserts how it trips (an exception, a state, an abort code) and that it does not without the
switch. Prints READY, STEP lines, PASS at the end; exits non-zero with a line starting with
FAIL on the first failure. Timing margins are 3x or more (user-mode Linux stalls for several
ms); where a switch is about time the switch's parameter is widened, not the margin. No
duration is asserted.
"""
import argparse
import os
import sys
import threading
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "python"))

import canopen  # noqa: E402
from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError  # noqa: E402
from drive_emu_testing import DriveEmu  # noqa: E402

OUT_LOCK = threading.Lock()


def say(line):
    with OUT_LOCK:
        print(line, flush=True)


class Fail(Exception):
    pass


def check(cond, msg):
    if not cond:
        raise Fail(msg)


def step(msg):
    say(f"STEP {msg}")


def wait_until(pred, timeout, what):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return
        time.sleep(0.01)
    raise Fail(f"{what} not within {timeout} s")


def abort_code(fn):
    """Run fn; the SDO abort code it raised, or None."""
    try:
        fn()
    except SdoAbortedError as e:
        return e.code
    return None


def enabled_402(node, mode="PROFILED POSITION"):
    """The usual python master: PDOs read, operational, mode, enable."""
    node.setup_402_state_machine()
    node.nmt.state = "OPERATIONAL"
    node.op_mode = mode
    node.state = "OPERATION ENABLED"


# ----------------------------------------------------------------------------- the cases

def enable_requires_mode(node, net, on):
    """ros_canopen PR 331 / ros2_canopen's handleInit: enable before a mode is set."""
    node.setup_402_state_machine()
    node.nmt.state = "OPERATIONAL"
    check(node.sdo[0x6060].raw == 0, "0x6060 starts at 0")
    try:
        node.state = "OPERATION ENABLED"
        enabled = True
    except RuntimeError as e:
        enabled = False
        step(f"state = 'OPERATION ENABLED' raised RuntimeError({e})")
    if on:
        check(not enabled, "the drive enabled without a mode")
        sw = node.sdo[0x6041].raw
        check(sw & 0x6F == 0x23, f"statusword {sw:#06x} is not SWITCHED ON")
        step("enable without a mode: stays SWITCHED ON")
        node.sdo[0x6060].raw = 1
        wait_until(lambda: node.sdo[0x6041].raw & 0x6F == 0x27, 1.5,
                   "OPERATION ENABLED once 0x6060 = 1")
        step("0x6060 = PP: OPERATION ENABLED by itself")
    else:
        check(enabled and node.state == "OPERATION ENABLED", "strict drive not enabled")
        step("enable without a mode: OPERATION ENABLED")


def sdo_response_delay(node, net, on):
    """ros2_canopen 194: a master with a short SDO timeout (20 ms in ros2_canopen; 200 ms
    here, so that a busy host does not make the strict drive late: still shorter than the
    300 ms delay, which no answer beats) against a drive whose answers come late."""
    node.sdo.RESPONSE_TIMEOUT = 0.2
    results = []
    for _ in range(4):
        try:
            results.append(node.sdo[0x1000].raw == 0x00020192)
        except SdoCommunicationError:
            results.append("timeout")
        time.sleep(0.6)  # the late answer (if any) arrives before the next request
    if on:
        check(results == ["timeout"] * 4, f"every read late: {results}")
        step("delay_ms = 300: every read times out (SdoCommunicationError)")
    else:
        check(results == [True] * 4, f"strict drive: {results}")
        step("strict: every read answered")


def sdo_response_delay_late_every(node, net, on):
    """ros2_canopen 194's "occasionally ~10 ms too late": every 3rd service late (300 ms
    here, against the master's 200 ms)."""
    node.sdo.RESPONSE_TIMEOUT = 0.2
    results = []
    for _ in range(6):
        try:
            results.append(node.sdo[0x1000].raw == 0x00020192)
        except SdoCommunicationError:
            results.append("timeout")
        time.sleep(0.6)
    if on:
        check(results == [True, True, "timeout", True, True, "timeout"],
              f"every 3rd read late: {results}")
        step("late_every = 3: reads 3 and 6 time out, the others are answered")
    else:
        check(results == [True] * 6, f"strict drive: {results}")
        step("strict: every read answered")


def pdo_remap(node, net, on):
    """python canopen PR 3: the master remaps TPDO1 without zeroing sub 0 first. Copley
    (strict, the default) aborts 0x06010000; a lenient drive takes it."""
    cob = 0x180 + node.id
    node.sdo[0x1800][1].raw = 0x80000000 | cob
    code = abort_code(lambda: setattr(node.sdo[0x1A00][1], "raw", 0x60410010))
    if not on:
        check(code == 0x06010000, f"strict remap: abort {code!r}, not 0x06010000")
        step("entry written while sub 0 = 2: SdoAbortedError 0x06010000")
    else:
        check(code is None, f"lenient remap refused: {code!r}")
        node.sdo[0x1A00][0].raw = 1
        node.sdo[0x1800][1].raw = cob
        frames = []
        net.subscribe(cob, lambda can_id, data, ts: frames.append(bytes(data)))
        node.nmt.state = "OPERATIONAL"
        wait_until(lambda: len(frames) >= 2, 2.0, "TPDO1 frames")
        check(all(len(f) == 2 for f in frames), f"TPDO1 carries the statusword alone: {frames}")
        step("lenient: entry accepted, TPDO1 carries the statusword alone")
        node.nmt.state = "PRE-OPERATIONAL"
    # python canopen's own save (sub 0 = 0 first) works on both
    node.tpdo.read()
    node.tpdo[1].clear()
    node.tpdo[1].add_variable(0x6041)
    node.tpdo[1].add_variable(0x6061)
    node.tpdo[1].save()
    step("tpdo[1].save() (sub 0 first) accepted")


def pdo_remap_copley(node, net, on):
    """The Copley profile: strict remap, and its vendor ID."""
    if on:
        vendor = node.sdo[0x1018][1].raw
        check(vendor == 0xAB, f"0x1018:1 = {vendor:#x}, not Copley's 0xAB")
        step("copley-accelnet: vendor ID 0xAB")
    # strict with and without the profile
    pdo_remap(node, net, False)


def tpdo_rtr_unsupported(node, net, on):
    """python canopen PR 228, Roboteq FBL2360T: tpdo.save() without read() clears bit 30."""
    node.tpdo[1].clear()
    node.tpdo[1].add_variable(0x6041)
    node.tpdo[1].cob_id = 0x180 + node.id
    node.tpdo[1].trans_type = 255
    node.tpdo[1].enabled = True
    code = abort_code(node.tpdo[1].save)
    if on:
        check(code == 0x06090030, f"abort {code!r}, not 0x06090030")
        step("save() without read(): SdoAbortedError 0x06090030")
        node.tpdo.read()
        check(not node.tpdo[1].rtr_allowed, "bit 30 read back")
        node.tpdo[1].save()
        step("read() first (PR 228): bit 30 kept, save() accepted")
    else:
        check(code is None, f"strict drive refused: {code!r}")
        step("strict: save() without read() accepted")


def controlword_min_hold(node, net, on):
    """yarp-devices 215, Technosoft: fault reset 0x80 and shutdown 0x06 back to back."""
    enabled_402(node)
    node.sdo[0x2101].raw = 0x8611  # the drive reports a fault
    wait_until(lambda: node.state == "FAULT", 2.0, "FAULT")
    node.sdo[0x2101].raw = 0
    time.sleep(0.1)
    rpdo = node.rpdo[1]
    rpdo["Controlword"].raw = 0x80
    rpdo.transmit()
    rpdo["Controlword"].raw = 0x06
    rpdo.transmit()
    time.sleep(0.5)
    state = node.state
    if on:
        check(state == "FAULT", f"0x80 held < 50 ms was seen: {state}")
        step("0x80 then 0x06 back to back: still FAULT (the reset was not seen)")
        rpdo["Controlword"].raw = 0x80
        rpdo.transmit()
        time.sleep(0.2)
        rpdo["Controlword"].raw = 0x06
        rpdo.transmit()
        wait_until(lambda: node.state == "READY TO SWITCH ON", 1.0, "READY TO SWITCH ON")
        step("0.2 s apart: READY TO SWITCH ON")
    else:
        check(state == "READY TO SWITCH ON", f"strict drive: {state}")
        step("strict: READY TO SWITCH ON (15 then 2)")


def quick_stop_skips_active_state(node, net, on):
    """python canopen 167: quick stop at standstill; the thread's drive shows QUICK STOP
    ACTIVE for one statusword."""
    node.tpdo.read()
    node.tpdo[1].inhibit_time = 0  # every statusword goes out, also one that lasts one tick
    node.tpdo[1].save()
    enabled_402(node)
    time.sleep(0.2)
    sws = []
    net.subscribe(0x180 + node.id,
                  lambda can_id, data, ts: sws.append(int.from_bytes(data[:2], "little")))
    node.controlword = 0x0002
    time.sleep(0.3)
    qsa = [i for i, s in enumerate(sws) if s & 0x6F == 0x07]
    sod = [i for i, s in enumerate(sws) if s & 0x4F == 0x40]
    check(sod, f"no SWITCH ON DISABLED: {[hex(s) for s in sws]}")
    if on:
        check(not qsa, f"QUICK STOP ACTIVE seen: {[hex(s) for s in sws]}")
        step("quick stop: straight to SWITCH ON DISABLED, never QUICK STOP ACTIVE")
    else:
        check(qsa and qsa[0] < sod[0], f"QSA before SOD: {[hex(s) for s in sws]}")
        step("strict: QUICK STOP ACTIVE, then SWITCH ON DISABLED")


def mode_change_blocked_by_halt(node, net, on):
    """ros2_canopen 234, ENGEL HBI: mode switch with the halt bit set."""
    enabled_402(node, "PROFILED VELOCITY")
    node.controlword = 0x010F
    time.sleep(0.1)
    node.op_mode = "PROFILED POSITION"  # logs its own timeout
    shown = node.sdo[0x6061].raw
    if on:
        check(shown == 3, f"0x6061 = {shown} while halted")
        step("halt set: 0x6061 stays PV")
        node.controlword = 0x000F
        wait_until(lambda: node.sdo[0x6061].raw == 1, 1.0, "0x6061 = PP after halt")
        step("halt cleared: 0x6061 = PP")
    else:
        check(shown == 1, f"strict: 0x6061 = {shown}")
        step("strict: 0x6061 = PP with halt set")


def homing_method_zero(node, net, on):
    """ros2_canopen 328 / 236: 0x6098 = 0 to skip homing."""
    rule = on
    code = abort_code(lambda: setattr(node.sdo[0x6098], "raw", 0))
    value = node.sdo[0x6098].raw
    skip = value == 0
    if rule == "ignore":
        check(code is None and value == 37 and not skip, f"ignore: {code!r}, {value}")
        step("faulhaber: 0x6098 = 0 confirmed, reads 37: the master homes anyway")
    elif rule == "refuse":
        check(code == 0x06090030 and value == 37, f"refuse: {code!r}, {value}")
        step("epos4: 0x6098 = 0 aborted 0x06090030")
    else:
        check(code is None and skip, f"strict: {code!r}, {value}")
        step("strict: 0x6098 = 0 stored, homing skipped")


def homing_status_bits_missing(node, net, on):
    """ros2_canopen 245 (JVL MIS), the attained reading: python's homing() sees INTERRUPTED."""
    node.sdo[0x6098].raw = 37
    node.setup_402_state_machine()
    node.nmt.state = "OPERATIONAL"
    node.op_mode = "HOMING"
    node.state = "OPERATION ENABLED"
    ok = node.homing(timeout=5)
    if on:
        check(ok is False, f"homing() returned {ok}")
        step("homing(): False (bits 13,12,10 = 0,0,1 is INTERRUPTED)")
    else:
        check(ok is True, f"homing() returned {ok}")
        step("strict: homing() True")


def bootup_then_heartbeat(node, net, on):
    """ros_canopen 435 (Nanotec PD4-N): a master watching the last heartbeat state."""
    states = []
    node.nmt.add_heartbeat_callback(states.append)
    node.nmt.state = "RESET COMMUNICATION"
    time.sleep(0.05)
    seen = list(states)
    if on:
        check(seen[:2] == [0, 127] and seen[-1] == 127, f"heartbeats {seen}")
        try:
            node.nmt.wait_for_bootup(1)
            raise Fail("wait_for_bootup() saw a boot-up")
        except canopen.nmt.NmtError:
            pass
        step("reset communication: [0, 127] within 50 ms; wait_for_bootup() times out")
    else:
        check(seen == [], f"heartbeats {seen}")
        node.nmt.wait_for_bootup(2)
        step("strict: the boot-up comes during wait_for_bootup()")


def not_ready_after_bootup(node, net, on):
    """python canopen 401: read at once after wait_for_bootup()."""
    node.nmt.state = "RESET COMMUNICATION"
    node.nmt.wait_for_bootup(10)
    try:
        ok = node.sdo[0x1000].raw == 0x00020192
    except SdoCommunicationError:
        ok = "timeout"
    if on:
        check(ok == "timeout", f"answered while not ready: {ok}")
        step("SDO right after the boot-up: SdoCommunicationError")
        got = threading.Event()
        node.nmt.add_heartbeat_callback(lambda s: s == 127 and got.set())
        check(got.wait(10), "no 0x7F heartbeat")
        check(node.sdo[0x1000].raw == 0x00020192, "0x1000 once ready")
        step("after the 0x7F heartbeat: 0x1000 read")
    else:
        check(ok is True, f"strict: {ok}")
        step("strict: 0x1000 read at once")


def sdo_first_upload_dropped(node, net, on):
    """ros_canopen 347: the first read of 0x6061 after the boot times out."""
    node.nmt.state = "RESET COMMUNICATION"
    node.nmt.wait_for_bootup(10)
    try:
        first = node.sdo[0x6061].raw
    except SdoCommunicationError:
        first = "timeout"
    second = node.sdo[0x6061].raw
    if on:
        check(first == "timeout" and second == 0, f"{first}, {second}")
        step("first read of 0x6061: timeout; second: 0")
    else:
        check(first == 0 and second == 0, f"{first}, {second}")
        step("strict: both reads answered")


def sdo_silent_objects(node, net, on):
    """python canopen PR 306: pdo.read() reads 0x1800:5, the device sends nothing."""
    try:
        node.setup_402_state_machine()
        ok = True
    except SdoCommunicationError:
        ok = False
    if on:
        check(not ok, "setup_402_state_machine() returned")
        step("setup_402_state_machine(): SdoCommunicationError (0x1800:5 silent)")
        check(node.sdo[0x1000].raw == 0x00020192, "the next request answered")
    else:
        check(ok and 0x6041 in node.tpdo_values, "strict: setup failed")
        step("strict: setup_402_state_machine() returns")


def unmappable_objects(node, net, on):
    """python canopen 283: a TPDO with an object the drive will not map."""
    node.tpdo.read()
    node.tpdo[3].clear()
    node.tpdo[3].add_variable(0x6077)
    code = abort_code(node.tpdo[3].save)
    if on:
        check(code == 0x06040041, f"abort {code!r}")
        step("tpdo[3].save() with 0x6077: SdoAbortedError 0x06040041")
    else:
        check(code is None, f"strict: {code!r}")
        step("strict: 0x6077 mapped")


# case: (function, drive arguments with the switch on, value passed as `on`)
CASES = {
    "enable_requires_mode": (enable_requires_mode, ["--profile", "nanotec-pd4c"], True),
    "sdo_response_delay": (sdo_response_delay,
                           ["--quirk", "sdo_response_delay.delay_ms=300"], True),
    "sdo_response_delay_late_every": (
        sdo_response_delay_late_every,
        ["--quirk", "sdo_response_delay.delay_ms=0",
         "--quirk", "sdo_response_delay.late_delay_ms=300",
         "--quirk", "sdo_response_delay.late_every=3"], True),
    "pdo_remap_lenient": (pdo_remap, ["--quirk", "pdo_remap_lenient"], True),
    "pdo_remap_copley": (pdo_remap_copley, ["--profile", "copley-accelnet"], True),
    "tpdo_rtr_unsupported": (tpdo_rtr_unsupported, ["--profile", "roboteq-fbl2360"], True),
    "controlword_min_hold": (controlword_min_hold,
                             ["--profile", "technosoft-ipos",
                              "--quirk", "controlword_min_hold.hold_us=50000"], True),
    "quick_stop_skips_active_state": (quick_stop_skips_active_state,
                                      ["--quirk", "quick_stop_skips_active_state"], True),
    "mode_change_blocked_by_halt": (mode_change_blocked_by_halt,
                                    ["--profile", "engel-hbi"], True),
    "homing_method_zero_ignore": (homing_method_zero, ["--profile", "faulhaber-mc5004"],
                                  "ignore"),
    "homing_method_zero_refuse": (homing_method_zero, ["--profile", "maxon-epos4"], "refuse"),
    "homing_status_bits_missing": (homing_status_bits_missing,
                                   ["--quirk", "homing_status_bits_missing.bits=[\"attained\"]"],
                                   True),
    "bootup_then_heartbeat": (bootup_then_heartbeat, ["--profile", "nanotec-pd4c"], True),
    "not_ready_after_bootup": (not_ready_after_bootup,
                               ["--quirk", "not_ready_after_bootup.ready_after_ms=3000"], True),
    "sdo_first_upload_dropped": (sdo_first_upload_dropped,
                                 ["--quirk", "sdo_first_upload_dropped"], True),
    "sdo_silent_objects": (sdo_silent_objects,
                           ["--quirk", "sdo_silent_objects.objects=[\"0x1800-0x1803:5\"]"],
                           True),
    "unmappable_objects": (unmappable_objects,
                           ["--quirk", "unmappable_objects.objects=[\"0x6077:0\"]"], True),
}


def run(args, case, on_args, on_value):
    emu = DriveEmu(iface=args.iface, node_id=args.node, binary=args.bin,
                   extra_args=on_args)
    emu.start()
    net = canopen.Network()
    try:
        net.connect(interface="socketcan", channel=args.iface)
        node = canopen.BaseNode402(args.node, emu.eds_path)
        net.add_node(node)
        # the drive has booted (the ready line); python's view of its NMT state starts at
        # INITIALISING until it hears something: say where it is, as a master does
        node.nmt.state = "PRE-OPERATIONAL"
        fn, _, _ = CASES[case]
        fn(node, net, on_value)
        ready = emu.ready["nodes"][0]
    finally:
        net.disconnect()
        emu.stop(check=False)
    check(emu.returncode == 0, f"drive-emu exited {emu.returncode}:\n{emu.stderr_text()}")
    check("panicked" not in emu.stderr_text(), emu.stderr_text())
    return ready, emu.stderr_text()


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--iface", required=True)
    p.add_argument("--node", type=int, required=True)
    p.add_argument("--bin", required=True)
    p.add_argument("case", choices=sorted(CASES))
    args = p.parse_args()
    say("READY")
    try:
        _, on_args, on_value = CASES[args.case]
        say(f"STEP --- switch on: drive-emu run {' '.join(on_args)}")
        ready, stderr = run(args, args.case, on_args, on_value)
        # the ready line and the start-up message say what is on
        profile = next((v for a, v in zip(on_args, on_args[1:]) if a == "--profile"), None)
        check(ready.get("profile") == profile, f"ready line: {ready}")
        named = {v.split(".")[0] for a, v in zip(on_args, on_args[1:]) if a == "--quirk"}
        check(named <= set(ready.get("quirks", [])), f"ready line: {ready}, not {named}")
        check(f"node {args.node}: profile {profile or 'none'}:" in stderr,
              f"no start-up message about the profile:\n{stderr}")
        say(f"STEP ready line: profile {profile}, quirks {ready['quirks']}")
        say("STEP --- switch off: drive-emu run")
        ready, _ = run(args, args.case, [], False)
        check(ready.get("profile") is None and ready.get("quirks") == [],
              f"ready line without a profile: {ready}")
    except Fail as e:
        say(f"FAIL: {e}")
        sys.exit(1)
    except Exception:
        say(f"FAIL: {traceback.format_exc()}")
        sys.exit(1)
    say("PASS")


if __name__ == "__main__":
    main()
