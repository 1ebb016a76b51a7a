"""Distributed clocks with SOEM (pysoem) against `drive-emu run --ethercat`: SYNC0 at 1 ms.

Usage: ethercat_dc.py IFACE [SECONDS]
       ethercat_dc.py IFACE --lockstep CYCLES   (against `run --ethercat IFACE --lockstep`)

Checks, and exits non-zero with the reason on the first failure:
- DC SYNC0 chosen (0x1C32:1 = 2) without SYNC0 activated: SAFE-OP refused, AL status code
  0x0030 (invalid DC SYNC configuration);
- config_dc, dc_sync(True, 1 ms), 0x1C32:1 = 2, config_map: SAFE-OP and OP, the working
  counter SOEM expects in every cycle;
- 0x2100 (the drive's loop statistics) says locked (sub 8 = 2) with a SYNC0 period of
  1000 us (sub 10) and its phase error (sub 9);
- CiA 402 enable and a CSP move from the process data: 0x6064 follows.
With SECONDS, the drive is held in OP that long more (the SYNC0-to-tick benchmark: the
emulator's --json statistics give the phase error's p50/p99).
With --lockstep: config_dc, SYNC0 at 1 ms, DC SYNC0, SAFE-OP, OP, enable, then CYCLES
process-data cycles of a CSP ramp as fast as the master goes; reports the process-data
frames sent and the drive's ticks from 0x2100 (sub 1) around the ramp and at the end, the
lock (0x2100 sub 8, 9, 10) and 0x6064 before and after the ramp.
Prints one JSON line with what it measured.
"""

import json
import struct
import sys
import time

import pysoem

SYNC0_NS = 1_000_000


