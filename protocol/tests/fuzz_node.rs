//! Stable fuzz harness (proptest) for the node behind a simple drive model: random frame
//! sequences, structured SDO exchanges into deep segmented / block states, PDO remaps, NMT,
//! SYNC, heartbeats, and time that advances, jumps by hours or goes backwards. The steps and
//! the invariants are in `fuzz/mod.rs` (shared with `emulator/tests/fuzz_node.rs`, which runs
//! the same harness on the real `AxisDrive`). The `cargo fuzz` target in `fuzz/` remains for
//! long nightly runs.
mod common;
mod fuzz;

use common::*;
use drive_protocol::NodeConfig;
use fuzz::{case_strategy, Harness, Objects};
use proptest::prelude::*;

fn config() -> NodeConfig {
    NodeConfig::new(ID, info()).with_od(od_with_handler())
}

fn advance(d: &mut SimDrive, _dt_us: u64) {
    // SimDrive integrates in `command`, once per poll; nothing to run here.
    let _ = d;
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 1500,
        max_shrink_iters: 2000,
        .. ProptestConfig::default()
    })]

    #[test]
    fn the_node_survives_any_sequence_and_keeps_its_invariants((start, ops) in case_strategy(ID, &Objects::of(&od_with_handler()), 200)) {
        let mut h = Harness::new(config(), SimDrive::default(), advance);
        h.run(start, &ops)?;
    }
}

#[test]
fn the_harness_reaches_deep_states() {
    // The generator is only worth something if it drives the node where bugs hide: check on
    // a fixed seed that cases enable the drive, move it, fault it and recover the SDO server.
    use proptest::strategy::ValueTree;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    let mut runner = TestRunner::new_with_rng(
        Config::default(),
        TestRng::from_seed(RngAlgorithm::ChaCha, &[7; 32]),
    );
    let strategy = case_strategy(ID, &Objects::of(&od_with_handler()), 200);
    let (mut enabled, mut faulted, mut recoveries, mut operational) = (0, 0, 0, 0);
    let mut st = fuzz::SdoStats::default();
    for _ in 0..60 {
        let (start, ops) = strategy.new_tree(&mut runner).unwrap().current();
        let mut h = Harness::new(config(), SimDrive::default(), advance);
        let id = ID;
        if start {
            h.handle(&drive_protocol::CanFrame::new(0, &[1, id]))
                .unwrap();
        }
        let (mut e, mut f, mut o) = (false, false, false);
        for op in &ops {
            h.apply(op).unwrap();
            e |= h.node.is_enabled();
            f |= matches!(h.node.cia402_state(), drive_protocol::Cia402State::Fault);
            o |= h.node.nmt_state() == drive_protocol::NmtState::Operational;
        }
        h.finish().unwrap();
        enabled += e as u32;
        faulted += f as u32;
        operational += o as u32;
        recoveries += h.recoveries;
        st.download_ok += h.stats.download_ok;
        st.aborts += h.stats.aborts;
        st.segments += h.stats.segments;
        st.block_download_done += h.stats.block_download_done;
        st.block_upload_end += h.stats.block_upload_end;
        st.block_acks += h.stats.block_acks;
    }
    eprintln!("{operational} operational, {enabled} enabled, {faulted} faulted, {recoveries} recoveries, {st:?}");
    assert!(operational >= 30, "{operational} of 60 cases operational");
    assert!(enabled >= 5, "{enabled} of 60 cases enabled the drive");
    assert!(faulted >= 3, "{faulted} of 60 cases faulted it");
    assert!(recoveries >= 120, "{recoveries} SDO recoveries checked");
    assert!(st.block_download_done >= 10, "{st:?}");
    assert!(st.block_upload_end >= 10, "{st:?}");
    assert!(st.segments >= 50, "{st:?}");
    assert!(st.download_ok >= 500, "{st:?}");
}
