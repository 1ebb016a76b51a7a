#!/usr/bin/env python3
"""python canopen 2.4.1 over python-can's socketcand interface against
`drive-emu run --socketcand ADDR --eds FILE` (issue 33): for each FILE given, the drive
serving it (one drive-emu process per file, this one python process for all):
- every readable object of FILE (from 0x1000) uploads with its type's size (strings and
  domains: any size), no abort;
- the identity 0x1018:1 is the file's;
- load_configuration() writes every ParameterValue of a DCF (nothing refused);
- the RPDO/TPDO maps read back as the file's defaults (or its ParameterValues once loaded).
Prints one JSON line per file: {"file", "uploads", "bad_sizes", "identity_ok",
"configured", "map_mismatches"}; exits non-zero on an exception.

    drive-emu run --socketcand 127.0.0.1:0 --node 5 --eds FILE --ready --json &  # PORT
    python3 vendor_file_check.py --node 5 PORT:FILE [PORT2:FILE2 ...]
"""
import argparse
import json
import struct
import sys

import canopen
from canopen.objectdictionary import ODArray, ODRecord, ODVariable

SIZES = {0x1: 1, 0x2: 1, 0x3: 2, 0x4: 4, 0x5: 1, 0x6: 2, 0x7: 4, 0x8: 4,
         0x11: 8, 0x15: 8, 0x1B: 8, 0x10: 3, 0x12: 3, 0x13: 5, 0x14: 6,
         0x16: 3, 0x18: 5, 0x19: 6, 0x1A: 7}


def variables(od):
    for obj in od.values():
        if isinstance(obj, ODVariable):
            yield obj
        elif isinstance(obj, (ODRecord, ODArray)):
            for v in obj.values():
                yield v


def check(network, node_id, path):
    node = canopen.RemoteNode(node_id, path)
    network.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 5.0
    uploads, bad = 0, []
    for v in variables(node.object_dictionary):
        # below 0x1000: data type definitions (python canopen adds 0x0002-0x0007 for
        # DummyUsage), not objects a device serves
        if v.index < 0x1000 or ("r" not in v.access_type and v.access_type != "const"):
            continue
        try:
            data = node.sdo.upload(v.index, v.subindex)
        except canopen.SdoAbortedError as e:
            bad.append(f"0x{v.index:04X}:{v.subindex} abort 0x{e.code:08X}")
            continue
        uploads += 1
        want = SIZES.get(v.data_type)
        if want is not None and len(data) != want:
            bad.append(f"0x{v.index:04X}:{v.subindex} {len(data)} bytes, type wants {want}")
    ident = node.object_dictionary.get(0x1018)
    identity_ok = True
    if ident is not None and 1 in ident and ident[1].default is not None:
        got = struct.unpack("<I", node.sdo.upload(0x1018, 1))[0]
        identity_ok = got == ident[1].default
    node.nmt.state = "PRE-OPERATIONAL"
    try:
        node.load_configuration()  # raises on the first refused ParameterValue
        configured = True
    except canopen.SdoAbortedError as e:
        configured = f"abort 0x{e.code:08X}"
    mismatches = []
    for base in (0x1600, 0x1A00):
        for n in range(512):
            obj = node.object_dictionary.get(base + n)
            if obj is None:
                continue
            for sub in obj.values():
                if sub.subindex == 0:
                    continue
                want = sub.value if sub.value is not None else sub.default
                if want is None:
                    continue
                got = struct.unpack("<I", node.sdo.upload(sub.index, sub.subindex))[0]
                if got != want:
                    mismatches.append(f"0x{sub.index:04X}:{sub.subindex} 0x{got:08X} != 0x{want:08X}")
    network.nodes.pop(node_id, None)
    return {"file": path, "uploads": uploads, "bad_sizes": bad,
            "identity_ok": identity_ok, "configured": configured, "map_mismatches": mismatches}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--channel", default="can0")
    ap.add_argument("--node", type=int, default=5)
    ap.add_argument("drives", nargs="+", metavar="PORT:FILE")
    a = ap.parse_args()
    for spec in a.drives:
        port, path = spec.split(":", 1)
        network = canopen.Network()
        network.connect(interface="socketcand", host=a.host, port=int(port), channel=a.channel)
        try:
            print(json.dumps(check(network, a.node, path)), flush=True)
        finally:
            network.disconnect()


if __name__ == "__main__":
    sys.exit(main())
