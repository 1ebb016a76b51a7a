#!/usr/bin/env python3
"""Load an EDS with python-canopen and check every object against a JSON list.

usage: check_eds.py EDS_FILE OBJECTS_JSON NODE_ID
The JSON list holds {"index", "sub", "otype", "data_type", "access", "pdo"} per row.
Exit 0 when everything matches, 1 with a list of differences, 2 when canopen is missing.
"""
import json
import sys

try:
    import canopen
    from canopen import objectdictionary as odmod
except ImportError as e:  # pragma: no cover
    print(f"python canopen is missing ({e}): pip install -r tests/requirements.txt", file=sys.stderr)
    sys.exit(2)


def main():
    eds, objs_path, node_id = sys.argv[1], sys.argv[2], int(sys.argv[3])
    od = canopen.import_od(eds, node_id)
    with open(objs_path) as f:
        rows = json.load(f)
    errors = []
    for r in rows:
        index, sub = r["index"], r["sub"]
        where = f"0x{index:04X}sub{sub}"
        if index not in od:
            errors.append(f"{where}: object missing")
            continue
        obj = od[index]
        if r["otype"] == "var":
            if not isinstance(obj, odmod.ODVariable):
                errors.append(f"{where}: expected VAR, got {type(obj).__name__}")
                continue
            var = obj
        else:
            want = odmod.ODArray if r["otype"] == "array" else odmod.ODRecord
            if not isinstance(obj, want):
                errors.append(f"{where}: expected {want.__name__}, got {type(obj).__name__}")
                continue
            if sub not in obj.subindices:
                errors.append(f"{where}: sub-index missing")
                continue
            var = obj.subindices[sub]
        if var.data_type != r["data_type"]:
            errors.append(f"{where}: data type {var.data_type:#x} != {r['data_type']:#x}")
        if var.access_type != r["access"]:
            errors.append(f"{where}: access {var.access_type} != {r['access']}")
        if bool(var.pdo_mappable) != bool(r["pdo"]):
            errors.append(f"{where}: PDO mapping {var.pdo_mappable} != {r['pdo']}")
    # $NODEID defaults resolve
    if od[0x1800][1].default != 0x180 + node_id:
        errors.append(f"0x1800sub1 default {od[0x1800][1].default:#x} != {0x180 + node_id:#x}")
    n_od = sum(1 for i in od.keys() if isinstance(i, int))
    n_json = len({r["index"] for r in rows})
    if n_od != n_json:
        errors.append(f"EDS has {n_od} objects, table has {n_json}")
    if errors:
        print("\n".join(errors), file=sys.stderr)
        return 1
    print(f"{len(rows)} entries of {n_json} objects match")
    return 0


if __name__ == "__main__":
    sys.exit(main())
