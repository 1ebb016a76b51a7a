"""The examples in python/examples run unchanged against a drive started by the fixture, on
vcan or over socketcand (no kernel CAN)."""
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.mark.parametrize("example, expect", [
    ("pp.py", ["booted", "mode PROFILED POSITION", "target reached at"]),
    ("pv.py", ["booted", "mode PROFILED VELOCITY", "PV at 10000 um/s"]),
    ("csp.py", ["booted", "mode CYCLIC SYNCHRONOUS POSITION", "CSP ramp"]),
])
@pytest.mark.drive_emu(node_id=26)
def test_example_runs_unchanged(drive_emu, example, expect):
    # The example's own flags for the bus the fixture's drive is on: vcan, or socketcand
    # where this machine has no kernel CAN.
    if drive_emu.socketcand:
        bus = ["--socketcand", "%s:%d" % drive_emu.socketcand]
    else:
        bus = ["--iface", drive_emu.iface]
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / example), *bus,
         "--node", str(drive_emu.node_id), "--eds", drive_emu.eds_path],
        capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{example} failed:\n{done.stdout}\n{done.stderr}\n" \
                                 f"drive stderr:\n{drive_emu.stderr_text()}"
    for text in expect:
        assert text in done.stdout, f"{example}: {text!r} missing in:\n{done.stdout}"
