//! The vendor behaviour switches (docs/quirks.md), one test per switch: the master's frames as
//! python canopen 2.4.1 sends them (SDO expedited downloads `0x2B/0x2F/0x23`, uploads `0x40`,
//! RPDO1 = controlword, the `PdoMap.save()` order), and the drive answering as the real
//! drive does with the switch on (the master trips) and as the strict drive with it off (the
//! same master succeeds). Also the two defaults that changed with the switches (every
//! controlword edge latched, QUICK STOP ACTIVE published) and the start-up checks.
mod common;
use common::*;
use drive_protocol::quirks::{
    BootupThenHeartbeat, ControlwordMinHold, HomingBitsMissing, HomingMethodZero, LateSyncBit15,
    NotReadyAfterBootup, ObjectList, SdoFirstUploadDropped, SdoResponseDelay, SyncWatchdog,
    TpdoRtrUnsupported, WatchdogPeriod,
};
use drive_protocol::{Cia402State as S, ConfigError, Node, NodeConfig, Quirks};

const SDO_RX: u32 = 0x600 + ID as u32;
const SDO_TX: u32 = 0x580 + ID as u32;
const HB: u32 = 0x700 + ID as u32;
const ABORT_UNSUPPORTED: u32 = 0x0601_0000;
const ABORT_NOT_MAPPABLE: u32 = 0x0604_0041;
const ABORT_VALUE_RANGE: u32 = 0x0609_0030;

fn config(q: Quirks) -> NodeConfig {
    NodeConfig::new(ID, info())
        .with_od(od_with_handler())
        .with_quirks(q)
}

fn bench(q: Quirks) -> Bench {
    Bench::with_config(config(q))
}

/// The node's RPDO1 (controlword, event-driven), as `node.rpdo[1].transmit()` sends it.
fn rpdo1(b: &mut Bench, cw: u16) {
    b.send(f(0x200 + ID as u32, &cw.to_le_bytes()));
}

/// An SDO request whose answer (if any) is returned without waiting.
fn sdo_now(b: &mut Bench, req: [u8; 8]) -> Vec<[u8; 8]> {
    b.take();
    b.send(f(SDO_RX, &req));
    b.take()
        .into_iter()
        .filter(|f| f.id == SDO_TX)
        .map(|f| f.data)
        .collect()
}

fn upload_req(index: u16, sub: u8) -> [u8; 8] {
    let i = index.to_le_bytes();
    [0x40, i[0], i[1], sub, 0, 0, 0, 0]
}

fn abort_code(d: &[u8; 8]) -> Option<u32> {
    (d[0] == 0x80).then(|| u32::from_le_bytes([d[4], d[5], d[6], d[7]]))
}

fn state(b: &Bench) -> S {
    b.node.cia402_state()
}

/// Heartbeat states sent so far (boot-up = 0).
fn heartbeats(b: &Bench) -> Vec<u8> {
    b.sent(HB).iter().map(|f| f.data[0]).collect()
}

/// In FAULT from an injected drive fault (0x2101), the cause gone again.
fn faulted(q: Quirks) -> Bench {
    let mut b = bench(q);
    b.start();
    b.enable(1);
    b.w16(0x2101, 0, 0x8611).unwrap();
    b.ticks(3);
    assert_eq!(state(&b), S::Fault);
    b.w16(0x2101, 0, 0).unwrap();
    b.cw(0x00);
    b.ticks(2);
    b
}

// ---------------------------------------------------------------- 3.1 enable_requires_mode

/// ros2_canopen's `handleInit` (and python's `node.state = 'OPERATION ENABLED'`): enable
/// before any mode is set. The PD4-C stays in SWITCHED ON; once 0x6060 holds a mode, the
/// controlword's level (still 0x0F) takes it to OPERATION ENABLED.
#[test]
fn enable_requires_mode_keeps_the_drive_switched_on_until_a_mode_is_set() {
    for on in [true, false] {
        let mut b = bench(Quirks {
            enable_requires_mode: on,
            ..Quirks::default()
        });
        b.start();
        b.tick();
        for cw in [0x06, 0x07, 0x0F] {
            rpdo1(&mut b, cw);
            b.ticks(2);
        }
        if on {
            assert_eq!(
                state(&b),
                S::SwitchedOn,
                "quirk on: enabling without a mode fails"
            );
            assert_eq!(b.node.statusword() & 0x6F, 0x23);
            assert!(b.emcys().is_empty(), "no EMCY, no fault: {:?}", b.emcys());
            // "3+4" from READY TO SWITCH ON does 3 only
            rpdo1(&mut b, 0x06);
            b.ticks(2);
            rpdo1(&mut b, 0x0F);
            b.ticks(2);
            assert_eq!(state(&b), S::SwitchedOn);
            b.w8(0x6060, 0, 1).unwrap();
            b.ticks(2);
            assert_eq!(state(&b), S::OperationEnabled, "the level is re-read");
            assert_eq!(b.node.mode(), 1);
        } else {
            assert_eq!(state(&b), S::OperationEnabled, "strict: no mode needed");
            assert_eq!(b.node.mode(), 0);
        }
    }
}

