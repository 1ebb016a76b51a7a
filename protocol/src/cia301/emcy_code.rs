//! What an EMCY error code means and what to do about it, for messages (CLI, scenarios, the
//! panel). The codes are CiA 301's error-code classes (Table "Emergency error codes") and the
//! CiA 402 drive codes this drive raises; a vendor-specific code (0xFF00..=0xFFFF) only says so,
//! unless the caller knows its own ([`EmcyMeaning::with`]).

/// The meaning of one error code: a short name and a hint what to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EmcyMeaning {
    /// What the code says, e.g. "heartbeat / life guard error".
    pub name: &'static str,
    /// What usually causes it here and what to do, one sentence.
    pub action: &'static str,
}

impl EmcyMeaning {
    /// A meaning for a code the caller defines (a manufacturer-specific code).
    pub const fn with(name: &'static str, action: &'static str) -> Self {
        EmcyMeaning { name, action }
    }
}

const fn m(name: &'static str, action: &'static str) -> EmcyMeaning {
    EmcyMeaning { name, action }
}

/// The meaning of `code`: the exact code where this drive raises it, else its CiA 301 class.
pub fn meaning(code: u16) -> EmcyMeaning {
    match code {
        0x0000 => m(
            "error reset / no error",
            "nothing: the errors before it are gone",
        ),
        0x2310 => m(
            "continuous over-current (current limit or motor I2t)",
            "the axis asks for more torque than the motor gives for long: lower the acceleration, \
             the speed or the load, or raise the current limit 0x6073",
        ),
        0x6100 => m(
            "internal software error (the simulation left its valid range)",
            "check the values set by --set, a scenario or the panel (a NaN, a stiffness too high \
             for the physics step); the drive stays in FAULT until they are sane",
        ),
        0x6320 => m(
            "parameter error: a PDO carried a value the drive refuses",
            "write the same object by SDO to read the abort code that says why, then fix the \
             master's set-point",
        ),
        0x7300 => m(
            "sensor error: an encoder signal is lost",
            "an encoder fault is active (scenario, panel or fault object): clear it, then reset \
             the fault (controlword bit 7)",
        ),
        0x8100 => m(
            "SYNC loss: the SYNCs came more than 1.5 periods (0x1006) apart",
            "make the master send SYNC on time; on a slow or virtualised host run the drive \
             with --lockstep",
        ),
        0x8110 => m(
            "CAN overrun: frames were lost",
            "the bus carries more than the drive reads per cycle: lower the bus load",
        ),
        0x8120 => m(
            "CAN in error passive mode",
            "check the bus: termination, bit rate, a node sending errors",
        ),
        0x8130 => m(
            "heartbeat / life guard error: the master's heartbeat (0x1016) stopped",
            "make the master send its heartbeat, with 0x1016's time 2-3 times its period",
        ),
        0x8250 => m(
            "RPDO timeout: the master's process data stopped (EtherCAT: the SM watchdog took \
             the slave from OP to SAFE-OP, AL status 0x001B)",
            "send the process data every cycle, within the SM watchdog time (0x0420); then OP \
             again and a fault reset (controlword bit 7)",
        ),
        0x8140 => m(
            "recovered from bus-off",
            "check the bus: termination, bit rate, a node sending errors",
        ),
        0x8210 => m(
            "PDO not processed: shorter than its mapping",
            "send each RPDO with the length its mapping (0x1600..) gives",
        ),
        0x8220 => m(
            "PDO length exceeded: longer than its mapping",
            "send each RPDO with the length its mapping (0x1600..) gives",
        ),
        0x8240 => m(
            "unexpected SYNC data length (0x1019)",
            "send SYNC with the counter byte 0x1019 asks for, or none when it is 0",
        ),
        0x8400 => m(
            "velocity control error: overspeed",
            "command less speed than the axis's maximum (0x6080 and the motor's)",
        ),
        0x8611 => m(
            "following error: the position lagged more than 0x6065 for longer than 0x6066",
            "lower the acceleration or the feed, widen 0x6065/0x6066, or look at the axis's \
             load and wear",
        ),
        0x8612 => m(
            "reference limit: the position left the software limits (0x607D)",
            "move back inside 0x607D after a fault reset",
        ),
        _ => class(code),
    }
}

/// The CiA 301 class of a code the table above does not name.
fn class(code: u16) -> EmcyMeaning {
    const SEE: &str = "see the drive's manual for this code";
    match code >> 8 {
        0x10 => m("generic error", SEE),
        0x20..=0x2F => m("current error", SEE),
        0x30..=0x3F => m("voltage error", SEE),
        0x40..=0x4F => m("temperature error", SEE),
        0x50..=0x5F => m("device hardware error", SEE),
        0x60..=0x6F => m("device software error", SEE),
        0x70..=0x7F => m("additional modules error", SEE),
        0x80..=0x8F => m("monitoring error", SEE),
        0x90..=0x9F => m("external error", SEE),
        0xF0 => m("additional functions error", SEE),
        0xFF => m("manufacturer-specific error", SEE),
        _ => m("error code outside the CiA 301 classes", SEE),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_code_the_drive_raises_has_its_own_meaning() {
        use crate::cia301::{pdo::rpdo, sync};
        for code in [
            sync::EMCY_SYNC_LOSS,
            sync::EMCY_SYNC_LENGTH,
            rpdo::EMCY_PDO_LENGTH,
            rpdo::EMCY_PDO_LENGTH_EXCEEDED,
            crate::node::EMCY_HEARTBEAT,
            crate::node::EMCY_RPDO_VALUE,
            crate::node::access::EMCY_RPDO_TIMEOUT,
            crate::cia402::EMCY_FOLLOWING_ERROR,
        ] {
            let mm = meaning(code);
            assert_ne!(
                mm.action,
                class(code).action,
                "{code:#06X} falls back to its class"
            );
            assert!(!mm.name.is_empty() && mm.action.len() > 20, "{code:#06X}");
        }
    }

    #[test]
    fn unknown_codes_fall_back_to_their_class() {
        assert_eq!(meaning(0x4210).name, "temperature error");
        assert_eq!(meaning(0xFF42).name, "manufacturer-specific error");
        assert_eq!(meaning(0x8F00).name, "monitoring error");
        assert_eq!(
            meaning(0xA000).name,
            "error code outside the CiA 301 classes"
        );
    }
}
