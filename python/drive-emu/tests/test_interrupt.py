"""Ctrl-C interrupts a run: SIGINT to a python process in a long sim (or sweep) raises
KeyboardInterrupt out of the native call, the run's threads stop, and the module works on.

No timing is asserted: a run that ignored the signal would finish and print `finished`, or
raise a KeyboardInterrupt after its end (once the call returned), without the note a stopped
run adds to the exception: how far it got (simulated time, runs done), checked to be short of
the end. The runs are long enough (several seconds even on an idle
machine) that the signal, sent after the child says it is running, lands inside them.
"""
import re
import signal
import subprocess
import sys
import time

import pytest

CHILD = r"""
import sys
import drive_emu
call = sys.argv[1]
drive_emu.sweep({"duration": 2.0}, progress=False)  # imports pandas before the long run
print("running", flush=True)
try:
    if call == "sim":
        # 4000 simulated s: 2-8 s of work; only the analysis window kept
        drive_emu.sim("cnc1", velocity=10.0, duration=4000.0, trace="window")
    else:
        # 20000 cases of 8 s: minutes of work on two threads
        drive_emu.sweep({"kv_per_s": [20.0 + i * 1e-3 for i in range(20000)]}, workers=2,
                        progress=False)
    print("finished", flush=True)
except KeyboardInterrupt as e:
    print("interrupted:", *getattr(e, "__notes__", ["no note"]), flush=True)
r = drive_emu.sim(velocity=10.0, duration=1.0)
print("after", r.summary["preset"], flush=True)
"""


@pytest.mark.parametrize("call", ["sim", "sweep"])
def test_sigint_interrupts_a_long_run(call):
    child = subprocess.Popen([sys.executable, "-c", CHILD, call], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "running"
        time.sleep(0.5)  # into the native call (not a measurement: nothing is timed)
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=600)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == 0, err
    lines = out.splitlines()
    assert "finished" not in lines, f"the {call} ran to its end despite SIGINT: {out}"
    # The note says how far the run got when the signal stopped it: not to its end.
    if call == "sim":
        m = re.fullmatch(r"interrupted: drive_emu.sim: stopped at (\S+) of 4000 simulated s",
                         lines[0])
        assert m and 0 < float(m[1]) < 4000.0, out
    else:
        m = re.fullmatch(r"interrupted: drive_emu.sweep: stopped after (\d+) of 20000 runs",
                         lines[0])
        assert m and int(m[1]) < 20000, out
    assert lines[1] == "after cnc1", out
