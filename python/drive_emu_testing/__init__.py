"""Run drive-emu (an emulated CANopen CiA 402 servo drive) from python, for tests.

`DriveEmu` starts `drive-emu run --ready --json` on a CAN interface (SocketCAN), or where
that interface does not exist (no vcan: macOS, Windows, containers, CI runners) serving the
bus over socketcand on 127.0.0.1 (python-can's `socketcand` interface), waits for its ready line
(`{"event": "ready", ...}` on stdout, printed once the drive has sent its boot-up), generates
the matching EDS with `drive-emu eds`, and stops the process with SIGTERM, collecting the
loop statistics it prints on exit. The pytest fixture `drive_emu` (plugin.py) wraps it.
"""

import json
import os
import queue
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from pathlib import Path

__all__ = ["DriveEmu", "DriveEmuError", "find_binary", "interface_exists", "STATISTICS"]

# 0x2100 sub 1..7, as the EDS names them
STATISTICS = (
    "ticks",
    "overruns",
    "lateness_p50_us",
    "lateness_p99_us",
    "lateness_max_us",
    "dropped_tx_frames",
    "node_tx_queue_overflows",
)


class DriveEmuError(RuntimeError):
    """drive-emu could not be started, did not get ready, or did not stop cleanly."""


def find_binary(explicit=None):
    """The drive-emu binary: `explicit`, else $DRIVE_EMU_BIN, else `drive-emu` on the PATH."""
    for candidate in (explicit, os.environ.get("DRIVE_EMU_BIN")):
        if candidate:
            if not (os.path.isfile(candidate) and os.access(candidate, os.X_OK)):
                raise DriveEmuError(f"drive-emu binary {candidate!r} is not an executable file")
            return candidate
    found = shutil.which("drive-emu")
    if not found:
        raise DriveEmuError(
            "drive-emu not found: `cargo install --path emulator` (repository root), "
            "or set DRIVE_EMU_BIN / --drive-emu-bin to the binary"
        )
    return found


def interface_exists(iface):
    """True if this machine has a network interface `iface` (Linux: /sys/class/net)."""
    return bool(iface) and "/" not in iface and os.path.exists(f"/sys/class/net/{iface}")


