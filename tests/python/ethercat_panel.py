"""The live panel of `drive-emu run --ethercat IFACE --panel ADDR`, as SOEM (pysoem) sees what
the panel injects (emulator/tests/ethercat_panel.rs).

Usage: ethercat_panel.py IFACE

One slave in OP, CSP, enabled and holding its position (the set-up of ethercat_faults.py).
Prints one JSON line per event, flushed, while the test injects from the panel:
- `{"op": true, "statusword": W}` once enabled in OP;
- `{"backlash_mm": V}` whenever 0x2000 (REAL32, mm), read over CoE every 250 cycles, changes;
- `{"rx_errors": N, "forwarded": M}` once the slave's RX error counters (0x0300 invalid frames,
  0x0308 forwarded errors, read with FPRD every 250 cycles) are no longer zero; it then clears
  them (a write to 0x0300, as a master's diagnostics does) and prints
  `{"rx_errors_after_clear": N}`;
- `{"al_status": S, "al_status_code": C, "wkc_bad": N}` when the slave has left OP, then exits 0.
Exits non-zero with the reason when OP is not reached, or the slave has not left OP in 120 s.
"""

import json
import struct
import sys
import time

import pysoem

from ethercat_faults import check, setup


def say(**kv):
    print(json.dumps(kv), flush=True)


def main():
    m = pysoem.Master()
    m.open(sys.argv[1])
    try:
        s, cycle, statusword, position, _emcys, _to_op, _enable, expected = setup(m)
        say(op=True, statusword=statusword())
        hold = position()
        last, n, other_run, wkc_bad = None, 0, 0, 0
        cleared = None  # None: counters not seen yet; False: cleared, not read back yet
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            wkc = cycle(0x0F, hold)
            n += 1
            if wkc != expected:
                wkc_bad += 1
            other_run = other_run + 1 if wkc not in (-1, 0, expected) else 0
            if n % 250 == 0 and wkc == expected:
                try:
                    v = round(struct.unpack("<f", s.sdo_read(0x2000, 0))[0], 6)
                except pysoem.SdoError:
                    v = last
                if v != last:
                    say(backlash_mm=v)
                    last = v
                errors = s._fprd(0x0300, 12)
                if len(errors) == 12 and cleared is None and (errors[0] or errors[8]):
                    say(rx_errors=errors[0], forwarded=errors[8])
                    s._fpwr(0x0300, b"\x00")
                    cleared = False
                elif len(errors) == 12 and cleared is False:
                    say(rx_errors_after_clear=errors[0] + errors[8])
                    cleared = True
            if other_run >= 5 or n % 200 == 0:
                m.read_state()
                # 0: the read went unanswered: not a state
                if s.state not in (0, pysoem.OP_STATE):
                    say(al_status=s.state, al_status_code=s.al_status, wkc_bad=wkc_bad)
                    return
        check(False, "the slave never left OP")
    finally:
        m.close()


if __name__ == "__main__":
    main()
