//! SOEM (pysoem, tests/python/ethercat_modes.py) against `drive-emu run --ethercat
//! --lockstep` on a veth pair of the host, with the master's own PDO mapping written in
//! PRE-OP (11 bytes of outputs, 13 of inputs: longer than a CAN frame):
//!
//! - CSP, CSV and a PP move (set-point handshake bits 4 / 12, target reached bit 10) from
//!   the process data;
//! - the paper's law over the EtherCAT wire: a worn axis (backlash_mm = 0.05, named here:
//!   the default axis is healthy) at constant speed in CSP, for three k_v written over CoE,
//!   0x606C from the process data; the limit cycle's frequency f from its spectrum is
//!   0.45..0.75 k_v. Lock-step: one drive cycle per master cycle, so the samples' times are
//!   the drive's (1 ms apart), whatever the load of the machine.
//!
//! Root (or CI, where a veth pair that cannot be made fails the test): see ethercat_rig.

mod ethercat_rig;
use ethercat_rig::*;

/// A directory of this test, removed when dropped (also when the test fails).
struct TempDir(std::path::PathBuf);

impl TempDir {
    fn new(name: &str) -> TempDir {
        let p = std::env::temp_dir().join(format!("drive-emu-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn pysoem_own_long_mapping_csp_csv_and_pp_from_the_process_data() {
    if !may_run("ethercat_modes") {
        return;
    }
    let veth = Veth::create('m').unwrap_or_else(|e| panic!("cannot create the veth pair: {e}"));
    let dir = TempDir::new("modes");
    let trace = dir.0.join("trace.csv");
    let mut emu = Emulator::start(
        &veth.slave,
        &[
            "--preset",
            "cnc1",
            "--lockstep",
            "--trace",
            trace.to_str().unwrap(),
        ],
    );
    let r = python("ethercat_modes.py", &[&veth.master, "modes"], 300);
    assert_eq!(r["expected_wkc"], 3);
    assert!(
        (r["csp_position"].as_i64().unwrap() - 3000).abs() <= 20,
        "{r}"
    );
    assert!(
        (r["csv_velocity"].as_i64().unwrap() + 5000).abs() <= 250,
        "{r}"
    );
    assert!(r["pp_error"].as_i64().unwrap().abs() <= 20, "{r}");
    let (stats, _) = emu.stop();
    assert_eq!(stats["refused"], 0, "{stats}");
    assert_eq!(stats["socket_errors"], 0, "{stats}");
    // lock-step: the drives ran one cycle per process-data frame, none on their own
    assert_eq!(stats["cycles"], r["cycles"], "{stats} / {r}");
    // --trace: the drive's own sample of every cycle, 1 ms apart, through CSP, CSV and PP
    let text = std::fs::read_to_string(&trace).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (t, mode) = (col("t_s"), col("mode_display"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len() as u64, stats["cycles"].as_u64().unwrap());
    for w in rows.windows(2) {
        assert!((w[1][t] - w[0][t] - 0.001).abs() < 1e-6, "{w:?}");
    }
    for m in [8.0, 9.0, 1.0] {
        assert!(rows.iter().any(|r| r[mode] == m), "mode {m} in the trace");
    }
}

#[test]
fn backlash_limit_cycle_in_0x606c_over_ethercat_follows_kv() {
    if !may_run("ethercat_modes") {
        return;
    }
    let veth = Veth::create('l').unwrap_or_else(|e| panic!("cannot create the veth pair: {e}"));
    let mut emu = Emulator::start(
        &veth.slave,
        &[
            "--preset",
            "cnc1",
            "--set",
            "backlash_mm=0.05",
            "--lockstep",
            "--detect",
        ],
    );
    let kvs = ["20", "30", "45"];
    let mut args = vec![veth.master.as_str(), "law"];
    args.extend(kvs);
    let r = python("ethercat_modes.py", &args, 300);
    let speed = r["speed_uu_per_s"].as_f64().unwrap();
    let runs = r["runs"].as_array().unwrap();
    assert_eq!(runs.len(), kvs.len());
    let mut ratios = Vec::new();
    for run in runs {
        let kv = run["kv_per_s"].as_f64().unwrap();
        let dt = run["sample_period_s"].as_f64().unwrap();
        let v: Vec<f64> = run["velocity_actual"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert_eq!(v.len(), 4000);
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        assert!(
            (mean - speed).abs() < 0.05 * speed,
            "k_v {kv}: mean 0x606C {mean}, commanded {speed}"
        );
        // a sustained oscillation, not encoder ripple
        let amp = drive_emu::analysis::half_peak_to_peak(&v);
        assert!(amp > 0.02 * speed, "k_v {kv}: 0x606C amplitude {amp}");
        let peak = drive_emu::analysis::fundamental(&v, 1.0 / dt, (kv / 8.0, 2.0 * kv))
            .unwrap_or_else(|| panic!("k_v {kv}: no line in 0x606C"));
        let ratio = peak.frequency_hz / kv;
        eprintln!(
            "k_v {kv} 1/s: f = {:.2} Hz, f/k_v = {ratio:.3}, amplitude {amp:.0} uu/s",
            peak.frequency_hz
        );
        ratios.push((kv, peak.frequency_hz, ratio));
    }
    for (kv, f, ratio) in &ratios {
        assert!(
            (0.45..=0.75).contains(ratio),
            "k_v {kv}: f = {f:.2} Hz, f/k_v = {ratio:.3} outside 0.45..0.75 ({ratios:?})"
        );
    }
    let (stats, _) = emu.stop();
    assert_eq!(stats["refused"], 0, "{stats}");
    // --detect on the drive's own samples: the same worn axis, seen from inside
    let rep = &stats["detect"][0]["report"];
    assert_eq!(rep["verdict"], "backlash", "{stats}");
    // ... and its warning, EMCY 0xFF01, reached the master over CoE
    assert!(
        r["emcys"].as_array().unwrap().iter().any(|c| c == 0xFF01),
        "{}",
        r["emcys"]
    );
}

#[test]
fn sm_watchdog_takes_the_slave_to_safe_op_and_the_drive_reacts_per_0x6007() {
    if !may_run("ethercat_modes") {
        return;
    }
    let veth = Veth::create('w').unwrap_or_else(|e| panic!("cannot create the veth pair: {e}"));
    // the drive's own tick: a master that stops sending is the point
    let mut emu = Emulator::start(&veth.slave, &["--preset", "cnc1"]);
    let r = python(
        "ethercat_modes.py",
        &[&veth.master, "watchdog", "1", "2", "3", "0"],
        300,
    );
    let rounds = r["rounds"].as_array().unwrap();
    assert_eq!(rounds.len(), 4, "{r}");
    for round in rounds {
        let option = round["option"].as_i64().unwrap();
        let sw = round["statusword"].as_u64().unwrap();
        assert_eq!(round["al_status"], 0x001B, "SM watchdog: {round}");
        assert!(
            round["emcys"]
                .as_array()
                .unwrap()
                .iter()
                .any(|c| c == 0x8250),
            "EMCY 0x8250 over CoE: {round}"
        );
        let state = sw & 0x6F;
        match option {
            // fault: FAULT (bit 3), 0x603F holds the code
            1 => {
                assert_eq!(sw & 0x4F, 0x08, "0x6007=1 -> fault: {round}");
                assert_eq!(round["error_code"], 0x8250, "{round}");
            }
            // disable voltage: SWITCH ON DISABLED
            2 => assert_eq!(sw & 0x4F, 0x40, "0x6007=2 -> switch on disabled: {round}"),
            // quick stop: QUICK STOP ACTIVE (or, the stop done, SWITCH ON DISABLED), no fault
            3 => assert!(
                state == 0x07 || sw & 0x4F == 0x40,
                "0x6007=3 -> quick stop: {round}"
            ),
            // none: still OPERATION ENABLED
            0 => assert_eq!(state, 0x27, "0x6007=0 -> no reaction: {round}"),
            _ => unreachable!(),
        }
        assert_eq!(
            round["enabled_again"], true,
            "OP and enabled again: {round}"
        );
    }
    let (stats, _) = emu.stop();
    assert_eq!(stats["refused"], 0, "{stats}");
}
