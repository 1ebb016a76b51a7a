//! The ballbar's figures from a measured path (docs/ballbar.md states them for users):
//!
//! - **Radial deviation**: per direction, a least-squares circle (Kasa's algebraic fit) is
//!   fitted to the data circle's measured points; a point's radial deviation is its distance
//!   from that centre minus the fitted radius.
//! - **Circular deviation G** (`circular_deviation_um`, ISO 230-4): max minus min radial
//!   deviation over the data circle (0..360 deg travelled).
//! - **Radius deviation** (`radius_deviation_um`): fitted radius minus the nominal one.
//! - **Reversal spike** (`reversal_spikes_um`) at a quadrant crossing where an axis reverses
//!   (X at 0 and 180 deg, Y at 90 and 270 deg): the largest radial deviation within
//!   +-[`SPIKE_HALF_WIDTH_DEG`] of travel of the crossing above the local baseline: a straight
//!   line (least squares, radial deviation against angle travelled) through the
//!   [`BASELINE_WIDTH_DEG`] before that window along the pass, the path as it was before the
//!   axis reversed, extrapolated. A line, not a level: a servo mismatch between the axes
//!   makes the path an ellipse, whose radial deviation has its steepest slope at the
//!   crossings. The 0 deg crossing is taken where the data circle starts, the arc-in giving
//!   its baseline.
//! - **Backlash estimate** (`backlash_estimate_mm`) per axis: the mean of its four spikes (two
//!   crossings, two directions). Near a crossing the radial direction is the reversing axis's
//!   own, so the radial excursion is that axis's lost motion as it crosses its gap.

use std::collections::BTreeMap;

/// Half width of the window in which a reversal spike is looked for, deg of travel.
pub const SPIKE_HALF_WIDTH_DEG: f64 = 10.0;
/// Width of the baseline before the spike window, deg of travel.
pub const BASELINE_WIDTH_DEG: f64 = 20.0;

/// A measured path with its pass bookkeeping, positions in mm (slices of a trace).
#[derive(Clone, Copy, Debug)]
pub struct TracePath<'a> {
    pub x_mm: &'a [f64],
    pub y_mm: &'a [f64],
    /// -1 CW, +1 CCW, 0 at rest.
    pub direction: &'a [i8],
    /// Angle travelled from the pass's data start, deg.
    pub travelled_deg: &'a [f64],
    /// True while the feed ramps.
    pub ramping: &'a [bool],
}

impl<'a> TracePath<'a> {
    pub fn of(t: &'a super::BallbarTrace) -> Self {
        TracePath {
            x_mm: &t.x_mm,
            y_mm: &t.y_mm,
            direction: &t.direction,
            travelled_deg: &t.travelled_deg,
            ramping: &t.ramping,
        }
    }
}

/// The figures of one direction.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct DirectionReport {
    /// G: max - min radial deviation over the data circle, um.
    pub circular_deviation_um: f64,
    /// Least-squares radius minus the nominal radius, um.
    pub radius_deviation_um: f64,
    /// Least-squares centre, mm.
    pub centre_mm: [f64; 2],
    /// Per axis, the spikes at its two reversal crossings (in the order of
    /// `reversal_angles_deg`), um.
    pub reversal_spikes_um: BTreeMap<String, [f64; 2]>,
    /// Samples on the data circle.
    pub samples: usize,
}

/// What the ballbar measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct BallbarReport {
    /// The axes' names, X first.
    pub axes: [String; 2],
    /// Where each axis reverses, deg (ballbar convention: counter-clockwise from +X).
    pub reversal_angles_deg: BTreeMap<String, [f64; 2]>,
    pub cw: DirectionReport,
    pub ccw: DirectionReport,
    /// Per axis, the mean of its four spikes, mm.
    pub backlash_estimate_mm: BTreeMap<String, f64>,
}

/// X reverses at 0 and 180 deg, Y at 90 and 270 deg.
const CROSSINGS_DEG: [[f64; 2]; 2] = [[0.0, 180.0], [90.0, 270.0]];

