"""drive-emu for researchers: the simulated worn CNC axis, the backlash detector and
parameter sweeps, from Python.

    import drive_emu
    run = drive_emu.sim("cnc1", set={"backlash_mm": 0.05}, velocity=16.7, duration=3)
    run.summary["fundamental_hz"]           # the limit cycle's frequency, Hz
    run.trace["motor_velocity_rpm"]         # numpy arrays, one row per position cycle
    run.to_pandas()                         # a DataFrame (pandas installed)
    drive_emu.analyze(run).verdict          # the backlash detector on the trace
    table = drive_emu.sweep({"preset": "cnc1", "kv_per_s": [15, 30, 60],
                             "backlash_mm": [0.02, 0.05]}, workers=2, out="sweep.parquet")

The same code as `drive-emu sim`, `analyze`, `sweep`, `eds` and `presets` runs underneath
(the extension module `drive_emu._native`, built from the emulator's library): `sim` gives
what `drive-emu sim --json` prints for the same inputs. Runs release the GIL; Ctrl-C stops a
run (KeyboardInterrupt); a bug in the emulator raises `InternalError`, never crashes the
interpreter; bad arguments raise ValueError or TypeError naming the argument and the reason.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import numbers
import os
import sys
import warnings
from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import Any, Optional

import numpy as np

from . import _native
from ._native import InternalError

__all__ = [
    "sim",
    "SimResult",
    "analyze",
    "Detection",
    "presets",
    "eds",
    "sweep",
    "InternalError",
    "DEFAULT_SWEEP_DURATION_S",
]
__version__ = _native.__version__

#: Simulated seconds of a sweep case unless the grid says `duration` (as `drive-emu sweep`).
DEFAULT_SWEEP_DURATION_S: float = _native.DEFAULT_SWEEP_DURATION_S

_PIP_HINT = "pip install './python/drive-emu[table]'"


# ---- argument checks: the argument's name and the reason -------------------------------------

def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name}: expected a number, got {type(value).__name__} {value!r}")
    return float(value)


def _opt_number(name: str, value: Any) -> Optional[float]:
    return None if value is None else _number(name, value)


def _text(name: str, value: Any) -> str:
    if not isinstance(value, str):
        raise TypeError(f"{name}: expected a string, got {type(value).__name__} {value!r}")
    return value


def _toml_value(key: str, value: Any) -> str:
    """A preset value as the TOML text `--set key=value` takes."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        v = float(value)
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(value, str):
        return value
    raise TypeError(f"set[{key!r}]: expected a number, bool or string, got "
                    f"{type(value).__name__} {value!r}")


def _sets(set: Any) -> list[str]:
    """`set={"backlash_mm": 0.05}` (or `["backlash_mm=0.05"]`) as `--set` strings."""
    if set is None:
        return []
    if isinstance(set, Mapping):
        out = []
        for k, v in set.items():
            if not isinstance(k, str):
                raise TypeError(f"set: keys are preset keys (strings), got {k!r}")
            out.append(f"{k}={_toml_value(k, v)}")
        return out
    if isinstance(set, str):
        raise TypeError("set: expected a dict {key: value} (or a list of 'key=value'), "
                        f"got the string {set!r}")
    if isinstance(set, Iterable):
        out = []
        for s in set:
            if not isinstance(s, str) or "=" not in s:
                raise ValueError(f"set: {s!r}: an override is written 'key=value'")
            out.append(s)
        return out
    raise TypeError(f"set: expected a dict {{key: value}}, got {type(set).__name__}")


# ---- sim --------------------------------------------------------------------------------------

