//! The ballbar's path from a bus capture (`drive-emu analyze --ballbar X,Y`): a master
//! interpolating the circle of ISO 230-4 both ways on two drives in CSP, recorded with
//! `candump -L`. Each node is decoded as `analyze` decodes one ([`crate::capture`]:
//! the PDO mapping in force, one row per SYNC); the command is the target position 0x607A in
//! force at each SYNC, the measured path the direct encoder 0x60E4 where it is mapped, else
//! the position 0x6064 (on a drive that closes its loop on the direct encoder, the same).
//!
//! What the offline run knows from its plan is found from the command: the centre and the
//! radius by a least-squares circle through the commanded points, the angle about it, the
//! passes (runs of one direction of rotation that sweep 360 deg or more), each pass's data
//! circle the middle 360 deg of its sweep (the arc-in and arc-out equal, as ISO 230-4 runs
//! them), and the feed's ramps (at the pass's ends, where the angular speed over 16 SYNCs is
//! below 98 % of the pass's median: a command in whole user units steps unevenly per SYNC).
//! The data circle must start at +X (0 deg), as the ballbar's reversal angles assume.

use anyhow::{bail, Context, Result};

use super::metrics::fit_circle;
use super::BallbarTrace;
use crate::capture::{decode, BusLog, DecodeOptions, PdoConfig};

/// Share of a pass's median angular speed below which the feed is taken as ramping.
const RAMP_SHARE: f64 = 0.98;
/// SYNCs over which the angular speed is taken.
const SPEED_WINDOW: usize = 16;
/// How far the data circle's start may be from +X, deg.
const START_TOLERANCE_DEG: f64 = 5.0;

/// The decoded path and the circle the command describes.
#[derive(Debug, Clone)]
pub struct CapturedCircle {
    /// One row per SYNC; the set-point and motor columns hold the command and the position.
    pub trace: BallbarTrace,
    /// The commanded circle's fitted centre and radius, mm.
    pub centre_mm: (f64, f64),
    pub radius_mm: f64,
    /// Passes found: (direction -1 CW / +1 CCW, SYNC rows).
    pub passes: Vec<(i8, usize)>,
}

/// The PDO configuration of node `node` after reset (its mapping, COB-IDs and periods): the
/// emulator reads it from its own drive's object dictionary for the capture's preset.
pub type DefaultsOf<'a> = &'a dyn Fn(u8) -> Result<PdoConfig>;

fn decode_node(
    text: &str,
    source: &str,
    node: u8,
    defaults: DefaultsOf,
    period: Option<u32>,
) -> Result<BusLog> {
    let opts = DecodeOptions {
        node_id: node,
        defaults: defaults(node)?,
        sync_period_us: period,
    };
    decode(text, source, &opts).with_context(|| format!("node {node}"))
}

/// The ballbar's path in a capture of two nodes, `nodes` = [X, Y], whose PDO configuration
/// after reset `defaults` gives.
pub fn from_capture_with(
    text: &str,
    source: &str,
    nodes: [u8; 2],
    defaults: DefaultsOf,
    sync_period_us: Option<u32>,
) -> Result<CapturedCircle> {
    if nodes[0] == nodes[1] {
        bail!(
            "--ballbar {},{}: two different nodes are needed",
            nodes[0],
            nodes[1]
        );
    }
    let x = decode_node(text, source, nodes[0], defaults, sync_period_us)?;
    let y = decode_node(text, source, nodes[1], defaults, sync_period_us)?;
    let mut t = paired_rows(&x, &y);
    if t.time_s.len() < 16 {
        bail!(
            "{source}: {} SYNCs with a target position 0x607A for both nodes {} and {}: no \
             circle to measure (a master interpolating in CSP sends one per SYNC)",
            t.time_s.len(),
            nodes[0],
            nodes[1]
        );
    }
    let ((cx, cy), r) = commanded_circle(&t)
        .with_context(|| format!("{source}: the command describes no circle"))?;
    let angle = unwrapped_angle(&t, (cx, cy));
    let passes = mark_passes(&mut t, &angle, source)?;
    // the columns the offline trace has and a capture does not: the set-point is the command
    t.x_setpoint_mm = t.x_cmd_mm.clone();
    t.y_setpoint_mm = t.y_cmd_mm.clone();
    t.x_motor_mm = t.x_mm.clone();
    t.y_motor_mm = t.y_mm.clone();
    Ok(CapturedCircle {
        trace: t,
        centre_mm: (cx, cy),
        radius_mm: r,
        passes,
    })
}

/// The rows where both nodes have a target position: time, command and measured path, mm.
fn paired_rows(x: &BusLog, y: &BusLog) -> BallbarTrace {
    let n = x.rows.len().min(y.rows.len());
    let mut t = BallbarTrace::default();
    let measured = |log: &BusLog, k: usize| {
        let r = &log.rows[k];
        if log.seen(crate::capture::follow::Object::DirectPosition) {
            f64::from(r.direct_position_uu)
        } else {
            f64::from(r.position_uu)
        }
    };
    for k in 0..n {
        let (Some(cx), Some(cy)) = (x.rows[k].target_position_uu, y.rows[k].target_position_uu)
        else {
            continue;
        };
        t.time_s.push(x.t_s(k));
        t.x_cmd_mm.push(f64::from(cx) * 1e-3);
        t.y_cmd_mm.push(f64::from(cy) * 1e-3);
        t.x_mm.push(measured(x, k) * 1e-3);
        t.y_mm.push(measured(y, k) * 1e-3);
    }
    t
}