/// The least-squares circle through points (Kasa): centre and radius.
pub fn fit_circle(x: &[f64], y: &[f64]) -> Option<((f64, f64), f64)> {
    let n = x.len();
    if n < 3 {
        return None;
    }
    let mx = x.iter().sum::<f64>() / n as f64;
    let my = y.iter().sum::<f64>() / n as f64;
    // u, v centred; solve for (a, b, c) in u^2 + v^2 = 2 a u + 2 b v + c
    let (mut suu, mut svv, mut suv, mut su, mut sv) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut suz, mut svz, mut sz) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (u, v) = (x[i] - mx, y[i] - my);
        let z = u * u + v * v;
        suu += u * u;
        svv += v * v;
        suv += u * v;
        su += u;
        sv += v;
        suz += u * z;
        svz += v * z;
        sz += z;
    }
    let nn = n as f64;
    // normal equations: [2suu 2suv su; 2suv 2svv sv; 2su 2sv n] [a b c]' = [suz svz sz]'
    let m = [
        [2.0 * suu, 2.0 * suv, su],
        [2.0 * suv, 2.0 * svv, sv],
        [2.0 * su, 2.0 * sv, nn],
    ];
    let rhs = [suz, svz, sz];
    let sol = solve3(m, rhs)?;
    let (a, b, c) = (sol[0], sol[1], sol[2]);
    let r2 = c + a * a + b * b;
    if r2.is_nan() || r2 <= 0.0 {
        return None;
    }
    Some(((mx + a, my + b), r2.sqrt()))
}

/// Gaussian elimination with partial pivoting.
fn solve3(mut m: [[f64; 3]; 3], mut r: [f64; 3]) -> Option<[f64; 3]> {
    for col in 0..3 {
        let p = (col..3).max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))?;
        if m[p][col].abs() < 1e-300 {
            return None;
        }
        m.swap(col, p);
        r.swap(col, p);
        for row in col + 1..3 {
            let f = m[row][col] / m[col][col];
            let pivot = m[col];
            for (k, v) in m[row].iter_mut().enumerate().skip(col) {
                *v -= f * pivot[k];
            }
            r[row] -= f * r[col];
        }
    }
    let mut out = [0.0; 3];
    for row in (0..3).rev() {
        let mut s = r[row];
        for k in row + 1..3 {
            s -= m[row][k] * out[k];
        }
        out[row] = s / m[row][row];
    }
    Some(out)
}

/// The least-squares straight line `d = c0 + c1 a` through points `(a, d)`.
fn fit_line(p: &[(f64, f64)]) -> Option<(f64, f64)> {
    if p.len() < 2 {
        return None;
    }
    let n = p.len() as f64;
    let ma = p.iter().map(|q| q.0).sum::<f64>() / n;
    let md = p.iter().map(|q| q.1).sum::<f64>() / n;
    let saa: f64 = p.iter().map(|q| (q.0 - ma).powi(2)).sum();
    let sad: f64 = p.iter().map(|q| (q.0 - ma) * (q.1 - md)).sum();
    if saa <= 0.0 {
        return None;
    }
    let c1 = sad / saa;
    Some((md - c1 * ma, c1))
}

