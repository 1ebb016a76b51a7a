//! Controlword 0x6040: device-control commands (CiA 402 table "device control commands").

/// A decoded device-control command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// 0x06: transitions 2, 6, 8.
    Shutdown,
    /// 0x07: switch on (3) / disable operation (5).
    SwitchOn,
    /// 0x0F: switch on + enable operation (3+4) / enable operation (4, 16).
    EnableOperation,
    /// 0bx0x: transitions 7, 9, 10, 12.
    DisableVoltage,
    /// 0b01x: transitions 7, 10, 11.
    QuickStop,
    /// Rising edge of bit 7: transition 15.
    FaultReset,
    /// Anything else: no transition.
    None,
}

/// Bit 4 in profile position mode: new set-point (rising edge takes 0x607A).
pub const BIT_NEW_SETPOINT: u16 = 1 << 4;
/// Bit 4 in homing mode: homing operation start (rising edge).
pub const BIT_HOMING_START: u16 = 1 << 4;
/// Bit 5 in profile position mode: change set immediately (else queue behind the running one).
pub const BIT_CHANGE_IMMEDIATELY: u16 = 1 << 5;
/// Bit 6 in profile position mode: the target is relative (else absolute).
pub const BIT_RELATIVE: u16 = 1 << 6;
/// Bit 7: fault reset (rising edge, transition 15).
pub const BIT_FAULT_RESET: u16 = 1 << 7;
/// Bit 8: halt (PP, PV, HM decelerate and hold; 0x605D says how).
pub const BIT_HALT: u16 = 1 << 8;

/// Decode `cw`; `prev` is the previous controlword (for the fault-reset edge).
pub fn decode(cw: u16, prev: u16) -> Command {
    if cw & BIT_FAULT_RESET != 0 && prev & BIT_FAULT_RESET == 0 {
        return Command::FaultReset;
    }
    if cw & 0x82 == 0x00 {
        Command::DisableVoltage
    } else if cw & 0x86 == 0x02 {
        Command::QuickStop
    } else if cw & 0x87 == 0x06 {
        Command::Shutdown
    } else if cw & 0x8F == 0x07 {
        Command::SwitchOn
    } else if cw & 0x8F == 0x0F {
        Command::EnableOperation
    } else {
        Command::None
    }
}
