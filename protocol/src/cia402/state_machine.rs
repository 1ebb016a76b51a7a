//! The CiA 402 device-control state machine: states and the command transitions 2-12, 15, 16.
//! The automatic transitions (0, 1, 13, 14, and 12 after a quick stop) and the deferred ones
//! (5 and 8 with a slow-down option code) are driven by the node in `cia402/mod.rs`.

use super::controlword::Command;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum State {
    NotReadyToSwitchOn,
    SwitchOnDisabled,
    ReadyToSwitchOn,
    SwitchedOn,
    OperationEnabled,
    QuickStopActive,
    FaultReactionActive,
    Fault,
}

impl State {
    /// The power stage produces torque in these states.
    pub fn enabled(self) -> bool {
        matches!(
            self,
            State::OperationEnabled | State::QuickStopActive | State::FaultReactionActive
        )
    }
}

/// The state a command leads to, with the transition number; `None` = no transition.
/// `quick_stop_option` (0x605A) decides whether transition 16 exists (5..=8).
/// Fault reset (15) also needs the drive to clear its fault; the caller checks that.
pub fn transition(s: State, cmd: Command, quick_stop_option: i16) -> Option<(State, u8)> {
    use State::*;
    Some(match (s, cmd) {
        (SwitchOnDisabled, Command::Shutdown) => (ReadyToSwitchOn, 2),
        (ReadyToSwitchOn, Command::SwitchOn) => (SwitchedOn, 3),
        (ReadyToSwitchOn, Command::EnableOperation) => (OperationEnabled, 4),
        (SwitchedOn, Command::EnableOperation) => (OperationEnabled, 4),
        (OperationEnabled, Command::SwitchOn) => (SwitchedOn, 5),
        (SwitchedOn, Command::Shutdown) => (ReadyToSwitchOn, 6),
        (ReadyToSwitchOn, Command::DisableVoltage | Command::QuickStop) => (SwitchOnDisabled, 7),
        (OperationEnabled, Command::Shutdown) => (ReadyToSwitchOn, 8),
        (OperationEnabled, Command::DisableVoltage) => (SwitchOnDisabled, 9),
        (SwitchedOn, Command::DisableVoltage | Command::QuickStop) => (SwitchOnDisabled, 10),
        (OperationEnabled, Command::QuickStop) => (QuickStopActive, 11),
        (QuickStopActive, Command::DisableVoltage) => (SwitchOnDisabled, 12),
        (QuickStopActive, Command::EnableOperation) if (5..=8).contains(&quick_stop_option) => {
            (OperationEnabled, 16)
        }
        (Fault, Command::FaultReset) => (SwitchOnDisabled, 15),
        _ => return None,
    })
}
