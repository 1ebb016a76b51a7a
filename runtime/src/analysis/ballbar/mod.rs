//! The virtual ballbar (ISO 230-4 circular test): two linear axes, X and Y, each a simulated
//! axis with its own cascade (position set-points every position cycle, as `sim` runs one),
//! the master interpolating a circle on them ([`crate::master::contour`]) with its backlash
//! compensation per axis ([`crate::master::compensation`]); the direct encoders measure the
//! path, as the ballbar's transducer does. [`metrics`] turns the path into the figures a
//! ballbar reports (circular deviation G, reversal spikes, radius deviation, a backlash
//! estimate per axis). docs/ballbar.md.

// The ballbar's trace, its figures and a capture's decoding run no drive: crate
// drive-analysis, re-exported here under their old paths.
pub use drive_analysis::ballbar::{metrics, BallbarTrace};

pub mod capture;
pub mod line;
pub mod through_drives;

use std::sync::atomic::{AtomicBool, Ordering};

use crate::drive::axis_drive::AxisDrive;
use crate::master::compensation::BacklashCompensation;
use crate::master::contour::{CircleTest, Direction};
use crate::presets::{AxisConfig, AxisKind, MAX_BACKLASH_M};

pub use metrics::{analyze, BallbarReport, DirectionReport};
use through_drives::DrivePair;

/// Controlword enable operation.
const ENABLED: u16 = 0x0F;

/// Default ballbar radius, mm (the common 100 mm bar).
pub const DEFAULT_RADIUS_MM: f64 = 100.0;
/// Default feed, mm/min.
pub const DEFAULT_FEED_MM_PER_MIN: f64 = 1000.0;
/// Longest radius accepted, mm (a QC20 with all its extensions reaches 1350 mm).
pub const MAX_RADIUS_MM: f64 = 2000.0;
/// Largest angle the circle may advance per position cycle, deg: the reversal windows
/// (+-10 deg) need samples.
pub const MAX_STEP_DEG: f64 = 1.0;
/// Longest test accepted, simulated s (both passes with dwells): the trace is kept in memory.
pub const MAX_DURATION_S: f64 = 1800.0;

/// One axis of the ballbar's plane.
#[derive(Clone, Debug)]
pub struct BallbarAxis {
    /// Its name in the report (X, Y, or the machine file's).
    pub name: String,
    /// The preset with its overrides.
    pub config: AxisConfig,
    /// The master's backlash compensation on this axis, mm (0 = none).
    pub backlash_comp_mm: f64,
}

/// What to run.
#[derive(Clone, Debug)]
pub struct BallbarSetup {
    /// The first axis is the circle's X, the second its Y.
    pub axes: [BallbarAxis; 2],
    pub radius_mm: f64,
    pub feed_mm_per_min: f64,
}

/// A run: its trace and what it measured.
#[derive(Clone, Debug)]
pub struct BallbarRun {
    pub trace: BallbarTrace,
    pub report: BallbarReport,
}

/// The largest speed an axis reaches, mm/s: its motor's maximum speed through the drive
/// train.
pub fn max_axis_speed_mm_per_s(cfg: &AxisConfig) -> anyhow::Result<f64> {
    let built = cfg.build().map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(built.axis.motor.max_speed / built.axis.mech.ratio / built.display_unit)
}

/// Check the setup; errors name the flag (or key) and the reason.
pub fn validate(setup: &BallbarSetup) -> anyhow::Result<CircleTest> {
    let r = setup.radius_mm;
    anyhow::ensure!(
        r.is_finite() && r > 0.0 && r <= MAX_RADIUS_MM,
        "--radius-mm {r}: must be a finite radius > 0 and <= {MAX_RADIUS_MM} mm"
    );
    let f = setup.feed_mm_per_min;
    anyhow::ensure!(
        f.is_finite() && f > 0.0,
        "--feed-mm-min {f}: must be a finite feed > 0 mm/min"
    );
    let mut cycle = None;
    for a in &setup.axes {
        anyhow::ensure!(
            a.config.kind == AxisKind::Linear,
            "axis {} ({}) is a rotary axis: the ballbar measures a circle on two linear axes \
             (use a linear preset such as cnc1, cnc2 or cnc4, or a machine file with --config)",
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
                "the two axes have different position cycles ({} us and {} us): the master \
                 interpolates one set-point per cycle for both, so they must match \
                 (position_cycle_us)",
                c0 * 1e6,
                pc * 1e6
            ),
        }
    }
    let test = CircleTest::new((0.0, 0.0), r * 1e-3, f / 60.0 * 1e-3);
    let cycle = cycle.unwrap_or(1e-3);
    let step_deg = (f / 60.0 * cycle / r).to_degrees();
    anyhow::ensure!(
        step_deg <= MAX_STEP_DEG,
        "--radius-mm {r} at --feed-mm-min {f}: the circle advances {step_deg:.2} deg per \
         position cycle, above {MAX_STEP_DEG} deg: too few samples around each reversal; raise \
         the radius or lower the feed"
    );
    let d = test.duration_s();
    anyhow::ensure!(
        d <= MAX_DURATION_S,
        "a circle of {r} mm at {f} mm/min takes {d:.0} s both ways, above the cap of \
         {MAX_DURATION_S:.0} s: raise --feed-mm-min or lower --radius-mm"
    );
    Ok(test)
}

