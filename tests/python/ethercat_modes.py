"""SOEM (pysoem) as the master of `drive-emu run --ethercat IFACE --lockstep`, one slave, with
its own PDO mapping written in PRE-OP (longer than a CAN frame).

Usage: ethercat_modes.py IFACE modes
       ethercat_modes.py IFACE law KV [KV ...]
       ethercat_modes.py IFACE watchdog OPTION [OPTION ...]

Both: the master writes 0x1600 = controlword, target position, target velocity, modes of
operation (11 bytes) and 0x1A00 = statusword, position actual, velocity actual, torque actual,
modes of operation display (13 bytes), assigns them in 0x1C12 / 0x1C13, config_map, SAFE-OP,
OP with the expected working counter in every cycle, CiA 402 enable from the process data.

modes: CSP (a ramp, 0x6064 follows), CSV (0x606C reaches the target velocity, 0x6064 moves at
it), PP (bit 4 new set-point, bit 12 acknowledge, bit 10 target reached at the target).

law: for each k_v (written to the drive's kv_per_s object over CoE), a constant-speed CSP
run; 0x606C from the process data once per master cycle.

watchdog: the master sets the SM watchdog to 1 s (a master stalled by a busy machine does not
trip it); for each 0x6007 abort connection option code, in OP with the drive enabled, the
master stops sending process data: the SM watchdog takes the slave to SAFE-OP with AL status
0x001B, the drive reacts as 0x6007 says and sends EMCY 0x8250 over CoE; the master
acknowledges, goes back to OP, resets the fault (controlword bit 7) and enables the drive again.
This one runs with the drive's own tick (not lock-step: a master that stops is what it tests).

modes and law: the drive runs lock-step: one drive cycle (1 ms of drive time) per process-data frame, so the
master's cycle count is the drive's clock; nothing here depends on wall-clock time. Prints one
JSON line with what it measured; exits non-zero with the reason on the first failure.
"""

import json
import struct
import sys
import time

import pysoem

# 0x1600 / 0x1A00 entries (index << 16 | sub << 8 | bits)
RX = [0x60400010, 0x607A0020, 0x60FF0020, 0x60600008]
TX = [0x60410010, 0x60640020, 0x606C0020, 0x60770010, 0x60610008]
OUT_LEN, IN_LEN = 11, 13
KV_OBJECT = 0x2007