/// The figures of one pass.
fn direction_report(
    p: &TracePath,
    sign: i8,
    radius_mm: f64,
    names: &[String; 2],
) -> anyhow::Result<DirectionReport> {
    let pass: Vec<usize> = (0..p.x_mm.len())
        .filter(|&i| p.direction[i] == sign && !p.ramping[i])
        .collect();
    let data: Vec<usize> = pass
        .iter()
        .copied()
        .filter(|&i| (0.0..360.0).contains(&p.travelled_deg[i]))
        .collect();
    let dir = if sign < 0 { "CW" } else { "CCW" };
    let xs: Vec<f64> = data.iter().map(|&i| p.x_mm[i]).collect();
    let ys: Vec<f64> = data.iter().map(|&i| p.y_mm[i]).collect();
    let ((cx, cy), r) = fit_circle(&xs, &ys).ok_or_else(|| {
        anyhow::anyhow!(
            "the {dir} pass has no measurable circle ({} samples on its data circle)",
            data.len()
        )
    })?;
    let dev = |i: usize| ((p.x_mm[i] - cx).hypot(p.y_mm[i] - cy) - r) * 1e3;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &i in &data {
        let d = dev(i);
        lo = lo.min(d);
        hi = hi.max(d);
    }
    let mut spikes = BTreeMap::new();
    for (axis, crossings) in names.iter().zip(CROSSINGS_DEG) {
        let mut s = [0.0; 2];
        for (k, angle) in crossings.iter().enumerate() {
            // the travelled angle at which this pass crosses `angle`
            let at = (f64::from(sign) * angle).rem_euclid(360.0);
            let mut window = Vec::new();
            let mut base = Vec::new();
            for &i in &pass {
                let a = p.travelled_deg[i] - at;
                if a.abs() <= SPIKE_HALF_WIDTH_DEG {
                    window.push((a, dev(i)));
                } else if (-SPIKE_HALF_WIDTH_DEG - BASELINE_WIDTH_DEG..-SPIKE_HALF_WIDTH_DEG)
                    .contains(&a)
                {
                    base.push((a, dev(i)));
                }
            }
            let line = fit_line(&base)
                .filter(|_| !window.is_empty())
                .ok_or_else(|| {
                    anyhow::anyhow!(
                        "the {dir} pass has no samples around {angle} deg, where axis {axis} \
                     reverses"
                    )
                })?;
            s[k] = window
                .iter()
                .map(|&(a, d)| d - (line.0 + line.1 * a))
                .fold(f64::NEG_INFINITY, f64::max);
        }
        spikes.insert(axis.clone(), s);
    }
    Ok(DirectionReport {
        circular_deviation_um: hi - lo,
        radius_deviation_um: (r - radius_mm) * 1e3,
        centre_mm: [cx, cy],
        reversal_spikes_um: spikes,
        samples: data.len(),
    })
}

/// The ballbar's figures from a path measured around a circle of `radius_mm`, both ways.
pub fn analyze(
    p: &TracePath,
    radius_mm: f64,
    names: &[String; 2],
) -> anyhow::Result<BallbarReport> {
    let n = p.x_mm.len();
    anyhow::ensure!(
        p.y_mm.len() == n
            && p.direction.len() == n
            && p.travelled_deg.len() == n
            && p.ramping.len() == n,
        "internal: the path's columns differ in length"
    );
    let cw = direction_report(p, -1, radius_mm, names)?;
    let ccw = direction_report(p, 1, radius_mm, names)?;
    let mut est = BTreeMap::new();
    let mut angles = BTreeMap::new();
    for (axis, crossings) in names.iter().zip(CROSSINGS_DEG) {
        let s = cw.reversal_spikes_um[axis]
            .iter()
            .chain(ccw.reversal_spikes_um[axis].iter())
            .sum::<f64>()
            / 4.0;
        est.insert(axis.clone(), s * 1e-3);
        angles.insert(axis.clone(), crossings);
    }
    Ok(BallbarReport {
        axes: names.clone(),
        reversal_angles_deg: angles,
        cw,
        ccw,
        backlash_estimate_mm: est,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_a_circle_exactly() {
        let (x, y): (Vec<f64>, Vec<f64>) = (0..100)
            .map(|i| {
                let a = i as f64 * 0.0628;
                (3.0 + 50.0 * a.cos(), -2.0 + 50.0 * a.sin())
            })
            .unzip();
        let ((cx, cy), r) = fit_circle(&x, &y).unwrap();
        assert!((cx - 3.0).abs() < 1e-9 && (cy + 2.0).abs() < 1e-9 && (r - 50.0).abs() < 1e-9);
        assert!(fit_circle(&x[..2], &y[..2]).is_none());
    }
}
