#!/usr/bin/env python3
"""Runs per second per core: the Python module's sweep against `drive-emu sweep`, the same grid.

    python3 bench/python_sweep.py [--cases 105] [--duration 8] [--repeats 3] [--threads 1,2] [--dask]

The grid is `drive-emu sweep --preset all --kv 0.5x..2x:K --backlash 0.5x,1x,2x` (K chosen for
about --cases runs, 8 simulated s each, the CLI's default), given to `drive_emu.sweep` as the
same list of cases. Each measurement runs the CLI and the module alternately (--repeats
pairs), on 1 thread and on 2 (--threads); per pair it takes the wall time and the CPU time
(the CLI's from its rusage as a child, the module's from this process's rusage), and prints
runs per wall second per thread and runs per CPU second, their medians and the ratio module /
CLI. The CLI's wall time is its whole process (start-up, parsing, writing sweep.csv/json),
the module's the call of sweep() (case list, runs, DataFrame). With --dask, also a
dask.distributed LocalCluster with one worker per thread count (processes, one thread each).
The CLI: $DRIVE_EMU_BIN, else target/release/drive-emu, else drive-emu on the PATH. Not a
test: figures depend on the machine and its load (give the load average with them).
"""
import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import drive_emu

ROOT = Path(__file__).resolve().parent.parent


def cli_path():
    for p in (os.environ.get("DRIVE_EMU_BIN"), ROOT / "target/release/drive-emu",
              shutil.which("drive-emu")):
        if p and os.access(p, os.X_OK):
            return str(p)
    sys.exit("no drive-emu binary: cargo build --release -p drive-emu, or set DRIVE_EMU_BIN")


def grid(n_cases, duration):
    presets = drive_emu.presets()
    k = max(1, round(n_cases / (len(presets) * 3)))
    # as the CLI's ValueSpec computes 0.5x..2x:k, to the last bit
    mults = [0.5 + (i / (k - 1)) * (2.0 - 0.5) for i in range(k)] if k > 1 else [0.5]
    cases = [{"preset": name, "kv_per_s": m * p["kv_per_s"], "backlash": b * p["backlash"],
              "duration": duration}
             for name, p in presets.items() for m in mults for b in (0.5, 1.0, 2.0)]
    cli_args = ["--preset", "all", "--kv", f"0.5x..2x:{k}" if k > 1 else "0.5x",
                "--backlash", "0.5x,1x,2x", "--duration", str(duration)]
    return cases, cli_args


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def self_cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def run_cli(exe, cli_args, threads, out):
    c0, t0 = children_cpu(), time.perf_counter()
    subprocess.run([exe, "sweep", *cli_args, "--threads", str(threads), "--out", out],
                   check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0, children_cpu() - c0, json.loads(
        (Path(out) / "sweep.json").read_text())


def run_py(cases, threads, client=None):
    c0, t0 = self_cpu(), time.perf_counter()
    t = drive_emu.sweep(cases, workers=threads, client=client, progress=False)
    return time.perf_counter() - t0, self_cpu() - c0, t


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=105)
    ap.add_argument("--duration", type=float, default=8.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--dask", action="store_true")
    args = ap.parse_args()
    exe = cli_path()
    cases, cli_args = grid(args.cases, args.duration)
    n = len(cases)
    print(f"{n} cases of {args.duration} simulated s; CLI {exe}; load average "
          f"{' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    with tempfile.TemporaryDirectory() as tmp:
        for threads in [int(x) for x in args.threads.split(",")]:
            cli_w, cli_c, py_w, py_c = [], [], [], []
            for r in range(args.repeats):
                w, c, rows = run_cli(exe, cli_args, threads, tmp)
                cli_w.append(n / w / threads)
                cli_c.append(n / c)
                w, c, t = run_py(cases, threads)
                py_w.append(n / w / threads)
                py_c.append(n / c)
                if r == 0:  # the same runs: the same numbers
                    same = all(t.iloc[i][k] == v for i, row in enumerate(rows)
                               for k, v in row.items() if v is not None)
                    assert same, "the module's rows differ from the CLI's"
            m = statistics.median
            print(f"{threads} thread(s): runs per wall s per thread  CLI {m(cli_w):7.1f}  "
                  f"python {m(py_w):7.1f}  ratio {m(py_w) / m(cli_w):.3f}   "
                  f"(pairs: {', '.join(f'{p / c:.2f}' for p, c in zip(py_w, cli_w))})")
            print(f"{' ' * len(f'{threads} thread(s): ')}runs per CPU s              CLI "
                  f"{m(cli_c):7.1f}  python {m(py_c):7.1f}  ratio {m(py_c) / m(cli_c):.3f}")
            if args.dask:
                from distributed import Client, LocalCluster
                with LocalCluster(n_workers=threads, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, Client(cluster) as client:
                    client.run(lambda: __import__("drive_emu"))  # import before timing
                    dw = []
                    for _ in range(args.repeats):
                        w, _, _ = run_py(cases, threads, client)
                        dw.append(n / w / threads)
                print(f"{' ' * len(f'{threads} thread(s): ')}dask LocalCluster, {threads} "
                      f"worker(s): runs per wall s per worker {m(dw):7.1f}  ratio to the CLI "
                      f"{m(dw) / m(cli_w):.3f}")


if __name__ == "__main__":
    main()
