//! Constant-velocity windows: the stretches of a trace where the set acceleration is zero and
//! the set speed is not, which is where the paper looks for the backlash limit cycle.

/// How windows are cut.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct WindowOptions {
    /// Set speeds below this (trace units/s) are standstill, not a window.
    pub min_speed: f64,
    /// Skipped at the start of each window: the transient after the acceleration ends, s.
    pub settle_s: f64,
    /// Shortest usable window after settling, s.
    pub min_len_s: f64,
    /// Longer stretches are cut into windows of this length (one measurement each), s.
    pub max_len_s: f64,
    /// Relative change of the set speed between samples still counted as constant.
    pub rel_tol: f64,
    /// A time between two samples longer than this ends a window (lost or late samples of a
    /// capture on its own time stamps: the spectrum is fitted on the samples' times, so a gap
    /// only costs what happened in it), s. None: 1.5 median sample intervals (a trace sampled
    /// evenly, where any gap is lost time).
    pub max_gap_s: Option<f64>,
}

impl Default for WindowOptions {
    fn default() -> Self {
        Self {
            min_speed: 1.0,
            settle_s: 0.4,
            min_len_s: 1.0,
            max_len_s: 4.0,
            rel_tol: 1e-6,
            max_gap_s: None,
        }
    }
}

/// A window: samples `start..end` of the trace, at set velocity `velocity`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Window {
    pub start: usize,
    pub end: usize,
    pub velocity: f64,
}

impl Window {
    pub fn len(&self) -> usize {
        self.end - self.start
    }
    pub fn is_empty(&self) -> bool {
        self.end == self.start
    }
}

/// Median sample interval of `t` (s), 0 if fewer than two samples.
pub fn median_dt(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    *d.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// What a search for windows found: the windows, and the constant-speed stretches they came
/// from (for the reason when there is no window).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct WindowScan {
    pub windows: Vec<Window>,
    /// Stretches of constant, non-zero set speed.
    pub runs: usize,
    /// The longest of them, s.
    pub longest_run_s: f64,
}

/// Find the constant-velocity windows. A time gap larger than [`WindowOptions::max_gap_s`]
/// (by default 1.5 sample intervals: skipped idle time, lost samples) ends a window.
pub fn constant_velocity_windows(
    t: &[f64],
    set_velocity: &[f64],
    o: &WindowOptions,
) -> Vec<Window> {
    scan_windows(t, set_velocity, o).windows
}

/// [`constant_velocity_windows`], with what the search saw.
pub fn scan_windows(t: &[f64], set_velocity: &[f64], o: &WindowOptions) -> WindowScan {
    scan_windows_bridging(t, set_velocity, o, None)
}

/// Longest silence [`scan_windows_bridging`] bridges, s.
pub const MAX_BRIDGE_S: f64 = 0.5;

/// Whether a silence from `t0` to `t1` at set speed `v` is bridged: the position `x0` ->
/// `x1` advanced as the speed says, within the line's residual bound twice over
/// ([`LINE_RESIDUAL_S`] of travel, [`LINE_RESIDUAL_UNITS`]) plus 2 % of the travel: no
/// change of speed hides in it.
pub fn bridges(t0: f64, t1: f64, x0: f64, x1: f64, v: f64) -> bool {
    let gap = t1 - t0;
    let travel = v * gap;
    gap <= MAX_BRIDGE_S && (x1 - x0 - travel).abs() <= 2.0 * line_bound(v) + 0.02 * travel.abs()
}

/// Whether the silence before sample `i` is bridged: the positions `x` on the time stamps
/// `t` go on across it along the line they follow around it (their speed over
/// [`LINE_BLOCK_S`] before and after, averaged: [`bridges`] at that speed). On the capture's
/// own clock, so a drive whose clock runs slow against the bus's (its speed in its own
/// seconds) is judged on the bus's.
pub fn bridges_at(t: &[f64], x: &[f64], i: usize) -> bool {
    if i == 0 || i >= t.len() || t[i] - t[i - 1] > MAX_BRIDGE_S {
        return false;
    }
    let Some(a) = (0..i).rev().find(|&j| t[i - 1] - t[j] >= LINE_BLOCK_S) else {
        return false;
    };
    let Some(b) = (i..t.len()).find(|&k| t[k] - t[i] >= LINE_BLOCK_S) else {
        return false;
    };
    let v = 0.5 * ((x[i - 1] - x[a]) / (t[i - 1] - t[a]) + (x[b] - x[i]) / (t[b] - t[i]));
    v.is_finite() && bridges(t[i - 1], t[i], x[i - 1], x[i], v)
}

