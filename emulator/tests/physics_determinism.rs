//! Same input, bit-identical output (with encoder noise on, which uses the seeded PRNG).

use drive_emu::analysis::{constant_velocity_run, RunOptions};
use drive_emu::presets::AxisConfig;

#[test]
fn two_runs_give_bit_identical_traces() {
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_overrides([
            "motor_encoder_noise_counts=3",
            "direct_encoder_noise_counts=2",
            "noise_seed=77",
        ])
        .unwrap();
    let mut opts = RunOptions::new(16.7, 2.0);
    opts.record = true;
    let a = constant_velocity_run(&cfg, &opts).unwrap().trace;
    let b = constant_velocity_run(&cfg, &opts).unwrap().trace;
    assert_eq!(a.len(), 2000);
    let cols = |t: &drive_emu::analysis::Trace| {
        [
            t.time_s.clone(),
            t.position_setpoint.clone(),
            t.direct_position.clone(),
            t.motor_position.clone(),
            t.motor_velocity_rpm.clone(),
            t.load_velocity.clone(),
            t.torque_nm.clone(),
            t.current_a.clone(),
            t.following_error.clone(),
        ]
    };
    for (ca, cb) in cols(&a).iter().zip(cols(&b).iter()) {
        let ba: Vec<u64> = ca.iter().map(|x| x.to_bits()).collect();
        let bb: Vec<u64> = cb.iter().map(|x| x.to_bits()).collect();
        assert_eq!(ba, bb);
    }
    // A different seed gives a different trace (the noise is really there).
    let other = cfg.with_override("noise_seed", "78").unwrap();
    let c = constant_velocity_run(&other, &opts).unwrap().trace;
    assert_ne!(
        a.motor_velocity_rpm
            .iter()
            .map(|x| x.to_bits())
            .collect::<Vec<_>>(),
        c.motor_velocity_rpm
            .iter()
            .map(|x| x.to_bits())
            .collect::<Vec<_>>()
    );
}
