#!/usr/bin/env python3
"""python canopen 2.4.1 over python-can's socketcand interface against
`drive-emu run --socketcand ADDR --eds FILE` (issue 33): for each FILE given, the drive
serving it (one drive-emu process per file, this one python process for all):
- every readable object of FILE (from 0x1000) uploads with its type's size (strings and
  domains: any size), no abort;
- the identity 0x1018:1 is the file's;
- load_configuration() writes every ParameterValue of a DCF (nothing refused) but those its
  ObjFlags bit 0 says not to download (CiA 306) and those no device takes, dropped first as a
  user must: 0x1010/0x1011 (commands) and values python canopen cannot encode in their own type;
- the RPDO/TPDO maps read back as the file's defaults (or its ParameterValues once loaded),
  over the entries in use (1..count);
- where the file offers LSS (the drive started non-configured, --node 255): LssMaster's
  fast_scan() finds the drive by the file's identity, configure_node_id() gives it the node-ID
  and it boots there ("lss": "fastscan" / "not offered" / what failed);
- BaseNode402 enables the drive in profile position (where 0x6502 offers it) and a move of one
  motor revolution at one revolution per second in the file's units (where a revolution is
  fewer than 30 user units, as the Nanotec N5 files' 1 uu = 1 revolution: two seconds at as
  many revolutions per second as make 30 uu/s) (its factor group, and
  its SI unit velocity 0x60A9 where that names revolutions per time or 0x60A8's unit per time)
  ends with bit 10 set within the position window ("pp": "reached" / "not reached" / "not
  offered"), its speed 0x606C peaking within 20 % of the speed asked ("pp_speed_ok"; the
  speed is measured from positions, or, where no factor group is served and 0x60A9 says
  revolutions per time (maxon's EPOS4 files), read as 0x606C);
- where 0x6502 offers no PP but profile velocity (SEVCON's Gen4): BaseNode402 enables the
  drive in PV at one motor revolution per second (4000 uu/s without a factor group) and
  0x606C comes within 20 % of it ("pv": "ran" / "failed" / "not offered");
- where 0x6502 offers cyclic synchronous velocity: a CSV move at one revolution per second
  runs at that speed (0x606C within 20 %) and the position advances ("csv": "ran" / "not
  offered" / what failed).
Prints one JSON line per file: {"file", "uploads", "bad_sizes", "identity_ok",
"configured", "map_mismatches", "lss", "pp", "csv", ...}; exits non-zero on an exception.

    drive-emu run --socketcand 127.0.0.1:0 --node 5 --eds FILE --ready --json &  # PORT
    python3 vendor_file_check.py --node 5 PORT:FILE [PORT2:FILE2 ...]
    # a file with LSS_Supported=1, its drive started with --node 255: PORT:FILE:lss
"""
import argparse
import json
import math
import struct
import sys
import threading
import time

import canopen
import logging
from canopen import lss
from canopen.objectdictionary import ODArray, ODRecord, ODVariable

from od_read import honour_objflags, read_od