/// [`scan_windows`] where a silence longer than the gap limit (a capture whose SYNCs stalled:
/// a python master in a busy machine) does not end a window when `position` (the set
/// position, or the measured one) across it advanced as the set speed says ([`bridges`]):
/// constant speed against the capture's own time stamps ([`bridges_at`]).
pub fn scan_windows_bridging(
    t: &[f64],
    set_velocity: &[f64],
    o: &WindowOptions,
    position: Option<&[f64]>,
) -> WindowScan {
    assert_eq!(t.len(), set_velocity.len());
    let dt = median_dt(t);
    let mut out = Vec::new();
    let (mut runs, mut longest_run_s) = (0usize, 0.0f64);
    if dt <= 0.0 {
        return WindowScan::default();
    }
    let max_gap = o.max_gap_s.unwrap_or(1.5 * dt).max(1.5 * dt);
    let mut push_run = |a: usize, b: usize| {
        // Run a..b (exclusive) at constant velocity: settle, then cut into windows.
        runs += 1;
        longest_run_s = longest_run_s.max(t[b - 1] - t[a] + dt);
        let t0 = t[a] + o.settle_s;
        let Some(s) = (a..b).find(|&i| t[i] >= t0) else {
            return;
        };
        let mut start = s;
        while start < b {
            let limit = t[start] + o.max_len_s - 0.5 * dt;
            let mut end = start;
            while end < b && t[end] < limit {
                end += 1;
            }
            if end > start && t[end - 1] - t[start] + dt >= o.min_len_s - 0.5 * dt {
                out.push(Window {
                    start,
                    end,
                    velocity: set_velocity[start],
                });
            }
            start = end;
        }
    };
    let constant = |i: usize| {
        let (v0, v1) = (set_velocity[i - 1], set_velocity[i]);
        (v1 - v0).abs() <= o.rel_tol * v1.abs().max(1.0)
            && v1.abs() >= o.min_speed
            && (t[i] - t[i - 1] <= max_gap || position.is_some_and(|x| bridges_at(t, x, i)))
    };
    let mut run_start: Option<usize> = None;
    for i in 1..t.len() {
        match (constant(i), run_start) {
            (true, None) => run_start = Some(i),
            (false, Some(a)) => {
                push_run(a, i);
                run_start = None;
            }
            _ => {}
        }
    }
    if let Some(a) = run_start {
        push_run(a, t.len());
    }
    WindowScan {
        windows: out,
        runs,
        longest_run_s,
    }
}

/// Span of the derivative in [`set_velocity_from_demand`] as the analysis uses it, s: two
/// units per span is 10 uu/s, 0.1 % of a 10 mm/s cruise.
pub const DEMAND_SPAN_S: f64 = 0.2;

/// The set velocity of a trace that has only a position demand, sampled with finite
/// resolution: a PLC's CSP targets on the wire (0x607A), or the drive's position demand
/// (0x6062), in integer user units. A speed that is not a whole number of units per cycle
/// comes as steps of N and N+1 units, so the plain difference is never constant. Here: the
/// derivative over a centred span of `span_s`, made piecewise constant (consecutive samples
/// within 0.5 % of their segment's running mean, or within two units per span at low speed,
/// share that mean), so that constant-speed stretches come out exactly constant for
/// [`constant_velocity_windows`] and ramps break into short segments that it skips.
///
/// On uneven times (a capture on its own time stamps) a lost or late set-point is a longer
/// interval, not a glitch: the demand is taken as it is.
pub fn set_velocity_from_demand(t: &[f64], demand: &[f64], span_s: f64) -> Vec<f64> {
    let demand = if evenly_sampled(t) {
        repair_glitches(demand)
    } else {
        demand.to_vec()
    };
    piecewise_constant_velocity(t, &demand, span_s, 5e-3, 2.0)
}

