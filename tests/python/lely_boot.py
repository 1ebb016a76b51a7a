#!/usr/bin/env python3
"""Boot a drive the way Lely's CANopen master does (what ros2_canopen runs), then move it.

Lely is not in the package registries, so this client replays its master on python-can 4.6.1
and python canopen 2.4.1's SDO client, from the files Lely's `dcfgen -rS bus.yml` writes
(master.dcf, master.bin and the slave's concise DCF <name>.bin), in Lely's order and with its
timeouts (lely-core, src/co/nmt.c, nmt_boot.c, nmt_cfg.c, csdo.c, nmt_hb.c; commit 620d1858):

 1. The master sends its own boot-up, then NMT 'reset communication' to all nodes (nmt.c,
    co_nmt_startup_master: node 0 unless a slave has the keep-alive bit 0x10 of 0x1F81), and
    produces SYNC from then on (COB-ID 0x1005, period 0x1006 of master.dcf), sending its
    synchronous TPDOs after each SYNC.
 2. An optional slave (0x1F81 bit 3 clear) is booted when its boot-up arrives (nmt.c,
    co_nmt_on_st); a mandatory one at once, retried every 1 s after error 'B'
    (LELY_CO_NMT_BOOT_WAIT_TIMEOUT) until the boot time 0x1F89 (0: for ever) has passed.
 3. 'boot slave' (nmt_boot.c): 0x1F81 bit 0 clear: error 'A'. Bit 2 set: read 0x1000 with up
    to 4 attempts on SDO timeout (LELY_CO_NMT_BOOT_SDO_RETRY 3), no answer: 'B', differs from
    0x1F84: 'C'; then 0x1018:1-4 against 0x1F85-0x1F88 where those are not 0 ('D', 'M', 'N',
    'O'); no keep-alive, software or configuration-date check in dcfgen's defaults; then the
    configuration (nmt_cfg.c, co_nmt_cfg_store_1f22_on_enter): every entry of the concise DCF
    (0x1F22:<node>, dcfgen's UploadFile) downloaded over SDO in file order, stopping at the
    first abort ('J'). Every SDO request times out after the master's SDO timeout
    (LELY_CO_NMT_TIMEOUT 100 ms unless the application sets another, BasicMaster::SetTimeout;
    --sdo-timeout-ms) and is aborted with 0x05040000.
 4. Start error control (co_nmt_boot_ec_on_enter): with a consumer time for the node in the
    master's 0x1016, wait that long for a heartbeat (a boot-up does not count) that arrives
    after this point; none: error 'K'. Then NMT 'start' to the node (co_nmt_boot_con: 0x1F81
    bits 0 and 2 set, 0x1F80 bit 3 clear) and heartbeat consumption at the same time from
    then on (nmt_hb.c: each heartbeat restarts the timer; expiry is a heartbeat event).
 5. CiA 402 as a ros2_canopen CSP driver does it: mode 8 (RPDO-mapped 0x6060, else SDO),
    controlword 6, 7, 15 to OPERATION ENABLED, then a short CSP move streamed one set-point
    per SYNC, checked from the TPDO position (0x6064) and statusword (0x6041).

Master TPDOs carry the remote objects of master.dcf's remote PDO mappings (0x5E00+, dcfgen
-r); synchronous ones (type 1-240) go out after every SYNC, event-driven ones (0xFE/0xFF) when
a mapped object is written. The drive's TPDOs are decoded with 0x5A00+. One value per remote
object, as in dcfgen's master DCF (an object the slave maps in several RPDOs is one local
sub-object of the master, 0x2200+).

Usage: lely_boot.py --iface vcan0 --node 5 --master-dcf DIR/master.dcf [--master-bin
DIR/master.bin] [--sdo-timeout-ms 100] [--boot-wait-s 30] [--move-uu 5000]
Paths in master.dcf (UploadFile) are taken relative to the working directory, as Lely does.
Prints one line per step; the last is PASS, or FAIL: / BOOT ERROR <letter>: with the reason.
Exit status: 0 pass, 1 fail, 2 bad input (files, options), 3 boot error.
"""
import argparse
import configparser
import struct
import sys
import threading
import time

