//! EtherCAT faults from a scenario, as an independent master sees them: SOEM through pysoem
//! (tests/python/ethercat_faults.py) against `drive-emu run --ethercat --scenario
//! scenarios/ethercat-faults.toml` on a veth pair: lost frames and the link down (no answer),
//! working counters not incremented, a late cycle, the slave dropping out of OP with AL status
//! code 0x001A; then the master brings it back to OP, the drive is enabled again, every cycle
//! has the expected working counter and a CoE read answers. The emulator's own account (the
//! scenario's events, EMCY 0x8250, the fault counts) is checked against it. A drive fault
//! of a scenario (encoder loss) reaches the master as on CAN.
//!
//! Root (or CI, where a veth pair that cannot be made fails the test): see ethercat_rig.

mod ethercat_rig;
use ethercat_rig::*;

#[test]
fn pysoem_sees_each_scenario_fault_and_recovers() {
    if !may_run("ethercat_faults") {
        return;
    }
    let veth = Veth::create('f').unwrap_or_else(|e| panic!("cannot create the veth pair: {e}"));
    let file = repo().join("scenarios/ethercat-faults.toml");
    // the run ends when the test stops it (the scenario's time would end it 1 s after its
    // last event, before a slow master has recovered)
    let mut emu = Emulator::start(
        &veth.slave,
        &["--scenario", file.to_str().unwrap(), "--duration", "600"],
    );
    assert_eq!(emu.ready["scenario"], "ethercat-faults");
    let report = python("ethercat_faults.py", &[&veth.master], 180);
    assert_eq!(report["al_status"], 0x14, "{report}");
    assert_eq!(report["al_status_code"], 0x001A, "{report}");
    assert!(report["no_answer"].as_u64().unwrap() >= 20, "{report}");
    assert!(report["wkc_zero"].as_u64().unwrap() >= 1, "{report}");
    assert_eq!(
        report["statusword"].as_u64().unwrap() & 0x6F,
        0x27,
        "{report}"
    );

    let (stats, _) = emu.stop();
    let faults = &stats["faults"];
    // the first 20 frames of the lost-frames fault and the link down's
    assert!(faults["lost"].as_u64().unwrap() >= 20, "{stats}");
    assert!(faults["held"].as_u64().unwrap() >= 1, "{stats}");
    assert!(faults["bad_wkc"].as_u64().unwrap() >= 1, "{stats}");
    let sc = &stats["scenario"];
    let events: Vec<&str> = sc["events"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["event"].as_str().unwrap())
        .collect();
    assert_eq!(events.len(), 5, "{sc}");
    for (e, want) in events.iter().zip([
        "next 20 frames lost",
        "working counter not incremented",
        "late cycle",
        "link down",
        "out of OP (AL status code 0x001A)",
    ]) {
        assert!(e.contains(want), "{e:?} lacks {want:?}");
    }
    assert!(
        sc["emcys"]
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e["code"] == "0x8250"),
        "{sc}"
    );
    assert_eq!(sc["passed"], true, "{sc}");
    assert_eq!(stats["refused"], 0, "{stats}");
    assert_eq!(stats["socket_errors"], 0, "{stats}");
}

/// A drive fault from a scenario works on EtherCAT as on CAN: scenarios/encoder-loss.toml
/// (the motor encoder's signal lost 1 s after operation enabled) as SOEM sees it: the fault
/// state in the statusword from the process data while the slave stays in OP, 0x603F =
/// 0x7300 and EMCY 0x7300 over CoE; the scenario's own expectations pass.
#[test]
fn a_scenarios_drive_fault_reaches_the_master_over_ethercat() {
    if !may_run("ethercat_faults") {
        return;
    }
    let veth = Veth::create('e').unwrap_or_else(|e| panic!("cannot create the veth pair: {e}"));
    let file = repo().join("scenarios/encoder-loss.toml");
    let mut emu = Emulator::start(
        &veth.slave,
        &["--scenario", file.to_str().unwrap(), "--duration", "600"],
    );
    let report = python("ethercat_faults.py", &[&veth.master, "encoder"], 180);
    assert_eq!(report["error_code"], 0x7300, "{report}");
    assert_eq!(
        report["statusword"].as_u64().unwrap() & 0x4F,
        0x08,
        "{report}"
    );
    let (stats, _) = emu.stop();
    let sc = &stats["scenario"];
    assert_eq!(sc["events"].as_array().map(Vec::len), Some(1), "{sc}");
    assert!(
        sc["emcys"]
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e["code"] == "0x7300"),
        "{sc}"
    );
    assert_eq!(sc["passed"], true, "{sc}");
    // no EtherCAT fault was injected: nothing lost, held or corrupted
    assert_eq!(stats["faults"]["lost"], 0, "{stats}");
    assert_eq!(stats["faults"]["bad_wkc"], 0, "{stats}");
}