class SimResult:
    """One constant-velocity run: `summary` (dict, as `drive-emu sim --json`) and `trace`
    (dict of numpy arrays named as the columns of `sim --trace`, units in the names: time_s,
    position_setpoint_mm, direct_encoder_position_mm, motor_encoder_position_mm,
    motor_velocity_rpm, load_velocity_mm_per_s, motor_torque_nm, motor_current_a,
    following_error_mm; deg on rotary axes)."""

    __slots__ = ("summary", "trace")

    def __init__(self, summary: dict, trace: dict):
        self.summary = summary
        self.trace = trace

    def __getitem__(self, column: str) -> np.ndarray:
        return self.trace[column]

    def __len__(self) -> int:
        return len(self.trace["time_s"])

    @property
    def columns(self) -> list[str]:
        return list(self.trace)

    def to_pandas(self):
        """The trace as a pandas DataFrame (a copy; one row per position cycle)."""
        try:
            import pandas as pd
        except ImportError as e:
            raise ImportError(f"SimResult.to_pandas() needs pandas: {_PIP_HINT}") from e
        return pd.DataFrame(self.trace)

    def __repr__(self) -> str:
        s = self.summary
        f = s.get("fundamental_hz")
        return (f"SimResult({s['preset']}, v={s['velocity']} {s['unit']}/s, "
                f"k_v={s['kv_per_s']} 1/s, backlash={s['backlash']} {s['unit']}, "
                f"f={'none' if f is None else f'{f:.2f} Hz'}, {len(self)} samples)")


def sim(preset: str = "cnc1", *, velocity: float, set: Any = None, duration: float = 5.0,
        accel: float = 0.0, kick: Optional[float] = None, trace: str = "full",
        max_memory_mb: float = _native.DEFAULT_MAX_MEMORY_MB) -> SimResult:
    """Run a preset axis at constant `velocity` (mm/s, deg/s on rotary axes) for `duration`
    simulated seconds: `drive-emu sim --preset PRESET --set K=V ... --velocity V --duration D`.

    `set`: preset overrides {key: value} (`drive-emu presets`, docs/physics.md). `accel`: the
    start ramp (0: reach the velocity in 0.1 s). `kick`: the start disturbance, a load velocity
    change (default 0.6 x velocity, 0 = none). `trace`: "full" (every position cycle) or
    "window" (the analysed window only, less memory). Returns a `SimResult`."""
    if trace not in ("full", "window"):
        raise ValueError(f"trace: {trace!r}: 'full' or 'window'")
    summary, columns = _native.sim(
        _text("preset", preset), _sets(set), _number("velocity", velocity),
        _number("duration", duration), _number("accel", accel), _opt_number("kick", kick),
        _number("max_memory_mb", max_memory_mb), trace == "full")
    return SimResult(json.loads(summary), columns)


# ---- analyze ----------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Detection:
    """The backlash detector's result (`drive-emu analyze --json`): the verdict ("ok",
    "backlash_suspected", "backlash" or "inconclusive") with its reasons, the limit cycle's
    frequency and amplitude (position unit: um or mdeg), every measured window, and what was
    read. `backlash_estimate` is the gap in `backlash_estimate_unit` ("mm", or "deg" on a
    rotary axis; the report's `backlash_estimate_mm` / `_deg`), `backlash_estimate_range`
    (lo, hi) the range it lies in, `backlash_estimate_method` "encoders" (motor minus direct
    encoder), "amplitude" (the limit cycle's) or "amplitude_lower_bound" (set-points with
    noise quench the limit cycle: the range reaches higher); all None on a healthy axis or where it
    cannot be said. `report` is the whole detector report as a dict."""

    verdict: str
    reasons: list
    inconclusive: Optional[str]
    frequency_hz: Optional[float]
    frequency_over_kv: Optional[float]
    dominant_hz: Optional[float]
    amplitude: float
    severity: float
    position_unit: str
    lost_motion: Optional[float]
    backlash_estimate: Optional[float]
    backlash_estimate_range: Optional[tuple]
    backlash_estimate_unit: str
    backlash_estimate_method: Optional[str]
    first_suspected_s: Optional[float]
    first_backlash_s: Optional[float]
    amplitude_trend_per_h: Optional[float]
    band_hz: tuple
    window_source: str
    windows: list
    forced_windows: list
    kv_per_s: float
    kv_source: str
    trace: str
    format: str
    notes: list
    capture: Optional[str]
    exit_code: int
    report_dir: Optional[str]
    plots: list
    report: dict = dataclasses.field(repr=False)

    @property
    def backlash_found(self) -> bool:
        return self.verdict in ("backlash", "backlash_suspected")

    @classmethod
    def _from_json(cls, text: str) -> "Detection":
        out = json.loads(text)
        rep = out["report"]
        keys = {f.name for f in dataclasses.fields(cls)}
        values = {k: v for k, v in rep.items() if k in keys}
        values.update({k: v for k, v in out.items() if k in keys and k != "report"})
        values["band_hz"] = tuple(rep["band_hz"])
        unit = "deg" if "backlash_estimate_deg" in rep else "mm"
        values["backlash_estimate"] = rep.get(f"backlash_estimate_{unit}")
        span = rep.get(f"backlash_estimate_range_{unit}")
        values["backlash_estimate_range"] = None if span is None else tuple(span)
        values["backlash_estimate_unit"] = unit
        values["backlash_estimate_method"] = rep.get("backlash_estimate_method")
        values["report_dir"] = out.get("report_dir") or None
        values["capture"] = out.get("capture")
        values["plots"] = out.get("plots", [])
        values["report"] = rep
        return cls(**values)


