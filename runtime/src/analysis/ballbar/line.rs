//! Line contours (G1) on two or three axes through the real drives: the master interpolates a
//! [`LineProgram`] (exact stop at each point) with its backlash compensation per axis, the
//! drives run on the ballbar's in-process bus ([`super::through_drives::Drives`]), the direct
//! encoders measure the path. Per segment: the contour error (the measured point's distance
//! from the commanded segment), the lost motion of each axis that reverses at its start, the
//! end-point error. docs/contour.md.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context;

use crate::drive::axis_drive::AxisDrive;
use crate::master::compensation::BacklashCompensation;
use crate::master::line::{LineProgram, DWELL_S, MAX_AXES, MAX_POINTS};
use crate::presets::{AxisKind, MAX_BACKLASH_M};

use super::max_axis_speed_mm_per_s;
use super::through_drives::Drives;

/// Controlword enable operation.
const ENABLED: u16 = 0x0F;
/// Default path acceleration of the feed ramps, mm/s^2: below what the tests' guideway
/// friction holds on cnc1 (150 N / 800 kg = 190 mm/s^2), so the load keeps its flank while the
/// axis decelerates into a corner (docs/contour.md).
pub const DEFAULT_ACCEL_MM_S2: f64 = 100.0;
/// Largest coordinate accepted, mm.
pub const MAX_TRAVEL_MM: f64 = 5000.0;
/// Longest program accepted, simulated s: the trace is kept in memory.
pub const MAX_DURATION_S: f64 = 600.0;
/// Position cycles between two looks at the stop flag.
const STOP_CHECK_CYCLES: usize = 1024;

/// One axis of the program: as one of the ballbar's (its name in the program and the report,
/// its configuration, the master's backlash compensation on it).
pub type ContourAxis = super::BallbarAxis;

/// What to run.
#[derive(Clone, Debug)]
pub struct ContourSetup {
    /// Two or three axes, in the order of the points' coordinates.
    pub axes: Vec<ContourAxis>,
    /// The points, mm: the first is the start (where the axes stand), every other the end of a
    /// segment. Coordinates beyond the axes' count are ignored.
    pub points_mm: Vec<[f64; MAX_AXES]>,
    pub feed_mm_per_min: f64,
    pub accel_mm_s2: f64,
}

/// The recorded program, one row per position cycle; positions in mm, per axis in the
/// setup's order.
#[derive(Clone, Debug, Default)]
pub struct ContourTrace {
    pub names: Vec<String>,
    pub time_s: Vec<f64>,
    /// The segment (1-based) whose motion or following dwell this row is in; 0 before the
    /// first.
    pub segment: Vec<usize>,
    /// The interpolator's position (the line, without compensation).
    pub cmd_mm: Vec<Vec<f64>>,
    /// Direct encoders: the measured path.
    pub actual_mm: Vec<Vec<f64>>,
    /// The set-points sent to the drives (the line plus the compensation).
    pub setpoint_mm: Vec<Vec<f64>>,
}

impl ContourTrace {
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// The CSV header of `contour --trace`: `time_s,segment`, then per axis `NAME_cmd_mm`,
    /// `NAME_mm` (direct encoder), `NAME_setpoint_mm`.
    pub fn header(&self) -> String {
        let mut h = vec!["time_s".to_string(), "segment".to_string()];
        for n in &self.names {
            h.push(format!("{n}_cmd_mm"));
            h.push(format!("{n}_mm"));
            h.push(format!("{n}_setpoint_mm"));
        }
        h.join(",")
    }

    pub fn write_csv(&self, w: &mut impl std::io::Write) -> std::io::Result<()> {
        writeln!(w, "{}", self.header())?;
        for i in 0..self.len() {
            write!(w, "{:.6},{}", self.time_s[i], self.segment[i])?;
            for k in 0..self.names.len() {
                write!(
                    w,
                    ",{:.9},{:.9},{:.9}",
                    self.cmd_mm[k][i], self.actual_mm[k][i], self.setpoint_mm[k][i]
                )?;
            }
            writeln!(w)?;
        }
        Ok(())
    }
}

