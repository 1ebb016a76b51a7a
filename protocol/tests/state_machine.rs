//! CiA 402 device control: every state crossed with every command.
mod common;
use common::*;
use drive_protocol::Cia402State as S;

/// Statusword mask/value per state, as CiA 402 defines them.
fn expected_sw(s: S) -> (u16, u16) {
    match s {
        S::NotReadyToSwitchOn => (0x4F, 0x00),
        S::SwitchOnDisabled => (0x4F, 0x40),
        S::ReadyToSwitchOn => (0x6F, 0x21),
        S::SwitchedOn => (0x6F, 0x23),
        S::OperationEnabled => (0x6F, 0x27),
        S::QuickStopActive => (0x6F, 0x07),
        S::FaultReactionActive => (0x4F, 0x0F),
        S::Fault => (0x4F, 0x08),
    }
}

/// Bring a fresh node into `s` (quick stop option 6: stay in QUICK STOP ACTIVE).
fn reach(s: S) -> Bench {
    let mut b = Bench::new();
    b.start();
    b.w16(0x605A, 0, 6).unwrap();
    b.tick();
    let seq: &[u16] = match s {
        S::SwitchOnDisabled | S::Fault => &[],
        S::ReadyToSwitchOn => &[0x06],
        S::SwitchedOn => &[0x06, 0x07],
        S::OperationEnabled => &[0x06, 0x07, 0x0F],
        S::QuickStopActive => &[0x06, 0x07, 0x0F, 0x02],
        _ => unreachable!(),
    };
    for &c in seq {
        b.cw(c);
        b.tick();
    }
    if s == S::Fault {
        b.drive.fault = Some(0x7300);
        b.tick();
        b.tick();
        b.drive.fault = None; // the cause is gone, the fault stays latched
        b.tick();
    }
    assert_eq!(b.node.cia402_state(), s, "setup");
    b
}

#[test]
fn every_state_times_every_command() {
    use S::*;
    let cmds: [(u16, &str); 6] = [
        (0x06, "shutdown"),
        (0x07, "switch on / disable operation"),
        (0x0F, "enable operation"),
        (0x00, "disable voltage"),
        (0x02, "quick stop"),
        (0x80, "fault reset"),
    ];
    #[rustfmt::skip]
    let table: [(S, [S; 6]); 6] = [
        //                    0x06             0x07        0x0F              0x00              0x02              0x80
        (SwitchOnDisabled,  [ReadyToSwitchOn, SwitchOnDisabled, SwitchOnDisabled, SwitchOnDisabled, SwitchOnDisabled, SwitchOnDisabled]),
        (ReadyToSwitchOn,   [ReadyToSwitchOn, SwitchedOn,       OperationEnabled, SwitchOnDisabled, SwitchOnDisabled, ReadyToSwitchOn]),
        (SwitchedOn,        [ReadyToSwitchOn, SwitchedOn,       OperationEnabled, SwitchOnDisabled, SwitchOnDisabled, SwitchedOn]),
        (OperationEnabled,  [ReadyToSwitchOn, SwitchedOn,       OperationEnabled, SwitchOnDisabled, QuickStopActive,  OperationEnabled]),
        (QuickStopActive,   [QuickStopActive, QuickStopActive,  OperationEnabled, SwitchOnDisabled, QuickStopActive,  QuickStopActive]),
        (Fault,             [Fault,           Fault,            Fault,            Fault,            Fault,            SwitchOnDisabled]),
    ];
    for (from, nexts) in table {
        for ((cw, name), want) in cmds.iter().zip(nexts) {
            let mut b = reach(from);
            if *cw == 0x80 {
                // a rising edge of bit 7 from a controlword without it
                b.cw(0x00);
                b.tick();
                b = if from == Fault { b } else { reach(from) };
            }
            b.cw(*cw);
            b.tick();
            let got = b.node.cia402_state();
            assert_eq!(got, want, "{from:?} + {name} ({cw:#04x})");
            let sw = b.statusword();
            let (mask, val) = expected_sw(want);
            assert_eq!(sw & mask, val, "{from:?} + {name}: statusword {sw:#06x}");
            assert_eq!(sw & 0x0200, 0x0200, "remote bit");
            let voltage = matches!(
                want,
                ReadyToSwitchOn | SwitchedOn | OperationEnabled | QuickStopActive
            );
            assert_eq!(
                sw & 0x10 != 0,
                voltage,
                "{from:?} + {name}: voltage enabled bit"
            );
            assert_eq!(
                sw & 0x20 == 0,
                want == QuickStopActive,
                "{from:?} + {name}: quick stop bit"
            );
            let enabled = matches!(want, OperationEnabled | QuickStopActive);
            assert_eq!(
                !matches!(
                    b.drive.last.unwrap().setpoint,
                    drive_protocol::Setpoint::Disabled
                ),
                enabled,
                "{from:?} + {name}: power stage"
            );
        }
    }
}

#[test]
fn fault_reset_needs_a_rising_edge_and_a_cleared_cause() {
    let mut b = reach(S::Fault);
    b.cw(0x80);
    b.tick();
    assert_eq!(b.node.cia402_state(), S::SwitchOnDisabled);
    // holding bit 7 does nothing more; a new fault while it is held stays
    b.drive.fault = Some(0x4310);
    b.tick();
    b.tick();
    assert_eq!(b.node.cia402_state(), S::Fault);
    b.drive.fault_persists = true;
    b.cw(0x00);
    b.tick();
    b.cw(0x80);
    b.tick();
    assert_eq!(b.node.cia402_state(), S::Fault, "cause persists");
    assert_eq!(b.r32(0x603F, 0), 0x4310);
}

#[test]
fn quick_stop_option_2_ends_in_switch_on_disabled_after_ramp() {
    let mut b = Bench::new();
    b.start();
    b.w32(0x6083, 0, 1_000_000).unwrap();
    b.w32(0x6085, 0, 50_000).unwrap(); // 50 mm/s^2
    b.enable(3);
    b.w32(0x60FF, 0, 20_000).unwrap(); // 20 mm/s
    b.ticks(200);
    let v0 = b.drive.vel;
    assert!(v0 > 19_000.0 * INC_PER_UU, "{v0}");
    b.cw(0x02);
    b.tick();
    assert_eq!(b.node.cia402_state(), S::QuickStopActive);
    // decelerating at about 50 mm/s^2: 20 mm/s takes 0.4 s
    b.ticks(200);
    assert_eq!(b.node.cia402_state(), S::QuickStopActive, "still ramping");
    let v_mid = b.drive.vel / INC_PER_UU;
    assert!(
        (v_mid - 10_000.0).abs() < 1500.0,
        "half speed after 0.2 s: {v_mid}"
    );
    b.ticks(250);
    assert_eq!(b.node.cia402_state(), S::SwitchOnDisabled);
}

#[test]
fn shutdown_with_slow_down_option_ramps_before_disabling() {
    let mut b = Bench::new();
    b.start();
    b.w16(0x605B, 0, 1).unwrap();
    b.w32(0x6083, 0, 1_000_000).unwrap();
    b.w32(0x6084, 0, 100_000).unwrap();
    b.enable(3);
    b.w32(0x60FF, 0, 10_000).unwrap();
    b.ticks(100);
    b.cw(0x06);
    b.tick();
    assert_eq!(
        b.node.cia402_state(),
        S::OperationEnabled,
        "ramping down first"
    );
    b.ticks(150);
    assert_eq!(b.node.cia402_state(), S::ReadyToSwitchOn);
}