// ------------------------------------------------------- 3.2 mode_change_blocked_by_halt

/// ros2_canopen's `switchMode` with bit 8 set in every controlword (ENGEL HBI): 0x6060 is
/// written and 0x6061 does not follow while the halt bit is set.
#[test]
fn mode_change_blocked_by_halt_defers_0x6061_until_halt_clears() {
    for on in [true, false] {
        let mut b = bench(Quirks {
            mode_change_blocked_by_halt: on,
            ..Quirks::default()
        });
        b.start();
        b.enable(3);
        b.cw(0x010F);
        b.tick();
        b.w8(0x6060, 0, 1).unwrap(); // accepted either way
        b.ticks(3);
        if on {
            assert_eq!(b.ri32(0x6061, 0), 3, "PV still in force while halted");
            b.cw(0x000F);
            b.ticks(2);
            assert_eq!(b.ri32(0x6061, 0), 1, "PP once the halt bit is clear");
        } else {
            assert_eq!(
                b.ri32(0x6061, 0),
                1,
                "strict: PP at the next tick, halt or not"
            );
        }
        assert_eq!(state(&b), S::OperationEnabled);
    }
    // in other states too: SWITCHED ON, halt set, 0x6060 written
    let mut b = bench(Quirks {
        mode_change_blocked_by_halt: true,
        ..Quirks::default()
    });
    b.start();
    b.cw(0x0106);
    b.tick();
    b.cw(0x0107);
    b.tick();
    b.w8(0x6060, 0, 8).unwrap();
    b.ticks(2);
    assert_eq!(b.ri32(0x6061, 0), 0);
    b.cw(0x0007);
    b.ticks(2);
    assert_eq!(b.ri32(0x6061, 0), 8);
}

// ------------------------------------------------------- 3.3 homing_status_bits_missing

/// Homing method 37 (home = here): python's `homing()` reads bits 13,12,10; ros2_canopen waits
/// for bit 12 and then bit 10.
#[test]
fn homing_status_bits_missing_hides_the_chosen_bit() {
    for (missing, want) in [
        (None, 0x1400u16),
        (
            Some(HomingBitsMissing {
                target_reached: false,
                attained: true,
            }),
            0x0400,
        ),
        (
            Some(HomingBitsMissing {
                target_reached: true,
                attained: false,
            }),
            0x1000,
        ),
    ] {
        let mut b = bench(Quirks {
            homing_status_bits_missing: missing,
            ..Quirks::default()
        });
        b.start();
        b.enable(6);
        b.ticks(5);
        let idle = b.node.statusword();
        b.cw(0x1F);
        b.ticks(5);
        let sw = b.node.statusword();
        assert_eq!(sw & 0x3400, want, "{missing:?}: {sw:#06x}");
        if missing.is_some_and(|m| m.target_reached) {
            assert_eq!(idle & 0x0400, 0, "bit 10 never set in HM, idle either");
        }
        // homing itself worked: the position is the home offset (0)
        assert_eq!(b.node.position_actual(), 0);
        // python canopen 2.4.1 reads 13,12,10 = 0,0,1 as 'INTERRUPTED' (homing() -> False)
        let interrupted = sw & 0x3400 == 0x0400;
        assert_eq!(interrupted, missing.is_some_and(|m| m.attained));
    }
}

// ---------------------------------------------------------------- 3.4 homing_method_zero

/// `node.sdo[0x6098].raw = 0` then ros2_canopen's "skip homing when 0x6098 reads 0".
#[test]
fn homing_method_zero_store_ignore_or_refuse_by_sdo() {
    for (rule, answer, read_back) in [
        (HomingMethodZero::Store, Ok(()), 0),
        (HomingMethodZero::Ignore, Ok(()), 37),
        (HomingMethodZero::Refuse, Err(ABORT_VALUE_RANGE), 37),
    ] {
        let mut b = bench(Quirks {
            homing_method_zero: rule,
            ..Quirks::default()
        });
        assert_eq!(b.w8(0x6098, 0, 0), answer, "{rule:?}");
        let skip = b.ri32(0x6098, 0) == 0;
        assert_eq!(b.ri32(0x6098, 0), read_back, "{rule:?}");
        assert_eq!(skip, rule == HomingMethodZero::Store, "{rule:?}");
        // other methods are stored by every rule
        b.w8(0x6098, 0, 35).unwrap();
        assert_eq!(b.ri32(0x6098, 0), 35);
    }
}

