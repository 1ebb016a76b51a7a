"""drive_emu.sim against `drive-emu sim`: the same inputs give the same summary, field by field,
and the same trace (to the CSV's printed precision); the trace as numpy arrays and a DataFrame."""
import csv
import math

import numpy as np
import pytest

import drive_emu

# (preset, set, velocity, duration, accel, kick): linear and rotary axes, with and without
# backlash, a negative speed, a given ramp and kick, no kick.
CASES = [
    ("cnc1", {"backlash_mm": 0.05}, 16.7, 3.0, None, None),
    ("cnc1", {"backlash_mm": 0.0}, 20.0, 3.0, None, None),
    ("cnc1", {"backlash_mm": 0.03, "kv_per_s": 45.0}, -12.5, 2.5, 500.0, 4.0),
    ("cnc3", {}, 9.36, 4.0, None, None),
    ("cnc4", {"backlash_mm": 0.04, "load_coulomb_friction_n": 80}, 20.0, 3.0, None, 0.0),
    ("cnc5", {"backlash_deg": 0.02, "motor_encoder_noise_counts": 2.0, "noise_seed": 7},
     9.0, 3.0, None, None),
]


NINE_DECIMALS = ("position_setpoint", "direct_encoder", "motor_encoder_position", "load_velocity",
                 "following_error")


def cli_args(preset, sets, velocity, duration, accel, kick):
    args = ["sim", "--preset", preset, "--velocity", repr(velocity), "--duration", repr(duration),
            "--json"]
    for k, v in sets.items():
        args += ["--set", f"{k}={v}"]
    if accel is not None:
        args += ["--accel", repr(accel)]
    if kick is not None:
        args += ["--kick", repr(kick)]
    return args


def py_kwargs(preset, sets, velocity, duration, accel, kick):
    kw = dict(set=sets, velocity=velocity, duration=duration)
    if accel is not None:
        kw["accel"] = accel
    if kick is not None:
        kw["kick"] = kick
    return kw


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c[0]}-{c[2]}")
def test_summary_equals_cli_json_field_by_field(cli, case):
    want = cli.json(*cli_args(*case))
    got = drive_emu.sim(case[0], **py_kwargs(*case)).summary
    assert list(got) == list(want), "the same fields in the same order"
    for key in want:
        assert got[key] == want[key], f"{key}: python {got[key]!r} != cli {want[key]!r}"


def test_trace_equals_cli_trace_csv(cli, tmp_path):
    case = CASES[0]
    path = tmp_path / "t.csv"
    cli(*cli_args(*case), "--trace", path)
    run = drive_emu.sim(case[0], **py_kwargs(*case))
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], np.array(rows[1:], dtype=float)
    assert header == run.columns
    assert body.shape == (len(run), len(header))
    for j, name in enumerate(header):
        # the CSV prints positions and speeds in mm with 9 decimals, the rest with 6: equal to
        # within half its last digit
        fine = name.startswith(NINE_DECIMALS)
        tol = (0.5e-9 if fine else 0.5e-6) * 1.0001
        np.testing.assert_allclose(run[name], body[:, j], rtol=0, atol=tol, err_msg=name)


def test_trace_is_numpy_and_to_pandas_holds_the_same():
    run = drive_emu.sim("cnc3", velocity=9.36, duration=2.0)
    assert run.columns == drive_emu._native.trace_columns("deg")
    for name, a in run.trace.items():
        assert isinstance(a, np.ndarray) and a.dtype == np.float64 and a.shape == (len(run),), name
    t = run["time_s"]
    assert np.all(np.diff(t) > 0), "time increases"
    np.testing.assert_allclose(np.diff(t), 1e-3, rtol=1e-9)  # cnc3's 1 ms position cycle
    df = run.to_pandas()
    assert list(df.columns) == run.columns and len(df) == len(run)
    for name in run.columns:
        np.testing.assert_array_equal(df[name].to_numpy(), run[name])


def test_window_trace_is_the_analysed_window():
    full = drive_emu.sim("cnc1", set={"backlash_mm": 0.05}, velocity=16.7, duration=3.0)
    window = drive_emu.sim("cnc1", set={"backlash_mm": 0.05}, velocity=16.7, duration=3.0,
                           trace="window")
    assert window.summary == full.summary
    start = window.summary["window_start_s"]
    assert math.isclose(window["time_s"][0], start + 1e-3, rel_tol=1e-9)
    n = len(window)
    np.testing.assert_array_equal(window["motor_velocity_rpm"], full["motor_velocity_rpm"][-n:])


def test_the_paper_law_holds_from_python():
    """f set by k_v, not by the gap: the same f at 0.02 and 0.07 mm, amplitude growing with it."""
    runs = [drive_emu.sim("cnc1", set={"backlash_mm": b}, velocity=20.0, duration=4.0)
            for b in (0.02, 0.045, 0.07)]
    fs = [r.summary["fundamental_hz"] for r in runs]
    amps = [r.summary["load_velocity_half_p2p"] for r in runs]
    assert max(fs) / min(fs) < 1.01, fs
    assert all(0.5 < r.summary["f_over_kv"] < 0.7 for r in runs)
    assert amps[0] < amps[1] < amps[2], amps
