//! The drive as SYNC producer (0x1005 bit 30, 0x1006, 0x1019 set over SDO), seen with
//! python-can: its SYNC frames on 0x1005's CAN-ID with the counter 1..=0x1019, CiA 301's
//! aborts, its synchronous TPDO2 after each of its SYNCs. The checks live in
//! tests/python/sync_producer.py.
//!
//! Needs vcan: `./vcan-setup.sh -- cargo nextest run -p e2e --test sync_producer`. Node 38 on bus 0.

use e2e::python_master_passes;

#[test]
fn python_can_sees_the_drives_own_sync() {
    // lock-step with no SYNC on the bus but its own: the producer runs on the communication
    // (wall) clock
    python_master_passes(
        "sync_producer.py",
        38,
        &[
            "STEP SYNC on 0x80",
            "STEP 0x1019 while",
            "STEP operational: TPDO2",
            "STEP stopped, restarted on 0x90",
        ],
    );
}