FACTOR_GROUP = ((0x608F, 1), (0x608F, 2), (0x6091, 1), (0x6091, 2), (0x6092, 1), (0x6092, 2))
# the least speed in position user units per second of the PP and CSV moves, so that the
# speed shows in whole user units where one is a motor revolution (the Nanotec N5 files)
COARSE_UU_PER_S = 30
# increments per motor revolution below which 0x608F is a placeholder (the drive runs with its
# encoder's count: protocol/src/od/placeholders.rs)
MIN_INCREMENTS_PER_REV = 4

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
    node = canopen.RemoteNode(node_id, read_od(path, node_id))
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
    # PDO parameters without a value in the file (the Elmo Gold DCFs leave some maps'
    # counts and entries empty): python canopen's pdo.read(from_od=True) cannot read them (a
    # TypeError); the master takes the drive's values there, as a configuration tool that
    # reads the device does (the map check below compares only what the file gives)
    sub0_from_drive = []
    od = node.object_dictionary
    for base in (0x1400, 0x1600, 0x1800, 0x1A00):
        for n in range(512):
            obj = od.get(base + n)
            if not isinstance(obj, (ODRecord, ODArray)):
                continue
            for sub in obj.values():
                if sub.value is None and sub.default is None and "r" in sub.access_type:
                    raw = node.sdo.upload(sub.index, sub.subindex)
                    sub.default = int.from_bytes(raw, "little")
                    sub0_from_drive.append(f"0x{sub.index:04X}:{sub.subindex}")
    # the factor group as the drive serves it before the DCF's ParameterValues: a DCF that
    # writes a placeholder encoder resolution back (Elmo's Whistle Gold: 0x608F:1 = 1,
    # 0x6092:1 = 1) leaves the drive running with its own encoder's count (the placeholder
    # rule), which a master of that drive knows; the move below takes it from here then
    factor_before = {}
    for index, sub in FACTOR_GROUP:
        obj = od.get(index)
        if obj is not None and sub in getattr(obj, "subindices", {}):
            factor_before[(index, sub)] = sdo_u32(node, index, sub)
    # values the file marks not to be downloaded (CiA 306 ObjFlags bit 0) left out, as a
    # master that reads ObjFlags does (python canopen 2.4.1 reads none: od_read.py)
    honour_objflags(od, path)
    # 0x1010/0x1011 are commands: a DCF's ParameterValue there is what a read returned (1,
    # the storage offered); written back it is a wrong signature, refused 0x08000020 by CiA
    # 301 (SEVCON's Gen4 DCF has them): dropped, as a user must
    for index in (0x1010, 0x1011):
        for sub in getattr(od.get(index), "values", lambda: [])():
            if sub.subindex > 0:
                sub.value = None
    # a ParameterValue python canopen cannot encode in its own type (the Gen4 DCF's INTEGER16
    # 0x8001 read as 32769) raises ValueError before any SDO, against any device: dropped
    for var in variables(od):
        if var.value is not None and not 0x1400 <= var.index < 0x1C00:
            try:
                var.encode_raw(var.value)
            except (ValueError, TypeError):
                var.value = None
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
            count = obj.subindices.get(0)
            count = None if count is None else (
                count.value if count.value is not None else count.default)
            for sub in obj.values():
                if sub.subindex == 0:
                    continue
                # entries past the count the file gives are not written (maxon's EPOS4 DCFs:
                # TPDO4 with 0 entries) and mean nothing
                want = sub.value if sub.value is not None else sub.default
                if want is None or (count is not None and sub.subindex > count):
                    continue
                got = struct.unpack("<I", node.sdo.upload(sub.index, sub.subindex))[0]
                if got != want:
                    mismatches.append(f"0x{sub.index:04X}:{sub.subindex} 0x{got:08X} != 0x{want:08X}")
    network.nodes.pop(node_id, None)
    out = {"file": path, "uploads": uploads, "bad_sizes": bad,
           "identity_ok": identity_ok, "configured": configured, "map_mismatches": mismatches,
           "sub0_from_drive": sub0_from_drive}
    out.update(pp_move(network, node_id, path, factor_before))
    return out


def connect(a, port):
    network = canopen.Network()
    network.connect(interface="socketcand", host=a.host, port=int(port), channel=a.channel)
    return network


