//! The ballbar's path from a bus capture (`drive-emu analyze --ballbar X,Y`): a master
//! interpolating the circle of ISO 230-4 both ways on two drives in CSP, recorded with
//! `candump -L`. Each node is decoded as `analyze` decodes one ([`crate::analysis::capture`]:
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
use crate::analysis::capture::{decode, BusLog, DecodeOptions, PdoConfig};

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

fn decode_node(
    text: &str,
    source: &str,
    node: u8,
    preset: &str,
    period: Option<u32>,
) -> Result<BusLog> {
    let (defaults, _) = PdoConfig::drive_defaults(node, preset)?;
    let opts = DecodeOptions {
        node_id: node,
        defaults,
        sync_period_us: period,
    };
    decode(text, source, &opts).with_context(|| format!("node {node}"))
}

/// The ballbar's path in a capture of two nodes, `nodes` = [X, Y], both of `preset` (their
/// PDO mapping after reset).
pub fn from_capture(
    text: &str,
    source: &str,
    nodes: [u8; 2],
    preset: &str,
    sync_period_us: Option<u32>,
) -> Result<CapturedCircle> {
    if nodes[0] == nodes[1] {
        bail!(
            "--ballbar {},{}: two different nodes are needed",
            nodes[0],
            nodes[1]
        );
    }
    let x = decode_node(text, source, nodes[0], preset, sync_period_us)?;
    let y = decode_node(text, source, nodes[1], preset, sync_period_us)?;
    let n = x.rows.len().min(y.rows.len());
    let mut t = BallbarTrace::default();
    let measured = |log: &BusLog, k: usize| {
        let r = &log.rows[k];
        if log.seen(crate::analysis::capture::follow::Object::DirectPosition) {
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
        t.x_mm.push(measured(&x, k) * 1e-3);
        t.y_mm.push(measured(&y, k) * 1e-3);
    }
    if t.time_s.len() < 16 {
        bail!(
            "{source}: {} SYNCs with a target position 0x607A for both nodes {} and {}: no \
             circle to measure (a master interpolating in CSP sends one per SYNC)",
            t.time_s.len(),
            nodes[0],
            nodes[1]
        );
    }
    // the commanded circle: fitted through the points where the command moves
    let moving: Vec<usize> = (1..t.len())
        .filter(|&k| t.x_cmd_mm[k] != t.x_cmd_mm[k - 1] || t.y_cmd_mm[k] != t.y_cmd_mm[k - 1])
        .collect();
    let xs: Vec<f64> = moving.iter().map(|&k| t.x_cmd_mm[k]).collect();
    let ys: Vec<f64> = moving.iter().map(|&k| t.y_cmd_mm[k]).collect();
    let ((cx, cy), r) = fit_circle(&xs, &ys)
        .with_context(|| format!("{source}: the command describes no circle"))?;
    // angle about the centre, unwrapped
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
        let sweep = (angle[end] - angle[start]).abs();
        if sweep >= std::f64::consts::TAU {
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