/// Whether `t` is evenly sampled ([`crate::spectrum::uniform_interval`]): the glitch repairs
/// here are for a time base that counts samples, where a lost or late one shows as a step of
/// the wrong size; on a capture's own time stamps it shows as an interval of another length.
fn evenly_sampled(t: &[f64]) -> bool {
    crate::spectrum::uniform_interval(t).0
}

/// Span of the derivative in [`set_velocity_from_actual`], s: long against the limit cycle's
/// period (> 8 periods at 18 Hz), so its +-20 um make less than 1 % of a 10 mm/s cruise.
pub const ACTUAL_SPAN_S: f64 = 0.5;

/// Where the set-point is not in the capture (a PP move, a log of actual values only): the
/// paper's criterion (set acceleration zero) applied to the measured position (or the
/// integral of the measured speed). The same piecewise-constant derivative as
/// [`set_velocity_from_demand`], over [`ACTUAL_SPAN_S`], with a tolerance of 2 % or 20 units
/// per span (the limit cycle and encoder noise ride on the measured position).
///
/// On uneven times (a capture on its own time stamps) the position is taken as it is.
pub fn set_velocity_from_actual(t: &[f64], position: &[f64]) -> Vec<f64> {
    let position = if evenly_sampled(t) {
        despike(position)
    } else {
        position.to_vec()
    };
    piecewise_constant_velocity(t, &position, ACTUAL_SPAN_S, 0.02, 20.0)
}

/// Where the set-point is not in the capture but the measured speed is (0x606C: a PP move):
/// the paper's criterion applied to the drive's own speed measurement, averaged over
/// [`ACTUAL_SPAN_S`] (centred; on uneven times over that span of the samples' own times),
/// piecewise constant within 2 % or 20 units per span. A speed
/// needs no clock: unlike positions over time stamps it does not depend on when each sample
/// was taken (a real-time drive samples within a control tick of its SYNC, and one that
/// stalled lost time against the bus's clock).
pub fn set_velocity_from_speed(t: &[f64], speed: &[f64]) -> Vec<f64> {
    assert_eq!(t.len(), speed.len());
    let n = t.len();
    let dt = median_dt(t);
    if n < 2 || dt <= 0.0 {
        return vec![0.0; n];
    }
    let k = ((0.5 * ACTUAL_SPAN_S / dt).round() as usize).max(1);
    let mut prefix = vec![0.0; n + 1];
    for i in 0..n {
        prefix[i + 1] = prefix[i] + if speed[i].is_finite() { speed[i] } else { 0.0 };
    }
    // Over k samples either side where they are even; over half the span either side on
    // the samples' own times where they are not (a capture whose SYNCs stalled: k samples
    // may span a second and smear the ramps into the cruise).
    let even = evenly_sampled(t);
    let half = 0.5 * ACTUAL_SPAN_S;
    let (mut a, mut b) = (0usize, 0usize);
    let avg: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = if even {
                (i.saturating_sub(k), (i + k + 1).min(n))
            } else {
                while t[a] < t[i] - half {
                    a += 1;
                }
                b = b.max(i + 1);
                while b < n && t[b] <= t[i] + half {
                    b += 1;
                }
                (a, b)
            };
            (prefix[b] - prefix[a]) / (b - a) as f64
        })
        .collect();
    let abs_tol = 20.0 / ACTUAL_SPAN_S;
    let mut out = vec![0.0; n];
    let (mut start, mut sum) = (0usize, avg[0]);
    for i in 1..=n {
        let mean = sum / (i - start) as f64;
        if i < n && (avg[i] - mean).abs() <= (0.02 * mean.abs()).max(abs_tol) {
            sum += avg[i];
        } else {
            out[start..i].fill(mean);
            if i < n {
                (start, sum) = (i, avg[i]);
            }
        }
    }
    out
}