def lss_fastscan(network, node_id, path):
    """The drive, non-configured (--node 255), found by fast_scan() with the file's identity,
    given `node_id` by LSS, and booted there."""
    od = read_od(path, node_id)
    ident = od.get(0x1018)
    lss.LssMaster.RESPONSE_TIMEOUT = 1.5
    found, lss_id = network.lss.fast_scan()
    if not found:
        return "fast_scan() found nobody"
    for sub, got in zip((1, 2, 3), lss_id[:3]):
        want = ident[sub].default if ident is not None and sub in ident else None
        if want is not None and got != want:
            return f"fast_scan() found 0x1018:{sub} = 0x{got:08X}, the file says 0x{want:08X}"
    network.lss.configure_node_id(node_id)
    booted = []
    network.subscribe(0x700 + node_id, lambda can_id, data, ts: booted.append(bytes(data)))
    network.lss.send_switch_state_global(network.lss.WAITING_STATE)
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline and b"\x00" not in booted:
        time.sleep(0.02)
    network.unsubscribe(0x700 + node_id)
    return "fastscan" if b"\x00" in booted else "no boot-up after configure_node_id"


def velocity_in_revolutions(node, od):
    """The SI unit velocity 0x60A9 names revolutions per time (0xB4 per s, min or h): a
    velocity then says revolutions whatever a position user unit is."""
    if od.get(0x60A9) is None:
        return False
    v = sdo_u32(node, 0x60A9, 0)
    return (v >> 16) & 0xFF == 0xB4 and (v >> 8) & 0xFF in (0x03, 0x47, 0x48)


def fastest_mean(samples, span_s):
    """The highest mean of (time, value) samples over `span_s` seconds."""
    best = 0.0
    for i, (t0, _) in enumerate(samples):
        window = [v for t, v in samples[i:] if t - t0 < span_s]
        if samples[-1][0] - t0 < span_s:
            break
        best = max(best, sum(window) / len(window))
    return best


def velocity_per_rev_per_s(node, od, inc_per_rev, uu_per_rev):
    """Velocity user units of one motor revolution per second as the drive serves them: the
    SI unit velocity 0x60A9 where it names revolutions per time (0xB4) or 0x60A8's unit per
    time, else position user units per second."""
    times = {0x03: 1.0, 0x47: 60.0, 0x48: 3600.0}
    if od.get(0x60A9) is None:
        return uu_per_rev
    v = sdo_u32(node, 0x60A9, 0)
    prefix, unit, per = struct.unpack("b", bytes([v >> 24]))[0], (v >> 16) & 0xFF, (v >> 8) & 0xFF
    if per not in times:
        return uu_per_rev
    if unit == 0xB4:  # revolutions (of the shaft: the factor group's gear as served)
        gm = sdo_u32(node, 0x6091, 1) if od.get(0x6091) is not None else 1
        gs = sdo_u32(node, 0x6091, 2) if od.get(0x6091) is not None else 1
        return times[per] / (gm / gs) / 10.0 ** prefix
    if od.get(0x60A8) is not None:
        p = sdo_u32(node, 0x60A8, 0)
        if (p >> 16) & 0xFF == unit and (p >> 8) & 0xFF == 0:
            p_prefix = struct.unpack("b", bytes([p >> 24]))[0]
            return uu_per_rev * times[per] * 10.0 ** (p_prefix - prefix)
    return uu_per_rev


def sdo_u32(node, index, sub):
    return int.from_bytes(node.sdo.upload(index, sub)[:4].ljust(4, b"\0"), "little")


