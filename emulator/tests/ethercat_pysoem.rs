//! `drive-emu run --ethercat` against an independent master: SOEM through pysoem
//! (tests/python/ethercat_pysoem.py) on a veth pair of the host, three slaves in one process:
//! config_init finds them with their SII identity equal to CoE 0x1018, SDO read/write,
//! complete access of 0x1C12, the abort of a missing object, SAFE-OP and OP with the working
//! counter SOEM expects in every cycle, CiA 402 enable and a CSP move whose 0x6064 comes back
//! in the process data.
//!
//! Root (or CI, where a veth pair that cannot be made fails the test): see ethercat_rig.

mod ethercat_rig;
use ethercat_rig::*;

#[test]
fn pysoem_configures_three_slaves_and_moves_them_in_csp() {
    if !may_run("ethercat_pysoem") {
        return;
    }
    let veth = Veth::create('p').unwrap_or_else(|e| panic!("cannot create the veth pair: {e}"));
    let dir = std::env::temp_dir().join(format!("drive-emu-ethercat-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let machine = dir.join("machine.toml");
    std::fs::write(
        &machine,
        "tick_hz = 1000\n[[axis]]\nnode_id = 1\npreset = \"cnc1\"\n[[axis]]\nnode_id = 2\n\
         preset = \"cnc1\"\n[[axis]]\nnode_id = 3\npreset = \"cnc1\"\n",
    )
    .unwrap();
    let mut emu = Emulator::start(&veth.slave, &["--config", machine.to_str().unwrap()]);
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(emu.ready["nodes"].as_array().map(Vec::len), Some(3));
    let report = python("ethercat_pysoem.py", &[&veth.master, "3"], 180);
    assert_eq!(report["slaves"], 3);
    assert_eq!(report["expected_wkc"], 9);
    assert!(report["cycles"].as_u64().unwrap() > 1000);
    for p in report["position_actual"].as_array().unwrap() {
        let p = p.as_i64().unwrap();
        assert!((p - 2000).abs() <= 20, "0x6064 {p}");
    }
    // stopped: the emulator's own count of what it answered and refused
    let (stats, _) = emu.stop();
    assert!(stats["frames"].as_u64().unwrap() > 1000, "{stats}");
    assert_eq!(stats["refused"], 0, "{stats}");
    assert_eq!(stats["socket_errors"], 0, "{stats}");
}
