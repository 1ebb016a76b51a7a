#!/usr/bin/env python3
"""python canopen 2.4.1 over python-can's socketcand interface against
`drive-emu run --socketcand ADDR --eds FILE` (issue 33): for each FILE given, the drive
serving it (one drive-emu process per file, this one python process for all):
- every readable object of FILE (from 0x1000) uploads with its type's size (strings and
  domains: any size), no abort;
- the identity 0x1018:1 is the file's;
- load_configuration() writes every ParameterValue of a DCF (nothing refused);
- the RPDO/TPDO maps read back as the file's defaults (or its ParameterValues once loaded);
- BaseNode402 enables the drive in profile position (where 0x6502 offers it) and a move of a
  quarter motor revolution in the file's units ends with bit 10 set within the position
  window ("pp": "reached" / "not reached" / "not offered").
Prints one JSON line per file: {"file", "uploads", "bad_sizes", "identity_ok",
"configured", "map_mismatches", "pp", ...}; exits non-zero on an exception.

    drive-emu run --socketcand 127.0.0.1:0 --node 5 --eds FILE --ready --json &  # PORT
    python3 vendor_file_check.py --node 5 PORT:FILE [PORT2:FILE2 ...]
"""
import argparse
import json
import struct
import sys
import time

import canopen
import logging
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
    out = {"file": path, "uploads": uploads, "bad_sizes": bad,
           "identity_ok": identity_ok, "configured": configured, "map_mismatches": mismatches}
    out.update(pp_move(network, node_id, path))
    return out


def sdo_u32(node, index, sub):
    return int.from_bytes(node.sdo.upload(index, sub)[:4].ljust(4, b"\0"), "little")


def pp_move(network, node_id, path):
    """BaseNode402 in profile position (where the drive offers it, 0x6502 as served): as a
    master does, its own profile (0x6081/0x6083/0x6084 within the file's limits), then a move
    of a quarter motor revolution in the file's own units (its factor group as served);
    reached = bit 10 set after the set-point was taken, within the position window."""
    node = canopen.BaseNode402(node_id, path)
    network.add_node(node)
    od = node.object_dictionary
    need = [0x6040, 0x6041, 0x6060, 0x6061, 0x6064, 0x607A, 0x6081]
    if any(od.get(i) is None for i in need) or od.get(0x6502) is None:
        network.nodes.pop(node_id, None)
        return {"pp": "not offered"}
    node.sdo.RESPONSE_TIMEOUT = 5.0
    if not sdo_u32(node, 0x6502, 0) & 1:
        network.nodes.pop(node_id, None)
        return {"pp": "not offered"}
    # a quarter motor revolution in user units, from the factor group as served
    def served(index, sub, fallback):
        return sdo_u32(node, index, sub) if od.get(index) is not None else fallback
    enc, enc_r = served(0x608F, 1, 0), served(0x608F, 2, 1)
    gm, gs = served(0x6091, 1, 1), served(0x6091, 2, 1)
    feed, feed_r = served(0x6092, 1, 0), served(0x6092, 2, 1)
    if enc and feed and enc_r and gm and gs and feed_r:
        uu_per_motor_rev = (feed / feed_r) / (gm / gs)
    else:
        uu_per_motor_rev = 4000
    delta = max(10, int(uu_per_motor_rev / 4))
    node.setup_402_state_machine(read_pdos=False)
    node.nmt.state = "OPERATIONAL"
    node.state = "SWITCH ON DISABLED"
    node.op_mode = "PROFILED POSITION"
    node.state = "OPERATION ENABLED"
    for index, want in ((0x6081, delta * 4), (0x6083, delta * 40), (0x6084, delta * 40)):
        var = od.get(index)
        if var is None or "w" not in var.access_type:
            continue
        if var.max is not None:
            want = min(want, var.max)
        node.sdo.download(index, 0, struct.pack("<I", want))
    # the position window as served; where the file has none (or 0xFFFFFFFF, off), a tenth
    # of the move
    window = served(0x6067, 0, 0xFFFFFFFF)
    if window == 0xFFFFFFFF:
        window = delta // 10
    start = struct.unpack("<i", node.sdo.upload(0x6064, 0))[0]
    target = start + delta
    node.sdo.download(0x607A, 0, struct.pack("<i", target))
    node.controlword = 0x1F
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and not sdo_u32(node, 0x6041, 0) & (1 << 12):
        time.sleep(0.01)
    node.controlword = 0x0F
    reached = False
    while time.monotonic() < deadline:
        sw = sdo_u32(node, 0x6041, 0)
        if sw & (1 << 10):
            reached = True
            break
        time.sleep(0.02)
    end = struct.unpack("<i", node.sdo.upload(0x6064, 0))[0]
    inside = abs(end - target) <= window
    node.nmt.state = "PRE-OPERATIONAL"
    network.nodes.pop(node_id, None)
    return {"pp": "reached" if reached and inside else "not reached", "pp_start": start,
            "pp_target": target, "pp_end": end, "pp_window": window}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--channel", default="can0")
    ap.add_argument("--node", type=int, default=5)
    ap.add_argument("drives", nargs="+", metavar="PORT:FILE")
    a = ap.parse_args()
    # BaseNode402 warns at every SDO fallback (the files map no statusword TPDO by default)
    logging.getLogger("canopen").setLevel(logging.ERROR)
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