/// The same through an RPDO mapping 0x6098: ignore takes it silently, refuse raises EMCY
/// 0x6320 as for any refused RPDO value.
#[test]
fn homing_method_zero_by_rpdo() {
    for rule in [
        HomingMethodZero::Store,
        HomingMethodZero::Ignore,
        HomingMethodZero::Refuse,
    ] {
        let mut b = bench(Quirks {
            homing_method_zero: rule,
            ..Quirks::default()
        });
        // RPDO1 remapped to controlword + homing method, as PdoMap.save() writes it
        let id = ID as u32;
        b.w32(0x1400, 1, 0x8000_0200 + id).unwrap();
        b.w8(0x1600, 0, 0).unwrap();
        b.w32(0x1600, 1, 0x6040_0010).unwrap();
        b.w32(0x1600, 2, 0x6098_0008).unwrap();
        b.w8(0x1600, 0, 2).unwrap();
        b.w32(0x1400, 1, 0x200 + id).unwrap();
        b.start();
        b.take();
        b.send(f(0x200 + id, &[0, 0, 0]));
        b.tick();
        let emcy = b.emcys().contains(&0x6320);
        assert_eq!(
            emcy,
            rule == HomingMethodZero::Refuse,
            "{rule:?}: {:?}",
            b.emcys()
        );
        let want = if rule == HomingMethodZero::Store {
            0
        } else {
            37
        };
        assert_eq!(b.ri32(0x6098, 0), want, "{rule:?}");
    }
}

// ------------------------------------------------------------- 3.5 bootup_then_heartbeat

/// ros_canopen's `reset_com()`: NMT reset communication, then wait for a heartbeat state 0
/// (it looks at the last heartbeat it received). The PD4-N's 0x7F follows the boot-up within
/// 100 us; by the time the master looks, the last state is 0x7F.
#[test]
fn bootup_then_heartbeat_hides_the_bootup_behind_a_0x7f() {
    for on in [true, false] {
        let mut cfg = config(Quirks {
            bootup_then_heartbeat: on.then_some(BootupThenHeartbeat {
                first_heartbeat_after_bootup_us: 100,
                heartbeat_ms_default: 100,
            }),
            ..Quirks::default()
        })
        .with_boot_delay_us(200_000);
        if on {
            cfg.reset_communication_boot_delay_us = Some(0);
        }
        let mut b = Bench::with_config(cfg);
        b.node.finish_boot(0);
        b.take();
        b.nmt(0x82, ID);
        let at = b.now;
        while b.now < at + 50_000 {
            b.tick();
        }
        let seen = heartbeats(&b);
        if on {
            assert_eq!(&seen[..2], &[0x00, 0x7F], "{seen:?}");
            assert_eq!(*seen.last().unwrap(), 0x7F);
            // the producer runs with the profile's 0x1017 default
            assert_eq!(b.r32(0x1017, 0), 100);
        } else {
            assert!(
                seen.is_empty(),
                "strict: nothing in the first 50 ms: {seen:?}"
            );
            b.run_until(at + 210_000);
            assert_eq!(heartbeats(&b), [0x00], "the boot-up after the boot delay");
            assert_eq!(b.r32(0x1017, 0), 0);
        }
    }
}

// ------------------------------------------------------------ 3.6 not_ready_after_bootup

/// python canopen 401: after `wait_for_bootup()` the master reads 0x1000 at once. The node
/// keeps reporting 0x00 and answers nothing until it is ready.
#[test]
fn not_ready_after_bootup_is_silent_until_ready() {
    for on in [true, false] {
        let mut b = bench(Quirks {
            not_ready_after_bootup: on.then_some(NotReadyAfterBootup {
                ready_after_ms: 3000,
                initialising_heartbeat_ms: 100,
            }),
            ..Quirks::default()
        });
        b.take();
        b.nmt(0x82, ID); // reset communication, no boot delay
        let t0 = b.now;
        assert_eq!(heartbeats(&b), [0x00], "the boot-up");
        let first = sdo_now(&mut b, upload_req(0x1000, 0));
        if !on {
            assert_eq!(first.len(), 1, "strict: answered at once");
            assert_eq!(&first[0][4..8], &0x0002_0192u32.to_le_bytes());
            continue;
        }
        assert!(
            first.is_empty(),
            "not ready: no answer, no abort: {first:?}"
        );
        b.nmt(0x01, ID); // NMT start ignored
        b.run_until(t0 + 1_000_000);
        assert_eq!(b.node.nmt_state(), drive_protocol::NmtState::PreOperational);
        let hb = heartbeats(&b);
        assert!(
            hb.len() >= 9 && hb.iter().all(|&s| s == 0x00),
            "heartbeat 0x00 every 100 ms: {hb:?}"
        );
        b.run_until(t0 + 3_010_000);
        assert_eq!(*heartbeats(&b).last().unwrap(), 0x7F, "ready: 0x7F");
        let ready = sdo_now(&mut b, upload_req(0x1000, 0));
        assert_eq!(ready.len(), 1);
        assert_eq!(&ready[0][4..8], &0x0002_0192u32.to_le_bytes());
        // a reset still works while not ready
        b.nmt(0x82, ID);
        b.ticks(10);
        assert!(sdo_now(&mut b, upload_req(0x1000, 0)).is_empty());
        b.nmt(0x81, ID);
        assert_eq!(b.node.nmt_state(), drive_protocol::NmtState::PreOperational);
    }
}

