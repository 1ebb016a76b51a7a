#!/usr/bin/env python3
"""python canopen (pinned, tests/requirements.txt) against drive-emu serving a vendor's EDS/DCF.

Usage: vendor_drive.py IFACE NODE FILE
Prints READY once connected; start `drive-emu run --eds FILE --node NODE --lockstep
--sync-period-us 10000` after it (the script waits for the boot-up). Then, with python
canopen's own reading of FILE (`canopen.import_od(FILE, NODE)`; a [Comments] section it cannot
read left out, od_read.py), as a master configured from
the vendor's file would:
  1. identity: 0x1000 and 0x1018:1-3 read over SDO equal the file's defaults;
  2. every object of the file is served: a read gives its type's size (write-only ones abort
     0x06010001);
  3. every rw object takes its own default back (0x1010/0x1011 are commands with a
     signature, not values; PDO parameters go through step 4); a motion limit whose file
     default 0 is a placeholder (0x607F, 0x60C5, ...) gets the drive's limit back after;
  4. `RemoteNode.load_configuration()`: the PDOs as the file says (python canopen's
     read(from_od=True) + save(): invalidate, sub 0 = 0, entries, sub 0, validate) and every
     ParameterValue of a DCF (but those its ObjFlags bit 0 says not to download), with no
     abort; the maps read back equal the file's. A PDO
     parameter the file leaves without any value (the Elmo Gold DCFs: 0x1601:0 and 0x1A01:0,
     entries 2..8) is read from the drive first, as a user of python canopen must: canopen
     2.4.1's own PdoMap.read(from_od=True) raises a TypeError on it (`range(1, None + 1)`)
     before any SDO is sent, whatever the device; each one is said (STEP ... taken from the
     drive) and a count so taken must count the entries the file gives. ParameterValues no
     device takes are dropped first and said (STEP ParameterValues not written): 0x1010/0x1011
     (commands) and values python canopen cannot encode in their own type;
  5. BaseNode402 with the file: NMT operational, SYNC every 10 ms, OPERATION ENABLED in a mode
     of the file's 0x6502 the emulator runs (PP, else PV, else CSP), a move seen in 0x6064
     (in 0x606C for a PV drive without 0x6064, SEVCON's Gen4).
Exits non-zero with a message starting with FAIL on the first failure; PASS at the end. No
timing is asserted (user-mode Linux is slow): BaseNode402's timeouts are raised.
"""
import os
import sys
import time
import traceback

import canopen
from canopen.objectdictionary import ODArray, ODRecord, ODVariable
from canopen.sdo.exceptions import SdoAbortedError

from od_read import honour_objflags, read_od

IFACE, NODE, FILE = sys.argv[1], int(sys.argv[2]), sys.argv[3]
SYNC_PERIOD = 0.01
COMMANDS = (0x1010, 0x1011)
# limits whose value 0 allows no motion (protocol/src/od/from_eds.rs PLACEHOLDERS): a file's
# default 0 there is a placeholder the drive serves as the simulated axis's limit
ZERO_STOPS_MOTION = (0x607F, 0x6080, 0x6072, 0x6073, 0x60C5, 0x60C6)
# defaults of a vendor's file the drive refuses to take back, with the abort it gives
# (protocol/tests/eds_node.rs KNOWN_REFUSALS, tests/eds/vendors/SOURCES.md): none now (SEVCON's
# Gen4 as SYNC producer, its EMCY COB-ID 0 and its profile torque mode are taken)
KNOWN_REFUSALS = {}


def fail(msg):
    print(f"FAIL: {msg}", flush=True)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)


def step(msg):
    print(f"STEP {msg}", flush=True)


def variables(od):
    # python canopen adds the data types DummyUsage allows (0x0001-0x0007) as objects; they
    # are type definitions for dummy mapping, not objects of the device
    for obj in od.values():
        if obj.index < 0x1000:
            continue
        if isinstance(obj, ODVariable):
            yield obj
        elif isinstance(obj, (ODRecord, ODArray)):
            for sub in obj.values():
                if isinstance(sub, ODVariable):
                    yield sub