/// Span of [`set_velocity_on_average`], s: over half a second a set-point that comes a
/// period late or early, or twice, moves the average by a few per cent at most.
pub const AVERAGE_SPAN_S: f64 = 0.5;

/// Where a master's set-points jitter, come late, twice or not at all (a PLC task that is
/// not synchronous with its SYNC, a python loop), no stretch of exactly constant set speed
/// exists although the master commands one. Constant on average: the derivative of the
/// set position over [`AVERAGE_SPAN_S`], piecewise constant within 5 % (or 20 units per
/// span). NaN where the set position is not known.
pub fn set_velocity_on_average(t: &[f64], set_position: &[f64]) -> Vec<f64> {
    piecewise_constant_velocity(t, set_position, AVERAGE_SPAN_S, 0.05, 20.0)
}

/// Length of the blocks [`set_velocity_by_line`] fits a line to, s.
pub const LINE_BLOCK_S: f64 = 0.25;
/// Residual bound of [`set_velocity_by_line`]: the rms distance of the set-points from their
/// line may be this many seconds of travel at the line's speed (a set-point taken from the
/// master's clock a few ms before or after its SYNC's time stamp), ...
pub const LINE_RESIDUAL_S: f64 = 0.005;
/// ... or this many position units (integer set-points at a low speed), whichever is more.
pub const LINE_RESIDUAL_UNITS: f64 = 2.0;
/// Blocks whose speeds differ by this much or less (relative) belong to one line.
pub const LINE_SPEED_TOL: f64 = 0.02;

/// Least-squares line `x = a + b t` through the points, and the rms residual; None with
/// fewer than three points or no spread in time.
fn fit_line(t: &[f64], x: &[f64]) -> Option<(f64, f64, f64)> {
    let n = t.len();
    if n < 3 {
        return None;
    }
    let m = n as f64;
    let (mt, mx) = (t.iter().sum::<f64>() / m, x.iter().sum::<f64>() / m);
    let (mut tt, mut tx) = (0.0, 0.0);
    for (a, b) in t.iter().zip(x) {
        tt += (a - mt) * (a - mt);
        tx += (a - mt) * (b - mx);
    }
    if tt <= 0.0 {
        return None;
    }
    let b = tx / tt;
    let a = mx - b * mt;
    let ss: f64 = t
        .iter()
        .zip(x)
        .map(|(ti, xi)| (xi - a - b * ti).powi(2))
        .sum();
    Some((a, b, (ss / m).sqrt()))
}

/// The residual bound at speed `v`, position units (rms).
fn line_bound(v: f64) -> f64 {
    (LINE_RESIDUAL_S * v.abs()).max(LINE_RESIDUAL_UNITS)
}

