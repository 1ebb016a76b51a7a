"""The axis FMU (`drive-emu fmu`) under FMPy, an independent FMI 2.0 importer.

Usage: fmu_fmpy.py DRIVE_EMU_BIN FMU_LIBRARY WORKDIR

For k_v over a sweep (20, 30, 45 1/s) on cnc1 with 0.05 mm backlash:
- the FMU that `drive-emu fmu` writes validates clean (fmpy.validate_fmu);
- FMPy simulates it in co-simulation with sim's own position set-points as input (the same
  input), 1 ms communication steps;
- the limit cycle's frequency in the FMU's following error equals that of `drive-emu sim`'s
  trace within 2 %, both measured by the one method below, and f / k_v is the paper's
  (0.45 .. 0.75).
A healthy axis (no backlash) shows no limit cycle in the FMU's output. Prints one line per
case and exits non-zero on the first failed check.
"""

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

BIN, LIB, WORK = sys.argv[1], sys.argv[2], Path(sys.argv[3])
WORK.mkdir(parents=True, exist_ok=True)
DURATION_S = 4.0
VELOCITY_MM_S = 10.0
WINDOW_START_S = 1.5


def dominant_hz(t, x):
    """Frequency of the largest peak of x's spectrum over the window (detrended, Hann,
    zero-padded 16x, parabolic interpolation of the peak), 2 Hz and up."""
    keep = t >= WINDOW_START_S
    t, x = t[keep], x[keep]
    dt = float(np.median(np.diff(t)))
    x = x - np.polyval(np.polyfit(t, x, 1), t)
    n = len(x) * 16
    spec = np.abs(np.fft.rfft(x * np.hanning(len(x)), n))
    freqs = np.fft.rfftfreq(n, dt)
    lo = np.searchsorted(freqs, 2.0)
    k = lo + int(np.argmax(spec[lo:]))
    a, b, c = np.log(spec[k - 1 : k + 2] + 1e-300)
    p = 0.5 * (a - c) / (a - 2 * b + c)
    return float((k + p) * (freqs[1] - freqs[0])), float(np.ptp(x))


def sim(kv, backlash_mm):
    trace = WORK / f"sim-{kv}-{backlash_mm}.csv"
    subprocess.run(
        [BIN, "sim", "--preset", "cnc1", "--set", f"kv_per_s={kv}", "--set",
         f"backlash_mm={backlash_mm}", "--velocity", str(VELOCITY_MM_S), "--duration",
         str(DURATION_S), "--trace", str(trace), "--json"],
        check=True, stdout=subprocess.DEVNULL)
    with open(trace) as f:
        rows = list(csv.DictReader(f))
    col = lambda k: np.array([float(r[k]) for r in rows])
    return col("time_s"), col("position_setpoint_mm"), col("following_error_mm")


def fmu(kv, backlash_mm):
    path = WORK / f"axis-{kv}-{backlash_mm}.fmu"
    subprocess.run(
        [BIN, "fmu", "--preset", "cnc1", "--set", f"kv_per_s={kv}", "--set",
         f"backlash_mm={backlash_mm}", "--library", LIB, "-o", str(path)],
        check=True, stderr=subprocess.DEVNULL)
    return path


def same_input(t, setpoint, kv, mass_kg):
    """sim's input as the FMU's: row k of sim's trace (time (k+1) ms) holds the set-point of
    the cycle that starts at k ms, where the FMU takes it; sim's knock (0.6 x the velocity
    from a 5 ms force pulse on the load, 5 / k_v after the 0.1 s start ramp) as load_force_n."""
    dt = 1e-3
    start = t - dt
    kick_start = int(np.ceil((0.1 + 5.0 / kv) / dt - 1e-9))
    force = mass_kg * 0.6 * VELOCITY_MM_S * 1e-3 / (5 * dt)
    k = np.rint(start / dt).astype(int)
    load = np.where((k >= kick_start) & (k < kick_start + 5), force, 0.0)
    return np.array(list(zip(start, setpoint, np.zeros_like(start), load)),
                    dtype=[("time", np.float64), ("position_setpoint_mm", np.float64),
                           ("velocity_setpoint_mm_per_s", np.float64), ("load_force_n", np.float64)])


def check(ok, what):
    if not ok:
        print("FAILED:", what)
        sys.exit(1)


def main():
    for kv in (20.0, 30.0, 45.0):
        t, setpoint, fe_sim = sim(kv, 0.05)
        path = fmu(kv, 0.05)
        problems = validate_fmu(str(path))
        check(problems == [], f"validate_fmu: {problems}")
        md = read_model_description(str(path))
        names = {v.name: v for v in md.modelVariables}
        check(names["backlash_mm"].start == "0.05", f"backlash_mm start {names['backlash_mm'].start}")
        check(float(names["kv_per_s"].start) == kv, f"kv_per_s start {names['kv_per_s'].start}")
        check(names["position_setpoint_mm"].causality == "input", "input")
        signals = same_input(t, setpoint, kv, float(names["carriage_mass_kg"].start))
        res = simulate_fmu(str(path), fmi_type="CoSimulation", stop_time=DURATION_S,
                           step_size=1e-3, output_interval=1e-3, input=signals,
                           output=["following_error_mm", "direct_encoder_position_mm"])
        f_fmu, p2p_fmu = dominant_hz(res["time"], res["following_error_mm"])
        f_sim, p2p_sim = dominant_hz(t, fe_sim)
        print(f"k_v {kv:5.1f}: FMU {f_fmu:7.3f} Hz ({f_fmu / kv:.3f} k_v, p2p {p2p_fmu * 1e3:.1f} um), "
              f"sim {f_sim:7.3f} Hz ({f_sim / kv:.3f} k_v, p2p {p2p_sim * 1e3:.1f} um)")
        check(abs(f_fmu - f_sim) <= 0.02 * f_sim, f"k_v {kv}: FMU {f_fmu} Hz vs sim {f_sim} Hz")
        check(0.45 <= f_fmu / kv <= 0.75, f"k_v {kv}: f/k_v {f_fmu / kv}")
        check(p2p_fmu > 1e-3, f"k_v {kv}: no limit cycle in the FMU ({p2p_fmu} mm p2p)")
        # Where it ends: the direct encoder follows the ramp, v / k_v behind (the P loop's lag).
        end = res["direct_encoder_position_mm"][-1]
        lag = VELOCITY_MM_S / kv
        check(abs(setpoint[-1] - end - lag) < 0.1,
              f"k_v {kv}: direct encoder at {end} mm, set-point {setpoint[-1]}, lag {lag}")
    # Healthy axis: no limit cycle (the following error settles to a small constant), even
    # after the knock.
    t, setpoint, _ = sim(30.0, 0.0)
    path = fmu(30.0, 0.0)
    signals = same_input(t, setpoint, 30.0, 800.0)
    res = simulate_fmu(str(path), fmi_type="CoSimulation", stop_time=DURATION_S, step_size=1e-3,
                       output_interval=1e-3, input=signals, output=["following_error_mm"])
    keep = res["time"] >= WINDOW_START_S
    p2p = float(np.ptp(res["following_error_mm"][keep]))
    print(f"healthy: following error p2p {p2p * 1e3:.3f} um")
    check(p2p < 1e-3, f"healthy axis: following error p2p {p2p} mm")
    print("fmu_fmpy: all checks passed")


main()