def size(var):
    # data type sizes python canopen knows (struct formats); strings/domains: None
    try:
        return var.STRUCT_TYPES[var.data_type].size
    except (KeyError, AttributeError):
        return None


def main():
    network = canopen.Network()
    network.connect(interface="socketcan", channel=IFACE)
    # steps 1-4 as a plain RemoteNode (what load_configuration belongs to), step 5 BaseNode402
    node = canopen.RemoteNode(NODE, read_od(FILE, NODE))
    network.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 2.0
    od = node.object_dictionary
    print("READY", flush=True)
    node.nmt.wait_for_bootup(60)
    step("boot-up")

    # 1. identity
    for index, sub in ((0x1000, None), (0x1018, 1), (0x1018, 2), (0x1018, 3)):
        if index not in od or (sub is not None and sub not in od[index].subindices):
            # (python canopen makes any sub of an ARRAY from its template: only the file's)
            continue
        var = od[index] if sub is None else od[index][sub]
        if var.default is None:
            continue
        got = node.sdo.upload(index, sub or 0)
        want = var.encode_raw(var.default)
        check(got == want, f"identity 0x{index:04X}:{sub or 0}: {got.hex()} != file {want.hex()}")
    step("identity as the file says")

    # 2. every object is served with its size
    n = 0
    for var in variables(od):
        sub = var.subindex if isinstance(var.parent, (ODRecord, ODArray)) else 0
        where = f"0x{var.index:04X}:{sub} ({var.name})"
        if not var.readable:
            try:
                node.sdo.upload(var.index, sub)
                fail(f"{where}: write-only, yet read")
            except SdoAbortedError as e:
                check(e.code == 0x06010001, f"{where}: abort {e.code:#010x}, want 0x06010001")
            continue
        try:
            data = node.sdo.upload(var.index, sub)
        except SdoAbortedError as e:
            fail(f"{where}: read aborted {e.code:#010x}")
        want = size(var)
        if want is not None:
            check(len(data) == want, f"{where}: {len(data)} bytes, type size {want}")
        n += 1
    step(f"every object served ({n} read)")

    # 3. rw objects take their own default
    n = unencodable = 0
    refused, restored = [], []
    for var in variables(od):
        sub = var.subindex if isinstance(var.parent, (ODRecord, ODArray)) else 0
        if (not var.writable or var.default is None or var.index in COMMANDS
                or 0x1400 <= var.index < 0x1C00 or size(var) is None):
            continue
        try:
            raw = var.encode_raw(var.default)
        except ValueError:
            # python canopen's own reading of the file gives a default its type cannot hold
            # (maxon writes 0xFFFF for an INTEGER16 -1): not a value a python master can send
            unencodable += 1
            continue
        # a limit whose file default 0 is a placeholder (igus's 0x607F and 0x60C5 = 0): the
        # drive serves the axis's limit and takes a written 0 as CiA 402 says (no speed, no
        # acceleration), which would stop the move of step 5; the write is checked, then the
        # limit the drive had is written back
        before = (node.sdo.upload(var.index, sub)
                  if var.index in ZERO_STOPS_MOTION and sub == 0 and var.default == 0
                  and var.readable else None)
        try:
            node.sdo.download(var.index, sub, raw)
            if before is not None and before != raw:
                node.sdo.download(var.index, sub, before)
                restored.append(f"0x{var.index:04X}")
        except SdoAbortedError as e:
            base = os.path.basename(FILE)
            known = next((k for f, k in KNOWN_REFUSALS.items() if base.startswith(f)), {})
            if known.get(var.index) == e.code:
                refused.append(f"0x{var.index:04X}:{sub} {e.code:#010x}")
                continue
            fail(f"0x{var.index:04X}:{sub} ({var.name}): writing its default {var.default!r}: "
                 f"abort {e.code:#010x}")
        n += 1
    step(f"rw objects take their default ({n} written, {unencodable} python cannot encode, "
         f"known refusals: {', '.join(refused) or 'none'}, placeholder limits restored: "
         f"{', '.join(restored) or 'none'})")

    # 4. load_configuration: PDOs as the file says, a DCF's ParameterValues. python canopen
    # 2.4.1 cannot read a PDO parameter without any value in the file (PdoMap.read(from_od=
    # True): `range(1, None + 1)`, a TypeError before any SDO): what a user does, read it
    # from the device and give it to the dictionary; then check the device's count counts
    # the entries the file gives (a device ships its map with those)
    from_drive = []
    for obj in od.values():
        if not (0x1400 <= obj.index < 0x1C00) or not isinstance(obj, (ODRecord, ODArray)):
            continue
        for sub in obj.values():
            if sub.value is None and sub.default is None and sub.readable:
                sub.default = int.from_bytes(node.sdo.upload(sub.index, sub.subindex), "little")
                from_drive.append(f"0x{sub.index:04X}:{sub.subindex} = {sub.default}")
                if sub.subindex == 0 and (0x1600 <= obj.index < 0x1800
                                          or 0x1A00 <= obj.index < 0x1C00):
                    given = 0
                    while given + 1 in obj.subindices:
                        e = obj[given + 1]
                        v = e.value if e.value is not None else e.default
                        if not v:
                            break
                        given += 1
                    check(sub.default == given,
                          f"0x{obj.index:04X}:0 = {sub.default} from the drive, the file "
                          f"gives {given} entries")
    if from_drive:
        step(f"PDO parameters without a value in the file taken from the drive "
             f"(python canopen cannot read them): {', '.join(from_drive)}")
    # values the file marks not to be downloaded (CiA 306 ObjFlags bit 0; maxon's EPOS4 DCFs:
    # 0x1003:0, 0x1010:1, 0x6040...) left out, as a master that reads ObjFlags does; python
    # canopen 2.4.1 reads none and would write them (od_read.py)
    kept_back = honour_objflags(od, FILE)
    if kept_back:
        step(f"{len(kept_back)} values with ObjFlags bit 0 not downloaded")
    # 0x1010/0x1011 are commands: a DCF's ParameterValue there is what a read returned (the
    # storage the device offers, 1), and written back it is a wrong signature, which CiA 301
    # has a device refuse (0x08000020; SEVCON's Gen4 DCF has them): a user drops them
    dropped = []
    for index in COMMANDS:
        for sub in getattr(od.get(index), "values", lambda: [])():
            if sub.value is not None and sub.subindex > 0:
                dropped.append(f"0x{index:04X}:{sub.subindex} = {sub.value}")
                sub.value = None
    # a ParameterValue python canopen's own reading cannot encode in its type (the Gen4 DCF's
    # INTEGER16 0x8001 read as 32769): encode_raw raises ValueError before any SDO, against
    # any device; a user drops it
    for var in variables(od):
        if var.value is not None and not 0x1400 <= var.index < 0x1C00:
            try:
                var.encode_raw(var.value)
            except (ValueError, TypeError):
                dropped.append(f"0x{var.index:04X}:{var.subindex} = {var.value!r} (unencodable)")
                var.value = None
    if dropped:
        step(f"ParameterValues not written: {', '.join(dropped)}")
    try:
        node.load_configuration()
    except SdoAbortedError as e:
        fail(f"load_configuration: abort {e}")
    def mappable_by_python(record):
        # python canopen skips an entry whose object the file lacks (it cannot size it): such
        # a map is not the file's any more after save(), whatever the drive does
        for sub in record.values():
            if sub.subindex == 0 or sub.default is None:
                continue
            index, subindex = sub.default >> 16, (sub.default >> 8) & 0xFF
            if sub.default and (index not in od or (subindex and subindex not in getattr(
                    od[index], "subindices", {subindex: None}))):
                return False
        return True

    maps = 0
    for obj in od.values():
        if not (0x1600 <= obj.index < 0x1800 or 0x1A00 <= obj.index < 0x1C00):
            continue
        if not mappable_by_python(obj):
            continue
        count = obj.subindices.get(0)
        count = None if count is None else (
            count.value if count.value is not None else count.default)
        for var in obj.values():
            # what load_configuration wrote: a DCF's ParameterValue, else the default; entries
            # past the count it gives are not written (maxon's EPOS4 DCFs: TPDO4 with 0
            # entries, whose sub 1 and 2 keep what the device had) and mean nothing
            want = var.value if var.value is not None else var.default
            if want is None or (count is not None and var.subindex > count):
                continue
            got = node.sdo.upload(var.index, var.subindex)
            check(got == var.encode_raw(want),
                  f"map 0x{var.index:04X}:{var.subindex}: {got.hex()} != file's {want:#x}")
        maps += 1
    check(maps >= 2, f"{maps} mapping records compared")
    step("load_configuration, maps read back as the file says")

    # 5. BaseNode402 moves the axis
    del network[NODE]
    node = canopen.BaseNode402(NODE, read_od(FILE, NODE))
    network.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 2.0
    modes = node.sdo.upload(0x6502, 0)
    mask = int.from_bytes(modes, "little")
    mode = next((m for m, bit in (("PROFILED POSITION", 0), ("PROFILED VELOCITY", 2),
                                  ("CYCLIC SYNCHRONOUS POSITION", 7)) if mask & (1 << bit)), None)
    check(mode is not None, f"0x6502 = {mask:#x} lists none of PP, PV, CSP")
    network.sync.start(SYNC_PERIOD)
    node.setup_402_state_machine(read_pdos=False)
    node.nmt.state = "OPERATIONAL"
    node.TIMEOUT_SWITCH_OP_MODE = 5.0
    node.TIMEOUT_SWITCH_STATE_FINAL = 10.0
    node.TIMEOUT_SWITCH_STATE_SINGLE = 5.0
    node.op_mode = mode
    got_mode = int.from_bytes(node.sdo.upload(0x6061, 0), "little", signed=True)
    check(got_mode == {"PROFILED POSITION": 1, "PROFILED VELOCITY": 3,
                       "CYCLIC SYNCHRONOUS POSITION": 8}[mode], f"0x6061 = {got_mode} for {mode}")
    node.state = "OPERATION ENABLED"
    step(f"OPERATION ENABLED in {mode}")

    def pos():
        return int.from_bytes(node.sdo.upload(0x6064, 0), "little", signed=True)

    # a drive without a position (SEVCON's Gen4 has no 0x6064) shows its PV move in 0x606C
    if 0x6064 not in od:
        check(mode == "PROFILED VELOCITY", f"no 0x6064 to see a {mode} move in")
        put_v = od[0x60FF]
        node.sdo.download(0x60FF, 0, put_v.encode_raw(1000))

        def vel():
            return int.from_bytes(node.sdo.upload(0x606C, 0), "little", signed=True)

        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and vel() < 500:
            time.sleep(0.1)
        v = vel()
        check(v >= 500, f"{mode}: 0x606C = {v} for 0x60FF = 1000")
        step(f"moved: 0x606C = {v} uu/s in {mode} (no 0x6064)")
        network.sync.stop()
        network.disconnect()
        print("PASS", flush=True)
        return

    p0 = pos()

    def put(index, value, signed=False):
        if index in od:
            var = od[index]
            node.sdo.download(index, 0, var.encode_raw(value))

    if mode == "PROFILED POSITION":
        for index, value in ((0x6081, 2000), (0x6083, 20000), (0x6084, 20000)):
            var = od.get(index)
            if var is not None and var.max is not None:
                value = min(value, var.max)
            put(index, value)
        put(0x607A, p0 + 500)
        node.controlword = 0x0F
        node.controlword = 0x1F
    elif mode == "PROFILED VELOCITY":
        put(0x6083, 20000)
        put(0x60FF, 1000)
    else:
        for k in range(1, 300):
            put(0x607A, p0 + k)
            time.sleep(SYNC_PERIOD)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and abs(pos() - p0) < 100:
        time.sleep(0.1)
    moved = pos() - p0
    check(abs(moved) >= 100, f"{mode}: 0x6064 moved {moved} uu")
    step(f"moved {moved} uu in {mode}")
    network.sync.stop()
    network.disconnect()
    print("PASS", flush=True)


if __name__ == "__main__":
    try:
        main()
    except SystemExit:
        raise
    except Exception:  # noqa: BLE001 - report any failure as FAIL with its trace
        traceback.print_exc()
        fail("exception")