def _columns_of(trace: Any) -> Optional[list]:
    """Named float64 columns of a mapping or a DataFrame, or None."""
    if isinstance(trace, Mapping):
        items = trace.items()
    elif hasattr(trace, "columns") and hasattr(trace, "__getitem__") and not isinstance(trace, str):
        items = ((c, trace[c]) for c in trace.columns)
    else:
        return None
    cols = []
    for name, values in items:
        if not isinstance(name, str):
            raise TypeError(f"trace: column names are strings, got {name!r}")
        try:
            a = np.ascontiguousarray(values, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise TypeError(f"trace: column {name!r} is not numeric: {e}") from None
        if a.ndim != 1:
            raise ValueError(f"trace: column {name!r} must be one-dimensional, has shape {a.shape}")
        cols.append((name, a))
    return cols


def analyze(trace: Any, *, kv: Optional[float] = None, preset: Optional[str] = None,
            node: int = 5, rotary: Optional[bool] = None, suspect: Optional[float] = None,
            alarm: Optional[float] = None, sync_period_us: Optional[int] = None,
            out: Any = None) -> Detection:
    """Run the backlash detector (`drive-emu analyze`) on
    - a `SimResult` (k_v and units from its summary unless given),
    - a file: a candump log (`candump -L` or `-ta`, plain or gzip; decoded with the PDO mapping
      of drive `node` / `preset`), or a CSV trace of `run --trace`, `sim --trace` or a scenario
      report,
    - named columns (a dict of arrays or a pandas DataFrame) as those CSV files have them.

    k_v: `kv`, else the last 0x2007 written in a capture, else `preset`'s. `suspect` / `alarm`:
    the thresholds in um (mdeg on rotary axes). `out`: a directory to write the report to
    (detector.json and plots, as the CLI); by default nothing is written. Returns a
    `Detection`."""
    path = None
    columns = None
    source = "columns"
    kv_given_by = None if kv is None else "kv"
    if isinstance(trace, SimResult):
        columns = list(trace.trace.items())
        source = f"sim {trace.summary['preset']}"
        if kv is None:
            kv = trace.summary["kv_per_s"]
            kv_given_by = "the run's kv_per_s"
        if preset is None:
            # the run's preset: its mechanics for the gap estimate
            preset = trace.summary["preset"]
        if rotary is None:
            rotary = trace.summary["unit"] == "deg"
    elif isinstance(trace, (str, os.PathLike)):
        path = os.fspath(trace)
    else:
        columns = _columns_of(trace)
        if columns is None:
            raise TypeError("trace: expected a SimResult, a file path, a dict of arrays or a "
                            f"DataFrame, got {type(trace).__name__}")
    if rotary is None:
        rotary = False
    if not isinstance(rotary, bool):
        raise TypeError(f"rotary: expected a bool, got {type(rotary).__name__}")
    if isinstance(node, bool) or not isinstance(node, numbers.Integral) or not 1 <= node <= 127:
        raise ValueError(f"node: {node!r}: a node ID 1..127")
    if sync_period_us is not None and (isinstance(sync_period_us, bool)
                                       or not isinstance(sync_period_us, numbers.Integral)
                                       or not 0 < sync_period_us < 2**32):
        raise ValueError(f"sync_period_us: {sync_period_us!r}: a whole number of us > 0")
    text = _native.analyze(
        path, columns, source, _opt_number("kv", kv),
        None if preset is None else _text("preset", preset), int(node), rotary,
        _opt_number("suspect", suspect), _opt_number("alarm", alarm),
        None if sync_period_us is None else int(sync_period_us),
        None if out is None else os.fspath(out))
    detection = Detection._from_json(text)
    if kv_given_by is not None:
        detection = dataclasses.replace(detection, kv_source=kv_given_by)
    return detection


# ---- presets, eds -------------------------------------------------------------------------------

def presets() -> dict:
    """The presets by name (`drive-emu presets`): every key of the preset file (units in the
    names), plus `backlash` in the axis unit, `unit` (mm or deg) and `user_unit` (the unit of
    positions on the bus)."""
    return {p["name"]: p for p in json.loads(_native.presets())}


def eds(preset: str = "cnc1", *, node: Optional[int] = None, set: Any = None,
        real32: str = "bits", canopen_monitor: bool = False) -> str:
    """The drive's EDS (CiA 306) as text: `drive-emu eds --preset PRESET --node N --set K=V
    --real32 bits|decimal` (decimal: REAL32 defaults python canopen reads)."""
    if node is not None and (isinstance(node, bool) or not isinstance(node, numbers.Integral)
                             or not 1 <= node <= 127):
        raise ValueError(f"node: {node!r}: a node ID 1..127")
    if canopen_monitor and node is None:
        raise ValueError("canopen_monitor: needs node")
    return _native.eds(_text("preset", preset), None if node is None else int(node), _sets(set),
                       _text("real32", real32), bool(canopen_monitor))


# ---- sweep --------------------------------------------------------------------------------------

_RUN_KEYS = ("preset", "velocity", "duration")

#: Grid keys that moved to the parameter registry's names (one name per parameter in `--set`,
#: scenario files, `drive-emu sweep`, the panel and here): still taken for one release, with a
#: DeprecationWarning. `backlash` (in each preset's unit) is `backlash_mm` on a linear preset
#: and `backlash_deg` on a rotary one.
_MOVED_GRID_KEYS = {
    "kv": ("kv_per_s", "`kv_per_s`"),
    "backlash": (None, "`backlash_mm` (linear presets) or `backlash_deg` (rotary presets)"),
}


def _moved_grid_key(i: int, case: dict, key: str) -> str:
    """The key a case's `key` is sent as: a moved one warns (DeprecationWarning) and becomes
    its new name where it has one; given beside its new name it is refused."""
    moved = _MOVED_GRID_KEYS.get(key)
    if moved is None:
        return key
    new, said = moved
    # Attributed to the caller's line (the first frame outside this module), where Python's
    # default filters show a DeprecationWarning.
    level, frame = 1, sys._getframe(0)
    while frame is not None and frame.f_globals.get("__name__", "").startswith("drive_emu"):
        frame = frame.f_back
        level += 1
    warnings.warn(f"sweep grid key `{key}` is now {said} (the old name works for this "
                  "release)", DeprecationWarning, stacklevel=level)
    if new is None:
        return key
    if new in case:
        raise ValueError(f"case {i}: `{key}` and `{new}` both given: `{key}` is now `{new}`")
    return new


#: Most cases one sweep takes: its table is held in memory. A grid whose size is known
#: (len()) beyond this is refused before any case runs (a grid over range(10**9) said
#: MemoryError); an iterator without len() is read lazily and refused when it yields one case
#: more. The same cap as `drive-emu sweep`'s (one constant, drive_emu::study::MAX_SWEEP_CASES).
MAX_SWEEP_CASES: int = _native.MAX_SWEEP_CASES

#: Cases handed to the native sweep at a time (at least; more with many threads): a grid is
#: never built whole, only this many of its cases are held before they run.
_SWEEP_CHUNK: int = 256


def _too_many(n: Any) -> ValueError:
    return ValueError(f"grid: {n} cases, above the {MAX_SWEEP_CASES:,} one sweep takes (its "
                      "table is held in memory): split the grid into several sweeps")


def _bounded(values: Iterable, what: str) -> list:
    """At most MAX_SWEEP_CASES items of `values` (refused beyond: never a list without end)."""
    out = list(itertools.islice(values, MAX_SWEEP_CASES + 1))
    if len(out) > MAX_SWEEP_CASES:
        raise _too_many(f"{what}: more than {MAX_SWEEP_CASES:,}")
    return out


def _odometer(axes: list) -> Iterator[tuple]:
    """Every combination of the axes' values, the first axis varying slowest, made one at a
    time by index (an axis is a sequence: a range is never listed)."""
    if any(len(a) == 0 for a in axes):
        return
    index = [0] * len(axes)
    while True:
        yield tuple(a[i] for a, i in zip(axes, index))
        k = len(axes) - 1
        while k >= 0:
            index[k] += 1
            if index[k] < len(axes[k]):
                break
            index[k] = 0
            k -= 1
        if k < 0:
            return


def _grid_iter(grid: Any) -> tuple:
    """The cases of a grid as a lazy iterator, and their count where it is known (else None):
    a dict of key -> value or list of values (every combination, the first key varying
    slowest), a list or iterator of dicts (one case each) or a DataFrame (one case per row).
    A known count above MAX_SWEEP_CASES is refused here, before any case is made; an iterator
    without len() is refused when it yields case MAX_SWEEP_CASES + 1."""
    cap = MAX_SWEEP_CASES
    if hasattr(grid, "to_dict") and hasattr(grid, "columns") and hasattr(grid, "iloc"):
        n = len(grid)
        if n > cap:
            raise _too_many(f"{n:,}")

        def rows(df=grid, n=n):
            for i in range(0, n, _SWEEP_CHUNK):
                yield from (dict(r) for r in df.iloc[i:i + _SWEEP_CHUNK].to_dict("records"))
        return rows(), n
    if isinstance(grid, Mapping):
        keys = list(grid)
        axes = []
        for k in keys:
            v = grid[k]
            if isinstance(v, (str, bytes, numbers.Number)) or v is None:
                axes.append([v])
            elif isinstance(v, Sequence):
                axes.append(v)  # a list, a tuple, a range: indexed, never copied
            elif hasattr(v, "tolist") and hasattr(v, "__len__"):
                axes.append(v.tolist())  # a numpy array or a pandas Series (in memory already)
            elif isinstance(v, Iterable):
                # an iterator: its values are needed once per combination of the keys before
                # it, so they are kept (at most the cap; beyond it refused)
                axes.append(_bounded(v, f"grid[{k!r}]"))
            else:
                raise TypeError(f"grid[{k!r}]: expected a value or a list of values, got "
                                f"{type(v).__name__}")
            if len(axes[-1]) == 0:
                raise ValueError(f"grid[{k!r}]: no values")
        total = math.prod(len(a) for a in axes)
        if total > cap:
            raise _too_many(f"{total:,}")
        return (dict(zip(keys, combo)) for combo in _odometer(axes)), total
    if isinstance(grid, Iterable) and not isinstance(grid, (str, bytes)):
        n = len(grid) if hasattr(grid, "__len__") else None
        if n is not None and n > cap:
            raise _too_many(f"{n:,}")

        def cases(grid=grid):
            for i, c in enumerate(grid):
                if i >= cap:
                    raise _too_many(f"grid: more than {cap:,}")
                if not isinstance(c, Mapping):
                    raise TypeError(f"grid[{i}]: a case is a dict, got {type(c).__name__}")
                yield dict(c)
        return cases(), n
    raise TypeError("grid: expected a dict of lists, a list of dicts or a DataFrame, got "
                    f"{type(grid).__name__}")


def _grid_cases(grid: Any) -> list[dict]:
    """Every case of a grid as a list (see `_grid_iter`; at most MAX_SWEEP_CASES)."""
    return list(_grid_iter(grid)[0])


def _grid_size(grid: Any) -> Any:
    """How many cases `grid` has, without building them ("?" where that cannot be told)."""
    if isinstance(grid, Mapping):
        n = 1
        for v in grid.values():
            if isinstance(v, (str, bytes, numbers.Number)) or v is None:
                continue
            if not hasattr(v, "__len__"):
                return "?"
            n *= len(v)
        return n
    return len(grid) if hasattr(grid, "__len__") else "?"


def _add_note(e: BaseException, note: str) -> None:
    """`e.add_note(note)` (Python 3.11+), or the same `__notes__` list on 3.10."""
    notes = getattr(e, "__notes__", None)
    if notes is None:
        notes = []
        e.__notes__ = notes
    notes.append(note)


def _native_case(i: int, case: dict) -> tuple:
    for k in case:
        if not isinstance(k, str):
            raise TypeError(f"case {i}: keys are strings, got {k!r}")
    preset = case.get("preset", "cnc1")
    if not isinstance(preset, str):
        raise TypeError(f"case {i}: preset: expected a string, got {preset!r}")
    velocity = case.get("velocity")
    duration = case.get("duration", DEFAULT_SWEEP_DURATION_S)
    try:
        velocity = _opt_number("velocity", velocity)
        duration = _number("duration", duration)
        sets = [f"{_moved_grid_key(i, case, k)}={_toml_value(k, v)}" for k, v in case.items()
                if k not in _RUN_KEYS]
    except TypeError as e:
        raise TypeError(f"case {i}: {e}") from None
    return (preset, sets, velocity, duration)


def _rows(cases: list[dict], rows: list[dict]) -> list[dict]:
    """Each case's inputs (as given) followed by what it measured (the columns of
    `drive-emu sweep`)."""
    out = []
    for case, row in zip(cases, rows):
        r = {k: v for k, v in case.items() if k not in ("velocity", "duration")}
        r["duration_s"] = float(case.get("duration", DEFAULT_SWEEP_DURATION_S))
        r.update(row)
        out.append(r)
    return out


def _run_chunk(native_cases: list, first_index: int = 0) -> list:
    """One chunk of a sweep on a Dask worker (one thread: the worker's own)."""
    return json.loads(_native.sweep(native_cases, 1, None, first_index, None))


def _bar(total: Optional[int], progress: bool, desc: str):
    if not progress:
        return None
    from tqdm.auto import tqdm
    return tqdm(total=total, desc=desc, unit="run", smoothing=0.1)


def _chunks(cases: Iterator[dict], size: int) -> Iterator[tuple]:
    """A grid's cases (`_grid_iter`) in chunks of `size`, made as they are asked for: (index
    of the first case, the cases as given, the cases as the native sweep takes them)."""
    first = 0
    while True:
        chunk = list(itertools.islice(cases, size))
        if not chunk:
            return
        native = [_native_case(first + i, c) for i, c in enumerate(chunk)]
        yield first, chunk, native
        first += len(chunk)


def _sweep_chunks(cases: Iterator[dict], total: Optional[int], workers: int,
                  report=None) -> Iterator[tuple]:
    """The local sweep, lazily: each chunk of a grid's cases (`_grid_iter(grid)`: the cases
    and their count, None where unknown) is made, run on `workers` threads and yielded as
    (cases, rows) before the next is taken from the grid. `report(done)` is called with the
    count of finished runs."""
    threads = workers if workers > 0 else (os.cpu_count() or 1)
    size = max(_SWEEP_CHUNK, 16 * threads)
    for first, chunk, native in _chunks(cases, size):
        def progress(n, first=first):
            report(first + n)
        rows = json.loads(_native.sweep(native, int(workers), progress if report else None,
                                        first, total))
        yield chunk, rows


def sweep(grid: Any, *, workers: int = 0, client: Any = None, progress: bool = True,
          out: Any = None, chunk_size: Optional[int] = None):
    """Run every case of `grid` as `drive-emu sweep` runs one (a constant-velocity run
    measured from its motor speed) and return one row per case as a pandas DataFrame: the
    case's inputs, then fundamental_hz, f_over_kv, limit_cycle, in_band, drag_number,
    amplitudes, the window (the columns of `drive-emu sweep`).

    `grid`: {key: value or list of values} (every combination), a list or an iterator of case
    dicts, or a DataFrame; at most MAX_SWEEP_CASES (10^6) cases. The grid is never built
    whole: its cases are made a chunk at a time as the runs go. A grid whose size is known
    (len()) is refused beyond the cap before any case runs; an iterator without len() is
    refused with ValueError when it yields one case more than the cap (the cases before it
    have run; nothing is returned). Keys: `preset` (default cnc1), `velocity` (default 20
    mm/s, tables 0.026 r/s), `duration` (default 8 s, 2..600), and any preset key by its
    registry name, as `--set` takes it (kv_per_s, backlash_mm or on a rotary preset
    backlash_deg, load_coulomb_friction_n, motor_encoder_noise_counts, noise_seed, ...; a
    typo gets "did you mean"). The grid keys that moved, `kv` and `backlash` (in the preset's
    unit), are taken for this release with a DeprecationWarning.

    Runs on `workers` threads of this machine (0 = all cores), or, given a
    `dask.distributed.Client` as `client`, on its cluster in chunks of `chunk_size` cases
    (default: about 8 chunks per worker, 256 cases where the grid's size is unknown). `progress`: a tqdm bar. `out`: also write
    the table to this Parquet file (pyarrow). Ctrl-C stops the sweep (KeyboardInterrupt)."""
    try:
        import pandas as pd
    except ImportError as e:
        raise ImportError(f"sweep() returns a pandas DataFrame: {_PIP_HINT}") from e
    if isinstance(workers, bool) or not isinstance(workers, numbers.Integral) or workers < 0:
        raise ValueError(f"workers: {workers!r}: a number of threads >= 0 (0 = all cores)")
    # the size where it is known; a grid beyond the cap is refused here, before any run
    grid_cases, total = _grid_iter(grid)
    cases: list = []
    rows: list = []
    try:
        if client is None:
            bar = _bar(total, progress, "sweep")
            try:
                def report(n, bar=bar):
                    bar.update(n - bar.n)
                for chunk, chunk_rows in _sweep_chunks(grid_cases, total, int(workers),
                                                       report if bar else None):
                    cases.extend(chunk)
                    rows.extend(chunk_rows)
            finally:
                if bar is not None:
                    bar.close()
        else:
            _sweep_dask(client, grid_cases, total, progress, chunk_size, cases, rows)
    except KeyboardInterrupt as e:
        # Ctrl-C between two chunks (the native sweep notes one inside a chunk)
        if not any(str(n).startswith("drive_emu.sweep:") for n in getattr(e, "__notes__", [])):
            _add_note(e, f"drive_emu.sweep: stopped after {len(rows)} of "
                         f"{'?' if total is None else total} runs")
        raise
    table = pd.DataFrame.from_records(_rows(cases, rows))
    if out is not None:
        table.to_parquet(os.fspath(out), engine="pyarrow", index=False)
    return table


def _sweep_dask(client: Any, grid_cases: Iterator[dict], total: Optional[int], progress: bool,
                chunk_size: Optional[int], cases: list, rows: list) -> None:
    """The sweep on a Dask cluster: chunks made from the grid as the cluster takes them (at
    most two per worker waiting), the rows appended in the grid's order."""
    from distributed import as_completed
    n_workers = max(1, len(client.scheduler_info().get("workers", {})))
    if chunk_size is None:
        chunk_size = (_SWEEP_CHUNK if total is None
                      else max(1, math.ceil(total / (8 * n_workers))))
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, numbers.Integral) or chunk_size < 1:
        raise ValueError(f"chunk_size: {chunk_size!r}: a number of cases >= 1")
    chunks = _chunks(grid_cases, int(chunk_size))
    submitted = []  # (future, cases), in the grid's order
    pending = as_completed()
    bar = _bar(total, progress, "sweep (dask)")

    def submit() -> bool:
        nxt = next(chunks, None)
        if nxt is None:
            return False
        first, chunk, native = nxt
        f = client.submit(_run_chunk, native, first, pure=False)
        submitted.append((f, chunk))
        pending.add(f)
        return True

    try:
        for _ in range(2 * n_workers):
            if not submit():
                break
        sizes = {f.key: len(c) for f, c in submitted}
        for f in pending:
            if bar is not None:
                bar.update(sizes.get(f.key, 0))
            if submit():
                f2, c2 = submitted[-1]
                sizes[f2.key] = len(c2)
        parts = client.gather([f for f, _ in submitted])
    except BaseException:
        client.cancel([f for f, _ in submitted])
        raise
    finally:
        if bar is not None:
            bar.close()
    for (_, chunk), part in zip(submitted, parts):
        cases.extend(chunk)
        rows.extend(part)