/// Constant speed from the set-points against the samples' own times (issue 31, item 5): a
/// master whose SYNCs jitter (a python master in a busy machine) takes each set-point from
/// its own clock, so the increment per SYNC is never the same twice although the set-point
/// against the SYNC's time stamp is a line. Here: a least-squares line through each block of
/// [`LINE_BLOCK_S`]; a block is straight when its rms residual is within [`line_bound`]
/// (5 ms of travel, or 2 units); consecutive straight blocks whose speeds agree within
/// [`LINE_SPEED_TOL`] of the run's first form one run, which is straight again as a whole
/// (else it ends before the block that bent it); every sample of a run gets the slope of
/// the line through the whole run, everything else NaN (never constant). A ramp's block
/// bends by `a T^2 / 27` (120 units at 50 000 units/s^2): not straight.
pub fn set_velocity_by_line(t: &[f64], set_position: &[f64]) -> Vec<f64> {
    assert_eq!(t.len(), set_position.len());
    let n = t.len();
    let mut out = vec![f64::NAN; n];
    let dt = median_dt(t);
    if n < 3 || dt <= 0.0 {
        return out;
    }
    let per_block = ((LINE_BLOCK_S / dt).round() as usize).max(8);
    // Blocks: [start, end) with their slope, where straight.
    let mut blocks: Vec<(usize, usize, Option<f64>)> = Vec::new();
    let mut i = 0;
    while i < n {
        let end = (i + per_block).min(n);
        let (bt, bx) = (&t[i..end], &set_position[i..end]);
        let straight = if bx.iter().all(|x| x.is_finite()) {
            fit_line(bt, bx).and_then(|(_, b, rms)| (rms <= line_bound(b)).then_some(b))
        } else {
            None
        };
        blocks.push((i, end, straight));
        i = end;
    }
    let same = |a: f64, b: f64| (a - b).abs() <= (LINE_SPEED_TOL * a.abs()).max(1e-9);
    let mut k = 0;
    while k < blocks.len() {
        let Some(v0) = blocks[k].2 else {
            k += 1;
            continue;
        };
        // Grow the run while the blocks agree and the whole stays a line.
        let mut last = k;
        let mut line = fit_line(
            &t[blocks[k].0..blocks[k].1],
            &set_position[blocks[k].0..blocks[k].1],
        );
        while last + 1 < blocks.len() {
            let Some(v) = blocks[last + 1].2 else { break };
            if !same(v0, v) {
                break;
            }
            let (a, b) = (blocks[k].0, blocks[last + 1].1);
            match fit_line(&t[a..b], &set_position[a..b]) {
                Some(f) if f.2 <= line_bound(f.1) => {
                    line = Some(f);
                    last += 1;
                }
                _ => break,
            }
        }
        if let Some((_, b, _)) = line {
            out[blocks[k].0..blocks[last].1].fill(b);
        }
        k = last + 1;
    }
    out
}

/// A measured position with single-sample spikes taken out: a sample missed or late in the
/// capture holds the previous value (increments 0 then 2 steps), half a step off the line
/// through its neighbours. A sample more than 0.35 of the local step (median of 9
/// increments) off that line becomes the midpoint. The limit cycle bends the line far less
/// (its second difference is (2 pi f dt)^2 x: 0.2 of a step at 10 ms, 15 um and 10 mm/s).
fn despike(x: &[f64]) -> Vec<f64> {
    let mut out = x.to_vec();
    let n = x.len();
    if n < 3 {
        return out;
    }
    let d: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    let mut buf = [0.0f64; 9];
    for i in 1..n - 1 {
        let (a, b) = (i.saturating_sub(4), (i + 5).min(d.len()));
        let w = &mut buf[..b - a];
        w.copy_from_slice(&d[a..b]);
        w.sort_unstable_by(f64::total_cmp);
        let step = w[w.len() / 2];
        let mid = 0.5 * (x[i - 1] + x[i + 1]);
        if step > 0.0 && (x[i] - mid).abs() > 0.35 * step {
            out[i] = mid;
        }
    }
    out
}

/// A piecewise-constant derivative of `x` over `t`: the centred difference over `span_s`;
/// consecutive samples within `rel_tol` of their segment's running mean, or `abs_units` per
/// span, share one value (the secant of `x` over the segment's interior).
fn piecewise_constant_velocity(
    t: &[f64],
    demand: &[f64],
    span_s: f64,
    rel_tol: f64,
    abs_units: f64,
) -> Vec<f64> {
    assert_eq!(t.len(), demand.len());
    let n = t.len();
    let dt = median_dt(t);
    if n < 2 || dt <= 0.0 {
        return vec![0.0; n];
    }
    let k = ((0.5 * span_s / dt).round() as usize).max(1);
    let v: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(k), (i + k).min(n - 1));
            let dt_ab = t[b] - t[a];
            if dt_ab > 0.0 {
                (demand[b] - demand[a]) / dt_ab
            } else {
                0.0
            }
        })
        .collect();
    let abs_tol = abs_units / span_s;
    let mut out = vec![0.0; n];
    let (mut start, mut sum) = (0usize, v[0]);
    for i in 1..=n {
        let mean = sum / (i - start) as f64;
        let same = i < n && (v[i] - mean).abs() <= (rel_tol * mean.abs()).max(abs_tol);
        if same {
            sum += v[i];
        } else {
            // A long segment gets the secant of the demand over its interior (k samples in
            // from each end, where the centred derivative still saw the ramps): exact to one
            // unit over the segment. A short one (a ramp piece), or one whose interior is
            // shorter than a span (a measured position's noise would dominate the secant),
            // keeps its mean.
            let value = if i - start > 4 * k + 1 {
                let (a, b) = (start + k, i - 1 - k);
                (demand[b] - demand[a]) / (t[b] - t[a])
            } else {
                mean
            };
            out[start..i].fill(value);
            if i < n {
                (start, sum) = (i, v[i]);
            }
        }
    }
    out
}