// ---------------------------------------------------------------- 3.7 sdo_response_delay

/// A master with a 100 ms SDO timeout (python's RESPONSE_TIMEOUT set as ros2_canopen's 20 ms
/// default is set): the answer comes after 300 ms.
#[test]
fn sdo_response_delay_holds_every_answer() {
    let mut b = bench(Quirks {
        sdo_response_delay: Some(SdoResponseDelay {
            delay_ms: 300,
            late_delay_ms: 0,
            late_every: 0,
        }),
        ..Quirks::default()
    });
    let t0 = b.now;
    assert!(sdo_now(&mut b, upload_req(0x1000, 0)).is_empty());
    assert_eq!(
        b.node.poll_at_comm(),
        Some(t0 + 300_000),
        "the answer's due time"
    );
    b.run_until(t0 + 299_000);
    assert!(b.sent(SDO_TX).is_empty(), "not before 300 ms");
    b.run_until(t0 + 301_000);
    let answers = b.sent(SDO_TX);
    assert_eq!(answers.len(), 1);
    assert_eq!(&answers[0].data[4..8], &0x0002_0192u32.to_le_bytes());
    // a segmented upload: every segment answer is late too, in order
    b.take();
    let t1 = b.now;
    b.send(f(SDO_RX, &upload_req(0x1008, 0)));
    b.run_until(t1 + 301_000);
    assert_eq!(b.take().iter().filter(|f| f.id == SDO_TX).count(), 1);
    b.send(f(SDO_RX, &[0x60, 0, 0, 0, 0, 0, 0, 0]));
    b.tick();
    assert!(b.sent(SDO_TX).is_empty());
    b.run_until(b.now + 300_000);
    assert_eq!(b.sent(SDO_TX)[0].data[0] & 0xE0, 0x00, "segment answer");
}

/// "occasionally ~10 ms too late": every 3rd service late, deterministic from the boot.
#[test]
fn sdo_response_delay_every_nth_service_late() {
    for on in [true, false] {
        let mut b = bench(Quirks {
            sdo_response_delay: on.then_some(SdoResponseDelay {
                delay_ms: 0,
                late_delay_ms: 300,
                late_every: 3,
            }),
            ..Quirks::default()
        });
        let answered: Vec<usize> = (0..6)
            .map(|_| {
                let n = sdo_now(&mut b, upload_req(0x1000, 0)).len();
                b.run_until(b.now + 400_000);
                n
            })
            .collect();
        if on {
            assert_eq!(answered, [1, 1, 0, 1, 1, 0]);
        } else {
            assert_eq!(answered, [1; 6]);
        }
    }
}

// ----------------------------------------------------------- 3.8 sdo_first_upload_dropped

/// ros_canopen 347: the first read of 0x6061 after the boot times out, the second works.
#[test]
fn sdo_first_upload_dropped_after_each_boot() {
    for on in [true, false] {
        let mut b = bench(Quirks {
            sdo_first_upload_dropped: on.then(|| SdoFirstUploadDropped {
                objects: ObjectList::parse(&["0x6061:0"]).unwrap(),
                count: 1,
            }),
            ..Quirks::default()
        });
        for _boot in 0..2 {
            b.nmt(0x82, ID);
            b.tick();
            let first = sdo_now(&mut b, upload_req(0x6061, 0));
            assert_eq!(first.is_empty(), on, "{first:?}");
            let second = sdo_now(&mut b, upload_req(0x6061, 0));
            assert_eq!(second.len(), 1);
            assert_eq!(second[0][0] & 0xE0, 0x40, "answered");
            // other objects and downloads are answered
            assert_eq!(sdo_now(&mut b, upload_req(0x6041, 0)).len(), 1);
        }
    }
}