def fail(msg):
    print(f"FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)


def main():
    iface = sys.argv[1]
    m = pysoem.Master()
    m.open(iface)
    try:
        if len(sys.argv) > 3 and sys.argv[2] == "--lockstep":
            run_lockstep(m, int(sys.argv[3]))
        else:
            run(m, float(sys.argv[2]) if len(sys.argv) > 2 else 0.0)
    finally:
        m.close()


def ticks(s):
    """0x2100 sub 1: the drive ticks the loop ran."""
    return struct.unpack("<I", s.sdo_read(0x2100, 1))[0]


def run_lockstep(m, cycles):
    s = init(m)
    check(m.config_dc(), "config_dc found no DC slave")
    s.dc_sync(True, SYNC0_NS)
    s.sdo_write(0x1C32, 1, struct.pack("<H", 2))
    s.sdo_write(0x6060, 0, struct.pack("<b", 8))
    size = m.config_map()
    check(size == 12, f"process image {size} bytes, expected 12")
    check(m.state_check(pysoem.SAFEOP_STATE, 500000) == pysoem.SAFEOP_STATE,
          f"SAFE-OP not reached: 0x{s.state:02X} code 0x{s.al_status:04X}")
    expected = m.expected_wkc
    sent = [0]
    wkcs = []

    def cycle(cw, target):
        s.output = struct.pack("<Hi", cw, target)
        m.send_processdata()
        sent[0] += 1
        wkcs.append(m.receive_processdata(10000))

    def statusword():
        return struct.unpack("<H", s.input[0:2])[0]

    def position():
        return struct.unpack("<i", s.input[2:6])[0]

    cycle(0, 0)
    m.state = pysoem.OP_STATE
    m.write_state()
    reached = pysoem.NONE_STATE
    for _ in range(200):
        cycle(0, 0)
        reached = m.state_check(pysoem.OP_STATE, 5000)
        if reached == pysoem.OP_STATE:
            break
    check(reached == pysoem.OP_STATE, f"OP not reached: 0x{s.state:02X}")
    for cw, want in [(0x06, 0x21), (0x07, 0x23), (0x0F, 0x27)]:
        for _ in range(3000):
            cycle(cw, 0)
            if statusword() & 0x6F == want:
                break
        check(statusword() & 0x6F == want,
              f"controlword 0x{cw:02X}: statusword 0x{statusword():04X}")
    sent_before, ticks_before, pos_before = sent[0], ticks(s), position()
    for step in range(1, cycles + 1):
        cycle(0x0F, 2 * step)
    sent_after, ticks_after = sent[0], ticks(s)
    for _ in range(100):
        cycle(0x0F, 2 * cycles)
    bad = [w for w in wkcs if w != expected]
    check(not bad, f"{len(bad)} of {len(wkcs)} cycles with a working counter other than "
          f"{expected}: {bad[:10]}")
    print(json.dumps({"frames": sent_after - sent_before, "ticks": ticks_after - ticks_before,
                      "frames_total": sent[0], "ticks_total": ticks(s), "lock": stats(s),
                      "position_before": pos_before, "position_actual": position(),
                      "target": 2 * cycles}))
    m.state = pysoem.INIT_STATE
    m.write_state()


def init(m):
    n = 0
    for _ in range(50):
        n = m.config_init()
        if n > 0:
            break
        time.sleep(0.1)
    check(n == 1, f"config_init found {n} slaves, expected 1")
    return m.slaves[0]


def stats(s):
    """0x2100 sub 8 (lock state), 9 (phase error, us), 10 (SYNC period, us)."""
    return [struct.unpack("<I", s.sdo_read(0x2100, sub))[0] for sub in (8, 9, 10)]


def run(m, hold_s):
    # DC SYNC0 chosen, SYNC0 not activated: SAFE-OP refused with 0x0030
    s = init(m)
    s.sdo_write(0x1C32, 1, struct.pack("<H", 2))
    m.config_map()
    check(m.state_check(pysoem.SAFEOP_STATE, 200000) != pysoem.SAFEOP_STATE,
          "SAFE-OP reached with DC SYNC0 and no SYNC0")
    m.read_state()
    check(s.state & 0x10 and s.al_status == 0x0030,
          f"refused SAFE-OP: AL status 0x{s.state:02X}, code 0x{s.al_status:04X}")
    refused_code = s.al_status

    # again, as a DC master does it: config_init, config_dc, SYNC0 at 1 ms, the sync type
    s = init(m)
    check(m.config_dc(), "config_dc found no DC slave")
    s.dc_sync(True, SYNC0_NS)
    s.sdo_write(0x1C32, 1, struct.pack("<H", 2))
    s.sdo_write(0x6060, 0, struct.pack("<b", 8))
    size = m.config_map()
    check(size == 12, f"process image {size} bytes, expected 12")
    check(m.state_check(pysoem.SAFEOP_STATE, 500000) == pysoem.SAFEOP_STATE,
          f"SAFE-OP not reached: 0x{s.state:02X} code 0x{s.al_status:04X}")
    expected = m.expected_wkc

    period_s = 0.001
    next_t = [time.monotonic()]

    def cycle(cw, target):
        next_t[0] += period_s
        delay = next_t[0] - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        else:
            next_t[0] = time.monotonic()
        s.output = struct.pack("<Hi", cw, target)
        m.send_processdata()
        return m.receive_processdata(10000)

    def statusword():
        return struct.unpack("<H", s.input[0:2])[0]

    def position():
        return struct.unpack("<i", s.input[2:6])[0]

    cycle(0, 0)
    m.state = pysoem.OP_STATE
    m.write_state()
    reached = pysoem.NONE_STATE
    for _ in range(200):
        cycle(0, 0)
        reached = m.state_check(pysoem.OP_STATE, 5000)
        if reached == pysoem.OP_STATE:
            break
    check(reached == pysoem.OP_STATE, f"OP not reached: 0x{s.state:02X}")
    wkcs = []
    for cw, want in [(0x06, 0x21), (0x07, 0x23), (0x0F, 0x27)]:
        for _ in range(3000):
            wkcs.append(cycle(cw, 0))
            if statusword() & 0x6F == want:
                break
        check(statusword() & 0x6F == want,
              f"controlword 0x{cw:02X}: statusword 0x{statusword():04X}")
    # the lock: 16 good pulses after 8 for the period (the first came 100 ms after dc_sync)
    lock = stats(s)
    for _ in range(20):
        if lock[0] == 2:
            break
        for _ in range(100):
            wkcs.append(cycle(0x0F, 0))
        lock = stats(s)
    check(lock[0] == 2 and lock[2] == 1000,
          f"0x2100: lock state {lock[0]}, SYNC period {lock[2]} us (want 2, 1000)")
    start = position()
    target = 0
    for step in range(1, 401):
        target = min(5 * step, 2000)
        wkcs.append(cycle(0x0F, target))
    for _ in range(3000):
        wkcs.append(cycle(0x0F, target))
        if abs(position() - 2000) <= 20:
            break
    pos = position()
    check(abs(pos - 2000) <= 20, f"0x6064 {start} -> {pos}, want 2000")
    end = time.monotonic() + hold_s
    while time.monotonic() < end:
        wkcs.append(cycle(0x0F, target))
    lock_end = stats(s)
    check(lock_end[0] == 2, f"0x2100 after the move: {lock_end}")
    bad = [w for w in wkcs if w != expected]
    check(not bad, f"{len(bad)} of {len(wkcs)} cycles with a working counter other than "
          f"{expected}: {bad[:10]}")
    print(json.dumps({"refused_code": refused_code, "lock": lock, "lock_end": lock_end,
                      "cycles": len(wkcs), "expected_wkc": expected, "position_actual": pos}))
    m.state = pysoem.INIT_STATE
    m.write_state()


if __name__ == "__main__":
    main()