/// The commanded circle (centre, radius; mm): fitted through the points where the command
/// moves.
fn commanded_circle(t: &BallbarTrace) -> Option<((f64, f64), f64)> {
    let moving: Vec<usize> = (1..t.len())
        .filter(|&k| t.x_cmd_mm[k] != t.x_cmd_mm[k - 1] || t.y_cmd_mm[k] != t.y_cmd_mm[k - 1])
        .collect();
    let xs: Vec<f64> = moving.iter().map(|&k| t.x_cmd_mm[k]).collect();
    let ys: Vec<f64> = moving.iter().map(|&k| t.y_cmd_mm[k]).collect();
    fit_circle(&xs, &ys)
}

/// The command's angle about `centre`, rad, unwrapped.
fn unwrapped_angle(t: &BallbarTrace, (cx, cy): (f64, f64)) -> Vec<f64> {
    let mut angle = Vec::with_capacity(t.len());
    for k in 0..t.len() {
        let a = (t.y_cmd_mm[k] - cy).atan2(t.x_cmd_mm[k] - cx);
        let a = match angle.last() {
            Some(&prev) => {
                let mut d: f64 = a - prev;
                d -= (d / std::f64::consts::TAU).round() * std::f64::consts::TAU;
                prev + d
            }
            None => a,
        };
        angle.push(a);
    }
    angle
}

/// Find the passes (runs of one direction of rotation that sweep 360 deg or more) and mark
/// their rows in `t` (direction, angle travelled, ramping); a CW and a CCW pass are needed.
fn mark_passes(t: &mut BallbarTrace, angle: &[f64], source: &str) -> Result<Vec<(i8, usize)>> {
    let step_eps = 1e-9;
    let dir_of = |k: usize| -> i8 {
        if k == 0 {
            return 0;
        }
        let d = angle[k] - angle[k - 1];
        if d > step_eps {
            1
        } else if d < -step_eps {
            -1
        } else {
            0
        }
    };
    t.direction = vec![0; t.len()];
    t.travelled_deg = vec![0.0; t.len()];
    t.ramping = vec![false; t.len()];
    let mut passes = Vec::new();
    let mut k = 1;
    while k < t.len() {
        let d = dir_of(k);
        if d == 0 {
            k += 1;
            continue;
        }
        let start = k - 1;
        let mut end = k;
        while end + 1 < t.len() && dir_of(end + 1) == d {
            end += 1;
        }
        if (angle[end] - angle[start]).abs() >= std::f64::consts::TAU {
            mark_pass(t, angle, (start, end), d, source)?;
            passes.push((d, end - start + 1));
        }
        k = end + 1;
    }
    if !passes.iter().any(|p| p.0 < 0) || !passes.iter().any(|p| p.0 > 0) {
        bail!(
            "{source}: the command runs no full circle both ways (passes of 360 deg or more \
             found: {}); the ballbar needs a CW and a CCW pass",
            passes.len()
        );
    }
    Ok(passes)
}

/// Mark one pass, rows `start..=end` turning in direction `d`, sweeping 360 deg or more: its
/// data circle is the middle 360 deg, which must start at +X; its ramps are at its ends.
fn mark_pass(
    t: &mut BallbarTrace,
    angle: &[f64],
    (start, end): (usize, usize),
    d: i8,
    source: &str,
) -> Result<()> {
    let sweep = (angle[end] - angle[start]).abs();
    let overrun = (sweep - std::f64::consts::TAU) / 2.0;
    let data_start = angle[start] + f64::from(d) * overrun;
    let off = (data_start.to_degrees() + 180.0).rem_euclid(360.0) - 180.0;
    if off.abs() > START_TOLERANCE_DEG {
        bail!(
            "{source}: the {} pass's data circle starts at {off:.1} deg, not at +X (0 \
             deg) as ISO 230-4 and the reversal angles assume",
            if d < 0 { "CW" } else { "CCW" }
        );
    }
    // The angular speed over SPEED_WINDOW SYNCs: a command in whole user units steps
    // unevenly from one SYNC to the next (at 1 um and 16 um per SYNC, +-6 %).
    let speed = |i: usize| {
        let j = i.saturating_sub(SPEED_WINDOW).max(start);
        if i > j {
            (angle[i] - angle[j]).abs() / (i - j) as f64
        } else {
            0.0
        }
    };
    let mut speeds: Vec<f64> = (start + 1..=end).map(speed).collect();
    speeds.sort_by(f64::total_cmp);
    let median = speeds[speeds.len() / 2];
    // The ramps are at the pass's ends: up to where the feed first reaches the
    // median's share, from where it last leaves it.
    let at_feed = |i: &usize| speed(*i) >= RAMP_SHARE * median;
    let up_end = (start..=end).find(at_feed).unwrap_or(end);
    let down_start = (start..=end).rev().find(at_feed).unwrap_or(start);
    for i in start..=end {
        t.direction[i] = d;
        t.travelled_deg[i] = ((angle[i] - angle[start]).abs() - overrun).to_degrees();
        // the window lags the feed: the ramp down is found up to a window late
        t.ramping[i] = i < up_end || i > down_start.saturating_sub(SPEED_WINDOW);
    }
    Ok(())
}