/// The demand with isolated glitches taken out: a set-point frame lost or late on the bus (a
/// capture that missed it) shows as an increment of 0 then 2 steps, or 2 steps once. Each
/// increment more than a quarter (at least 2 units) off the median of its 9 neighbours is
/// replaced by that median; steady increments of N and N+1, and ramps, are left alone.
fn repair_glitches(demand: &[f64]) -> Vec<f64> {
    let d: Vec<f64> = demand.windows(2).map(|w| w[1] - w[0]).collect();
    let mut out = Vec::with_capacity(demand.len());
    let Some(&first) = demand.first() else {
        return out;
    };
    out.push(first);
    let mut buf = [0.0f64; 9];
    for i in 0..d.len() {
        let (a, b) = (i.saturating_sub(4), (i + 5).min(d.len()));
        let w = &mut buf[..b - a];
        w.copy_from_slice(&d[a..b]);
        w.sort_unstable_by(f64::total_cmp);
        let median = w[w.len() / 2];
        let step = if (d[i] - median).abs() > (0.25 * median.abs()).max(2.0) {
            median
        } else {
            d[i]
        };
        out.push(out[i] + step);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integer_demand_at_a_fractional_speed_gives_exact_cruise_windows() {
        // 16.7 units per 1 ms cycle, rounded to whole units as a PLC sends it: steps of 16
        // and 17. Ramp 0.5 s, cruise 3 s, ramp down 0.5 s.
        let (mut t, mut pos, mut x, mut vel) = (Vec::new(), Vec::new(), 0.0f64, 0.0f64);
        for i in 0..4_500 {
            let ts = i as f64 * 1e-3;
            let v_cmd = if ts < 3.5 { 16_700.0 } else { 0.0 };
            vel += (v_cmd - vel).clamp(-33.4, 33.4);
            x += vel * 1e-3;
            t.push(ts);
            pos.push(x.round());
        }
        let raw: Vec<f64> = pos.windows(2).map(|w| (w[1] - w[0]) * 1e3).collect();
        assert!(raw[1000..3000].contains(&16_000.0) && raw.contains(&17_000.0));
        // A capture that missed frames: every 37th set-point late (held, then caught up) and
        // every 101st sample lost altogether.
        let (mut t2, mut pos2) = (Vec::new(), Vec::new());
        for i in 0..t.len() {
            if i % 101 == 50 {
                continue;
            }
            t2.push(t[t2.len()]);
            pos2.push(if i % 37 == 36 { pos[i - 1] } else { pos[i] });
        }
        let w2 = constant_velocity_windows(
            &t2,
            &set_velocity_from_demand(&t2, &pos2, 0.2),
            &WindowOptions::default(),
        );
        assert_eq!(w2.len(), 1, "with glitches: {w2:?}");
        // A lost sample's double step is a glitch too: the speed stays right (within the
        // median's rounding of the 16/17 pattern at the repaired increments).
        assert!(
            (w2[0].velocity / 16_700.0 - 1.0).abs() < 3e-3,
            "{}",
            w2[0].velocity
        );

        let v = set_velocity_from_demand(&t, &pos, 0.2);
        let w = constant_velocity_windows(&t, &v, &WindowOptions::default());
        assert_eq!(w.len(), 1, "{w:?}");
        assert!((w[0].velocity - 16_700.0).abs() < 1.0, "{}", w[0].velocity);
        // The window lies inside the cruise (0.5 .. 3.5 s), after settling.
        assert!(t[w[0].start] >= 0.9 && t[w[0].end - 1] <= 3.5, "{w:?}");
        assert!(w[0].len() >= 2_000, "{}", w[0].len());
    }

    #[test]
    fn finds_cruise_windows_after_the_ramps() {
        // 1 kHz: 0.5 s ramp to 100, 3 s cruise, 0.5 s ramp to -100, 5 s cruise, stop.
        let mut t = Vec::new();
        let mut v = Vec::new();
        for i in 0..10_000 {
            let ts = i as f64 * 1e-3;
            let vel = if ts < 0.5 {
                200.0 * ts
            } else if ts < 3.5 {
                100.0
            } else if ts < 4.0 {
                100.0 - 400.0 * (ts - 3.5)
            } else if ts < 9.0 {
                -100.0
            } else {
                0.0
            };
            t.push(ts);
            v.push(vel);
        }
        let w = constant_velocity_windows(&t, &v, &WindowOptions::default());
        assert_eq!(w.len(), 2, "{w:?}");
        assert_eq!(w[0].velocity, 100.0);
        assert!((t[w[0].start] - 0.9).abs() < 3e-3);
        assert!((t[w[0].end - 1] - 3.5).abs() < 3e-3);
        assert_eq!(w[1].velocity, -100.0);
        // 4.4 .. 8.4 s; the 0.6 s left before the stop is too short.
        assert_eq!(w[1].len(), 4000);
    }

    /// Deterministic uniform numbers in 0..1 (splitmix64 of k).
    fn unit(k: u64) -> f64 {
        let mut z = k.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A capture of a master whose SYNCs jitter (4 ms nominal, intervals 1..20 ms, and a
    /// stall of `stall_s` every second), each set-point taken from its clock up to 3 ms
    /// before the SYNC's time stamp: a trapezoid 0.2 s ramp, 10 mm/s cruise from 0.2 s to
    /// `cruise_end_s`, ramp down. Returns (stamps, set positions).
    fn jittery_capture(stall_s: f64, cruise_end_s: f64) -> (Vec<f64>, Vec<f64>) {
        let (v, a) = (10_000.0, 50_000.0);
        let x = |t: f64| -> f64 {
            let tr = v / a;
            if t < 0.0 {
                0.0
            } else if t < tr {
                0.5 * a * t * t
            } else if t < cruise_end_s {
                0.5 * a * tr * tr + v * (t - tr)
            } else {
                let td = (t - cruise_end_s).min(tr);
                0.5 * a * tr * tr + v * (cruise_end_s - tr) + v * td - 0.5 * a * td * td
            }
        };
        let (mut t, mut pos) = (Vec::new(), Vec::new());
        let mut now = 0.0;
        let mut next_stall = 1.0;
        let mut k = 0u64;
        while now < cruise_end_s + 0.5 {
            let u = unit(k);
            now += if u < 0.8 {
                0.001 + 0.006 * unit(k + 7_000_000)
            } else {
                0.02
            };
            if now >= next_stall {
                now += stall_s;
                next_stall += 1.0;
            }
            t.push(now);
            pos.push(x(now - 0.003 * unit(k + 1_000_000)).round());
            k += 1;
        }
        (t, pos)
    }

    #[test]
    fn the_set_point_against_jittery_time_stamps_is_a_line() {
        let (t, x) = jittery_capture(0.0, 4.0);
        // Per SYNC the increments are never constant: no exact window.
        let exact = set_velocity_from_demand(&t, &x, DEMAND_SPAN_S);
        // Gaps up to 2 / k_v bridged, as the detector does (k_v 30 1/s).
        let o = WindowOptions {
            max_gap_s: Some(2.0 / 30.0),
            ..WindowOptions::default()
        };
        assert!(constant_velocity_windows(&t, &exact, &o).is_empty());
        let v = set_velocity_by_line(&t, &x);
        let w = constant_velocity_windows(&t, &v, &o);
        assert_eq!(w.len(), 1, "{w:?}");
        // The speed to 0.5 %, the window inside the cruise (after the ramp, before the end
        // but for what a block that straddles it hides).
        assert!(
            (w[0].velocity / 10_000.0 - 1.0).abs() < 5e-3,
            "{}",
            w[0].velocity
        );
        assert!(
            t[w[0].start] >= 0.2 && t[w[0].end - 1] <= 4.0 + LINE_BLOCK_S,
            "{w:?}: {} .. {}",
            t[w[0].start],
            t[w[0].end - 1]
        );
        assert!(t[w[0].end - 1] - t[w[0].start] >= 2.5, "{w:?}");
        // The ramps are not lines: NaN there.
        let ramp = t.iter().position(|&s| s > 0.05).unwrap();
        assert!(v[ramp].is_nan());
        // A bend in the middle of the cruise (speed 10 -> 10.5 mm/s) ends the line.
        let bent: Vec<f64> = t
            .iter()
            .zip(&x)
            .map(|(&s, &p)| if s > 2.0 { p + 500.0 * (s - 2.0) } else { p })
            .collect();
        let w = constant_velocity_windows(&t, &set_velocity_by_line(&t, &bent), &o);
        assert!(
            w.iter()
                .all(|w| t[w.start] >= 2.0 || t[w.end - 1] <= 2.0 + LINE_BLOCK_S),
            "{w:?}"
        );
    }

    #[test]
    fn a_silence_is_bridged_where_the_position_went_on_at_the_speed() {
        // Stalls of 150 ms every second, longer than the gap limit of 67 ms (k_v 30 1/s).
        let (t, x) = jittery_capture(0.15, 4.0);
        let v = set_velocity_by_line(&t, &x);
        let o = WindowOptions {
            max_gap_s: Some(2.0 / 30.0),
            ..WindowOptions::default()
        };
        assert!(scan_windows(&t, &v, &o).windows.is_empty(), "unbridged");
        let w = scan_windows_bridging(&t, &v, &o, Some(&x)).windows;
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            (w[0].velocity / 10_000.0 - 1.0).abs() < 5e-3,
            "{}",
            w[0].velocity
        );
        // A silence in which the axis went elsewhere (a stop and a restart: 0.4 mm short)
        // is not bridged.
        let i = t.iter().position(|&s| s > 2.0).unwrap();
        let short: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(k, &p)| if k >= i { p - 400.0 } else { p })
            .collect();
        assert!(!bridges(t[i - 1], t[i], short[i - 1], short[i], 10_000.0));
        assert!(bridges(t[i - 1], t[i], x[i - 1], x[i], 10_000.0));
        // The same judged on the line around the silence, where it is one (a stall).
        let stall = (1..t.len())
            .find(|&k| t[k] > 2.0 && t[k] - t[k - 1] > 0.1)
            .unwrap();
        assert!(bridges_at(&t, &x, stall));
        let short: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(k, &p)| if k >= stall { p - 400.0 } else { p })
            .collect();
        assert!(!bridges_at(&t, &short, stall));
        // A drive whose clock runs 30 % slow: its speed in its own seconds does not bridge
        // the silence, the line on the bus's clock does.
        let slow: Vec<f64> = x.iter().map(|p| 0.7 * p).collect();
        assert!(bridges_at(&t, &slow, stall));
        assert!(!bridges(
            t[stall - 1],
            t[stall],
            slow[stall - 1],
            slow[stall],
            10_000.0
        ));
        // Nor a silence longer than MAX_BRIDGE_S.
        assert!(!bridges(
            1.0,
            1.0 + MAX_BRIDGE_S + 0.1,
            0.0,
            10_000.0 * (MAX_BRIDGE_S + 0.1),
            10_000.0
        ));
    }

    #[test]
    fn a_time_gap_splits_windows() {
        let mut t: Vec<f64> = (0..3000).map(|i| i as f64 * 1e-3).collect();
        t.extend((0..3000).map(|i| 100.0 + i as f64 * 1e-3));
        let v = vec![50.0; t.len()];
        let w = constant_velocity_windows(&t, &v, &WindowOptions::default());
        assert_eq!(w.len(), 2);
    }
}