import canopen
from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

T0 = time.monotonic()

# Lely's boot error letters (CiA 302-2; lely-core include/lely/co/nmt.h co_nmt_es2str)
BOOT_ERRORS = {
    "A": "the slave is not in the network list (0x1F81 bit 0)",
    "B": "no response received for upload request of object 1000",
    "C": "value of object 1000 from the slave differs from object 1F84 (device type)",
    "D": "value of object 1018:01 differs from object 1F85 (vendor-ID)",
    "J": "configuration download failed (concise DCF of 0x1F22)",
    "K": "heartbeat event during start error control service: no heartbeat message received "
    "from the slave within the master's consumer time (0x1016)",
    "M": "value of object 1018:02 differs from object 1F86 (product code)",
    "N": "value of object 1018:03 differs from object 1F87 (revision number)",
    "O": "value of object 1018:04 differs from object 1F88 (serial number)",
}


def log(msg):
    print(f"LELY t={time.monotonic() - T0:7.3f} {msg}", flush=True)


# CiA 402 objects of a signed type (the rest a PDO carries here is unsigned)
SIGNED = {0x6061, 0x6062, 0x6063, 0x6064, 0x606C, 0x6071, 0x6077, 0x607A, 0x60B1, 0x60B2,
          0x60E4, 0x60F4, 0x60FF}


class BadInput(Exception):
    """A file or option the client cannot use (exit 2)."""


class BootError(Exception):
    """Lely's 'boot slave' ended with an error letter (exit 3)."""

    def __init__(self, letter, detail):
        super().__init__(f"BOOT ERROR {letter}: {BOOT_ERRORS[letter]} ({detail})")
        self.letter = letter


class Fail(Exception):
    """The drive did not do what the master asked (exit 1)."""


# ---------------------------------------------------------------------------------------
# master.dcf (the INI text of CiA 306 as dcfgen writes it) and master.bin


def parse_int(text, node_id, where):
    t = text.strip()
    base = 0
    if t.upper().startswith("$NODEID"):
        base, t = node_id, t[len("$NODEID"):].lstrip("+ ").strip() or "0"
    try:
        return base + int(t, 0)
    except ValueError:
        raise BadInput(f"{where}: not an integer: {text!r}") from None


class MasterDcf:
    """The master's object values: master.dcf, overlaid by master.bin (concise DCF)."""

    def __init__(self, path, bin_path):
        cp = configparser.ConfigParser(strict=False, interpolation=None)
        cp.optionxform = str
        try:
            with open(path, encoding="utf-8") as f:
                cp.read_file(f)
        except (OSError, configparser.Error) as e:
            raise BadInput(f"{path}: {e}") from None
        self.path = path
        self.cp = cp
        sec = "DeviceComissioning"
        self.node_id = parse_int(cp.get(sec, "NodeID", fallback="0"), 0, f"{path}: [{sec}] NodeID")
        if not 1 <= self.node_id <= 127:
            raise BadInput(f"{path}: [{sec}] NodeID={self.node_id}: the master needs 1-127")
        self.overlay = {}
        if bin_path:
            for index, sub, data in read_concise_dcf(bin_path):
                self.overlay[(index, sub)] = int.from_bytes(data[:4].ljust(4, b"\0"), "little")

    def value(self, index, sub, default=None):
        """The value of index:sub, or `default` where the DCF has none."""
        if (index, sub) in self.overlay:
            return self.overlay[(index, sub)]
        where = f"{self.path}: object 0x{index:04X} sub {sub}"
        for section in (f"{index:X}sub{sub:X}", f"{index:04X}sub{sub:X}"):
            if self.cp.has_section(section):
                for key in ("ParameterValue", "DefaultValue"):
                    v = self.cp.get(section, key, fallback="").strip()
                    if v:
                        return parse_int(v, self.node_id, where)
                return default
        if sub == 0 and self.cp.has_section(f"{index:04X}"):
            # a plain variable, or sub-index 0 of a compact array (CiA 306 CompactSubObj:
            # its highest sub-index)
            for key in ("ParameterValue", "DefaultValue", "CompactSubObj"):
                v = self.cp.get(f"{index:04X}", key, fallback="").strip()
                if v:
                    return parse_int(v, self.node_id, where)
        section = f"{index:04X}Value"
        if self.cp.has_section(section):
            # Lely's dcf.c co_obj_parse_values: the keys are decimal sub-indices
            v = self.cp.get(section, str(sub), fallback="").strip()
            if v:
                return parse_int(v, self.node_id, where)
        return default

    def text(self, section, key):
        return self.cp.get(section, key, fallback="").strip()


