#!/usr/bin/env python3
"""Compare our EDS/DCF parse with python canopen's (an independent reader).

usage: compare_eds.py EDS_FILE OURS_JSON NODE_ID

OURS_JSON is what drive_protocol::od::eds_parse made of the file (written by
protocol/tests/eds_vendors.rs): a list of objects {"index", "code", "compact", "subs": [{"sub",
"data_type", "access", "default"}]} where "default" is the hex of the wire bytes of the
DefaultValue resolved for NODE_ID, or null.

Each (index, sub) of ours must exist in python canopen's object dictionary with the same data
type and access type, and every default python canopen resolves must encode to the same bytes.
The differences python canopen is known to have are counted by class and printed; any other
difference fails (exit 1). Exit 2 when canopen is missing.

Known python canopen 2.4.1 differences (canopen/objectdictionary/eds.py):
- compact-sub0: CompactSubObj's sub 0 is built with access "rw" and no default (ours: ro, N, as Lely).
- default-none: python leaves a default None when int(text, 0) or float(text) fails: hex REAL32
  bits, leading-0 octal, $NODEID forms other than "+"; ours resolves them.
- signed-hex: a hex default above a signed type's maximum stays a large positive number in
  python (its encode fails); ours reads the two's complement pattern.
- dummy-objects: python adds an object 0x0001-0x0007 per DummyUsage=1 type; ours keeps
  DummyUsage as flags (EdsFile::dummy_usage).
A file whose [Comments] python canopen cannot read at all (read_od) is compared as python
canopen reads it without that section.
"""
import json
import sys
from collections import Counter
from pathlib import Path

try:
    import canopen
    from canopen import objectdictionary as odmod
except ImportError as e:  # pragma: no cover
    print(f"python canopen is missing ({e}): pip install -r tests/requirements.txt", file=sys.stderr)
    sys.exit(2)


# python canopen's reading of a file, with the [Comments] fallback: the vendor drive checks
# module (tests/python/od_read.py), one copy
sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "tests" / "python"))
from od_read import read_od  # noqa: E402


def main():
    path, ours_path, node_id = sys.argv[1], sys.argv[2], int(sys.argv[3])
    od = read_od(path, node_id)
    with open(ours_path) as f:
        ours = json.load(f)
    known = Counter()
    errors = []
    our_indices = {o["index"] for o in ours}
    for index in od.keys():
        if not isinstance(index, int):
            continue
        if index not in our_indices:
            if 1 <= index <= 7:
                known["dummy-objects"] += 1
            else:
                errors.append(f"0x{index:04X}: python canopen has it, we do not")
    for o in ours:
        index = o["index"]
        if index not in od:
            errors.append(f"0x{index:04X}: missing in python canopen")
            continue
        pobj = od[index]
        for s in o["subs"]:
            sub = s["sub"]
            where = f"0x{index:04X}sub{sub:X}"
            if isinstance(pobj, odmod.ODVariable):
                if sub != 0:
                    errors.append(f"{where}: python has a VAR")
                    continue
                var = pobj
            else:
                try:
                    var = pobj[sub]  # an ODArray makes subs 2..N from sub 1, as CompactSubObj does
                except KeyError:
                    errors.append(f"{where}: sub-index missing in python canopen")
                    continue
            compact0 = o["compact"] and sub == 0
            if var.data_type != s["data_type"]:
                errors.append(f"{where}: data type python 0x{var.data_type:X}, ours 0x{s['data_type']:X}")
            if var.access_type != s["access"]:
                if compact0 and var.access_type == "rw":
                    known["compact-sub0"] += 1
                    continue
                errors.append(f"{where}: access python {var.access_type}, ours {s['access']}")
            theirs = var.default
            mine = s["default"]
            if theirs is None:
                if mine is None:
                    continue
                if compact0:
                    known["compact-sub0"] += 1
                else:
                    known["default-none"] += 1
                continue
            try:
                raw = var.encode_raw(theirs)
            except Exception:  # struct.error, OverflowError, ...
                if s["data_type"] in (2, 3, 4, 0x10, 0x12, 0x13, 0x14, 0x15) and mine is not None:
                    known["signed-hex"] += 1
                    continue
                errors.append(f"{where}: python default {theirs!r} does not encode")
                continue
            if mine is None and theirs in ("", b""):
                # `DefaultValue=` (empty) on a string or domain: python '' / b'', ours none;
                # both serve an empty value
                known["empty-string"] += 1
            elif mine is None:
                errors.append(f"{where}: python default {theirs!r}, ours none")
            elif raw.hex() != mine:
                errors.append(f"{where}: default python {raw.hex()} ({theirs!r}), ours {mine}")
    n = sum(len(o["subs"]) for o in ours)
    print(f"{path}: {len(ours)} objects, {n} sub-indices compared; known python canopen differences: "
          + (", ".join(f"{k} {v}" for k, v in sorted(known.items())) or "none"))
    if errors:
        print("\n".join(errors), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
