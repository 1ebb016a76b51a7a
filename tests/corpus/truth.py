#!/usr/bin/env python3
"""Ground truth of a corpus capture, measured independently of drive-emu's decoder.

Usage: truth.py CAPTURE.log.gz NODE MODE REMAPPED [LOCKSTEP]   (prints JSON; LOCKSTEP 1/0,
default 1)

The capture is read with python-can's candump log reader; the velocity actual 0x606C is taken
from the TPDO where the recording master put it (TPDO3: bytes 0-3 when the master remapped,
else bytes 2-5 after the statusword, the drive's default), sampled at every SYNC, and the
constant-speed part is the longest run where the speed, averaged over 0.25 s, stays within 10 % of
the most frequent cruise speed (the first 0.5 s dropped: the transient). numpy's FFT (Hann window) of that part gives
the limit cycle's frequency and its amplitude (zero-to-peak, um/s) and the displacement
equivalent A / (2 pi f) (um); `limit_cycle` is true when that line stands 8x above the
spectrum's median and is at least 1 um (the user unit): a worn axis in a position loop. A
worn axis in CSV/PV (speed loop only, no k_v) shows none: physically healthy-looking.

The master's own set-point (CSP target 0x607A, or the integral of the CSV target 0x60FF, from
the RPDO the master sent: RPDO1 bytes 2-5 when it remapped, else the default RPDO2 / RPDO3
bytes 2-5), held from SYNC to SYNC, is measured the same way over the same part: its strongest
line between 3 Hz and the search limit (`set_point_um`). Where the speed's line is 1 um or
more and the set-point itself moves by 1 um or more and by half that line or more (set-points that jitter by a
good part of a period, a set-point task that beats with SYNC), the axis is forced: `forced` is
true, and no limit cycle of its own can be measured (the case is inconclusive). An increment
above the median by half of it (or 2 um) is a catch-up; where such are a fifth of the
increments or fewer, they are SYNCs the capture lost (its time base counts SYNCs) and take the
median increment. Holds (the master sent nothing new) and patterns that beat with SYNC stay. The set position, its linear trend (the cruise) removed, is then analysed as a
displacement.

Time: with a lock-step drive (its clock is the SYNC count) sample k is at k x the median SYNC
interval, with the values received last before SYNC k. With a drive on its own clock
(`lockstep` false: a real-time drive) each synchronous TPDO answers one SYNC, in order (the
first TPDO3 after a SYNC answers the oldest SYNC it has not answered, at most 32 back), the
sample is at that SYNC's time stamp, and the samples are interpolated (numpy.interp) onto an
even grid of the median interval before the FFT; SYNCs never answered are left out.

A master that closes the position loop itself (mode `csvloop`: CSV whose target velocity is
v_ref + k (x_ref - x) on the direct encoder): its set-point follows the axis. Where the
target velocity over the cruise is fitted by numpy's least squares as a + b t - k x(t - lag),
x the direct encoder 0x60E4 sub 1 from TPDO4 0-3 samples earlier, and that explains 80 % or
more of its variation beyond the trend, `master_kv_fit` is k and the set-point's motion is the
loop's, not a force (`forced` false).
"""
import gzip
import json
import os
import sys
import tempfile

import can
import numpy as np


def read_frames(path):
    with gzip.open(path, "rt") as f:
        text = f.read()
    with tempfile.NamedTemporaryFile("w", suffix=".log", delete=False) as tmp:
        tmp.write(text)
        name = tmp.name
    try:
        return list(can.io.CanutilsLogReader(name))
    finally:
        os.remove(name)


def set_point_um(sp, dt, band):
    """Strongest line of the set position's own motion in `band` (Hz), um."""
    d = np.diff(sp)
    if len(d) < 16 or not np.all(np.isfinite(d)):
        return None
    med = np.median(d)
    catch_up = (d - med) * np.sign(med) > max(0.5 * abs(med), 2.0)
    if np.mean(catch_up) <= 0.2:
        d = np.where(catch_up, med, d)
    x = np.append(0.0, np.cumsum(d))
    i = np.arange(len(x))
    x = x - np.polyval(np.polyfit(i, x, 1), i)  # the cruise itself
    w = np.hanning(len(x))
    spec = np.abs(np.fft.rfft(x * w)) * 2.0 / np.sum(w)
    f = np.fft.rfftfreq(len(x), dt)
    sel = (f >= band[0]) & (f <= band[1]) & (f > 0)
    return float(np.max(spec[sel])) if np.any(sel) else None


