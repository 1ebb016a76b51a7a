//! Integrator checks on the free two-mass oscillator (motor disabled, no friction, no
//! gravity): energy is conserved without damping and decays with damping.

use drive_emu::axis::Axis;
use drive_emu::presets::AxisConfig;

fn free_axis(damping_ratio: &str, backlash_mm: &str) -> Axis {
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_overrides([
            "vertical=false",
            "load_coulomb_friction_n=0",
            "load_viscous_friction_n_per_m_per_s=0",
            "motor_coulomb_friction_nm=0",
            "motor_viscous_friction_nm_per_rad_per_s=0",
        ])
        .unwrap()
        .with_override("damping_ratio", damping_ratio)
        .unwrap()
        .with_override("backlash_mm", backlash_mm)
        .unwrap();
    let p = cfg.build().unwrap().axis;
    assert_eq!(p.mech.load_friction.coulomb, 0.0);
    assert_eq!(p.mech.load_friction.viscous, 0.0);
    let mut axis = Axis::new(p).unwrap();
    // Motor disabled (zero torque), the drive train wound up by 20 um at rest.
    axis.motor.disable();
    axis.mech.state.load.pos = -20e-6 - 0.5 * p.mech.contact.backlash;
    axis
}

fn period_steps(axis: &Axis) -> usize {
    let w = axis.mech.params().contact_omega();
    (2.0 * std::f64::consts::PI / w / axis.step_size()).round() as usize
}

#[test]
fn free_oscillation_conserves_energy() {
    // Bound: relative energy error below 0.1 % over 200 periods (the drift-kick-drift
    // integrator's error is of order (omega h)^2 / 8 ~ 2e-4 and does not accumulate).
    for backlash in ["0", "0.03"] {
        let mut axis = free_axis("0", backlash);
        let e0 = axis.mech.energy();
        assert!(e0 > 0.0);
        let n = 200 * period_steps(&axis);
        let mut worst: f64 = 0.0;
        for _ in 0..n {
            axis.substep();
            worst = worst.max((axis.mech.energy() - e0).abs() / e0);
        }
        assert!(worst < 1e-3, "backlash {backlash}: energy error {worst}");
        // It really oscillated: the momentum keeps moving between the masses.
        assert!(axis.load_velocity() != 0.0);
    }
}

#[test]
fn damped_free_oscillation_decays() {
    // Damping ratio 0.05 of the contact oscillator: energy ~ exp(-2 zeta omega t), after
    // 20 periods below exp(-2 * 0.05 * 2 pi * 20) ~ 3.5e-6; we ask for < 1e-3.
    let mut axis = free_axis("0.05", "0");
    let e0 = axis.mech.energy();
    let n = period_steps(&axis);
    let mut last = e0;
    for p in 0..20 {
        for _ in 0..n {
            axis.substep();
        }
        let e = axis.mech.energy();
        assert!(
            e < last,
            "period {p}: energy did not decrease ({e} >= {last})"
        );
        last = e;
    }
    assert!(last < 1e-3 * e0, "energy after 20 periods {last} of {e0}");
}