// ---------------------------------------------------------------- 3.9 pdo_remap_lenient

/// The master of before python canopen PR 3: COB-ID invalid, then the entries without zeroing
/// sub 0 first. Copley (strict, the default) aborts 0x06010000; lenient accepts and remaps.
#[test]
fn pdo_remap_lenient_or_strict() {
    let id = ID as u32;
    for lenient in [false, true] {
        let mut b = bench(Quirks {
            pdo_remap_lenient: lenient,
            ..Quirks::default()
        });
        b.w32(0x1800, 1, 0x8000_0180 + id).unwrap();
        let r = b.w32(0x1A00, 1, 0x6041_0010);
        if !lenient {
            assert_eq!(r, Err(ABORT_UNSUPPORTED), "strict: sub 0 first");
            continue;
        }
        r.unwrap();
        // the entry is checked and the mapping must still fit
        assert_eq!(b.w32(0x1A00, 2, 0x2200_0120), Err(ABORT_NOT_MAPPABLE));
        b.w32(0x1A00, 2, 0x6064_0020).unwrap();
        assert_eq!(b.w32(0x1A00, 1, 0x6064_0020), Ok(()));
        b.w32(0x1A00, 1, 0x6041_0010).unwrap();
        b.w8(0x1A00, 0, 1).unwrap();
        b.w32(0x1800, 1, 0x180 + id).unwrap();
        b.start();
        b.take();
        b.ticks(60);
        let tpdo1 = b.sent(0x180 + id);
        assert!(!tpdo1.is_empty());
        assert!(tpdo1.iter().all(|f| f.len == 2), "statusword alone");
    }
    // python canopen 2.4.1's own save (sub 0 = 0 first) works in both
    for lenient in [false, true] {
        let mut b = bench(Quirks {
            pdo_remap_lenient: lenient,
            ..Quirks::default()
        });
        b.w32(0x1800, 1, 0xC000_0180 + id).unwrap();
        b.w8(0x1A00, 0, 0).unwrap();
        b.w32(0x1A00, 1, 0x6041_0010).unwrap();
        b.w8(0x1A00, 0, 1).unwrap();
        b.w32(0x1800, 1, 0x4000_0180 + id).unwrap();
    }
}

// ------------------------------------------------------------- 3.10 tpdo_rtr_unsupported

/// python canopen before PR 228: `tpdo[1].save()` without `read()` writes the COB-ID with bit
/// 31 and without bit 30 (`rtr_allowed` defaults to True): the Roboteq aborts 0x06090030.
/// With `read()` first, python keeps bit 30 and the save works.
#[test]
fn tpdo_rtr_unsupported_refuses_a_cob_id_without_bit_30() {
    let id = ID as u32;
    for on in [true, false] {
        let mut b = bench(Quirks {
            tpdo_rtr_unsupported: on.then_some(TpdoRtrUnsupported {
                abort_code: ABORT_VALUE_RANGE,
            }),
            ..Quirks::default()
        });
        let default = b.r32(0x1800, 1);
        assert_eq!(default, if on { 0x4000_0180 + id } else { 0x180 + id });
        let save = b.w32(0x1800, 1, 0x8000_0180 + id);
        if on {
            assert_eq!(save, Err(ABORT_VALUE_RANGE));
            assert_eq!(b.r32(0x1800, 1), default, "nothing stored");
            assert_eq!(b.w32(0x1800, 1, 0x180 + id), Err(ABORT_VALUE_RANGE));
        } else {
            save.unwrap();
        }
        // the master that read the COB-ID first keeps bit 30
        b.w32(0x1800, 1, 0xC000_0180 + id).unwrap();
        b.w8(0x1800, 2, 253).unwrap();
        b.w32(0x1800, 1, 0x4000_0180 + id).unwrap();
        // a remote frame is never answered
        b.start();
        b.take();
        b.send(drive_protocol::CanFrame::remote(0x180 + id, 3));
        assert!(b.sent(0x180 + id).is_empty(), "bit 30 set: no RTR");
        if !on {
            b.w32(0x1800, 1, 0x8000_0180 + id).unwrap();
            b.w32(0x1800, 1, 0x180 + id).unwrap();
            b.take();
            b.send(drive_protocol::CanFrame::remote(0x180 + id, 3));
            assert_eq!(
                b.sent(0x180 + id).len(),
                1,
                "strict: RTR answered without bit 30"
            );
        }
    }
}

// ------------------------------------------------------------- 3.11 controlword_min_hold