def master_kv(v, x, dt):
    """k of v = a + b t - k x(t - lag), lag 0-3 samples, when x explains 80 % or more of v's
    variation beyond its trend (numpy least squares); else None."""
    best = None
    for lag in range(4):
        vv, xx = v[lag:], x[:len(x) - lag]
        if len(vv) < 16 or not np.all(np.isfinite(vv)):
            continue
        t = np.arange(len(vv)) * dt
        trend = np.vstack([np.ones_like(t), t]).T
        r0 = vv - trend @ np.linalg.lstsq(trend, vv, rcond=None)[0]
        a = np.vstack([np.ones_like(t), t, xx]).T
        coef = np.linalg.lstsq(a, vv, rcond=None)[0]
        r1 = vv - a @ coef
        ss0 = float(np.sum(r0 ** 2))
        if ss0 / len(vv) < 1.0:
            continue
        explained = 1.0 - float(np.sum(r1 ** 2)) / ss0
        if best is None or explained > best[0]:
            best = (explained, -coef[2])
    if best and best[0] >= 0.8 and 0 < best[1] <= 1000:
        return float(best[1])
    return None


def measure(path, node, mode, remapped, lockstep=True):
    frames = read_frames(path)
    tpdo3 = 0x380 + node
    tpdo4 = 0x480 + node
    off = 0 if remapped else 2
    off4 = 4 if remapped else 2  # 0x60E4 sub 1 in TPDO4: after 0x6064, or the statusword
    vmode = "csv" if mode == "csvloop" else mode
    # the set-point's RPDO (see the docstring); PV and PP set-points go over SDO: constant
    rpdo = (0x200 if remapped else (0x300 if vmode == "csp" else 0x400)) + node
    vel, t_sync, last, sp_last, sps, xd, xd_last = [], [], 0, None, [], [], 0
    answers = {}  # SYNC index -> velocity of the TPDO3 that answered it (real-time drive)
    answers_x = {}
    next_unanswered = 0
    for msg in frames:
        if msg.is_error_frame or msg.is_remote_frame:
            continue
        if msg.arbitration_id == tpdo3 and len(msg.data) >= off + 4:
            last = int.from_bytes(msg.data[off:off + 4], "little", signed=True)
            if t_sync:
                j = max(next_unanswered, len(t_sync) - 32)
                answers[j] = last
                next_unanswered = j + 1
        elif msg.arbitration_id == tpdo4 and len(msg.data) >= off4 + 4:
            xd_last = int.from_bytes(msg.data[off4:off4 + 4], "little", signed=True)
            if t_sync:
                answers_x[max(next_unanswered - 1, 0)] = xd_last
        elif vmode in ("csp", "csv") and msg.arbitration_id == rpdo and len(msg.data) >= 6:
            sp_last = int.from_bytes(msg.data[2:6], "little", signed=True)
        elif msg.arbitration_id == 0x80:
            vel.append(last)
            sps.append(np.nan if sp_last is None else sp_last)
            xd.append(xd_last)
            t_sync.append(msg.timestamp)
    if not lockstep and len(t_sync) > 1:
        # each SYNC's own answer at its own time, then onto an even grid
        rows = sorted(answers)
        ts = np.array([t_sync[j] for j in rows])
        dt_med = float(np.median(np.diff(t_sync)))
        grid = np.arange(ts[0], ts[-1], dt_med) if len(ts) > 1 else ts
        vel = np.interp(grid, ts, [answers[j] for j in rows])
        sps = np.interp(grid, np.array(t_sync), np.array(sps, dtype=float))
        xs = sorted(answers_x)
        xd = np.interp(grid, np.array([t_sync[j] for j in xs]), [answers_x[j] for j in xs]) \
            if len(xs) > 1 else np.zeros(len(grid))
        t_sync = list(grid)
    vel = np.array(vel, dtype=float)
    sps = np.array(sps, dtype=float)
    xd = np.array(xd, dtype=float)
    dt = float(np.median(np.diff(t_sync))) if len(t_sync) > 1 else 0.0
    out = {"syncs": len(vel), "limit_cycle": False, "sync_period_s_measured": round(dt, 6),
           "frequency_hz": None, "speed_amplitude_uu_s": None, "displacement_um": None,
           "cruise_s": 0.0, "cruise_speed_uu_s": None}
    if len(vel) < 16 or dt <= 0:
        return out
    # the cruise: the longest run where the speed averaged over 0.25 s (the limit cycle
    # averages out) stays within 10 % of the averaged speed met most often away from zero
    k_avg = max(1, int(round(0.25 / dt)))
    smooth = np.convolve(vel, np.ones(k_avg) / k_avg, mode="same")
    moving = smooth[np.abs(smooth) > 1000]
    if len(moving) == 0:
        return out
    hist, edges = np.histogram(moving, bins=50)
    k = int(np.argmax(hist))
    v_c = 0.5 * (edges[k] + edges[k + 1])
    near = np.abs(smooth - v_c) <= 0.1 * abs(v_c)
    best, start = (0, 0), None
    for i, ok in enumerate(np.append(near, False)):
        if ok and start is None:
            start = i
        elif not ok and start is not None:
            if i - start > best[1] - best[0]:
                best = (start, i)
            start = None
    a = best[0] + int(round(0.5 / dt))
    b = best[1]
    seg = vel[a:b]
    out["cruise_s"] = round(max(0, b - a) * dt, 3)
    if len(seg) < int(1.0 / dt):
        return out
    # a constant speed has a flat mean: a cruise whose mean drifts by 20 % is not one
    halves = np.array_split(seg, 4)
    means = [float(np.mean(h)) for h in halves]
    if max(means) - min(means) > 0.1 * abs(np.mean(seg)):
        return out
    out["cruise_speed_uu_s"] = round(float(np.mean(seg)), 1)
    x = seg - np.mean(seg)
    w = np.hanning(len(x))
    n = 8 * len(x)
    spec = np.abs(np.fft.rfft(x * w, n)) * 2.0 / np.sum(w)
    f = np.fft.rfftfreq(n, dt)
    band = (f >= 3.0) & (f <= min(60.0, 0.4 / dt))
    i = int(np.argmax(np.where(band, spec, 0.0)))
    amp = float(spec[i])
    med = float(np.median(spec[band]))
    out["frequency_hz"] = round(float(f[i]), 3)
    out["speed_amplitude_uu_s"] = round(amp, 2)
    out["displacement_um"] = round(amp / (2 * np.pi * f[i]), 3)
    out["peak_over_median"] = round(amp / med, 1) if med > 0 else None
    # a limit cycle: a line 8x above the spectrum's median, of at least 1 um (the user unit)
    out["limit_cycle"] = bool(out["displacement_um"] >= 1.0 and med > 0 and amp / med >= 8)
    # the set-point's own motion in the band: the axis forced by the master
    sp_seg = sps[a:b]
    if vmode == "csv":
        sp_seg = np.cumsum(np.nan_to_num(sp_seg)) * dt
    band = (3.0, min(60.0, 0.4 / dt))
    spu = set_point_um(sp_seg, dt, band) if vmode in ("csp", "csv") else 0.0
    out["set_point_um"] = None if spu is None else round(spu, 3)
    disp = out["displacement_um"]
    kv = master_kv(sps[a:b], xd[a:b], dt) if mode == "csvloop" else None
    out["master_kv_fit"] = None if kv is None else round(kv, 3)
    out["forced"] = bool(kv is None and spu is not None and disp >= 1.0
                         and spu >= max(1.0, 0.5 * disp))
    if out["forced"]:
        out["limit_cycle"] = False
    return out


if __name__ == "__main__":
    p, node, mode, remapped = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4] == "1"
    lockstep = len(sys.argv) < 6 or sys.argv[5] == "1"
    print(json.dumps(measure(p, node, mode, remapped, lockstep), indent=1, sort_keys=True))
