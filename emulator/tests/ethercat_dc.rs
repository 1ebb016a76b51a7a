//! Distributed clocks over the wire: SOEM through pysoem (tests/python/ethercat_dc.py) with
//! SYNC0 at 1 ms (`config_dc`, `dc_sync(True, 1_000_000)`, 0x1C32:1 = 2) on a veth pair.
//! DC SYNC0 without SYNC0 is refused with AL status code 0x0030; with it, SAFE-OP and OP, the
//! drive's cycle locks to SYNC0 (0x2100: lock state 2, period 1000 us) and a CSP move from the
//! process data reaches its target; the emulator counts its cycles locked to SYNC0 and their
//! phase error.
//!
//! Root (or CI, where a veth pair that cannot be made fails the test): see ethercat_rig.

mod ethercat_rig;
use ethercat_rig::*;

#[test]
fn soem_dc_sync0_locks_the_drive_cycle_and_moves() {
    if !may_run("ethercat_dc") {
        return;
    }
    let veth = Veth::create('d').unwrap_or_else(|e| panic!("cannot create the veth pair: {e}"));
    let mut emu = Emulator::start(&veth.slave, &["--preset", "cnc1"]);
    let report = python("ethercat_dc.py", &[&veth.master], 180);
    assert_eq!(report["refused_code"], 0x0030);
    assert_eq!(report["lock"][0], 2, "{report}");
    assert_eq!(report["lock"][2], 1000, "{report}");
    assert_eq!(report["lock_end"][0], 2, "{report}");
    let p = report["position_actual"].as_i64().unwrap();
    assert!((p - 2000).abs() <= 20, "0x6064 {p}");
    let (stats, _) = emu.stop();
    assert!(
        stats["sync0_locked_cycles"].as_u64().unwrap() > 300,
        "{stats}"
    );
    // the phase error is measured: a figure, and below the SYNC0 period at its median
    assert!(
        stats["sync0_phase_p50_us"].as_u64().unwrap() < 1000,
        "{stats}"
    );
    assert_eq!(stats["refused"], 0, "{stats}");
}

/// `--lockstep` with DC SYNC0 at 1 ms and the drive ticking at 4 kHz: every process-data
/// frame is a SYNC0 event and runs exactly 4 drive ticks (0x2100 sub 1 counts them), 0x2100
/// says locked with a 1000 us period, and a CSP ramp from the process data is followed.
/// Counts only: the master cycles as fast as it goes.
#[test]
fn soem_dc_sync0_in_lockstep_runs_the_sync0_cycles_ticks_per_frame() {
    if !may_run("ethercat_dc") {
        return;
    }
    let veth = Veth::create('k').unwrap_or_else(|e| panic!("cannot create the veth pair: {e}"));
    let mut emu = Emulator::start(
        &veth.slave,
        &["--preset", "cnc1", "--lockstep", "--tick-hz", "4000"],
    );
    let report = python("ethercat_dc.py", &[&veth.master, "--lockstep", "300"], 180);
    assert_eq!(report["frames"], 300, "{report}");
    assert_eq!(
        report["ticks"],
        4 * 300,
        "4 ticks per SYNC0 event: {report}"
    );
    let total = report["frames_total"].as_u64().unwrap();
    assert_eq!(
        report["ticks_total"],
        4 * total,
        "every frame from SAFE-OP on: {report}"
    );
    assert_eq!(report["lock"][0], 2, "{report}");
    assert_eq!(report["lock"][2], 1000, "{report}");
    let p = report["position_actual"].as_i64().unwrap();
    assert!((p - 600).abs() <= 20, "0x6064 {p} after a ramp to 600");
    let (stats, _) = emu.stop();
    assert_eq!(stats["cycles"].as_u64().unwrap(), 4 * total, "{stats}");
    assert_eq!(stats["sync0_locked_cycles"], stats["cycles"], "{stats}");
    assert_eq!(stats["refused"], 0, "{stats}");
}
