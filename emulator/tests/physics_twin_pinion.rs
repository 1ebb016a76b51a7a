//! Twin-pinion presets over k_v (issue 31, item 1: "Done when", physics): on cnc3, cnc4 and
//! cnc5 from half to twice each preset's own k_v, measured as the paper's law is (the sweep's
//! constant-velocity run: FFT of the measured motor speed after a start ramp and a knock on
//! the load, simulated time only; `drive_emu::study`):
//!
//! - with the preload lost (0, as shipped: the paper measured these machines with the limit
//!   cycle) the limit cycle is there with f / k_v in the paper's 0.45..0.75 and k_v/4 < f < k_v;
//! - with the preload above the load torque per pinion of the start ramp (0.1 s to the
//!   cruise speed) and of the steady drag, and above the limit cycle's own load torque per
//!   pinion `m k_v^2 b / (2 r)` by the preload number [`HOLDING_PRELOAD_NUMBER`], there is no
//!   limit cycle, the knock on the load included (the knock, 0.6 x the velocity in 5 ms, is
//!   far above any preload: it parts the pinions whatever the bias, and the cycle it starts
//!   lives on if the preload is below its own torque: docs/physics.md, "Twin pinion").

use drive_emu::presets::{preset_names, AxisConfig};
use drive_emu::study::{default_velocity, own_backlash, run_cases, Case, CaseRow};

/// `2 T_p r / (m k_v^2 b)`: the preload per motor against the limit cycle's load torque per
/// pinion. Measured with the knock (docs/physics.md): at 20 % preload the cycle lived on at
/// 2.6 and 2.9 (cnc5 and cnc3 at 2 x k_v) and was gone from 4.7 on; at 2.4 (cnc5, 17.9 %) it
/// died: below about 3 the knock decides. The test holds it at 6.
const HOLDING_PRELOAD_NUMBER: f64 = 6.0;

const DURATION_S: f64 = 6.0;
const TWINS: [&str; 3] = ["cnc3", "cnc4", "cnc5"];
const KV_MULTIPLIERS: [f64; 5] = [0.5, 0.75, 1.0, 1.5, 2.0];

fn show(r: &CaseRow) -> String {
    format!(
        "{} k_v {:.1}: f {:?} Hz, f/k_v {:?}, amplitude {:.5} {}/s, cycle {}",
        r.preset,
        r.kv_per_s,
        r.fundamental_hz.map(|f| (f * 100.0).round() / 100.0),
        r.f_over_kv.map(|x| (x * 1000.0).round() / 1000.0),
        r.load_velocity_amplitude,
        r.unit,
        r.limit_cycle,
    )
}

/// Load torques per pinion of a case, N m at the motor: the start ramp's (0.1 s to the cruise
/// velocity, with the drag at cruise) and the limit cycle's scale `m k_v^2 b / (2 r)`.
fn torques_per_pinion(cfg: &AxisConfig, kv: f64) -> (f64, f64) {
    let built = cfg.build().unwrap();
    let mech = built.axis.mech;
    let v = default_velocity(cfg) * built.display_unit;
    let b = own_backlash(cfg) * built.display_unit;
    let drag = mech.load_friction.coulomb_at(v) + mech.load_friction.viscous * v;
    let ramp = (mech.load_mass * v / 0.1 + drag) / (2.0 * mech.ratio);
    let cycle = mech.load_mass * kv * kv * b / (2.0 * mech.ratio);
    (ramp, cycle)
}

/// The preload, % of each motor's rated torque, for a torque per motor, N m.
fn pct(cfg: &AxisConfig, torque: f64) -> f64 {
    let p = 100.0 * torque / (0.5 * cfg.rated_torque_nm);
    assert!(p <= 100.0, "{}: {p} % of the rated torque", cfg.name);
    p
}

/// Every twin preset at every k_v multiplier, the preload of each case from `preload_pct`
/// (the preset, k_v).
fn sweep(
    presets: &[&str],
    kvs: &[f64],
    preload_pct: impl Fn(&AxisConfig, f64) -> f64,
) -> Vec<CaseRow> {
    let mut cases = Vec::new();
    for name in presets {
        let base = AxisConfig::from_preset(name).unwrap();
        for m in kvs {
            let kv = m * base.kv_per_s;
            let cfg = base
                .with_override("preload_pct", &format!("{}", preload_pct(&base, kv)))
                .unwrap();
            cases.push((
                cfg.clone(),
                Case {
                    preset: name.to_string(),
                    kv_per_s: kv,
                    backlash: own_backlash(&cfg),
                    velocity: default_velocity(&cfg),
                    duration_s: DURATION_S,
                },
            ));
        }
    }
    run_cases(&cases, 0)
        .into_iter()
        .map(|r| r.expect("valid case"))
        .collect()
}