/// yarp-devices 215: a fault reset 0x0080 and a shutdown 0x0006 sent back to back. Technosoft's
/// 1 ms loop never sees the 0x0080; the strict drive latches its edge and does both (15, 2).
#[test]
fn controlword_min_hold_loses_a_short_fault_reset() {
    for on in [true, false] {
        let q = Quirks {
            controlword_min_hold: on.then_some(ControlwordMinHold { hold_us: 1000 }),
            ..Quirks::default()
        };
        let mut b = faulted(q.clone());
        rpdo1(&mut b, 0x80);
        rpdo1(&mut b, 0x06);
        b.ticks(5);
        if on {
            assert_eq!(state(&b), S::Fault, "the 0x0080 stood < 1 ms: not seen");
            assert_eq!(b.node.statusword() & 0x4F, 0x08);
        } else {
            assert_eq!(state(&b), S::ReadyToSwitchOn, "strict: 15 then 2");
        }
        // 1 ms or more apart: seen
        let mut b = faulted(q);
        rpdo1(&mut b, 0x80);
        b.tick();
        b.tick();
        rpdo1(&mut b, 0x06);
        b.ticks(3);
        assert_eq!(state(&b), S::ReadyToSwitchOn, "on = {on}: held long enough");
    }
}

/// The default changed with the switch: a PP new set-point pulse written and cleared between
/// two ticks is taken (it was lost before).
#[test]
fn a_new_set_point_pulse_between_two_ticks_is_taken() {
    let mut b = bench(Quirks::default());
    b.start();
    b.enable(1);
    b.w32(0x607A, 0, 1000).unwrap();
    b.cw(0x1F);
    b.cw(0x0F);
    b.tick();
    assert_eq!(b.node.statusword() & 0x1000, 0x1000, "acknowledged once");
    b.ticks(2000);
    assert!(
        (b.node.position_actual() - 1000).abs() <= 2,
        "moved to 1000"
    );
}

// ------------------------------------------------------ 3.12 quick_stop_skips_active_state

/// python canopen 167: quick stop at standstill. The drive of the thread shows QUICK STOP
/// ACTIVE for one statusword (the strict default now); with the switch, straight to SWITCH ON
/// DISABLED (what drive-emu did before).
#[test]
fn quick_stop_at_standstill_shows_quick_stop_active_unless_skipped() {
    for skip in [true, false] {
        let mut b = bench(Quirks {
            quick_stop_skips_active_state: skip,
            ..Quirks::default()
        });
        b.w32(0x1800, 1, 0x8000_0185).unwrap();
        b.w16(0x1800, 3, 0).unwrap(); // inhibit 0: every statusword is sent
        b.w32(0x1800, 1, 0x185).unwrap();
        b.start();
        b.enable(1);
        b.ticks(10);
        b.take();
        rpdo1(&mut b, 0x02);
        b.ticks(10);
        let sws: Vec<u16> = b
            .sent(0x185)
            .iter()
            .map(|f| u16::from_le_bytes([f.data[0], f.data[1]]))
            .collect();
        let qsa = sws.iter().position(|s| s & 0x6F == 0x07);
        let sod = sws.iter().position(|s| s & 0x4F == 0x40);
        assert!(sod.is_some(), "{sws:04x?}");
        if skip {
            assert_eq!(qsa, None, "never QUICK STOP ACTIVE: {sws:04x?}");
        } else {
            assert!(qsa.unwrap() < sod.unwrap(), "QSA before SOD: {sws:04x?}");
        }
        assert_eq!(state(&b), S::SwitchOnDisabled);
    }
}

// -------------------------------------------------------------------- 3.13 sync_watchdog

/// ros_canopen 293: the master stalls its SYNC for 60 ms (6 periods of 0x60C2 = 10 ms, 0x1006
/// not written). The Delta alarms after 2 periods; the strict drive (no 0x1006) does not
/// supervise.
#[test]
fn sync_watchdog_faults_after_missed_periods_in_watched_modes() {
    for (on, mode) in [(true, 8i8), (false, 8), (true, 1)] {
        let mut b = bench(Quirks {
            sync_watchdog: on.then(|| SyncWatchdog {
                missed_periods: 2.0,
                period_from: WatchdogPeriod::Interpolation,
                modes: [7i8, 8].into_iter().collect(),
                emcy_code: 0x8100,
            }),
            ..Quirks::default()
        });
        b.w8(0x60C2, 1, 10).unwrap();
        b.w8(0x60C2, 2, (-3i8) as u8).unwrap();
        b.start();
        b.enable(mode);
        for _ in 0..20 {
            b.sync();
            b.ticks(10);
        }
        assert_eq!(state(&b), S::OperationEnabled);
        b.ticks(60); // the master stalls
        for _ in 0..5 {
            b.sync();
            b.ticks(10);
        }
        if on && mode == 8 {
            assert_eq!(state(&b), S::Fault, "alarm");
            assert!(b.emcys().contains(&0x8100), "{:?}", b.emcys());
            assert_eq!(b.r32(0x603F, 0), 0x8100);
        } else {
            assert_eq!(state(&b), S::OperationEnabled, "on={on} mode={mode}");
            assert!(b.emcys().is_empty(), "{:?}", b.emcys());
        }
    }
}

