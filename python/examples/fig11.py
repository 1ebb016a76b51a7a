"""The paper's Fig. 11 from Python: the limit cycle's frequency f against the position gain k_v,
each of the five presets at its own backlash over half to twice its own k_v, every point a
simulated run. Checks what the figure claims (Moosavian & MohammadiAsl, eq. 11-13): every run
oscillates with k_v/4 < f < k_v, and f is proportional to k_v, f = 0.6 k_v.

    python python/examples/fig11.py [--png fig11.png]      # needs drive-emu[table] (+ [plot])
"""
import argparse
import sys

import numpy as np

import drive_emu

ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
ap.add_argument("--png", help="draw the figure into this PNG file (matplotlib)")
args = ap.parse_args()

cases = [{"preset": name, "kv_per_s": kv}
         for name, p in drive_emu.presets().items()
         for kv in p["kv_per_s"] * np.linspace(0.5, 2.0, 7)]
t = drive_emu.sweep(cases, progress=False)

slope = float(np.sum(t.fundamental_hz * t.kv_per_s) / np.sum(t.kv_per_s ** 2))
print(t.groupby("preset").f_over_kv.agg(["min", "max"]).round(3).to_string())
print(f"{len(t)} runs: f = {slope:.3f} k_v (least squares through 0), f/k_v "
      f"{t.f_over_kv.min():.3f}..{t.f_over_kv.max():.3f}")

failed = []
if not t.limit_cycle.all():
    failed.append(f"no limit cycle in {(~t.limit_cycle).sum()} runs")
if not t.in_band.all():  # eq. 11, 12
    failed.append(f"{(~t.in_band).sum()} runs outside k_v/4 < f < k_v")
if abs(slope - 0.6) > 0.05:  # eq. 13, "with an acceptable accuracy"
    failed.append(f"f = {slope:.3f} k_v, not 0.6 k_v within 0.05")
if not t.f_over_kv.between(0.5, 0.7).all():
    failed.append("a run's f/k_v outside 0.6 +- 0.1")

if args.png:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 5))
    for name, g in t.groupby("preset"):
        ax.plot(g.kv_per_s, g.fundamental_hz, "o", label=name)
    k = np.linspace(0, t.kv_per_s.max() * 1.05, 2)
    for factor, style, label in [(1, "k--", "k_v"), (0.6, "k-", "0.6 k_v"), (0.25, "k:", "k_v/4")]:
        ax.plot(k, factor * k, style, lw=1, label=label)
    ax.set(xlabel="k_v [1/s]", ylabel="f [Hz]",
           title="Fig. 11: limit-cycle frequency against k_v (simulated runs)")
    ax.legend()
    fig.savefig(args.png, dpi=100)
    print(f"figure: {args.png}")

if failed:
    sys.exit("Fig. 11 claim FAILED: " + "; ".join(failed))
print("Fig. 11 claim holds: k_v/4 < f < k_v on every run, f = 0.6 k_v")
