"""SOEM (pysoem) against `drive-emu run --ethercat IFACE --esi FILE`: the slave serves the
vendor ESI's identity and PDO map.

Usage: ethercat_esi.py IFACE

Prints one JSON line: the identity config_init read from the SII, the same from CoE 0x1018,
the PDO assignment 0x1C12 / 0x1C13 (complete access), the output and input lengths SOEM
mapped, and the AL state reached after config_map (SAFE-OP when the slave accepts the map).
"""

import json
import struct
import sys
import time

import pysoem


def main():
    iface = sys.argv[1]
    m = pysoem.Master()
    m.open(iface)
    try:
        n = 0
        for _ in range(50):
            n = m.config_init()
            if n > 0:
                break
            time.sleep(0.1)
        if n != 1:
            print(f"FAIL: config_init found {n} slaves, expected 1", file=sys.stderr)
            sys.exit(1)
        s = m.slaves[0]

        def assign(index):
            ca = s.sdo_read(index, 0, ca=True)
            return [struct.unpack("<H", ca[2 + 2 * k:4 + 2 * k])[0] for k in range(ca[0])]

        out = {
            "sii": [s.man, s.id, s.rev],
            "coe": [struct.unpack("<I", s.sdo_read(0x1018, sub)[:4])[0] for sub in (1, 2, 3)],
            "name": s.name,
            "rx_assign": assign(0x1C12),
            "tx_assign": assign(0x1C13),
        }
        size = m.config_map()
        out["image"] = size
        out["outputs"] = len(s.output)
        out["inputs"] = len(s.input)
        out["safe_op"] = m.state_check(pysoem.SAFEOP_STATE, 500000) == pysoem.SAFEOP_STATE
        out["al_status"] = s.al_status
        m.state = pysoem.INIT_STATE
        m.write_state()
        print(json.dumps(out))
    finally:
        m.close()


if __name__ == "__main__":
    main()