class DriveEmu:
    """One `drive-emu run` process with one axis.

    The bus: `socketcand="HOST:PORT"` serves it over socketcand (port 0: any free port);
    `socketcand=None` (default) does so on 127.0.0.1:0 when $DRIVE_EMU_SOCKETCAND says so (an
    address) or when `iface` does not exist on this machine, else the drive is on `iface`.
    `socketcand=False`: always `iface`.

    Attributes once started: `iface`, `node_id`, `preset`, `eds_path` (EDS generated for the
    same preset, --set values and node ID), `ready` (the ready line as a dict), `pid`,
    `transport` ("socketcan" or "socketcand"), `socketcand` ((host, port) or None) and
    `can_args`: the keyword arguments of `can.Bus(...)` / `canopen.Network().connect(...)`
    that reach the drive either way.
    After `stop()`: `exit_statistics` (dict, the loop statistics printed at exit),
    `returncode`, `stderr` (all lines the process wrote to stderr).
    """

    def __init__(self, iface="vcan0", node_id=5, preset="cnc1", set=(), binary=None,
                 lockstep=False, sync_period_us=None, boot_delay_ms=None, extra_args=(),
                 ready_timeout=60.0, workdir=None, socketcand=None):
        self.iface = iface
        if socketcand is None:
            socketcand = os.environ.get("DRIVE_EMU_SOCKETCAND") or (
                None if interface_exists(iface) else "127.0.0.1:0")
        self.socketcand_addr = socketcand or None
        self.transport = "socketcand" if self.socketcand_addr else "socketcan"
        self.socketcand = None
        self.node_id = int(node_id)
        self.preset = preset
        self.set = list(set)
        self.binary = find_binary(binary)
        self.lockstep = lockstep
        self.sync_period_us = sync_period_us
        self.boot_delay_ms = boot_delay_ms
        self.extra_args = list(extra_args)
        self.ready_timeout = ready_timeout
        self._own_dir = workdir is None
        self.workdir = Path(workdir or tempfile.mkdtemp(prefix="drive-emu-"))
        self.eds_path = None
        self.ready = None
        self.exit_statistics = None
        self.returncode = None
        self.stderr = []
        self._proc = None
        self._stdout = queue.Queue()
        self._threads = []

    # ---- lifecycle
    def _set_args(self):
        out = []
        for kv in self.set:
            out += ["--set", kv]
        return out

    def write_eds(self):
        """Generate the EDS for this drive (`drive-emu eds`); returns its path."""
        path = self.workdir / f"drive-emu-{self.preset}-node{self.node_id}.eds"
        # REAL32 defaults as decimals: python canopen reads no other form
        cmd = [self.binary, "eds", "--preset", self.preset, "--node", str(self.node_id),
               "--real32", "decimal"]
        done = subprocess.run(cmd + self._set_args(), capture_output=True, text=True,
                              timeout=120)
        if done.returncode != 0:
            raise DriveEmuError(f"{' '.join(cmd)} failed:\n{done.stderr}")
        path.write_text(done.stdout)
        self.eds_path = str(path)
        return self.eds_path

    def command(self):
        """The `drive-emu run` command line."""
        bus = (["--socketcand", self.socketcand_addr] if self.socketcand_addr
               else ["--iface", self.iface])
        cmd = [self.binary, "run", *bus, "--node", str(self.node_id),
               "--preset", self.preset, "--ready", "--json",
               # unprivileged and inside user-mode Linux: no SCHED_FIFO, no mlockall
               "--rt-priority", "0", "--no-mlock"]
        cmd += self._set_args()
        if self.lockstep:
            cmd.append("--lockstep")
        if self.sync_period_us is not None:
            cmd += ["--sync-period-us", str(self.sync_period_us)]
        if self.boot_delay_ms is not None:
            cmd += ["--boot-delay-ms", str(self.boot_delay_ms)]
        return cmd + self.extra_args

    def start(self):
        """Write the EDS, start the drive and wait for its ready line."""
        if self.eds_path is None:
            self.write_eds()
        self._proc = subprocess.Popen(self.command(), stdin=subprocess.DEVNULL,
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                      text=True, bufsize=1)
        self._threads = [
            threading.Thread(target=self._pump, args=(self._proc.stdout, self._stdout.put),
                             daemon=True),
            threading.Thread(target=self._pump, args=(self._proc.stderr, self.stderr.append),
                             daemon=True),
        ]
        for t in self._threads:
            t.start()
        deadline = time.monotonic() + self.ready_timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                self.stop(check=False)
                raise DriveEmuError(f"drive-emu not ready within {self.ready_timeout} s; "
                                    f"stderr:\n{self.stderr_text()}")
            try:
                line = self._stdout.get(timeout=min(left, 0.5))
            except queue.Empty:
                if self._proc.poll() is not None:
                    for t in self._threads:
                        t.join(timeout=5)
                    raise DriveEmuError(f"drive-emu exited with {self._proc.returncode} "
                                        f"before it was ready; stderr:\n{self.stderr_text()}")
                continue
            if line is None:
                continue
            try:
                msg = json.loads(line)
            except ValueError:
                continue
            if isinstance(msg, dict) and msg.get("event") == "ready":
                self.ready = msg
                sc = msg.get("socketcand")
                if sc:
                    self.socketcand = (sc["host"], sc["port"])
                    self._channel = sc["channel"]
                return self

    @staticmethod
    def _pump(stream, sink):
        for line in stream:
            sink(line.rstrip("\n"))
        stream.close()

    @property
    def pid(self):
        return self._proc.pid if self._proc else None

    def alive(self):
        return self._proc is not None and self._proc.poll() is None

    def stderr_text(self):
        return "\n".join(self.stderr)

    def stop(self, timeout=30.0, check=True):
        """SIGTERM, wait up to `timeout` s (then SIGKILL), parse the exit statistics.

        With `check`, raise DriveEmuError unless the drive exited 0 with statistics."""
        if self._proc is None:
            return self.exit_statistics
        if self._proc.poll() is None:
            self._proc.send_signal(signal.SIGTERM)
            try:
                self._proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
        self.returncode = self._proc.returncode
        for t in self._threads:
            t.join(timeout=10)
        rest = []
        while not self._stdout.empty():
            rest.append(self._stdout.get())
        text = "\n".join(rest).strip()
        if text:
            try:
                stats = json.loads(text)
                # `run --json` prints {"stats": {...}, ...}: the loop statistics at the top
                # level, the rest (lock-step period, free-run ticks) beside them.
                if isinstance(stats, dict) and isinstance(stats.get("stats"), dict):
                    stats = {**{k: v for k, v in stats.items() if k != "stats"}, **stats["stats"]}
                self.exit_statistics = stats
            except ValueError:
                self.exit_statistics = None
        self._proc = None
        if self._own_dir:
            shutil.rmtree(self.workdir, ignore_errors=True)
        if check:
            if self.returncode != 0:
                raise DriveEmuError(f"drive-emu exited with {self.returncode}; stderr:\n"
                                    f"{self.stderr_text()}")
            if self.exit_statistics is None:
                raise DriveEmuError(f"drive-emu printed no exit statistics; stdout:\n{text}")
            if "panicked" in self.stderr_text():
                raise DriveEmuError(f"drive-emu panicked:\n{self.stderr_text()}")
        return self.exit_statistics

    # ---- while it runs
    @property
    def can_args(self):
        """python-can bus arguments that reach this drive: `can.Bus(**emu.can_args)`,
        `network.connect(**emu.can_args)`."""
        if self.socketcand:
            host, port = self.socketcand
            return {"interface": "socketcand", "host": host, "port": port,
                    "channel": self._channel}
        return {"interface": "socketcan", "channel": self.iface}

    def statistics(self, node):
        """The loop statistics (0x2100) read over SDO with a python canopen node."""
        return {name: int.from_bytes(node.sdo.upload(0x2100, sub + 1), "little")
                for sub, name in enumerate(STATISTICS)}

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop(check=exc[0] is None)
        return False
