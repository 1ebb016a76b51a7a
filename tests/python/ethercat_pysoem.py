"""An independent EtherCAT master (SOEM through pysoem) against `drive-emu run --ethercat`.

Usage: ethercat_pysoem.py IFACE SLAVES

Checks, and exits non-zero with the reason on the first failure:
- config_init finds SLAVES slaves, each with its SII identity equal to CoE 0x1018;
- CoE SDO read and write (read back), complete access of 0x1C12, the abort of a missing object;
- config_map, SAFE-OP and OP; the working counter SOEM expects in every cycle;
- CiA 402 enable and a CSP move from the process data: 0x6064 in the inputs follows.
Prints one JSON line with what it measured.
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


def u32(b):
    return struct.unpack("<I", b[:4])[0]


def main():
    iface, n_expected = sys.argv[1], int(sys.argv[2])
    m = pysoem.Master()
    m.open(iface)
    try:
        run(m, n_expected)
    finally:
        m.close()


def run(m, n_expected):
    n = 0
    for _ in range(50):
        n = m.config_init()
        if n > 0:
            break
        time.sleep(0.1)
    check(n == n_expected, f"config_init found {n} slaves, expected {n_expected}")
    out = {"slaves": n}
    for k, s in enumerate(m.slaves):
        ident = [u32(s.sdo_read(0x1018, sub)) for sub in (1, 2, 3)]
        check(
            [s.man, s.id, s.rev] == ident,
            f"slave {k}: SII identity {[hex(v) for v in (s.man, s.id, s.rev)]} "
            f"!= CoE 0x1018 {[hex(v) for v in ident]}",
        )
        # SDO write and read back
        s.sdo_write(0x607A, 0, struct.pack("<i", -1234 - k))
        got = struct.unpack("<i", s.sdo_read(0x607A, 0))[0]
        check(got == -1234 - k, f"slave {k}: 0x607A read back {got}")
        # complete access of the PDO assignment
        ca = s.sdo_read(0x1C12, 0, ca=True)
        check(ca[0] == 1 and struct.unpack("<H", ca[2:4])[0] == 0x1601,
              f"slave {k}: 0x1C12 complete access {ca.hex()}")
        # a missing object: the CiA 301 abort code
        try:
            s.sdo_read(0x2FFF, 0)
            fail(f"slave {k}: a read of 0x2FFF did not abort")
        except pysoem.SdoError as e:
            check(e.abort_code == 0x06020000, f"slave {k}: abort 0x{e.abort_code:08X}")
        # CSP
        s.sdo_write(0x6060, 0, struct.pack("<b", 8))
    size = m.config_map()
    check(size == 12 * n, f"process image {size} bytes, expected {12 * n}")
    check(m.state_check(pysoem.SAFEOP_STATE, 500000) == pysoem.SAFEOP_STATE,
          f"SAFE-OP not reached: {[hex(s.al_status) for s in m.slaves]}")
    expected = m.expected_wkc
    check(expected == 3 * n, f"expected working counter {expected}, want {3 * n}")

    period_s = 0.001
    next_t = [time.monotonic()]

    def cycle(cw, targets):
        # a 1 ms cycle, as a master's task runs it
        next_t[0] += period_s
        delay = next_t[0] - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        else:
            next_t[0] = time.monotonic()
        for s, t in zip(m.slaves, targets):
            s.output = struct.pack("<Hi", cw, t)
        m.send_processdata()
        return m.receive_processdata(10000)

    def statuswords():
        return [struct.unpack("<H", s.input[0:2])[0] for s in m.slaves]

    cycle(0, [0] * n)
    m.state = pysoem.OP_STATE
    m.write_state()
    reached = pysoem.NONE_STATE
    for _ in range(200):
        wkc = cycle(0, [0] * n)
        reached = m.state_check(pysoem.OP_STATE, 5000)
        if reached == pysoem.OP_STATE:
            break
    check(reached == pysoem.OP_STATE, f"OP not reached: {[hex(s.state) for s in m.slaves]}")
    wkcs = []
    # CiA 402: shutdown, switch on, enable operation, each until every drive shows its state
    for cw, mask, want in [(0x06, 0x6F, 0x21), (0x07, 0x6F, 0x23), (0x0F, 0x6F, 0x27)]:
        for _ in range(3000):
            wkcs.append(cycle(cw, [0] * n))
            if all(sw & mask == want for sw in statuswords()):
                break
        check(all(sw & mask == want for sw in statuswords()),
              f"controlword 0x{cw:02X}: statuswords {[hex(sw) for sw in statuswords()]}")
    # CSP: ramp to 2000 uu (2 mm) at 2 uu per cycle, then hold
    targets = [0] * n
    def positions():
        return [struct.unpack("<i", s.input[2:6])[0] for s in m.slaves]

    start = positions()
    for step in range(1, 1001):
        targets = [min(2 * step, 2000)] * n
        wkcs.append(cycle(0x0F, targets))
    moving = positions()
    check(all(p > s0 + 500 for p, s0 in zip(moving, start)),
          f"0x6064 does not follow the ramp: {start} -> {moving}")
    # held at the target until every axis has settled (a loaded machine runs fewer drive
    # cycles per master cycle: up to 3 s)
    for _ in range(3000):
        wkcs.append(cycle(0x0F, targets))
        if all(abs(p - 2000) <= 20 for p in positions()):
            break
    pos = positions()
    check(all(abs(p - 2000) <= 20 for p in pos), f"0x6064 from the process data: {pos}")
    bad = [w for w in wkcs if w != expected]
    check(not bad, f"{len(bad)} of {len(wkcs)} cycles with a working counter other than "
          f"{expected}: {bad[:10]}")
    out.update({"cycles": len(wkcs), "expected_wkc": expected, "position_actual": pos})
    m.state = pysoem.INIT_STATE
    m.write_state()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
