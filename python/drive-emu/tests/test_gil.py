"""The GIL is released during a run: another Python thread runs (here: a whole short sim of its
own) while a long sim is inside its native call.

No timing: with the switch interval raised to 100 s, a thread that holds the GIL keeps it
until it gives it up itself. The long run's thread marks `started` and enters the native call;
the other thread can take the GIL only if that call released it. It then runs its short sim
and looks whether the long one has returned yet: it must not have (were the GIL held through
the call, the other thread would only get it after the long call returned).
"""
import sys
import threading

import drive_emu


def test_another_thread_runs_during_a_sim():
    state = {"started": False, "returned": False, "other_saw_returned": None}
    started = threading.Event()

    def long_run():
        state["started"] = True
        started.set()
        # about 1500 simulated s: 0.5-4 s of work, only the analysis window kept
        drive_emu.sim("cnc1", velocity=10.0, duration=1500.0, trace="window")
        state["returned"] = True

    def other():
        started.wait()
        drive_emu.sim("cnc3", velocity=9.36, duration=1.0)
        state["other_saw_returned"] = state["returned"]

    old = sys.getswitchinterval()
    sys.setswitchinterval(100.0)
    try:
        a = threading.Thread(target=long_run)
        b = threading.Thread(target=other)
        b.start()
        a.start()
        a.join(600)
        b.join(600)
    finally:
        sys.setswitchinterval(old)
    assert state["started"] and state["returned"]
    assert state["other_saw_returned"] is False, \
        "the other thread ran only after the long sim had returned: the GIL was held"
