//! The CiA 402 device-control state machine: states and the command transitions 2-12, 15, 16.
//! The automatic transitions (0, 1, 13, 14, and 12 after a quick stop) and the deferred ones
//! (5 and 8 with a slow-down option code) are driven by the node in `cia402/mod.rs`.

use super::controlword::Command;

/// A state of the CiA 402 device-control state machine (exported as `Cia402State`).
/// `Display` gives the standard's name in capitals, e.g. `OPERATION ENABLED`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum State {
    /// Not ready to switch on (initialising).
    NotReadyToSwitchOn,
    /// Switch on disabled.
    SwitchOnDisabled,
    /// Ready to switch on.
    ReadyToSwitchOn,
    /// Switched on.
    SwitchedOn,
    /// Operation enabled.
    OperationEnabled,
    /// Quick stop active.
    QuickStopActive,
    /// Fault reaction active.
    FaultReactionActive,
    /// Fault.
    Fault,
}

impl core::fmt::Display for State {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

impl State {
    /// Every state, in the order of the standard.
    pub const ALL: [State; 8] = [
        State::NotReadyToSwitchOn,
        State::SwitchOnDisabled,
        State::ReadyToSwitchOn,
        State::SwitchedOn,
        State::OperationEnabled,
        State::QuickStopActive,
        State::FaultReactionActive,
        State::Fault,
    ];

    /// The standard's name in capitals (`OPERATION ENABLED`).
    pub fn name(self) -> &'static str {
        match self {
            State::NotReadyToSwitchOn => "NOT READY TO SWITCH ON",
            State::SwitchOnDisabled => "SWITCH ON DISABLED",
            State::ReadyToSwitchOn => "READY TO SWITCH ON",
            State::SwitchedOn => "SWITCHED ON",
            State::OperationEnabled => "OPERATION ENABLED",
            State::QuickStopActive => "QUICK STOP ACTIVE",
            State::FaultReactionActive => "FAULT REACTION ACTIVE",
            State::Fault => "FAULT",
        }
    }

    /// The name as a snake-case key (`operation_enabled`), as scenario files write it.
    pub fn key(self) -> &'static str {
        match self {
            State::NotReadyToSwitchOn => "not_ready_to_switch_on",
            State::SwitchOnDisabled => "switch_on_disabled",
            State::ReadyToSwitchOn => "ready_to_switch_on",
            State::SwitchedOn => "switched_on",
            State::OperationEnabled => "operation_enabled",
            State::QuickStopActive => "quick_stop_active",
            State::FaultReactionActive => "fault_reaction_active",
            State::Fault => "fault",
        }
    }

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