/// The figures of one segment.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SegmentReport {
    /// 1-based.
    pub segment: usize,
    /// Its start and end point per axis, mm.
    pub from_mm: BTreeMap<String, f64>,
    pub to_mm: BTreeMap<String, f64>,
    /// The measured point's largest and RMS distance from the commanded segment's line over its
    /// motion and the dwell after it, um.
    pub max_contour_error_um: f64,
    pub rms_contour_error_um: f64,
    /// Per axis that reverses at this segment's start (its commanded direction opposite to
    /// its last one): its lost motion, the commanded minus the measured travel in the new
    /// direction from rest before the segment to rest after it (the reversal value of
    /// ISO 230-2 for that pair of stops), um.
    pub lost_motion_um: BTreeMap<String, f64>,
    /// Measured minus target at the end of the dwell after the segment, per axis, um.
    pub end_point_error_um: BTreeMap<String, f64>,
    /// Its length, um.
    pub end_point_error_norm_um: f64,
}

/// What a program measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ContourReport {
    pub axes: Vec<String>,
    pub segments: Vec<SegmentReport>,
    /// Per axis, the largest lost motion over its reversals, um (0 without a reversal).
    pub max_lost_motion_um: BTreeMap<String, f64>,
    /// Per axis, its number of reversals.
    pub reversals: BTreeMap<String, usize>,
}

