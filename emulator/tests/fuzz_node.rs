//! Stable fuzz harness (proptest) for a node driving the real simulated axis (`AxisDrive`,
//! CNC1 with backlash): random frame sequences, structured SDO exchanges into deep segmented
//! and block states, axis parameter writes, PDO remaps, RPDOs, NMT, SYNC, heartbeats, CiA 402
//! enables in every mode, and time that advances, jumps by hours or goes backwards. The
//! steps and invariants are the protocol crate's (`protocol/tests/fuzz/mod.rs`, included
//! here); the physics runs for the forward part of each time step (at most 10 ms per poll,
//! as the runtime runs one tick per poll). Bounded: a few seconds on one busy core.

#[path = "../../protocol/tests/fuzz/mod.rs"]
mod fuzz;

use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::drive::{node_config, NodeOptions};
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::SimulatedDrive;
use drive_protocol::NodeConfig;
use fuzz::{case_strategy, Harness, Objects};
use proptest::prelude::*;

const ID: u8 = 5;

fn axis() -> AxisDrive {
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("backlash_mm", "0.05")
        .unwrap();
    AxisDrive::from_config(&cfg).unwrap()
}

/// The drive and its node's configuration (the drive knows its objects' slots in it).
fn axis_and_config() -> (AxisDrive, NodeConfig) {
    let mut drive = axis();
    let cfg = node_config(&mut drive, &NodeOptions::new(ID)).unwrap();
    (drive, cfg)
}

fn objects() -> Objects {
    Objects::of(&axis_and_config().1.od)
}

fn advance(d: &mut AxisDrive, dt_us: u64) {
    d.advance(dt_us);
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 600,
        max_shrink_iters: 500,
        .. ProptestConfig::default()
    })]

    #[test]
    fn a_node_on_the_real_axis_survives_any_sequence((start, ops) in case_strategy(ID, &objects(), 150)) {
        let (drive, cfg) = axis_and_config();
        let mut h = Harness::new(cfg, drive, advance);
        h.run(start, &ops)?;
    }
}
