"""Bad arguments raise ValueError or TypeError naming the argument (or key) and the reason; a
panic in the emulator raises InternalError and leaves the interpreter working."""
import subprocess
import sys

import numpy as np
import pytest

import drive_emu


@pytest.mark.parametrize("kwargs, error, words", [
    (dict(preset="cnc9", velocity=10), ValueError, ["preset", "cnc9", "cnc1"]),
    (dict(preset=1, velocity=10), TypeError, ["preset", "string"]),
    (dict(velocity="fast"), TypeError, ["velocity", "number", "str"]),
    (dict(velocity=True), TypeError, ["velocity", "number", "bool"]),
    (dict(velocity=5000), ValueError, ["velocity", "5000", "1000"]),
    (dict(velocity=float("nan")), ValueError, ["velocity", "finite"]),
    (dict(velocity=10, duration=-1), ValueError, ["duration", "> 0"]),
    (dict(velocity=10, duration=1e6), ValueError, ["duration", "max_memory_mb"]),
    (dict(velocity=10, accel=-3), ValueError, ["accel", ">= 0"]),
    (dict(velocity=10, kick=float("inf")), ValueError, ["kick", "finite"]),
    (dict(velocity=10, set={"backlash_mm": -0.1}), ValueError, ["backlash_mm", "0"]),
    (dict(velocity=10, set={"backlash_mm": 0.5e3}), ValueError, ["backlash_mm", "<="]),
    (dict(velocity=10, set={"no_such_key": 1}), ValueError, ["no_such_key", "unknown key"]),
    (dict(velocity=10, set={"kv_per_s": [30]}), TypeError, ["kv_per_s", "list"]),
    (dict(velocity=10, set={"kv_per_s": float("nan")}), ValueError, ["kv_per_s", "finite"]),
    (dict(velocity=10, set={"motor_encoder_counts_per_rev": 1.5}), ValueError,
     ["motor_encoder_counts_per_rev"]),
    (dict(velocity=10, set="backlash_mm=0.05"), TypeError, ["set", "dict"]),
    (dict(velocity=10, set=["backlash_mm"]), ValueError, ["set", "key=value"]),
    (dict(velocity=10, trace="all"), ValueError, ["trace", "full", "window"]),
])
def test_sim_bad_arguments(kwargs, error, words):
    with pytest.raises(error) as e:
        drive_emu.sim(**kwargs)
    text = str(e.value)
    for w in words:
        assert w in text, f"{w!r} missing in {error.__name__}: {text}"
    assert "--" not in text, f"CLI flag names in a Python error: {text}"


def test_sim_needs_a_velocity():
    with pytest.raises(TypeError, match="velocity"):
        drive_emu.sim("cnc1")


def test_analyze_bad_arguments(tmp_path):
    run = drive_emu.sim(velocity=16.7, duration=2.0)
    with pytest.raises(FileNotFoundError, match="nothing.csv"):
        drive_emu.analyze(tmp_path / "nothing.csv", kv=30)
    with pytest.raises(ValueError, match="no k_v: give kv, or preset"):
        drive_emu.analyze(dict(run.trace))
    with pytest.raises(ValueError, match=r"kv -1: must be within the drive.s range 1e-9 \.\. 1000"):
        drive_emu.analyze(run, kv=-1)
    with pytest.raises(ValueError, match="no column"):
        drive_emu.analyze({"time_s": run["time_s"]}, kv=30)
    with pytest.raises(TypeError, match="trace"):
        drive_emu.analyze(42, kv=30)
    with pytest.raises(TypeError, match="column 'x' is not numeric"):
        drive_emu.analyze({"x": ["a", "b"]}, kv=30)
    with pytest.raises(ValueError, match="node"):
        drive_emu.analyze(run, node=0)
    with pytest.raises(ValueError, match="preset.*cnc7"):
        drive_emu.analyze(run, preset="cnc7")
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,motor_velocity_rpm\n0.0,abc\n0.001,1.0\n")
    with pytest.raises(ValueError, match="bad.csv"):
        drive_emu.analyze(bad, kv=30)


def test_sweep_bad_arguments():
    with pytest.raises(ValueError, match=r"case 1 .*kv_per_s.*> 0"):
        drive_emu.sweep({"kv_per_s": [30, -1]}, progress=False)
    with pytest.raises(ValueError, match=r"no_such_key.*unknown key"):
        drive_emu.sweep({"no_such_key": [1]}, progress=False)
    with pytest.raises(ValueError, match=r"duration 1.*2\.\.600"):
        drive_emu.sweep({"duration": 1.0}, progress=False)
    with pytest.raises(ValueError, match=r"unknown preset `cnc0`"):
        drive_emu.sweep({"preset": ["cnc1", "cnc0"]}, progress=False)
    with pytest.raises(TypeError, match=r"case 0: velocity"):
        drive_emu.sweep([{"velocity": "slow"}], progress=False)
    with pytest.raises(TypeError, match=r"grid\[1\]: a case is a dict"):
        drive_emu.sweep([{}, 3], progress=False)
    with pytest.raises(ValueError, match=r"grid\['kv_per_s'\]: no values"):
        drive_emu.sweep({"kv_per_s": []}, progress=False)
    with pytest.raises(ValueError, match="workers"):
        drive_emu.sweep({}, workers=-2, progress=False)


def test_eds_bad_arguments():
    with pytest.raises(ValueError, match=r"(?s)invalid value 'hex'.*real32.*bits, decimal"):
        drive_emu.eds("cnc1", real32="hex")
    with pytest.raises(ValueError, match="node"):
        drive_emu.eds("cnc1", node=128)
    with pytest.raises(ValueError, match="unknown preset"):
        drive_emu.eds("cnc6")
    with pytest.raises(ValueError, match="kv_per_s"):
        drive_emu.eds("cnc1", set={"kv_per_s": 0})


def test_a_panic_becomes_internal_error_and_the_interpreter_goes_on():
    # In a child process: were the panic to abort, the child would die of SIGABRT.
    code = (
        "import drive_emu\n"
        "try:\n"
        "    drive_emu._native._panic_for_test('on purpose')\n"
        "except drive_emu.InternalError as e:\n"
        "    assert isinstance(e, RuntimeError)\n"
        "    print('caught:', e)\n"
        "r = drive_emu.sim(velocity=10.0, duration=1.0)\n"
        "print('after:', r.summary['preset'])\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert "caught: drive-emu panicked: on purpose" in done.stdout
    assert "after: cnc1" in done.stdout


def test_columns_of_any_float_like_type_are_taken():
    run = drive_emu.sim(set={"backlash_mm": 0.05}, velocity=16.7, duration=3.0)
    as_lists = {k: v.tolist() for k, v in run.trace.items()}
    as_f32 = {k: v.astype(np.float32) for k, v in run.trace.items()}
    a = drive_emu.analyze(as_lists, kv=30)
    b = drive_emu.analyze(run)
    c = drive_emu.analyze(as_f32, kv=30)
    assert a.report == b.report
    assert c.verdict == b.verdict == "backlash"