def fail(msg):
    print(f"FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)


def remap(s, assign, index, entries):
    """The master's own mapping, in PRE-OP, as SOEM's PO2SO hooks or TwinCAT's start-up list."""
    s.sdo_write(assign, 0, bytes([0]))
    s.sdo_write(index, 0, bytes([0]))
    for k, e in enumerate(entries):
        s.sdo_write(index, k + 1, struct.pack("<I", e))
    s.sdo_write(index, 0, bytes([len(entries)]))
    s.sdo_write(assign, 1, struct.pack("<H", index))
    s.sdo_write(assign, 0, bytes([1]))


class Master:
    def __init__(self, iface):
        self.m = pysoem.Master()
        self.m.open(iface)
        self.wkcs = []
        self.cycles = 0
        self.cw, self.target_pos, self.target_vel, self.mode = 0, 0, 0, 8
        # lock-step: no pause, one drive cycle per master cycle; else about the drive's tick
        self.pause_s = 0.0
        # the SM watchdog time the master sets (None: the slave's default, 100 ms)
        self.watchdog_ms = None

    def close(self):
        self.m.close()

    def configure(self):
        m = self.m
        n = 0
        for _ in range(50):
            n = m.config_init()
            if n > 0:
                break
            time.sleep(0.1)
        check(n == 1, f"config_init found {n} slaves, expected 1")
        s = m.slaves[0]
        self.s = s
        # the drive's emergencies over CoE (they come in the mailbox with SDO answers)
        self.emcys = []
        s.add_emergency_callback(lambda e: self.emcys.append(e.error_code))

        def hook(slave_pos):
            remap(s, 0x1C12, 0x1600, RX)
            remap(s, 0x1C13, 0x1A00, TX)

        s.config_func = hook
        size = m.config_map()
        if self.watchdog_ms is not None:
            # long enough that a master stalled by a busy machine does not trip it
            s.set_watchdog("processdata", self.watchdog_ms)
            got = s.get_watchdog("processdata")
            check(abs(got - self.watchdog_ms) < 1, f"SM watchdog {got} ms")
        check(size == OUT_LEN + IN_LEN, f"process image {size} bytes, want {OUT_LEN + IN_LEN}")
        got = s.sdo_read(0x1600, 0, ca=True)
        check(got[0] == len(RX), f"0x1600 read back {got.hex()}")
        check(m.state_check(pysoem.SAFEOP_STATE, 500000) == pysoem.SAFEOP_STATE,
              f"SAFE-OP not reached: 0x{s.al_status:04X}")
        self.expected = m.expected_wkc
        check(self.expected == 3, f"expected working counter {self.expected}, want 3")
        self.cycle()
        m.state = pysoem.OP_STATE
        m.write_state()
        reached = pysoem.NONE_STATE
        for _ in range(200):
            self.cycle()
            reached = m.state_check(pysoem.OP_STATE, 5000)
            if reached == pysoem.OP_STATE:
                break
        check(reached == pysoem.OP_STATE, f"OP not reached: 0x{s.state:02X}")

    def cycle(self):
        """One master cycle (= one drive cycle in lock-step)."""
        if self.pause_s:
            time.sleep(self.pause_s)
        self.s.output = struct.pack("<HiiB", self.cw, self.target_pos, self.target_vel,
                                    self.mode & 0xFF)
        self.m.send_processdata()
        w = self.m.receive_processdata(100000)
        self.wkcs.append(w)
        self.cycles += 1
        return w

    def inputs(self):
        sw, pos, vel, torque, mode = struct.unpack("<HiihB", bytes(self.s.input[:IN_LEN]))
        return {"sw": sw, "pos": pos, "vel": vel, "torque": torque, "mode": struct.unpack(
            "<b", bytes([mode]))[0]}

    def until(self, cond, cycles, what):
        for _ in range(cycles):
            self.cycle()
            if cond(self.inputs()):
                return
        fail(f"{what}: not within {cycles} cycles: {self.inputs()}")

    def enable(self, mode):
        self.mode = mode
        self.target_pos = self.inputs()["pos"]
        for cw, want in [(0x06, 0x21), (0x07, 0x23), (0x0F, 0x27)]:
            self.cw = cw
            self.until(lambda i: i["sw"] & 0x6F == want, 2000, f"controlword 0x{cw:02X}")
        self.until(lambda i: i["mode"] == mode, 100, f"modes display {mode}")

    def bad_wkcs(self):
        return [w for w in self.wkcs if w != self.expected]


def modes(mm):
    out = {}
    mm.enable(8)
    # CSP: 2 um per cycle to +3000 um, then hold
    start = mm.inputs()["pos"]
    for step in range(1, 2001):
        mm.target_pos = start + min(2 * step, 3000)
        mm.cycle()
    mm.until(lambda i: abs(i["pos"] - (start + 3000)) <= 20, 3000, "CSP at its target")
    out["csp_position"] = mm.inputs()["pos"] - start
    # CSV: -5000 uu/s (5 mm/s back), same process data, mode 9
    mm.mode = 9
    mm.target_vel = -5000
    mm.until(lambda i: i["mode"] == 9, 100, "modes display CSV")
    mm.until(lambda i: abs(i["vel"] + 5000) <= 250, 3000, "CSV at its velocity")
    p0 = mm.inputs()["pos"]
    for _ in range(500):
        mm.cycle()
    moved = mm.inputs()["pos"] - p0
    out["csv_velocity"] = mm.inputs()["vel"]
    out["csv_moved_500_cycles"] = moved
    check(abs(moved + 2500) <= 150, f"CSV: 500 cycles at -5000 uu/s moved {moved} uu")
    mm.target_vel = 0
    mm.until(lambda i: abs(i["vel"]) <= 50, 3000, "CSV stopped")
    # PP: profile velocity and accelerations over CoE, then a set-point handshake
    s = mm.s
    s.sdo_write(0x6081, 0, struct.pack("<I", 20000))
    s.sdo_write(0x6083, 0, struct.pack("<I", 200000))
    s.sdo_write(0x6084, 0, struct.pack("<I", 200000))
    mm.mode = 1
    mm.until(lambda i: i["mode"] == 1, 100, "modes display PP")
    target = mm.inputs()["pos"] + 4000
    mm.target_pos = target
    mm.cw = 0x1F  # new set-point, absolute, change set immediately off
    mm.until(lambda i: i["sw"] & 0x1000, 200, "PP set-point acknowledge (bit 12)")
    mm.cw = 0x0F
    mm.until(lambda i: not i["sw"] & 0x1000, 200, "PP acknowledge cleared")
    moving = mm.inputs()
    check(not moving["sw"] & 0x0400, f"target reached before the move: {moving}")
    mm.until(lambda i: i["sw"] & 0x0400, 5000, "PP target reached (bit 10)")
    out["pp_error"] = mm.inputs()["pos"] - target
    check(abs(out["pp_error"]) <= 20, f"PP: at {mm.inputs()['pos']}, target {target}")
    return out


def law(mm, kvs):
    s = mm.s
    mm.enable(8)
    speed = 10  # uu (um) per cycle: 10 mm/s
    settle, record = 2000, 4000
    runs = []
    for kv in kvs:
        s.sdo_write(KV_OBJECT, 0, struct.pack("<f", kv))
        got = struct.unpack("<f", s.sdo_read(KV_OBJECT, 0))[0]
        check(abs(got - kv) < 1e-3, f"k_v read back {got}, wrote {kv}")
        vel = []
        for k in range(settle + record):
            mm.target_pos += speed
            mm.cycle()
            if k >= settle:
                vel.append(mm.inputs()["vel"])
        check(not mm.inputs()["sw"] & 0x08, f"k_v {kv}: fault {mm.inputs()}")
        runs.append({"kv_per_s": kv, "sample_period_s": 0.001, "velocity_actual": vel})
    # one more mailbox exchange: an emergency waiting in the mailbox comes with it
    s.sdo_read(0x1018, 1)
    return {"runs": runs, "speed_uu_per_s": speed * 1000, "emcys": list(mm.emcys)}


def watchdog(mm, options):
    s = mm.s
    emcys = mm.emcys
    rounds = []
    for option in options:
        s.sdo_write(0x6007, 0, struct.pack("<h", option))
        mm.enable(8)
        # the master stops: no process data; only AL status reads until SAFE-OP + error
        al = None
        for _ in range(1000):
            time.sleep(0.01)
            mm.m.read_state()
            if s.state == pysoem.SAFEOP_STATE | pysoem.STATE_ERROR:
                al = s.al_status
                break
        check(al is not None, f"0x6007={option}: no SAFE-OP + error: state 0x{s.state:02X}")
        # the mailbox still works in SAFE-OP: the drive's state and the EMCY that came
        sw = struct.unpack("<H", s.sdo_read(0x6041, 0))[0]
        err = struct.unpack("<H", s.sdo_read(0x603F, 0))[0]
        got = list(emcys)
        emcys.clear()
        # acknowledge, process data again, OP
        s.state = pysoem.SAFEOP_STATE | pysoem.STATE_ACK
        s.write_state()
        mm.cw = 0x00
        mm.cycle()
        mm.m.state = pysoem.OP_STATE
        mm.m.write_state()
        reached = pysoem.NONE_STATE
        for _ in range(500):
            mm.cycle()
            time.sleep(0.001)
            reached = mm.m.state_check(pysoem.OP_STATE, 5000)
            if reached == pysoem.OP_STATE:
                break
        check(reached == pysoem.OP_STATE, f"0x6007={option}: OP again: 0x{s.state:02X}")
        after_op = mm.inputs()["sw"]
        # fault reset (bit 7, a rising edge), then enable again
        mm.cw = 0x80
        mm.until(lambda i: not i["sw"] & 0x08, 2000, f"0x6007={option}: fault reset")
        mm.enable(8)
        rounds.append({"option": option, "al_status": al, "statusword": sw,
                       "error_code": err, "emcys": got, "statusword_in_op": after_op,
                       "enabled_again": mm.inputs()["sw"] & 0x6F == 0x27})
    return {"rounds": rounds}


def main():
    iface, what = sys.argv[1], sys.argv[2]
    mm = Master(iface)
    if what == "watchdog":
        mm.pause_s = 0.001
        mm.watchdog_ms = 1000.0
    try:
        mm.configure()
        if what == "modes":
            out = modes(mm)
        elif what == "law":
            out = law(mm, [float(v) for v in sys.argv[3:]])
        elif what == "watchdog":
            out = watchdog(mm, [int(v) for v in sys.argv[3:]])
        else:
            fail(f"unknown test {what}")
        bad = mm.bad_wkcs()
        check(not bad, f"{len(bad)} of {len(mm.wkcs)} cycles with a working counter other "
              f"than {mm.expected}: {bad[:10]}")
        out.update({"cycles": mm.cycles, "expected_wkc": mm.expected})
        mm.m.state = pysoem.INIT_STATE
        mm.m.write_state()
        print(json.dumps(out))
    finally:
        mm.close()


if __name__ == "__main__":
    main()
