"""EtherCAT faults as a master sees them: SOEM (pysoem) against
`drive-emu run --ethercat IFACE --scenario scenarios/ethercat-faults.toml`.

Usage: ethercat_faults.py IFACE [encoder]

With `encoder` (against scenarios/encoder-loss.toml): a drive fault the scenario injects (the
motor encoder's signal lost) as the master sees it: the statusword's fault state in the
process data, the slave still in OP, the error code 0x7300 in 0x603F and its EMCY over CoE.

One slave, CSP, enabled and holding its position in OP while the scenario injects, one after
the other: 20 lost frames, bad working counters, late cycles, the link down, and the slave
dropping out of OP with an AL status code. Checks, and exits non-zero with the reason on the
first failure:
- the working counters the master sees: -1 (no answer: lost, late, link down), 0 (not
  incremented), in the timeline's order, until the slave has left OP;
- the slave's AL status (SAFE-OP + error) and AL status code when it dropped out of OP;
- recovery: the master acknowledges, brings the slave back to OP, resets the drive's fault and
  enables it again; every cycle then has the expected working counter; a CoE read answers;
  the drive's EMCY 0x8250 (outputs lost) came over CoE.
Prints one JSON line with what it saw.
"""

import json
import struct
import sys
import time

import pysoem


def fail(msg):
    print(f"FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)


def main():
    m = pysoem.Master()
    m.open(sys.argv[1])
    try:
        if sys.argv[2:] == ["encoder"]:
            encoder(m)
        else:
            run(m)
    finally:
        m.close()


def setup(m):
    """One slave in OP, CSP, enabled; what the checks use of it."""
    n = 0
    for _ in range(50):
        n = m.config_init()
        if n > 0:
            break
        time.sleep(0.1)
    check(n == 1, f"config_init found {n} slaves, expected 1")
    s = m.slaves[0]
    # the drive's emergencies over CoE (they come in the mailbox with SDO answers)
    emcys = []
    s.add_emergency_callback(lambda e: emcys.append(e.error_code))
    s.sdo_write(0x6060, 0, struct.pack("<b", 8))
    m.config_map()
    # long enough that a master stalled by a busy machine (or 20 lost frames of 10 ms each)
    # does not trip it: the drop out of OP must be the scenario's
    s.set_watchdog("processdata", 1000.0)
    check(m.state_check(pysoem.SAFEOP_STATE, 500000) == pysoem.SAFEOP_STATE,
          f"SAFE-OP not reached: 0x{s.al_status:04X}")
    expected = m.expected_wkc
    check(expected == 3, f"expected working counter {expected}")
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

    def to_op():
        m.state = pysoem.OP_STATE
        m.write_state()
        for _ in range(2000):
            cycle(0, position())
            if m.state_check(pysoem.OP_STATE, 5000) == pysoem.OP_STATE:
                return
        fail(f"OP not reached: state 0x{s.state:02X}, AL status code 0x{s.al_status:04X}")

    def enable():
        # a fault (the drive's reaction to lost outputs) is reset first: a rising edge of
        # controlword bit 7
        for _ in range(1000):
            if statusword() & 0x4F != 0x08:
                break
            cycle(0x00, position())
            cycle(0x80, position())
        for cw, mask, want in [(0x06, 0x6F, 0x21), (0x07, 0x6F, 0x23), (0x0F, 0x6F, 0x27)]:
            for _ in range(3000):
                cycle(cw, position())
                if statusword() & mask == want:
                    break
            check(statusword() & mask == want, f"controlword 0x{cw:02X}: 0x{statusword():04X}")

    cycle(0, 0)
    to_op()
    enable()
    return s, cycle, statusword, position, emcys, to_op, enable, expected


def run(m):
    s, cycle, statusword, position, emcys, to_op, enable, expected = setup(m)
    hold = position()
    # the scenario's faults start 0.5 s after operation enabled and end with the drop out of
    # OP at 2.5 s (the drive's time): watch the working counter until the slave left OP
    seen = []  # the working counter of every cycle, in order
    other_run = 0
    left_op = False
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        wkc = cycle(0x0F, hold)
        seen.append(wkc)
        # outputs refused (SAFE-OP) several cycles in a row, or every 200 cycles: the AL status
        other_run = other_run + 1 if wkc not in (-1, 0, expected) else 0
        if other_run >= 5 or len(seen) % 200 == 0:
            m.read_state()
            # 0: the read went unanswered (a lost frame, the link down): not a state
            if s.state not in (0, pysoem.OP_STATE):
                left_op = True
                break
    check(left_op, f"the slave never left OP: {summary(seen)}")
    al_state, al_code = s.state, s.al_status
    check(al_state == 0x14, f"AL status 0x{al_state:02X}, expected SAFE-OP + error (0x14)")
    check(al_code == 0x001A, f"AL status code 0x{al_code:04X}, expected 0x001A")
    # what the master saw before, in the scenario's order
    first = {}
    for k, w in enumerate(seen):
        first.setdefault(w, k)
    lost = sum(1 for w in seen if w == -1)
    bad = sum(1 for w in seen if w == 0)
    check(lost >= 20, f"{lost} cycles without an answer, expected >= 20: {summary(seen)}")
    check(bad >= 1, f"no cycle with working counter 0: {summary(seen)}")
    check(first[-1] < first[0],
          f"the faults out of order: first -1 at {first[-1]}, first 0 at {first[0]}")
    # recovery: acknowledge, OP, fault reset, enable, and a clean run
    s.state = pysoem.SAFEOP_STATE | 0x10
    s.write_state()
    to_op()
    enable()
    after = [cycle(0x0F, position()) for _ in range(300)]
    bad_after = [w for w in after if w != expected]
    check(not bad_after, f"{len(bad_after)} of 300 cycles after recovery with a working "
          f"counter other than {expected}: {bad_after[:10]}")
    ident = struct.unpack("<I", s.sdo_read(0x1018, 1)[:4])[0]
    check(ident == s.man, f"CoE 0x1018:1 0x{ident:08X} != SII vendor 0x{s.man:08X}")
    # the drive's EMCY for the outputs it lost with OP, over CoE
    check(0x8250 in emcys, f"no EMCY 0x8250 over CoE: {[hex(c) for c in emcys]}")
    m.state = pysoem.INIT_STATE
    m.write_state()
    print(json.dumps({"cycles": len(seen), "no_answer": lost, "wkc_zero": bad,
                      "al_status": al_state, "al_status_code": al_code,
                      "recovered_cycles": len(after), "statusword": statusword(),
                      "emcys": emcys}))


def encoder(m):
    s, cycle, statusword, position, emcys, _, _, expected = setup(m)
    hold = position()
    wkcs = []
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and statusword() & 0x4F != 0x08:
        wkcs.append(cycle(0x0F, hold))
    check(statusword() & 0x4F == 0x08, f"no fault in the statusword: 0x{statusword():04X}")
    bad = [w for w in wkcs if w != expected]
    check(not bad, f"{len(bad)} of {len(wkcs)} cycles with a working counter other than "
          f"{expected}: the slave left OP?")
    m.read_state()
    check(s.state == pysoem.OP_STATE, f"AL state 0x{s.state:02X}: a drive fault is not a "
          f"slave's")
    code = struct.unpack("<H", s.sdo_read(0x603F, 0))[0]
    check(code == 0x7300, f"0x603F = 0x{code:04X}, expected 0x7300 (sensor)")
    check(0x7300 in emcys, f"no EMCY 0x7300 over CoE: {[hex(c) for c in emcys]}")
    m.state = pysoem.INIT_STATE
    m.write_state()
    print(json.dumps({"cycles": len(wkcs), "error_code": code, "emcys": emcys,
                      "statusword": statusword()}))


def summary(seen):
    counts = {}
    for w in seen:
        counts[w] = counts.get(w, 0) + 1
    return f"{len(seen)} cycles, working counters {counts}"


if __name__ == "__main__":
    main()