// ------------------------------------------------------- 3.14 late_sync_statusword_bit15

/// SYNCs every 10 ms with 0x1006 = 10000, one 15 ms late: bit 15 in the statusword after it
/// (a PLC comparing the statusword to 0x1637 sees a mismatch), clear after the next one.
#[test]
fn late_sync_sets_statusword_bit15() {
    for on in [true, false] {
        let mut b = bench(Quirks {
            late_sync_statusword_bit15: on.then_some(LateSyncBit15 {
                late_tolerance_us: 200,
            }),
            ..Quirks::default()
        });
        b.w32(0x1006, 0, 10_000).unwrap();
        b.start();
        b.enable(8);
        let mut bit15 = Vec::new();
        for k in 0..10 {
            b.sync();
            b.ticks(if k == 4 { 15 } else { 10 });
            bit15.push(b.node.statusword() & 0x8000 != 0);
        }
        if on {
            // SYNC 5 came 15 ms after SYNC 4: bit 15 after it, cleared after SYNC 6
            assert_eq!(
                bit15,
                [false, false, false, false, false, true, false, false, false, false]
            );
        } else {
            assert!(bit15.iter().all(|b| !b));
        }
    }
}

// --------------------------------------------------------------- 3.15 unmappable_objects

/// python canopen 283: `tpdo[3].add_variable(0x6077); tpdo[3].save()`: the drive's EDS says
/// mappable, the drive refuses the entry.
#[test]
fn unmappable_objects_refuse_the_mapping_entry() {
    let id = ID as u32;
    for on in [true, false] {
        let mut b = bench(Quirks {
            unmappable_objects: on.then(|| ObjectList::parse(&["0x6077:0"]).unwrap()),
            ..Quirks::default()
        });
        b.w32(0x1802, 1, 0x8000_0380 + id).unwrap();
        b.w8(0x1A02, 0, 0).unwrap();
        let r = b.w32(0x1A02, 1, 0x6077_0010);
        if on {
            assert_eq!(r, Err(ABORT_NOT_MAPPABLE));
        } else {
            r.unwrap();
            b.w8(0x1A02, 0, 1).unwrap();
            b.w32(0x1802, 1, 0x380 + id).unwrap();
            b.start();
            b.take();
            b.sync();
            assert_eq!(b.sent(0x380 + id)[0].len, 2, "torque actual in TPDO3");
        }
        // other objects map as before
        b.w32(0x1802, 1, 0x8000_0380 + id).unwrap();
        b.w8(0x1A02, 0, 0).unwrap();
        b.w32(0x1A02, 1, 0x6041_0010).unwrap();
    }
}

// --------------------------------------------------------------- 3.16 sdo_silent_objects

/// python canopen PR 306: `pdo.read()` reads 0x1800:5 of an event-driven TPDO; the device
/// sends nothing, python raises SdoCommunicationError. The next request is served.
#[test]
fn sdo_silent_objects_get_no_answer_and_the_server_stays_idle() {
    for on in [true, false] {
        let mut b = bench(Quirks {
            sdo_silent_objects: on.then(|| ObjectList::parse(&["0x1800-0x1803:5"]).unwrap()),
            ..Quirks::default()
        });
        let r = sdo_now(&mut b, upload_req(0x1800, 5));
        assert_eq!(r.is_empty(), on, "{r:?}");
        let r = sdo_now(&mut b, [0x2B, 0x03, 0x18, 5, 20, 0, 0, 0]);
        assert_eq!(r.is_empty(), on, "downloads too: {r:?}");
        let next = sdo_now(&mut b, upload_req(0x1800, 2));
        assert_eq!(next.len(), 1, "the next request is served");
        assert_eq!(abort_code(&next[0]), None);
        // with the range: 0x1803:5 silent, 0x1804 does not exist and is aborted
        assert_eq!(sdo_now(&mut b, upload_req(0x1803, 5)).is_empty(), on);
        let r = sdo_now(&mut b, upload_req(0x1804, 5));
        assert_eq!(abort_code(&r[0]), Some(0x0602_0000));
    }
}

// ------------------------------------------------------------------- start-up checks