/// Distance of `p` from the line through `a` and `b` (perpendicular: a lag or an overshoot
/// along the line is not a contour error), all in one unit.
fn distance_to_line(p: &[f64], a: &[f64], b: &[f64]) -> f64 {
    let n = p.len();
    let ab: f64 = (0..n).map(|k| (b[k] - a[k]).powi(2)).sum();
    let dot: f64 = (0..n).map(|k| (p[k] - a[k]) * (b[k] - a[k])).sum();
    let u = if ab > 0.0 { dot / ab } else { 0.0 };
    (0..n)
        .map(|k| (p[k] - a[k] - u * (b[k] - a[k])).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The figures from a trace: `points_mm` the program's points (the first its start),
/// `segment`, `cmd_mm` and `actual_mm` the trace's columns (per axis in `names`' order).
pub fn analyze(
    names: &[String],
    points_mm: &[[f64; MAX_AXES]],
    segment: &[usize],
    cmd_mm: &[Vec<f64>],
    actual_mm: &[Vec<f64>],
) -> anyhow::Result<ContourReport> {
    let n_axes = names.len();
    anyhow::ensure!(
        cmd_mm.len() == n_axes && actual_mm.len() == n_axes,
        "the trace has {} / {} axes, not {n_axes}",
        cmd_mm.len(),
        actual_mm.len()
    );
    let mut last_dir = vec![0i8; n_axes];
    let mut segments = Vec::with_capacity(points_mm.len().saturating_sub(1));
    let mut max_lost = BTreeMap::new();
    let mut reversals = BTreeMap::new();
    for n in names {
        max_lost.insert(n.clone(), 0.0f64);
        reversals.insert(n.clone(), 0usize);
    }
    let mut p = vec![0.0; n_axes];
    for s in 1..points_mm.len() {
        let (a, b) = (&points_mm[s - 1][..n_axes], &points_mm[s][..n_axes]);
        let rows: Vec<usize> = (0..segment.len()).filter(|&i| segment[i] == s).collect();
        anyhow::ensure!(!rows.is_empty(), "segment {s} has no samples in the trace");
        let before = rows[0].checked_sub(1).filter(|&i| segment[i] == s - 1);
        let before = before.with_context(|| format!("segment {s}: no sample at rest before it"))?;
        let end = *rows.last().expect("not empty");
        let (mut max_e, mut sum_e2) = (0.0f64, 0.0f64);
        for &i in &rows {
            for (v, column) in p.iter_mut().zip(actual_mm) {
                *v = column[i];
            }
            let e = distance_to_line(&p, a, b) * 1e3;
            max_e = max_e.max(e);
            sum_e2 += e * e;
        }
        let mut lost = BTreeMap::new();
        for k in 0..n_axes {
            let d = b[k] - a[k];
            let dir: i8 = if d > 0.0 {
                1
            } else if d < 0.0 {
                -1
            } else {
                0
            };
            if dir == 0 {
                continue;
            }
            if last_dir[k] == -dir {
                // commanded minus measured travel in the new direction, rest to rest
                let err = |i: usize| actual_mm[k][i] - cmd_mm[k][i];
                let v = f64::from(dir) * (err(before) - err(end)) * 1e3;
                lost.insert(names[k].clone(), v);
                let m = max_lost.get_mut(&names[k]).expect("every axis");
                *m = m.max(v);
                *reversals.get_mut(&names[k]).expect("every axis") += 1;
            }
            last_dir[k] = dir;
        }
        let mut end_err = BTreeMap::new();
        let mut norm2 = 0.0;
        for k in 0..n_axes {
            let e = (actual_mm[k][end] - b[k]) * 1e3;
            norm2 += e * e;
            end_err.insert(names[k].clone(), e);
        }
        let map = |pt: &[f64]| -> BTreeMap<String, f64> {
            names.iter().cloned().zip(pt.iter().copied()).collect()
        };
        segments.push(SegmentReport {
            segment: s,
            from_mm: map(a),
            to_mm: map(b),
            max_contour_error_um: max_e,
            rms_contour_error_um: (sum_e2 / rows.len() as f64).sqrt(),
            lost_motion_um: lost,
            end_point_error_um: end_err,
            end_point_error_norm_um: norm2.sqrt(),
        });
    }
    Ok(ContourReport {
        axes: names.to_vec(),
        segments,
        max_lost_motion_um: max_lost,
        reversals,
    })
}

/// Check the setup; errors name the flag (or key) and the reason. Returns the plan in m.
pub fn validate(setup: &ContourSetup) -> anyhow::Result<LineProgram> {
    let n = setup.axes.len();
    anyhow::ensure!(
        (2..=MAX_AXES).contains(&n),
        "{n} axes: a line program runs on two or three"
    );
    let f = setup.feed_mm_per_min;
    anyhow::ensure!(
        f.is_finite() && f > 0.0,
        "--feed-mm-min {f}: must be a finite feed > 0 mm/min"
    );
    let acc = setup.accel_mm_s2;
    anyhow::ensure!(
        acc.is_finite() && acc > 0.0,
        "--accel-mm-s2 {acc}: must be a finite acceleration > 0 mm/s^2"
    );
    let segs = setup.points_mm.len().saturating_sub(1);
    anyhow::ensure!(
        (1..MAX_POINTS).contains(&segs),
        "--path: {segs} points; a program has 1 to {} (`X10 Y5; X0 Y0`)",
        MAX_POINTS - 1
    );
    for (i, p) in setup.points_mm.iter().enumerate().skip(1) {
        for (k, a) in setup.axes.iter().enumerate() {
            anyhow::ensure!(
                p[k].is_finite() && p[k].abs() <= MAX_TRAVEL_MM,
                "--path point {i}: {}{} is outside +-{MAX_TRAVEL_MM} mm",
                a.name,
                p[k]
            );
        }
        let same = (0..n).all(|k| p[k] == setup.points_mm[i - 1][k]);
        anyhow::ensure!(
            !same,
            "--path point {i} is where the axes already stand (point {}): a segment of zero \
             length",
            i - 1
        );
    }
    let mut cycle = None;
    for a in &setup.axes {
        anyhow::ensure!(
            a.config.kind == AxisKind::Linear,
            "axis {} ({}) is a rotary axis: a line program runs on linear axes (use a linear \
             preset such as cnc1, cnc2 or cnc4, or a machine file with --config)",
            a.name,
            a.config.name
        );
        let c = a.backlash_comp_mm;
        anyhow::ensure!(
            c.is_finite() && (0.0..=MAX_BACKLASH_M * 1e3).contains(&c),
            "--backlash-comp-mm {c} on axis {}: must be a finite value in 0..={} mm",
            a.name,
            MAX_BACKLASH_M * 1e3
        );
        let vmax = max_axis_speed_mm_per_s(&a.config)?;
        anyhow::ensure!(
            f / 60.0 <= vmax,
            "--feed-mm-min {f}: above axis {} ({})'s maximum speed of {:.0} mm/min (its motor's \
             max_speed_rpm through the drive train)",
            a.name,
            a.config.name,
            vmax * 60.0
        );
        let built = a.config.build().map_err(|e| anyhow::anyhow!("{e}"))?;
        let pc = built.control.position_cycle;
        match cycle {
            None => cycle = Some(pc),
            Some(c0) => anyhow::ensure!(
                (pc - c0).abs() <= 1e-9 * c0,
                "the axes have different position cycles ({} us and {} us): the master \
                 interpolates one set-point per cycle for all, so they must match \
                 (position_cycle_us)",
                c0 * 1e6,
                pc * 1e6
            ),
        }
    }
    let pts_m: Vec<[f64; MAX_AXES]> = setup
        .points_mm
        .iter()
        .map(|p| p.map(|v| v * 1e-3))
        .collect();
    let plan = LineProgram::new(&pts_m, n, f / 60.0 * 1e-3, acc * 1e-3, DWELL_S)
        .map_err(|e| anyhow::anyhow!("--path: {e}"))?;
    let d = plan.duration_s();
    anyhow::ensure!(
        d <= MAX_DURATION_S,
        "the program takes {d:.0} s at {f} mm/min, above the cap of {MAX_DURATION_S:.0} s: \
         raise --feed-mm-min or shorten --path"
    );
    Ok(plan)
}

/// A run: its trace and what it measured.
#[derive(Clone, Debug)]
pub struct ContourRun {
    pub trace: ContourTrace,
    pub report: ContourReport,
}

/// Run the program through the drives and measure it. Ends early with an error once `stop`
/// is set.
pub fn run(setup: &ContourSetup, stop: &AtomicBool) -> anyhow::Result<ContourRun> {
    let plan = validate(setup)?;
    let mut drives = Vec::with_capacity(setup.axes.len());
    for a in &setup.axes {
        drives.push(
            AxisDrive::from_config(&a.config)
                .map_err(|e| anyhow::anyhow!("axis {}: {e}", a.name))?,
        );
    }
    let trace = match setup.axes.len() {
        2 => run_n::<2>(setup, &plan, drives, stop)?,
        _ => run_n::<3>(setup, &plan, drives, stop)?,
    };
    let report = analyze(
        &trace.names,
        &setup.points_mm,
        &trace.segment,
        &trace.cmd_mm,
        &trace.actual_mm,
    )?;
    Ok(ContourRun { trace, report })
}

fn run_n<const N: usize>(
    setup: &ContourSetup,
    plan: &LineProgram,
    drives: Vec<AxisDrive>,
    stop: &AtomicBool,
) -> anyhow::Result<ContourTrace> {
    let drives: [AxisDrive; N] = drives.try_into().map_err(|_| anyhow::anyhow!("{N} axes"))?;
    let cycle_s = drives[0].position_cycle_s();
    let period_us = (cycle_s * 1e6).round() as u64;
    let start = plan.point(0);
    let mut set = Drives::<N>::new(drives, period_us, std::array::from_fn(|k| start[k]))?;
    let mut comp: [BacklashCompensation; N] =
        std::array::from_fn(|k| BacklashCompensation::new(setup.axes[k].backlash_comp_mm * 1e-3));
    let dt = period_us as f64 * 1e-6;
    let n = (plan.duration_s() / dt).ceil() as usize + 1;
    let column = || Vec::with_capacity(n);
    let mut t = ContourTrace {
        names: setup.axes.iter().map(|a| a.name.clone()).collect(),
        time_s: column(),
        segment: Vec::with_capacity(n),
        cmd_mm: (0..N).map(|_| column()).collect(),
        actual_mm: (0..N).map(|_| column()).collect(),
        setpoint_mm: (0..N).map(|_| column()).collect(),
    };
    for i in 0..n {
        if i % STOP_CHECK_CYCLES == 0 && stop.load(Ordering::Relaxed) {
            anyhow::bail!("the run was stopped at {:.3} s", i as f64 * dt);
        }
        // the set-point for the SYNC period that starts now, sent before the SYNC
        let s = plan.sample(i as f64 * dt);
        let sp: [f64; N] = std::array::from_fn(|k| comp[k].apply(s.position[k]));
        set.cycle(ENABLED, sp)?;
        let act = set.direct_m();
        t.time_s.push(i as f64 * dt);
        t.segment.push(s.segment);
        for k in 0..N {
            t.cmd_mm[k].push(s.position[k] * 1e3);
            t.actual_mm[k].push(act[k] * 1e3);
            t.setpoint_mm[k].push(sp[k] * 1e3);
        }
    }
    let sw = set.statuswords();
    anyhow::ensure!(
        sw.iter().all(|s| s & 0x08 == 0),
        "a drive faulted during the program (statusword {sw:04X?}): a parameter puts the axis \
         outside what its drive supervises"
    );
    if let Some(i) = (0..t.len()).find(|&i| (0..N).any(|k| !t.actual_mm[k][i].is_finite())) {
        anyhow::bail!(
            "the simulation diverged at t = {:.6} s: a parameter is outside what the model \
             resolves",
            t.time_s[i]
        );
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_to_a_line_is_perpendicular() {
        let (a, b) = ([0.0, 0.0], [10.0, 0.0]);
        assert!((distance_to_line(&[5.0, 3.0], &a, &b) - 3.0).abs() < 1e-12);
        assert!((distance_to_line(&[-4.0, 3.0], &a, &b) - 3.0).abs() < 1e-12);
        let (a, b) = ([0.0, 0.0, 0.0], [1.0, 1.0, 0.0]);
        assert!((distance_to_line(&[1.0, 0.0, 0.0], &a, &b) - 0.5f64.sqrt()).abs() < 1e-12);
    }

    /// A synthetic there-and-back on X whose answer is known: X stands where commanded after
    /// the first segment and 20 um short after the second (a lost motion of 20 um, an end
    /// error of +20 um on the way back to 0); Y is 2 um off the line once.
    #[test]
    fn analyze_finds_a_known_lost_motion() {
        let names = ["X".to_string(), "Y".to_string()];
        let pts = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
        let mut seg = vec![0, 0];
        let mut cmd = vec![vec![0.0, 0.0], vec![0.0, 0.0]];
        let mut act = vec![vec![0.0, 0.0], vec![0.0, 0.0]];
        for i in 0..=10 {
            seg.push(1);
            cmd[0].push(f64::from(i) * 0.1);
            act[0].push(f64::from(i) * 0.1);
            cmd[1].push(0.0);
            act[1].push(0.0);
        }
        for i in 0..=10 {
            seg.push(2);
            let c = 1.0 - f64::from(i) * 0.1;
            cmd[0].push(c);
            act[0].push(if i == 0 { c } else { c + 0.020 });
            cmd[1].push(0.0);
            act[1].push(if i == 5 { 0.002 } else { 0.0 });
        }
        let r = analyze(&names, &pts, &seg, &cmd, &act).unwrap();
        assert_eq!(r.segments.len(), 2);
        assert!(r.segments[0].lost_motion_um.is_empty());
        assert!((r.segments[1].lost_motion_um["X"] - 20.0).abs() < 1e-9);
        assert!(!r.segments[1].lost_motion_um.contains_key("Y"));
        assert!((r.segments[1].max_contour_error_um - 2.0).abs() < 1e-9);
        assert!((r.segments[1].end_point_error_um["X"] - 20.0).abs() < 1e-9);
        assert!(r.segments[0].end_point_error_norm_um.abs() < 1e-9);
        assert_eq!(r.reversals["X"], 1);
        assert_eq!(r.reversals["Y"], 0);
    }
}