def pp_move(network, node_id, path, factor_before=None):
    """BaseNode402 in profile position (where the drive offers it, 0x6502 as served): as a
    master does, its own profile (0x6081/0x6083/0x6084 within the file's limits), then a move
    of one motor revolution in the file's own units (its factor group as served);
    reached = bit 10 set after the set-point was taken, within the position window."""
    node = canopen.BaseNode402(node_id, read_od(path, node_id))
    network.add_node(node)
    od = node.object_dictionary
    need = [0x6040, 0x6041, 0x6060, 0x6061, 0x6064, 0x607A, 0x6081]
    node.sdo.RESPONSE_TIMEOUT = 5.0
    if (any(od.get(i) is None for i in need) or od.get(0x6502) is None
            or not sdo_u32(node, 0x6502, 0) & 1):
        out = {"pp": "not offered"}
        out.update(pv_move(node, od))
        network.nodes.pop(node_id, None)
        return out
    # one motor revolution in user units, from the factor group as served
    def served(index, sub, fallback):
        return sdo_u32(node, index, sub) if od.get(index) is not None else fallback
    factor = served
    if od.get(0x608F) is not None and factor_before:
        e, r = served(0x608F, 1, 0), served(0x608F, 2, 1)
        if e and r and e < MIN_INCREMENTS_PER_REV * r:
            # a placeholder written back: the drive runs as before the write
            def factor(index, sub, fallback):
                return factor_before.get((index, sub), fallback)
    enc, enc_r = factor(0x608F, 1, 0), factor(0x608F, 2, 1)
    gm, gs = factor(0x6091, 1, 1), factor(0x6091, 2, 1)
    feed, feed_r = factor(0x6092, 1, 0), factor(0x6092, 2, 1)
    factor_known = bool(enc and feed and enc_r and gm and gs and feed_r)
    if factor_known:
        uu_per_motor_rev = (feed / feed_r) / (gm / gs)
    else:
        uu_per_motor_rev = 4000
    # no factor group served (maxon's EPOS4 files) while velocities are in revolutions per
    # time (0x60A9 rev/min): the master cannot tell a revolution in position user units, so
    # a speed is not computed from positions but read as the drive's 0x606C, in that unit
    by_606c = (not factor_known and od.get(0x606C) is not None
               and velocity_in_revolutions(node, od))
    # the move a user of that drive asks: one motor revolution at one revolution per second
    # where a revolution is many user units; where it is few (the Nanotec N5 files: 1 uu = one
    # revolution), as many revolutions per second as make 30 uu/s, for two seconds, so that
    # the speed is seen in whole user units (measured over 1 s: 30 +- 1 uu)
    revs_per_s = max(1, math.ceil(COARSE_UU_PER_S / uu_per_motor_rev))
    move_s, span_s = (1, 0.3) if revs_per_s == 1 else (2, 1.0)
    delta = max(10, int(uu_per_motor_rev * revs_per_s * move_s))
    # revs_per_s motor revolutions per second, ten times that per second squared, in the
    # velocity unit served
    vel = velocity_per_rev_per_s(node, od, enc, uu_per_motor_rev) * revs_per_s
    node.setup_402_state_machine(read_pdos=False)
    node.nmt.state = "OPERATIONAL"
    node.state = "SWITCH ON DISABLED"
    node.op_mode = "PROFILED POSITION"
    node.state = "OPERATION ENABLED"
    asked = None
    for index, want in ((0x6081, round(vel)), (0x6083, round(vel * 10)), (0x6084, round(vel * 10))):
        var = od.get(index)
        if var is None or "w" not in var.access_type:
            continue
        if var.max is not None:
            want = min(want, var.max)
        node.sdo.download(index, 0, struct.pack("<I", want))
        if index == 0x6081:
            asked = want
    if asked is not None and od.get(0x607F) is not None:
        asked = min(asked, sdo_u32(node, 0x607F, 0))
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
    track, velocities = [], []
    while time.monotonic() < deadline:
        sw = sdo_u32(node, 0x6041, 0)
        if sw & (1 << 10):
            reached = True
            break
        track.append((time.monotonic(), struct.unpack("<i", node.sdo.upload(0x6064, 0))[0]))
        if by_606c:
            velocities.append((time.monotonic(), struct.unpack(
                "<i", node.sdo.upload(0x606C, 0)[:4].ljust(4, b"\0"))[0]))
    # the speed it moved at, in the velocity unit: the position's fastest 0.3 s (the cruise
    # lasts 0.9 s; 0x606C of a coarse encoder jitters by an increment per sample); without
    # a factor group, 0x606C's fastest 0.15 s (the cruise of a 4000 uu move may be short)
    if by_606c:
        speed = round(fastest_mean(velocities, 0.15)) if len(velocities) > 2 else 0
    else:
        speed = round(fastest(track, span_s) * vel / (uu_per_motor_rev * revs_per_s))
    measure = len(track) > 2
    end = struct.unpack("<i", node.sdo.upload(0x6064, 0))[0]
    inside = abs(end - target) <= window
    out = {"pp": "reached" if reached and inside else "not reached", "pp_start": start,
           "pp_target": target, "pp_end": end, "pp_window": window,
           "pp_speed_asked": asked, "pp_speed": speed if measure else None,
           "pp_speed_ok": (None if not measure or not asked
                           else 0.8 * asked <= speed <= 1.2 * asked)}
    out.update(csv_move(node, od, vel, uu_per_motor_rev * revs_per_s, by_606c))
    node.nmt.state = "PRE-OPERATIONAL"
    network.nodes.pop(node_id, None)
    return out


