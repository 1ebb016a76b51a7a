//! python `canopen` runs the drive in profile torque mode (0x6060 = 4): BaseNode402 to
//! OPERATION ENABLED in PT, target torque 0x6071 written, the demand 0x6074 at it (bit 10),
//! the actual torque 0x6077 and velocity 0x606C following it both ways, halt to 0. The checks
//! live in tests/python/profile_torque.py.
//!
//! Needs vcan: `./vcan-setup.sh -- cargo nextest run -p e2e --test profile_torque`. Node 37 on bus 0.

use e2e::python_master_passes;

#[test]
fn python_canopen_runs_the_drive_in_profile_torque() {
    // lock-step with the script's 10 ms SYNC: the drive's physics do not depend on the host's load
    python_master_passes(
        "profile_torque.py",
        37,
        &[
            "STEP PT, OPERATION ENABLED",
            "STEP +200 per mille",
            "STEP -200 per mille",
            "STEP halt",
        ],
    );
}
