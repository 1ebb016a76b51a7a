//! The paper's claims, measured the way a controller would: from the TPDOs the reference
//! master receives over the (in-process) CAN bus, through the whole protocol stack.

use drive_emu::cli::demo::{run_once, DemoArgs};

fn args(preset: &str) -> DemoArgs {
    DemoArgs {
        preset: preset.into(),
        backlash_mm: None,
        backlash_deg: None,
        backlash: None,
        velocity: 10.0,
        cruise_s: 4.0,
        json: false,
        iface: None,
        node: 5,
        panel: Default::default(),
    }
}

#[test]
fn cnc1_limit_cycle_seen_on_the_wire_follows_kv_not_the_gap() {
    let a = args("cnc1");
    let healthy = run_once(&a, 0.0).unwrap();
    assert_eq!(
        healthy.fundamental_hz, None,
        "no vibration without backlash"
    );
    let mut last_amp = 0.0;
    let mut freqs = vec![];
    for backlash_mm in [0.02, 0.04, 0.07] {
        let r = run_once(&a, backlash_mm).unwrap();
        let f = r.fundamental_hz.expect("a limit cycle with backlash");
        assert!((f - 18.0).abs() < 0.15 * 18.0, "{backlash_mm} mm: {f} Hz");
        assert!(f > r.kv_per_s / 4.0 && f < r.kv_per_s);
        assert!(
            r.velocity_amplitude > last_amp,
            "amplitude grows with the gap"
        );
        assert!(r.current_amplitude_permille > 0.0);
        last_amp = r.velocity_amplitude;
        freqs.push(f);
        assert!(
            r.emcy_codes.is_empty(),
            "no EMCY expected: {:?}",
            r.emcy_codes
        );
    }
    let (lo, hi) = freqs
        .iter()
        .fold((f64::MAX, 0f64), |(l, h), &f| (l.min(f), h.max(f)));
    assert!(
        hi / lo < 1.10,
        "frequency independent of the gap: {freqs:?}"
    );
}