def pv_move(node, od):
    """Profile velocity, where the drive offers no PP but PV (0x6502 bit 2; SEVCON's Gen4, a
    traction controller with PV and torque only): BaseNode402 enables it in PV and asks a
    velocity in the file's units (one motor revolution per second where the factor group says
    what one is, else 4000 uu/s); 0x606C, averaged over 0.4 s once it first comes within
    20 % (the ramp), within 20 % of it ("pv": "ran" / "failed" / "not offered")."""
    need = [0x6040, 0x6041, 0x6060, 0x6061, 0x606C, 0x60FF, 0x6502]
    if any(od.get(i) is None for i in need) or not sdo_u32(node, 0x6502, 0) & (1 << 2):
        return {"pv": "not offered"}
    enc, feed = (sdo_u32(node, i, 1) if od.get(i) is not None else 0 for i in (0x608F, 0x6092))
    uu_per_rev = 4000
    if enc and feed and od.get(0x6091) is not None:
        gm, gs = sdo_u32(node, 0x6091, 1), sdo_u32(node, 0x6091, 2)
        feed_r = sdo_u32(node, 0x6092, 2)
        if gm and gs and feed_r:
            uu_per_rev = (feed / feed_r) / (gm / gs)
    want = max(1, round(velocity_per_rev_per_s(node, od, enc, uu_per_rev)))
    node.setup_402_state_machine(read_pdos=False)
    node.nmt.state = "OPERATIONAL"
    node.state = "SWITCH ON DISABLED"
    node.op_mode = "PROFILED VELOCITY"
    node.state = "OPERATION ENABLED"
    var = od.get(0x6083)
    if var is not None and "w" in var.access_type:
        node.sdo.download(0x6083, 0, struct.pack("<I", min(want * 10, var.max or want * 10)))
    node.sdo.download(0x60FF, 0, struct.pack("<i", want))

    def actual():
        return struct.unpack("<i", node.sdo.upload(0x606C, 0)[:4].ljust(4, b"\0"))[0]
    # the ramp: until 0x606C first comes within 20 % (10 s at most), then 0.4 s of samples
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline and not 0.8 * want <= actual() <= 1.2 * want:
        pass
    samples = []
    deadline = time.monotonic() + 0.4
    while time.monotonic() < deadline:
        samples.append(actual())
    node.sdo.download(0x60FF, 0, struct.pack("<i", 0))
    node.nmt.state = "PRE-OPERATIONAL"
    speed = round(sum(samples) / len(samples)) if samples else 0
    ok = 0.8 * want <= speed <= 1.2 * want
    return {"pv": "ran" if ok else "failed", "pv_speed_asked": want, "pv_speed": speed}


def fastest(track, span_s):
    """The highest mean speed over `span_s` seconds of (time, position) samples."""
    best, j = 0.0, 0
    for i, (t0, p0) in enumerate(track):
        while j < len(track) and track[j][0] - t0 < span_s:
            j += 1
        if j == len(track):
            break
        t1, p1 = track[j]
        best = max(best, (p1 - p0) / (t1 - t0))
    return best