/// Position cycles between two looks at the stop flag.
const STOP_CHECK_CYCLES: usize = 1024;

/// Run the circular test both ways and measure it. Ends early with an error once `stop` is
/// set.
pub fn run(setup: &BallbarSetup, stop: &AtomicBool) -> anyhow::Result<BallbarRun> {
    let test = validate(setup)?;
    let (x0, y0) = test.start_point();
    let mut drives = Vec::with_capacity(2);
    for a in &setup.axes {
        let d = AxisDrive::from_config(&a.config)
            .map_err(|e| anyhow::anyhow!("axis {}: {e}", a.name))?;
        drives.push(d);
    }
    let cycle_s = drives[0].position_cycle_s();
    let period_us = (cycle_s * 1e6).round() as u64;
    let drives: [AxisDrive; 2] = drives.try_into().map_err(|_| anyhow::anyhow!("two axes"))?;
    let mut pair = DrivePair::new(drives, period_us, [x0, y0])?;
    let mut comp = [
        BacklashCompensation::new(setup.axes[0].backlash_comp_mm * 1e-3),
        BacklashCompensation::new(setup.axes[1].backlash_comp_mm * 1e-3),
    ];
    let dt = period_us as f64 * 1e-6;
    let n = (test.duration_s() / dt).ceil() as usize + 1;
    let mut t = BallbarTrace::default();
    for v in [
        &mut t.time_s,
        &mut t.x_cmd_mm,
        &mut t.y_cmd_mm,
        &mut t.x_mm,
        &mut t.y_mm,
        &mut t.x_setpoint_mm,
        &mut t.y_setpoint_mm,
        &mut t.x_motor_mm,
        &mut t.y_motor_mm,
        &mut t.travelled_deg,
    ] {
        v.reserve_exact(n);
    }
    t.direction.reserve_exact(n);
    t.ramping.reserve_exact(n);
    for i in 0..n {
        if i % STOP_CHECK_CYCLES == 0 && stop.load(Ordering::Relaxed) {
            anyhow::bail!("the run was stopped at {:.3} s", i as f64 * dt);
        }
        // The set-point for the SYNC period that starts now, as the master sends it before
        // the SYNC; the drives interpolate it over the period.
        let s = test.sample(i as f64 * dt);
        let sp = [comp[0].apply(s.x), comp[1].apply(s.y)];
        pair.cycle(ENABLED, sp)?;
        let [x, y] = pair.direct_m();
        let [xm, ym] = pair.motor_m();
        t.time_s.push(i as f64 * dt);
        t.x_cmd_mm.push(s.x * 1e3);
        t.y_cmd_mm.push(s.y * 1e3);
        t.x_setpoint_mm.push(sp[0] * 1e3);
        t.y_setpoint_mm.push(sp[1] * 1e3);
        t.x_mm.push(x * 1e3);
        t.y_mm.push(y * 1e3);
        t.x_motor_mm.push(xm * 1e3);
        t.y_motor_mm.push(ym * 1e3);
        t.direction.push(match s.direction {
            Some(Direction::Cw) => -1,
            Some(Direction::Ccw) => 1,
            None => 0,
        });
        t.travelled_deg.push(s.travelled_rad.to_degrees());
        t.ramping.push(s.ramping);
    }
    let sw = pair.statuswords();
    anyhow::ensure!(
        sw.iter().all(|s| s & 0x08 == 0),
        "a drive faulted during the test (statusword {sw:04X?}): a parameter puts the axis \
         outside what its drive supervises"
    );
    if let Some(i) = (0..t.len()).find(|&i| !(t.x_mm[i].is_finite() && t.y_mm[i].is_finite())) {
        anyhow::bail!(
            "the simulation diverged at t = {:.6} s: a parameter is outside what the model \
             resolves",
            t.time_s[i]
        );
    }
    let names = [setup.axes[0].name.clone(), setup.axes[1].name.clone()];
    let report = analyze(&metrics::TracePath::of(&t), setup.radius_mm, &names)?;
    Ok(BallbarRun { trace: t, report })
}