/// A switch that needs an object the dictionary lacks is refused when the node is built, and
/// says which; all off is the strict drive.
#[test]
fn a_switch_needs_its_objects_and_all_off_is_strict() {
    let q = Quirks {
        sync_watchdog: Some(SyncWatchdog {
            missed_periods: 2.0,
            period_from: WatchdogPeriod::Interpolation,
            modes: [8i8].into_iter().collect(),
            emcy_code: 0x8100,
        }),
        ..Quirks::default()
    };
    let mut od = od_with_handler();
    assert!(od.remove(0x60C2, 1));
    let e = Node::new(config(q.clone()).with_od(od)).unwrap_err();
    assert_eq!(
        e,
        ConfigError::QuirkNeedsObject {
            switch: "sync_watchdog",
            index: 0x60C2,
            sub: 1
        }
    );
    assert!(e.to_string().contains("0x60C2") && e.to_string().contains("sync_watchdog"));
    assert!(Node::new(config(q.clone())).is_ok());
    assert!(Quirks::default().is_strict());
    assert_eq!(q.on().collect::<Vec<_>>(), ["sync_watchdog"]);
    assert_eq!(Quirks::SWITCHES.len(), 16);
}

// ------------------------------------------------------------- robustness, switches on

use proptest::prelude::*;

/// A frame a bus peer may send: SDO requests (any bytes, and initiates of the listed objects),
/// RPDOs, SYNC, NMT (resets too), heartbeats, remote frames; with the time since the last one.
fn peer_frame() -> impl Strategy<Value = (drive_protocol::CanFrame, u32)> {
    let id = ID as u32;
    let sdo_any = proptest::array::uniform8(any::<u8>()).prop_map(move |d| f(0x600 + id, &d));
    let sdo_listed = (
        prop_oneof![
            Just(0x40u8),
            Just(0x2B),
            Just(0x2F),
            Just(0x21),
            Just(0xA0),
            Just(0xC0)
        ],
        prop_oneof![
            Just((0x6041u16, 0u8)),
            Just((0x1000, 0)),
            Just((0x1800, 5)),
            Just((0x1A00, 1))
        ],
        any::<u32>(),
    )
        .prop_map(move |(cs, (i, s), v)| {
            let i = i.to_le_bytes();
            let v = v.to_le_bytes();
            f(0x600 + id, &[cs, i[0], i[1], s, v[0], v[1], v[2], v[3]])
        });
    let rpdo = (0u32..4, proptest::collection::vec(any::<u8>(), 0..=8))
        .prop_map(move |(k, d)| f(0x200 + 0x100 * k + id, &d));
    let nmt = (
        prop_oneof![Just(1u8), Just(2), Just(0x80), Just(0x81), Just(0x82)],
        any::<bool>(),
    )
        .prop_map(move |(cs, all)| f(0, &[cs, if all { 0 } else { ID }]));
    let sync = proptest::collection::vec(any::<u8>(), 0..=1).prop_map(|d| f(0x80, &d));
    let rtr =
        (0u32..4).prop_map(move |k| drive_protocol::CanFrame::remote(0x180 + 0x100 * k + id, 4));
    (
        prop_oneof![4 => sdo_any, 4 => sdo_listed, 3 => rpdo, 1 => nmt, 2 => sync, 1 => rtr],
        0u32..20_000,
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

    /// Nothing a bus peer sends breaks a node with every switch on: no panic, the transmit
    /// queue drains, and after a reset and the ready time the node answers SDO again (late).
    #[test]
    fn arbitrary_frames_never_break_a_node_with_every_switch_on(
        frames in proptest::collection::vec(peer_frame(), 1..200)
    ) {
        let mut node = Node::new(config(every_switch())).unwrap();
        let mut drive = SimDrive::default();
        let mut now = 0u64;
        node.boot(now);
        for (fr, dt) in frames {
            now += u64::from(dt);
            let _ = node.handle(&fr, now, &mut drive);
            node.poll(now, &mut drive);
            while node.pop_tx().is_some() {}
        }
        node.handle(&f(0, &[0x82, ID]), now, &mut drive);
        let mut answer = None;
        for k in 0..200u64 {
            now += 1000;
            node.poll(now, &mut drive);
            if k == 50 {
                // ready (20 ms) by now: an upload of an object no switch silences
                node.handle(&f(0x600 + ID as u32, &upload_req(0x1018, 2)), now, &mut drive);
            }
            while let Some(fr) = node.pop_tx() {
                if fr.id == SDO_TX {
                    answer = Some(fr.data);
                }
            }
        }
        let a = answer.expect("SDO answered after the reset");
        prop_assert_eq!(&a[..4], &[0x43, 0x18, 0x10, 2][..]);
    }
}