#[test]
fn the_twin_presets_are_the_papers_twin_pinion_machines() {
    for name in preset_names() {
        let cfg = AxisConfig::from_preset(name).unwrap();
        assert_eq!(cfg.twin_pinion, TWINS.contains(&name), "{name}");
        assert_eq!(
            cfg.preload_pct, 0.0,
            "{name}: shipped with the preload lost"
        );
    }
}

#[test]
fn limit_cycle_at_the_papers_frequency_with_the_preload_lost() {
    let rows = sweep(&TWINS, &KV_MULTIPLIERS, |_, _| 0.0);
    let mut failures = Vec::new();
    for r in &rows {
        println!("preload 0 %: {}", show(r));
        let ok =
            r.limit_cycle && r.in_band && r.f_over_kv.is_some_and(|x| (0.45..=0.75).contains(&x));
        if !ok {
            failures.push(show(r));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The holding preload of a case: above the start ramp and the drag per pinion (x 1.25) and
/// the cycle's torque per pinion x [`HOLDING_PRELOAD_NUMBER`].
fn holding(cfg: &AxisConfig, kv: f64) -> f64 {
    let (ramp, cycle) = torques_per_pinion(cfg, kv);
    pct(cfg, (1.25 * ramp).max(HOLDING_PRELOAD_NUMBER * cycle))
}

#[test]
fn no_limit_cycle_with_the_preload_holding() {
    let lost = sweep(&TWINS, &KV_MULTIPLIERS, |_, _| 0.0);
    let held = sweep(&TWINS, &KV_MULTIPLIERS, holding);
    let mut failures = Vec::new();
    for (l, h) in lost.iter().zip(&held) {
        let cfg = AxisConfig::from_preset(&h.preset).unwrap();
        println!("preload {:.1} %: {}", holding(&cfg, h.kv_per_s), show(h));
        // No cycle by the sweep's own classification, and the line left at the limit
        // cycle's frequency a small fraction of the lost preload's.
        if h.limit_cycle || h.load_velocity_amplitude > 0.05 * l.load_velocity_amplitude {
            failures.push(format!("{}\n   lost: {}", show(h), show(l)));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn the_figure_shows_the_cycle_with_the_preload_lost_and_none_with_it_holding() {
    let d = drive_emu::study::figures::fig_twin_data().unwrap();
    assert_eq!(d.traces.len(), 2);
    let (lost, held) = (&d.traces[0], &d.traces[1]);
    assert_eq!((lost.preload_pct, held.preload_pct), (0.0, 40.0));
    let f_over_kv = lost.fundamental_hz.unwrap() / d.kv_per_s;
    assert!((0.45..=0.75).contains(&f_over_kv), "{f_over_kv}");
    assert!(
        held.motor_velocity_amplitude_rpm < 0.05 * lost.motor_velocity_amplitude_rpm,
        "{} rpm held, {} rpm lost",
        held.motor_velocity_amplitude_rpm,
        lost.motor_velocity_amplitude_rpm
    );
    assert!(!held.time_s.is_empty() && held.time_s.len() == held.motor_velocity_rpm.len());
}

#[test]
fn the_drive_takes_the_preload_live_on_a_twin_and_refuses_it_on_a_single_contact() {
    use drive_emu::drive::axis_drive::AxisDrive;
    use drive_emu::drive::{AxisParam, ParamError};
    let mut one = AxisDrive::from_config(&AxisConfig::from_preset("cnc1").unwrap()).unwrap();
    assert_eq!(
        one.set_param(AxisParam::Preload, 0.2),
        Err(ParamError::OutOfRange { min: 0.0, max: 0.0 })
    );
    assert_eq!(one.param(AxisParam::Preload), 0.0);
    one.set_param(AxisParam::Preload, 0.0).unwrap();
    let mut two = AxisDrive::from_config(&AxisConfig::from_preset("cnc3").unwrap()).unwrap();
    assert_eq!(two.param(AxisParam::Preload), 0.0);
    two.set_param(AxisParam::Preload, 0.3).unwrap();
    assert!((two.param(AxisParam::Preload) - 0.3).abs() < 1e-12);
    for bad in [-0.1, 1.5, f64::NAN] {
        assert!(two.set_param(AxisParam::Preload, bad).is_err(), "{bad}");
    }
    assert!((two.param(AxisParam::Preload) - 0.3).abs() < 1e-12);
}