def csv_move(node, od, vel, uu_per_rev, by_606c=False):
    """Cyclic synchronous velocity (where 0x6502 offers it, bit 8): 0x60FF = `vel` (the PP
    move's speed: `uu_per_rev` position user units per second) for 0.8 s; the speed over the
    last 0.4 s within 20 % and the position advanced. `by_606c`: the speed is the mean of
    0x606C over the last 0.4 s (no factor group: positions say no revolutions)."""
    if od.get(0x60FF) is None or od.get(0x606C) is None or not sdo_u32(node, 0x6502, 0) & (1 << 8):
        return {"csv": "not offered"}
    want = round(vel)
    if od.get(0x607F) is not None:
        want = min(want, sdo_u32(node, 0x607F, 0))
    node.op_mode = "CYCLIC SYNCHRONOUS VELOCITY"
    start = struct.unpack("<i", node.sdo.upload(0x6064, 0))[0]
    node.sdo.download(0x60FF, 0, struct.pack("<i", want))
    track, velocities = [], []
    deadline = time.monotonic() + 0.8
    while time.monotonic() < deadline:
        track.append((time.monotonic(), struct.unpack("<i", node.sdo.upload(0x6064, 0))[0]))
        if by_606c:
            velocities.append((time.monotonic(), struct.unpack(
                "<i", node.sdo.upload(0x606C, 0)[:4].ljust(4, b"\0"))[0]))
    node.sdo.download(0x60FF, 0, struct.pack("<i", 0))
    end = struct.unpack("<i", node.sdo.upload(0x6064, 0))[0]
    # the mean speed over the last half, in the velocity unit
    half = [x for x in track if x[0] >= track[0][0] + 0.4]
    speed = 0
    if by_606c:
        late = [v for t, v in velocities if t >= track[0][0] + 0.4]
        speed = round(sum(late) / len(late)) if late else 0
    elif len(half) > 1:
        (t0, p0), (t1, p1) = half[0], half[-1]
        speed = round((p1 - p0) / (t1 - t0) * vel / uu_per_rev)
    ok = 0.8 * want <= speed <= 1.2 * want and end > start
    return {"csv": "ran" if ok else "failed", "csv_speed_asked": want,
            "csv_speed": speed, "csv_moved": end - start}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--channel", default="can0")
    ap.add_argument("--node", type=int, default=5)
    ap.add_argument("drives", nargs="+", metavar="PORT:FILE")
    a = ap.parse_args()
    # BaseNode402 warns at every SDO fallback (the files map no statusword TPDO by default)
    logging.getLogger("canopen").setLevel(logging.ERROR)
    specs = []
    for spec in a.drives:
        port, path = spec.split(":", 1)
        with_lss = path.endswith(":lss")
        specs.append((port, path[: -len(":lss")] if with_lss else path, with_lss))
    # LSS first, every drive on its own bus at once: fast_scan() waits out a missing answer
    # for every 1 bit of the identity (tens of seconds per drive)
    found = {}

    def scan(port, path):
        network = connect(a, port)
        try:
            found[port] = lss_fastscan(network, a.node, path)
        except Exception as e:  # reported in that file's line
            found[port] = f"exception: {e!r}"
        finally:
            network.disconnect()
    threads = [threading.Thread(target=scan, args=(port, path))
               for port, path, with_lss in specs if with_lss]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for port, path, with_lss in specs:
        network = connect(a, port)
        try:
            found_here = found.get(port, "not offered")
            if found_here in ("fastscan", "not offered"):
                out = check(network, a.node, path)
            else:
                out = {"file": path}  # not configured: nothing else can run
            out["lss"] = found_here
            print(json.dumps(out), flush=True)
        finally:
            network.disconnect()


if __name__ == "__main__":
    sys.exit(main())