def read_concise_dcf(path):
    """Entries (index, sub, bytes) of a concise DCF: u32 count, then index u16, sub u8,
    size u32, data (CiA 302-3; Lely csdo.c co_csdo_dn_dcf_req)."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except OSError as e:
        raise BadInput(f"concise DCF {path}: {e}") from None
    if len(raw) < 4:
        raise BadInput(f"concise DCF {path}: {len(raw)} bytes, no entry count")
    (n,) = struct.unpack_from("<I", raw, 0)
    pos, out = 4, []
    for k in range(n):
        if pos + 7 > len(raw):
            raise BadInput(f"concise DCF {path}: entry {k + 1} of {n} cut at byte {pos}")
        index, sub, size = struct.unpack_from("<HBI", raw, pos)
        pos += 7
        if pos + size > len(raw):
            raise BadInput(f"concise DCF {path}: entry {k + 1} (0x{index:04X}:{sub}) needs "
                           f"{size} bytes, {len(raw) - pos} left")
        out.append((index, sub, raw[pos:pos + size]))
        pos += size
    if pos != len(raw):
        raise BadInput(f"concise DCF {path}: {len(raw) - pos} bytes after the {n} entries")
    return out


class Pdo:
    """One PDO of the master: COB-ID, transmission type and the remote objects it carries."""

    def __init__(self, cob_id, ttype, mapping):
        self.cob_id = cob_id
        self.ttype = ttype
        self.mapping = mapping  # [(index, sub, bits)]

    def objects(self):
        return {(i, s) for i, s, _ in self.mapping}


def master_pdos(dcf, comm_base, remote_map_base):
    pdos = []
    for k in range(512):
        cob = dcf.value(comm_base + k, 1)
        if cob is None:
            break
        if cob & 0x8000_0000:
            continue
        ttype = dcf.value(comm_base + k, 2, 0xFF)
        n = dcf.value(remote_map_base + k, 0)
        if n is None:
            raise BadInput(
                f"{dcf.path}: PDO 0x{comm_base + k:04X} has no remote mapping "
                f"0x{remote_map_base + k:04X}: generate the DCF with `dcfgen -r` (remote PDO "
                "mapping), as ros2_canopen does")
        mapping = []
        for s in range(1, n + 1):
            m = dcf.value(remote_map_base + k, s, 0)
            mapping.append((m >> 16, (m >> 8) & 0xFF, m & 0xFF))
        pdos.append(Pdo(cob & 0x7FF, ttype, mapping))
    return pdos


# ---------------------------------------------------------------------------------------
# the master


class LelyMaster:
    def __init__(self, args):
        self.args = args
        self.dcf = MasterDcf(args.master_dcf, args.master_bin)
        self.node = args.node
        self.sdo_timeout = args.sdo_timeout_ms / 1000.0
        self.lock = threading.Lock()
        self.values = {}  # remote objects of the master's TPDOs, (index, sub) -> int
        self.rx = {}  # remote objects received in the drive's TPDOs
        self.rx_count = 0
        self.heartbeats = []  # (monotonic time, state byte)
        self.bootups = []
        self.emcys = []
        self.syncs = 0
        self.sync_cob = None
        self.stop = threading.Event()
        self.hb_ms = 0
        self.hb_watch_from = None
        self.hb_events = []

        self.tpdos = master_pdos(self.dcf, 0x1800, 0x5E00)  # to the drive (its RPDOs)
        self.rpdos = master_pdos(self.dcf, 0x1400, 0x5A00)  # from the drive (its TPDOs)
        mapped_tx = set().union(*(p.objects() for p in self.tpdos)) if self.tpdos else set()
        for obj in mapped_tx:
            self.values[obj] = 0

        self.net = canopen.Network()
        self.net.connect(interface="socketcan", channel=args.iface)
        self.remote = canopen.RemoteNode(self.node, canopen.ObjectDictionary())
        self.net.add_node(self.remote)
        self.remote.sdo.RESPONSE_TIMEOUT = self.sdo_timeout
        self.remote.sdo.MAX_RETRIES = 1  # one attempt; Lely's CSDO does not resend
        self.net.subscribe(0x700 + self.node, self._on_ec)
        self.net.subscribe(0x080 + self.node, self._on_emcy)
        for pdo in self.rpdos:
            self.net.subscribe(pdo.cob_id, self._on_rpdo)

    # -- receive callbacks (python-can's notifier thread)
    def _on_ec(self, _cob, data, _ts):
        now = time.monotonic()
        if not data:
            return
        with self.lock:
            if data[0] == 0:
                self.bootups.append(now)
            else:
                self.heartbeats.append((now, data[0] & 0x7F))

    def _on_emcy(self, _cob, data, _ts):
        if len(data) >= 3:
            code = data[0] | data[1] << 8
            with self.lock:
                self.emcys.append((time.monotonic(), code, data[2]))
            log(f"EMCY {code:04X} error register {data[2]:02X}")

    def _on_rpdo(self, cob, data, _ts):
        pdo = next(p for p in self.rpdos if p.cob_id == cob)
        bits = int.from_bytes(bytes(data), "little")
        pos = 0
        with self.lock:
            for index, sub, n in pdo.mapping:
                raw = (bits >> pos) & ((1 << n) - 1)
                if index in SIGNED and raw >> (n - 1):
                    raw -= 1 << n
                self.rx[(index, sub)] = raw
                pos += n
            self.rx_count += 1

    # -- sending
    def _send_pdo(self, pdo):
        bits, pos = 0, 0
        for index, sub, n in pdo.mapping:
            bits |= (self.values.get((index, sub), 0) & ((1 << n) - 1)) << pos
            pos += n
        self.net.send_message(pdo.cob_id, bits.to_bytes((pos + 7) // 8, "little"))

    def write(self, index, sub, value):
        """Write a remote object through the master's PDOs (event-driven ones go out now,
        synchronous ones after the next SYNC), or over SDO where no TPDO maps it."""
        carriers = [p for p in self.tpdos if (index, sub) in p.objects()]
        if not carriers:
            size = {0x6060: 1, 0x6040: 2}.get(index, 4)
            self.sdo_download(index, sub, (value & ((1 << (8 * size)) - 1)).to_bytes(size, "little"))
            return
        with self.lock:
            self.values[(index, sub)] = value
            for p in carriers:
                if p.ttype >= 0xFE:
                    self._send_pdo(p)

    def _sync_loop(self, period):
        nxt = time.monotonic()
        while not self.stop.is_set():
            nxt += period
            delay = nxt - time.monotonic()
            if delay > 0:
                self.stop.wait(delay)
            else:
                nxt = time.monotonic()  # late (loaded host): no burst of catch-up SYNCs
            self.net.send_message(self.sync_cob, b"")
            with self.lock:
                self.syncs += 1
                for p in self.tpdos:
                    if 1 <= p.ttype <= 240 and self.syncs % p.ttype == 0:
                        self._send_pdo(p)

    def _heartbeat_loop(self):
        while not self.stop.wait(0.005):
            self._check_heartbeat()

    def _check_heartbeat(self):
        """Lely's heartbeat consumer after the boot (nmt_hb.c): an event when no heartbeat
        came within the consumer time of the last one (or of the boot's end)."""
        if not self.hb_watch_from or not self.hb_ms:
            return
        now = time.monotonic()
        with self.lock:
            last = max([t for t, _ in self.heartbeats] + [self.hb_watch_from])
        if now - last > self.hb_ms / 1000.0 and (not self.hb_events or self.hb_events[-1] < last):
            self.hb_events.append(now)
            log(f"HEARTBEAT EVENT: none from node {self.node} for {1000 * (now - last):.0f} ms "
                f"(consumer time {self.hb_ms} ms)")

    # -- SDO with Lely's timeout
    def sdo_upload(self, index, sub):
        return self.remote.sdo.upload(index, sub)

    def sdo_download(self, index, sub, data):
        self.remote.sdo.download(index, sub, bytes(data))

    # -- the boot
    def start(self):
        log(f"master node {self.dcf.node_id}: boot-up, NMT reset communication to all nodes")
        self.net.send_message(0x700 + self.dcf.node_id, b"\x00")
        assignment = {n: self.dcf.value(0x1F81, n, 0) for n in range(1, 128)}
        keep = any(a & 0x11 == 0x11 for a in assignment.values())
        if keep:
            for n, a in assignment.items():
                if n != self.dcf.node_id and a & 0x11 != 0x11:
                    self.net.send_message(0x000, bytes([0x82, n]))
        else:
            self.net.send_message(0x000, b"\x82\x00")
        threading.Thread(target=self._heartbeat_loop, daemon=True).start()
        sync_id = self.dcf.value(0x1005, 0, 0x80)
        period_us = self.dcf.value(0x1006, 0, 0)
        if sync_id & 0x4000_0000 and period_us:
            self.sync_cob = sync_id & 0x7FF
            log(f"SYNC producer: COB-ID 0x{self.sync_cob:03X} every {period_us} us")
            threading.Thread(target=self._sync_loop, args=(period_us / 1e6,), daemon=True).start()
        else:
            log("no SYNC producer in master.dcf (0x1005 bit 30 / 0x1006)")
        return assignment[self.node]

    def boot(self, assignment):
        """Lely's 'boot slave' for our node; returns the NMT state of the last heartbeat."""
        if not assignment & 0x01:
            raise BootError("A", f"0x1F81:{self.node} = 0x{assignment:08X}")
        mandatory = bool(assignment & 0x08)
        deadline = time.monotonic() + self.args.boot_wait_s
        if not mandatory:
            log(f"node {self.node} optional: boot on its boot-up message")
            while not self.bootups:
                if time.monotonic() > deadline:
                    raise Fail(f"no boot-up from node {self.node} within {self.args.boot_wait_s} s "
                               "of the NMT reset (an optional slave is booted on its boot-up)")
                time.sleep(0.002)
            log(f"boot-up of node {self.node}")
        boot_time_ms = self.dcf.value(0x1F89, 0, 0)
        while True:
            try:
                return self._boot_once(assignment)
            except BootError as e:
                # nmt_boot.c co_nmt_boot_abort_on_enter: 'B' is retried after 1 s while a
                # mandatory slave's boot time has not passed (non-mandatory: always)
                elapsed_ms = (time.monotonic() - T0) * 1000
                retry = e.letter == "B" and (not mandatory or not boot_time_ms
                                             or elapsed_ms < boot_time_ms)
                if not retry or time.monotonic() > deadline:
                    raise
                log(f"{e}; boot again in 1 s (LELY_CO_NMT_BOOT_WAIT_TIMEOUT)")
                time.sleep(1.0)

    def _boot_once(self, assignment):
        self.hb_ms = 0
        for s in range(1, (self.dcf.value(0x1016, 0, 0) or 0) + 1):
            v = self.dcf.value(0x1016, s, 0)
            if (v >> 16) & 0x7F == self.node:
                self.hb_ms = v & 0xFFFF
        if assignment & 0x04:
            self._check_identity()
            self._configure()
        return self._start_error_control()

    def _upload_u32(self, index, sub):
        data = self.sdo_upload(index, sub)
        return int.from_bytes(bytes(data[:4]).ljust(4, b"\0"), "little")

    def _check_identity(self):
        # co_nmt_boot_chk_device_type_on_enter: 1 + LELY_CO_NMT_BOOT_SDO_RETRY attempts
        for attempt in range(4):
            try:
                device_type = self._upload_u32(0x1000, 0)
                break
            except SdoCommunicationError:
                log(f"0x1000: SDO timeout ({self.args.sdo_timeout_ms} ms), attempt {attempt + 1}/4")
            except SdoAbortedError as e:
                raise BootError("B", f"SDO abort 0x{e.code:08X} on 0x1000") from None
        else:
            raise BootError("B", f"4 uploads of 0x1000 unanswered within "
                                 f"{self.args.sdo_timeout_ms} ms each")
        expected = self.dcf.value(0x1F84, self.node, 0)
        log(f"0x1000 = 0x{device_type:08X} (0x1F84: 0x{expected:08X})")
        if expected and device_type != expected:
            raise BootError("C", f"0x{device_type:08X} != 0x{expected:08X}")
        for sub, obj, letter, name in ((1, 0x1F85, "D", "vendor-ID"), (2, 0x1F86, "M", "product code"),
                                       (3, 0x1F87, "N", "revision"), (4, 0x1F88, "O", "serial")):
            expected = self.dcf.value(obj, self.node, 0)
            if not expected:
                continue
            try:
                got = self._upload_u32(0x1018, sub)
            except (SdoCommunicationError, SdoAbortedError) as e:
                raise BootError(letter, f"0x1018:{sub}: {e}") from None
            log(f"0x1018:{sub} {name} = 0x{got:08X} (0x{obj:04X}: 0x{expected:08X})")
            if got != expected:
                raise BootError(letter, f"0x{got:08X} != 0x{expected:08X}")

    def _configure(self):
        path = self.dcf.text(f"1F22sub{self.node:X}", "UploadFile")
        if not path:
            log("no concise DCF for the node (0x1F22): nothing to download")
            return
        entries = read_concise_dcf(path)
        log(f"configuration: {len(entries)} SDO downloads from {path}")
        for index, sub, data in entries:
            try:
                self.sdo_download(index, sub, data)
            except SdoAbortedError as e:
                raise BootError("J", f"0x{index:04X}:{sub} <- {data.hex()}: abort 0x{e.code:08X}") from None
            except SdoCommunicationError:
                raise BootError("J", f"0x{index:04X}:{sub} <- {data.hex()}: no answer within "
                                     f"{self.args.sdo_timeout_ms} ms") from None
        log(f"configuration done: {len(entries)} downloads")

    def _start_error_control(self):
        if not self.hb_ms:
            log("no heartbeat consumer time for the node in 0x1016: error control not checked")
            return None
        start = time.monotonic()
        log(f"start error control: waiting {self.hb_ms} ms for a heartbeat (0x1016)")
        while time.monotonic() - start < self.hb_ms / 1000.0:
            with self.lock:
                hb = [(t, s) for t, s in self.heartbeats if t >= start]
            if hb:
                t, state = hb[0]
                log(f"heartbeat after {1000 * (t - start):.0f} ms, NMT state 0x{state:02X}")
                self.hb_watch_from = t
                return state
            time.sleep(0.001)
        with self.lock:
            seen = len(self.heartbeats)
        raise BootError("K", f"none within {self.hb_ms} ms; heartbeats seen in all: {seen}")

    def start_node(self, assignment):
        startup = self.dcf.value(0x1F80, 0, 0)
        if assignment & 0x05 == 0x05 and not startup & 0x08:
            log(f"NMT start node {self.node}")
            self.net.send_message(0x000, bytes([0x01, self.node]))


# ---------------------------------------------------------------------------------------
# CiA 402


def cia402(m, args):
    def mapped(index):
        return any((index, 0) in p.objects() for p in m.rpdos)

    def rx(index):
        with m.lock:
            return m.rx.get((index, 0))

    def wait_syncs(pred, syncs, what, poll_s=0.001):
        """Wait until pred() holds, for at most `syncs` SYNCs (the drive's time in
        lock-step), with 60 s of wall time as a bound on a stalled host."""
        s0, t0 = m.syncs, time.monotonic()
        while m.syncs - s0 < syncs and time.monotonic() - t0 < 60:
            if pred():
                return
            time.sleep(poll_s)
        raise Fail(f"{what}: not within {syncs} SYNCs (statusword {sw():#06x})")

    def sw():
        return rx(0x6041) or 0

    for index, name in ((0x6041, "statusword"), (0x6064, "position actual value")):
        if not mapped(index):
            raise BadInput(f"{name} (0x{index:04X}) is in none of the drive's TPDOs of master.dcf")
    wait_syncs(lambda: rx(0x6041) is not None and rx(0x6064) is not None, 100,
               "first TPDO with statusword and position")
    m.write(0x6060, 0, 8)
    how = "RPDO" if any((0x6060, 0) in p.objects() for p in m.tpdos) else "SDO"
    if mapped(0x6061):
        wait_syncs(lambda: rx(0x6061) == 8, 200, "mode display 8 (CSP)")
    else:
        wait_syncs(lambda: mode_display_sdo(m) == 8, 200, "mode display 8 (CSP)", 0.01)
    log(f"mode 8 (CSP) written by {how}; mode display 8")
    for cw, want, name in ((0x06, 0x21, "READY TO SWITCH ON"), (0x07, 0x23, "SWITCHED ON"),
                           (0x0F, 0x27, "OPERATION ENABLED")):
        if cw == 0x0F:
            m.write(0x607A, 0, rx(0x6064))
        m.write(0x6040, 0, cw)
        wait_syncs(lambda: sw() & 0x6F == want, 200, name)
        log(f"{name} (statusword 0x{sw():04X})")
    start = rx(0x6064)
    steps = args.move_syncs
    for k in range(1, steps + 1):
        s = m.syncs
        m.write(0x607A, 0, start + args.move_uu * k // steps)
        wait_syncs(lambda: m.syncs > s, 10, "next SYNC")
        if sw() & 0x0008:
            raise Fail(f"FAULT during the CSP move (statusword 0x{sw():04X}, EMCYs {m.emcys})")
    end = start + args.move_uu
    wait_syncs(lambda: abs(rx(0x6064) - end) <= args.tolerance_uu, 200,
               f"position within {args.tolerance_uu} uu of the end point {end}")
    if sw() & 0x6F != 0x27:
        raise Fail(f"not OPERATION ENABLED after the move: statusword 0x{sw():04X}")
    log(f"CSP move of {args.move_uu} uu in {steps} SYNCs: {start} -> {rx(0x6064)} "
        f"(end point {end}), statusword 0x{sw():04X}")


def mode_display_sdo(m):
    try:
        return int.from_bytes(bytes(m.sdo_upload(0x6061, 0)[:1]), "little", signed=True)
    except (SdoCommunicationError, SdoAbortedError):
        return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iface", required=True)
    ap.add_argument("--node", type=int, required=True)
    ap.add_argument("--master-dcf", required=True)
    ap.add_argument("--master-bin", default=None)
    ap.add_argument("--sdo-timeout-ms", type=int, default=100,
                    help="the master's SDO timeout (Lely: LELY_CO_NMT_TIMEOUT = 100 ms)")
    ap.add_argument("--boot-wait-s", type=float, default=30.0,
                    help="bound on the wait for the boot-up (Lely waits for ever)")
    ap.add_argument("--move-uu", type=int, default=5000)
    ap.add_argument("--move-syncs", type=int, default=100)
    ap.add_argument("--tolerance-uu", type=int, default=100)
    ap.add_argument("--no-move", action="store_true", help="boot only")
    args = ap.parse_args()
    if not 1 <= args.node <= 127:
        print(f"FAIL: --node {args.node}: 1-127", flush=True)
        return 2
    m = None
    try:
        m = LelyMaster(args)
        assignment = m.start()
        state = m.boot(assignment)
        log(f"BOOTED node {args.node} (NMT state {'-' if state is None else hex(state)})")
        m.start_node(assignment)
        if not args.no_move:
            cia402(m, args)
        if m.hb_events:
            raise Fail(f"{len(m.hb_events)} heartbeat event(s) after the boot (consumer time "
                       f"{m.hb_ms} ms)")
        log(f"SYNCs sent {m.syncs}, heartbeats {len(m.heartbeats)}, EMCYs {len(m.emcys)}")
        print("PASS", flush=True)
        return 0
    except BadInput as e:
        print(f"FAIL: bad input: {e}", flush=True)
        return 2
    except BootError as e:
        print(str(e), flush=True)
        return 3
    except (Fail, SdoCommunicationError, SdoAbortedError) as e:
        print(f"FAIL: {e}", flush=True)
        return 1
    finally:
        if m is not None:
            m.stop.set()
            m.net.disconnect()


if __name__ == "__main__":
    sys.exit(main())
