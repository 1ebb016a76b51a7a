//! Statusword 0x6041: the state bits of CiA 402 and the common bits.

use super::state_machine::State;

/// Bit 4: voltage enabled (high voltage applied to the drive).
pub const BIT_VOLTAGE_ENABLED: u16 = 1 << 4;
/// Bit 5: quick stop (active low: 0 while QUICK STOP ACTIVE).
pub const BIT_QUICK_STOP: u16 = 1 << 5;
/// Bit 7: warning.
pub const BIT_WARNING: u16 = 1 << 7;
/// Bit 9: remote (the controlword is processed).
pub const BIT_REMOTE: u16 = 1 << 9;
/// Bit 10: target reached (mode-specific; also set when a quick stop or halt has stopped the axis).
pub const BIT_TARGET_REACHED: u16 = 1 << 10;
/// Bit 11: internal limit active (software position limit 0x607D, velocity or torque clamp).
pub const BIT_INTERNAL_LIMIT: u16 = 1 << 11;
/// Bit 12: operation-mode specific (PP set-point acknowledge, PV speed zero, HM homing attained, CSx target value ignored = 0).
pub const BIT_OMS12: u16 = 1 << 12;
/// Bit 13: operation-mode specific (PP/CSP following error, HM homing error).
pub const BIT_OMS13: u16 = 1 << 13;

/// Bits 0-6 of the statusword for a state (mask 0x6F / 0x4F values of CiA 402).
pub fn state_bits(s: State) -> u16 {
    match s {
        State::NotReadyToSwitchOn => BIT_QUICK_STOP,
        State::SwitchOnDisabled => 0x0040 | BIT_QUICK_STOP,
        State::ReadyToSwitchOn => 0x0021 | BIT_VOLTAGE_ENABLED,
        State::SwitchedOn => 0x0023 | BIT_VOLTAGE_ENABLED,
        State::OperationEnabled => 0x0027 | BIT_VOLTAGE_ENABLED,
        State::QuickStopActive => 0x0007 | BIT_VOLTAGE_ENABLED,
        State::FaultReactionActive => 0x000F | BIT_QUICK_STOP,
        State::Fault => 0x0008 | BIT_QUICK_STOP,
    }
}

/// The state a statusword shows (for masters and tests).
pub fn decode_state(sw: u16) -> Option<State> {
    Some(match (sw & 0x4F, sw & 0x6F) {
        (0x00, _) => State::NotReadyToSwitchOn,
        (0x40, _) => State::SwitchOnDisabled,
        (_, 0x21) => State::ReadyToSwitchOn,
        (_, 0x23) => State::SwitchedOn,
        (_, 0x27) => State::OperationEnabled,
        (_, 0x07) => State::QuickStopActive,
        (0x0F, _) => State::FaultReactionActive,
        (0x08, _) => State::Fault,
        _ => return None,
    })
}

impl State {
    /// The state a statusword shows (CiA 402 masks), `None` for a pattern that is none.
    pub fn from_statusword(sw: u16) -> Option<State> {
        decode_state(sw)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every state survives statusword encoding and decoding, whatever the common bits
    /// (remote, target reached, warning, mode-specific) around it; names are distinct.
    #[test]
    fn every_state_decodes_from_its_statusword() {
        let extra = [
            0,
            BIT_REMOTE,
            BIT_REMOTE | BIT_TARGET_REACHED | BIT_OMS12,
            BIT_WARNING | BIT_INTERNAL_LIMIT | BIT_OMS13,
        ];
        for s in State::ALL {
            for e in extra {
                assert_eq!(State::from_statusword(state_bits(s) | e), Some(s), "{s}");
            }
            assert_eq!(s.to_string(), s.name());
            assert_eq!(s.key(), s.name().to_ascii_lowercase().replace(' ', "_"));
        }
        let mut names: Vec<_> = State::ALL.iter().map(|s| s.name()).collect();
        names.dedup();
        assert_eq!(names.len(), 8);
    }
}
