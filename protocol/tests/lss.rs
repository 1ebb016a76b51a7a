//! LSS slave (CiA 305): every service frame by frame with its exact bytes, the state rules
//! (nothing answered in the wrong state), and fastscan run by a master that sends python
//! canopen 2.4.1's `LssMaster.fast_scan()` frames in its order, against one, two and three
//! slaves on one simulated bus.
use drive_protocol::cia305::{LssEvent, LssIdentity, LssOutput, LssSlave, LssState};
use drive_protocol::CanFrame;

const ID: LssIdentity = LssIdentity {
    vendor_id: 0x0000_0123,
    product_code: 0x0000_0402,
    revision_number: 0x0001_0000,
    serial_number: 0x8000_0011,
};

fn req(bytes: [u8; 8]) -> CanFrame {
    CanFrame::new(0x7E5, &bytes)
}

fn unconfigured() -> LssSlave {
    LssSlave::new(ID, None, 2).unwrap()
}

/// Send one request; the response's 8 bytes (None: silent) and the event.
fn send(s: &mut LssSlave, bytes: [u8; 8]) -> (Option<[u8; 8]>, Option<LssEvent>) {
    let LssOutput { response, event } = s.handle(&req(bytes));
    if let Some(f) = &response {
        assert_eq!((f.id, f.len, f.rtr, f.extended), (0x7E4, 8, false, false));
    }
    (response.map(|f| f.data), event)
}

const TO_CONFIG: [u8; 8] = [0x04, 0x01, 0, 0, 0, 0, 0, 0];
const TO_WAITING: [u8; 8] = [0x04, 0x00, 0, 0, 0, 0, 0, 0];

fn u32_frame(cs: u8, v: u32) -> [u8; 8] {
    let b = v.to_le_bytes();
    [cs, b[0], b[1], b[2], b[3], 0, 0, 0]
}

#[test]
fn switch_state_global_and_inquiries() {
    let mut s = unconfigured();
    assert_eq!(s.state(), LssState::Waiting);
    assert_eq!(
        send(&mut s, TO_CONFIG),
        (None, Some(LssEvent::ConfigurationState))
    );
    assert_eq!(s.state(), LssState::Configuration);
    // again: no change, no event
    assert_eq!(send(&mut s, TO_CONFIG), (None, None));
    for (cs, v) in [
        (0x5A, ID.vendor_id),
        (0x5B, ID.product_code),
        (0x5C, ID.revision_number),
        (0x5D, ID.serial_number),
    ] {
        assert_eq!(
            send(&mut s, [cs, 0, 0, 0, 0, 0, 0, 0]),
            (Some(u32_frame(cs, v)), None)
        );
    }
    // the exact bytes of one: serial 0x80000011 little-endian
    assert_eq!(
        send(&mut s, [0x5D, 0, 0, 0, 0, 0, 0, 0]).0,
        Some([0x5D, 0x11, 0x00, 0x00, 0x80, 0, 0, 0])
    );
    // non-configured: inquire node-ID answers 0xFF
    assert_eq!(
        send(&mut s, [0x5E, 0, 0, 0, 0, 0, 0, 0]).0,
        Some([0x5E, 0xFF, 0, 0, 0, 0, 0, 0])
    );
    // a non-configured slave without a pending node-ID goes back to waiting plainly
    assert_eq!(
        send(&mut s, TO_WAITING),
        (None, Some(LssEvent::WaitingState))
    );
    assert_eq!(s.state(), LssState::Waiting);
    // an undefined mode is not a switch
    assert_eq!(send(&mut s, [0x04, 0x02, 0, 0, 0, 0, 0, 0]), (None, None));
    assert_eq!(s.state(), LssState::Waiting);
}

#[test]
fn configure_node_id_answers_error_codes_and_the_id_boots_after_switching_to_waiting() {
    let mut s = unconfigured();
    send(&mut s, TO_CONFIG);
    // out of range: error 1, nothing pending
    for bad in [0u8, 128, 200, 254] {
        assert_eq!(
            send(&mut s, [0x11, bad, 0, 0, 0, 0, 0, 0]),
            (Some([0x11, 0x01, 0, 0, 0, 0, 0, 0]), None),
            "node-ID {bad}"
        );
        assert_eq!(s.pending_node_id(), None);
    }
    for ok in [1u8, 127, 12] {
        assert_eq!(
            send(&mut s, [0x11, ok, 0, 0, 0, 0, 0, 0]),
            (
                Some([0x11, 0x00, 0, 0, 0, 0, 0, 0]),
                Some(LssEvent::NodeIdConfigured { pending: Some(ok) })
            )
        );
    }
    // pending, not active: inquire still answers 0xFF, and a non-configured slave with a
    // pending ID no longer counts as non-configured
    assert_eq!(
        send(&mut s, [0x5E, 0, 0, 0, 0, 0, 0, 0]).0,
        Some([0x5E, 0xFF, 0, 0, 0, 0, 0, 0])
    );
    assert_eq!(s.active_node_id(), None);
    assert_eq!(s.pending_node_id(), Some(12));
    // back to waiting: the node resets communication and boots as 12
    assert_eq!(
        send(&mut s, TO_WAITING),
        (None, Some(LssEvent::ResetCommunication { node_id: 12 }))
    );
    assert_eq!(s.active_node_id(), Some(12));
    assert_eq!(s.state(), LssState::Waiting);
    send(&mut s, TO_CONFIG);
    assert_eq!(
        send(&mut s, [0x5E, 0, 0, 0, 0, 0, 0, 0]).0,
        Some([0x5E, 12, 0, 0, 0, 0, 0, 0])
    );
    // a configured slave given a new ID keeps the active one until an NMT reset
    assert_eq!(
        send(&mut s, [0x11, 30, 0, 0, 0, 0, 0, 0]).1,
        Some(LssEvent::NodeIdConfigured { pending: Some(30) })
    );
    assert_eq!(
        send(&mut s, TO_WAITING),
        (None, Some(LssEvent::WaitingState))
    );
    assert_eq!(s.active_node_id(), Some(12));
    s.reset_communication();
    assert_eq!(s.active_node_id(), Some(30));
    // 0xFF unconfigures (at the next reset communication)
    send(&mut s, TO_CONFIG);
    assert_eq!(
        send(&mut s, [0x11, 0xFF, 0, 0, 0, 0, 0, 0]),
        (
            Some([0x11, 0x00, 0, 0, 0, 0, 0, 0]),
            Some(LssEvent::NodeIdConfigured { pending: None })
        )
    );
    assert_eq!(s.active_node_id(), Some(30));
    s.reset_communication();
    assert_eq!(s.active_node_id(), None);
}

#[test]
fn bit_timing_configure_and_activate() {
    let mut s = LssSlave::new(ID, Some(5), 0).unwrap();
    send(&mut s, TO_CONFIG);
    // the CiA 301 table: every supported index accepted
    for i in [0u8, 1, 2, 3, 4, 6, 7, 8] {
        assert_eq!(
            send(&mut s, [0x13, 0, i, 0, 0, 0, 0, 0]),
            (
                Some([0x13, 0x00, 0, 0, 0, 0, 0, 0]),
                Some(LssEvent::BitTimingConfigured { table_index: i })
            )
        );
    }
    // reserved 5, automatic 9, beyond, or another table: error 1, pending kept
    for (sel, i) in [(0u8, 5u8), (0, 9), (0, 10), (0, 0xFF), (1, 0), (0x80, 2)] {
        assert_eq!(
            send(&mut s, [0x13, sel, i, 0, 0, 0, 0, 0]),
            (Some([0x13, 0x01, 0, 0, 0, 0, 0, 0]), None),
            "selector {sel} index {i}"
        );
    }
    assert_eq!(s.pending_bit_timing(), 8);
    send(&mut s, [0x13, 0, 3, 0, 0, 0, 0, 0]);
    assert_eq!(s.active_bit_timing(), 0);
    // activate: no answer; the switch delay little-endian (1000 ms = E8 03)
    assert_eq!(
        send(&mut s, [0x15, 0xE8, 0x03, 0, 0, 0, 0, 0]),
        (
            None,
            Some(LssEvent::ActivateBitTiming {
                table_index: 3,
                switch_delay_ms: 1000
            })
        )
    );
    assert_eq!(s.active_bit_timing(), 3);
}

#[test]
fn store_configuration_answers_after_the_store_and_reset_node_loads_it() {
    let mut s = unconfigured();
    send(&mut s, TO_CONFIG);
    send(&mut s, [0x11, 9, 0, 0, 0, 0, 0, 0]);
    send(&mut s, [0x13, 0, 4, 0, 0, 0, 0, 0]);
    assert_eq!(
        send(&mut s, [0x17, 0, 0, 0, 0, 0, 0, 0]),
        (
            None,
            Some(LssEvent::StoreRequested {
                node_id: Some(9),
                bit_timing_index: 4
            })
        )
    );
    assert!(s.store_pending());
    // what was asked is stored, even if the pending values change meanwhile
    send(&mut s, [0x11, 10, 0, 0, 0, 0, 0, 0]);
    let f = s.store_done(true).unwrap();
    assert_eq!((f.id, f.data), (0x7E4, [0x17, 0, 0, 0, 0, 0, 0, 0]));
    assert_eq!((s.stored_node_id(), s.stored_bit_timing()), (Some(9), 4));
    assert!(s.store_done(true).is_none(), "one answer per store");
    // NMT reset node (or power-on) loads the stored values, not the pending 10
    s.reset_node();
    assert_eq!((s.active_node_id(), s.active_bit_timing()), (Some(9), 4));
    assert_eq!(s.pending_node_id(), Some(9));
    // the medium failed: error 2, nothing stored
    send(&mut s, TO_CONFIG);
    send(&mut s, [0x11, 20, 0, 0, 0, 0, 0, 0]);
    send(&mut s, [0x17, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(
        s.store_done(false).unwrap().data,
        [0x17, 0x02, 0, 0, 0, 0, 0, 0]
    );
    assert_eq!(s.stored_node_id(), Some(9));
    // a slave without storage: error 1 at once, no event
    s.set_store_supported(false);
    assert_eq!(
        send(&mut s, [0x17, 0, 0, 0, 0, 0, 0, 0]),
        (Some([0x17, 0x01, 0, 0, 0, 0, 0, 0]), None)
    );
    // a store not yet answered does not survive a reset node
    s.set_store_supported(true);
    send(&mut s, [0x17, 0, 0, 0, 0, 0, 0, 0]);
    s.reset_node();
    assert!(s.store_done(true).is_none());
    assert_eq!(s.active_node_id(), Some(9));
}

fn selective(s: &mut LssSlave, id: &LssIdentity) -> Vec<(Option<[u8; 8]>, Option<LssEvent>)> {
    [
        u32_frame(0x40, id.vendor_id),
        u32_frame(0x41, id.product_code),
        u32_frame(0x42, id.revision_number),
        u32_frame(0x43, id.serial_number),
    ]
    .into_iter()
    .map(|f| send(s, f))
    .collect()
}

#[test]
fn switch_state_selective_by_the_four_parts_in_order() {
    let mut s = LssSlave::new(ID, Some(7), 2).unwrap();
    let r = selective(&mut s, &ID);
    assert_eq!(&r[..3], &[(None, None), (None, None), (None, None)]);
    assert_eq!(
        r[3],
        (
            Some([0x44, 0, 0, 0, 0, 0, 0, 0]),
            Some(LssEvent::ConfigurationState)
        )
    );
    assert_eq!(s.state(), LssState::Configuration);
    // each part wrong in turn: silent, still waiting
    for k in 0..4 {
        let mut s = LssSlave::new(ID, Some(7), 2).unwrap();
        let mut other = ID;
        match k {
            0 => other.vendor_id ^= 1,
            1 => other.product_code ^= 0x100,
            2 => other.revision_number += 1,
            _ => other.serial_number ^= 0x8000_0000,
        }
        assert!(selective(&mut s, &other).iter().all(|r| *r == (None, None)));
        assert_eq!(s.state(), LssState::Waiting, "part {k} wrong");
    }
    // out of order: product before vendor, or a part skipped
    let mut s = LssSlave::new(ID, Some(7), 2).unwrap();
    for f in [
        u32_frame(0x41, ID.product_code),
        u32_frame(0x40, ID.vendor_id),
        u32_frame(0x42, ID.revision_number),
        u32_frame(0x43, ID.serial_number),
    ] {
        assert_eq!(send(&mut s, f), (None, None));
    }
    assert_eq!(s.state(), LssState::Waiting);
    // a repeated vendor-ID starts the sequence again
    send(&mut s, u32_frame(0x40, ID.vendor_id));
    let r = selective(&mut s, &ID);
    assert_eq!(r[3].0, Some([0x44, 0, 0, 0, 0, 0, 0, 0]));
    // a wrong vendor-ID in the middle ends it
    let mut s = LssSlave::new(ID, Some(7), 2).unwrap();
    send(&mut s, u32_frame(0x40, ID.vendor_id));
    send(&mut s, u32_frame(0x41, ID.product_code));
    send(&mut s, u32_frame(0x40, 0xDEAD));
    send(&mut s, u32_frame(0x42, ID.revision_number));
    assert_eq!(
        send(&mut s, u32_frame(0x43, ID.serial_number)),
        (None, None)
    );
}

fn identify(s: &mut LssSlave, v: [u32; 6]) -> Option<[u8; 8]> {
    let mut last = None;
    for (k, x) in v.into_iter().enumerate() {
        let (r, e) = send(s, u32_frame(0x46 + k as u8, x));
        assert_eq!(e, None);
        if k < 5 {
            assert_eq!(r, None, "only the last frame is answered");
        }
        last = r;
    }
    last
}

#[test]
fn identify_remote_slave_by_ranges_inclusive_in_both_states() {
    let (r, sn) = (ID.revision_number, ID.serial_number);
    let hit = Some([0x4F, 0, 0, 0, 0, 0, 0, 0]);
    for configuring in [false, true] {
        let mut s = LssSlave::new(ID, Some(7), 2).unwrap();
        if configuring {
            send(&mut s, TO_CONFIG);
        }
        let v = ID.vendor_id;
        let p = ID.product_code;
        // ranges that hold it, boundaries included
        for range in [
            [v, p, 0, u32::MAX, 0, u32::MAX],
            [v, p, r, r, sn, sn],
            [v, p, r - 1, r + 1, sn - 1, sn + 1],
        ] {
            assert_eq!(identify(&mut s, range), hit, "{range:X?}");
        }
        // ranges that miss it
        for range in [
            [v + 1, p, 0, u32::MAX, 0, u32::MAX],
            [v, p + 1, 0, u32::MAX, 0, u32::MAX],
            [v, p, r + 1, u32::MAX, 0, u32::MAX],
            [v, p, 0, r - 1, 0, u32::MAX],
            [v, p, 0, u32::MAX, sn + 1, u32::MAX],
            [v, p, 0, u32::MAX, 0, sn - 1],
        ] {
            assert_eq!(identify(&mut s, range), None, "{range:X?}");
        }
        // the last field alone is not a sequence
        assert_eq!(send(&mut s, u32_frame(0x4B, u32::MAX)), (None, None));
        // identify changes no state
        assert_eq!(
            s.state(),
            if configuring {
                LssState::Configuration
            } else {
                LssState::Waiting
            }
        );
    }
}

#[test]
fn identify_non_configured_remote_slave() {
    let q = [0x4C, 0, 0, 0, 0, 0, 0, 0];
    let mut s = unconfigured();
    assert_eq!(send(&mut s, q), (Some([0x50, 0, 0, 0, 0, 0, 0, 0]), None));
    send(&mut s, TO_CONFIG);
    assert_eq!(send(&mut s, q).0, Some([0x50, 0, 0, 0, 0, 0, 0, 0]));
    // a pending node-ID makes it configured for this service
    send(&mut s, [0x11, 3, 0, 0, 0, 0, 0, 0]);
    assert_eq!(send(&mut s, q), (None, None));
    let mut s = LssSlave::new(ID, Some(4), 2).unwrap();
    assert_eq!(send(&mut s, q), (None, None));
}

/// In waiting state the configuration services are silent and change nothing; in
/// configuration state the selective switch and fastscan are silent; frames that are not LSS
/// requests (another COB-ID, remote, extended, short, unknown) are ignored in both.
#[test]
fn nothing_is_answered_in_the_wrong_state() {
    let config_only: [[u8; 8]; 10] = [
        [0x11, 9, 0, 0, 0, 0, 0, 0],
        [0x13, 0, 2, 0, 0, 0, 0, 0],
        [0x15, 10, 0, 0, 0, 0, 0, 0],
        [0x17, 0, 0, 0, 0, 0, 0, 0],
        [0x5A, 0, 0, 0, 0, 0, 0, 0],
        [0x5B, 0, 0, 0, 0, 0, 0, 0],
        [0x5C, 0, 0, 0, 0, 0, 0, 0],
        [0x5D, 0, 0, 0, 0, 0, 0, 0],
        [0x5E, 0, 0, 0, 0, 0, 0, 0],
        [0x13, 0, 5, 0, 0, 0, 0, 0],
    ];
    let mut s = unconfigured();
    for f in config_only {
        assert_eq!(send(&mut s, f), (None, None), "{f:02X?} in waiting");
    }
    assert_eq!(s.pending_node_id(), None);
    assert_eq!((s.pending_bit_timing(), s.active_bit_timing()), (2, 2));
    assert!(!s.store_pending());
    assert_eq!(s.state(), LssState::Waiting);

    send(&mut s, TO_CONFIG);
    let mut waiting_only: Vec<[u8; 8]> = selective_frames(&ID).to_vec();
    waiting_only.push([0x51, 0, 0, 0, 0, 0x80, 0, 0]);
    waiting_only.push(fastscan_frame(ID.vendor_id, 0, 0, 1));
    for f in waiting_only {
        assert_eq!(send(&mut s, f), (None, None), "{f:02X?} in configuration");
    }
    assert_eq!(s.state(), LssState::Configuration);

    // not LSS requests, in both states
    for state in [TO_CONFIG, TO_WAITING] {
        send(&mut s, state);
        let inquire = [0x5E, 0, 0, 0, 0, 0, 0, 0];
        let reset_scan = [0x51, 0, 0, 0, 0, 0x80, 0, 0];
        let mut remote = CanFrame::remote(0x7E5, 8);
        remote.data = inquire;
        let mut extended = req(inquire);
        extended.extended = true;
        let mut ext_scan = req(reset_scan);
        ext_scan.extended = true;
        for f in [
            CanFrame::new(0x7E4, &inquire),
            CanFrame::new(0x7E4, &reset_scan),
            CanFrame::new(0x7E6, &inquire),
            remote,
            extended,
            ext_scan,
            CanFrame::new(0x7E5, &[]),
            CanFrame::new(0x7E5, &[0x51, 0, 0, 0, 0, 0x80, 0]),
            CanFrame::new(0x7E5, &[0x04]),
            CanFrame::new(0x7E5, &[0x51, 0, 0, 0, 0, 0x40, 0, 0]),
            CanFrame::new(0x7E5, &[0x51, 0, 0, 0, 0, 0x80, 4, 0]),
            CanFrame::new(0x7E5, &[0x99, 0, 0, 0, 0, 0, 0, 0]),
            CanFrame::new(0x7E5, &[0x44, 0, 0, 0, 0, 0, 0, 0]),
        ] {
            assert_eq!(s.handle(&f), LssOutput::default(), "{f:?}");
        }
    }
}

/// A configured slave takes no part in fastscan: CiA 305 and python canopen scan for
/// non-configured slaves (CANopenNode's slave does the same).
#[test]
fn a_configured_slave_ignores_fastscan() {
    let mut s = LssSlave::new(ID, Some(5), 2).unwrap();
    for f in python_fast_scan_frames_for(&ID) {
        assert_eq!(send(&mut s, f), (None, None), "{f:02X?}");
    }
    assert_eq!(s.state(), LssState::Waiting);
}

// ---- fastscan with python canopen's master ----

fn selective_frames(id: &LssIdentity) -> [[u8; 8]; 4] {
    [
        u32_frame(0x40, id.vendor_id),
        u32_frame(0x41, id.product_code),
        u32_frame(0x42, id.revision_number),
        u32_frame(0x43, id.serial_number),
    ]
}

/// `struct.pack('<BIBBB', 0x51, id_number, bit_checker, lss_sub, lss_next)`.
fn fastscan_frame(id_number: u32, bit: u8, sub: u8, next: u8) -> [u8; 8] {
    let b = id_number.to_le_bytes();
    [0x51, b[0], b[1], b[2], b[3], bit, sub, next]
}

/// Slaves on one bus: a request reaches every slave; identical answers of several slaves are
/// one frame on a real bus, so the master sees whether any answered.
struct Bus {
    slaves: Vec<LssSlave>,
    /// Frames the master sent.
    sent: Vec<[u8; 8]>,
}

impl Bus {
    fn new(ids: &[LssIdentity]) -> Bus {
        Bus {
            slaves: ids
                .iter()
                .map(|id| LssSlave::new(*id, None, 2).unwrap())
                .collect(),
            sent: Vec::new(),
        }
    }

    /// Send a request; the answers of all slaves. A store is completed at once (as the node
    /// would after writing).
    fn send(&mut self, bytes: [u8; 8]) -> Vec<[u8; 8]> {
        self.sent.push(bytes);
        let mut out = Vec::new();
        for s in &mut self.slaves {
            let o = s.handle(&req(bytes));
            out.extend(o.response.map(|f| f.data));
            if let Some(LssEvent::StoreRequested { .. }) = o.event {
                out.extend(s.store_done(true).map(|f| f.data));
            }
        }
        out
    }

    /// python canopen's `__send_fast_scan_message`: True when a response with cs 0x4F came.
    fn fast_scan_message(&mut self, id: u32, bit: u8, sub: u8, next: u8) -> bool {
        let answers = self.send(fastscan_frame(id, bit, sub, next));
        let first = answers.first().map(|a| a[0]);
        assert!(
            answers.iter().all(|a| *a == [0x4F, 0, 0, 0, 0, 0, 0, 0]),
            "fastscan answers are 0x4F frames, all alike: {answers:02X?}"
        );
        first == Some(0x4F)
    }

    /// python canopen 2.4.1 `LssMaster.fast_scan()`, frame for frame (its sleeps left out).
    fn python_fast_scan(&mut self) -> Option<[u32; 4]> {
        let mut lss_id = [0u32; 4];
        let mut lss_bit_check: u8 = 128;
        let mut lss_sub: u8 = 0;
        let mut lss_next: u8 = 0;
        if !self.fast_scan_message(lss_id[0], lss_bit_check, lss_sub, lss_next) {
            return None;
        }
        while lss_sub < 4 {
            lss_bit_check = 32;
            while lss_bit_check > 0 {
                lss_bit_check -= 1;
                let k = usize::from(lss_sub);
                if !self.fast_scan_message(lss_id[k], lss_bit_check, lss_sub, lss_next) {
                    lss_id[k] |= 1 << lss_bit_check;
                }
            }
            lss_next = (lss_sub + 1) & 3;
            let k = usize::from(lss_sub);
            if !self.fast_scan_message(lss_id[k], lss_bit_check, lss_sub, lss_next) {
                return None;
            }
            lss_sub += 1;
        }
        Some(lss_id)
    }

    /// What a python script does with each slave it finds: configure_node_id(n) (expects
    /// 0x11 error 0), store_configuration() (0x17 error 0), send_switch_state_global(WAITING).
    fn assign(&mut self, node_id: u8) {
        assert_eq!(
            self.send([0x11, node_id, 0, 0, 0, 0, 0, 0]),
            [[0x11, 0, 0, 0, 0, 0, 0, 0]],
            "one slave answers configure node-ID"
        );
        assert_eq!(
            self.send([0x17, 0, 0, 0, 0, 0, 0, 0]),
            [[0x17, 0, 0, 0, 0, 0, 0, 0]]
        );
        assert!(self.send(TO_WAITING).is_empty());
    }
}

/// The frames python canopen's fast_scan sends when `id` is the only slave (for the
/// configured-slave test: there, nobody answers and the scan stops after the first frame,
/// so the whole sequence is sent regardless).
fn python_fast_scan_frames_for(id: &LssIdentity) -> Vec<[u8; 8]> {
    let mut bus = Bus::new(&[*id]);
    bus.python_fast_scan().expect("found");
    bus.sent
}

fn u(x: [u32; 4]) -> LssIdentity {
    LssIdentity {
        vendor_id: x[0],
        product_code: x[1],
        revision_number: x[2],
        serial_number: x[3],
    }
}

/// Scan, assign, repeat until the scan finds nobody: each slave is found once, in address
/// order (vendor-ID first ... serial last), gets its node-ID and boots with it.
fn scan_all(ids: &[LssIdentity]) {
    let mut bus = Bus::new(ids);
    let mut found = Vec::new();
    while let Some(x) = bus.python_fast_scan() {
        assert!(
            found.len() < ids.len(),
            "more found than on the bus: {found:X?}"
        );
        let n = 10 + found.len() as u8;
        bus.assign(n);
        found.push(u(x));
    }
    let mut sorted = ids.to_vec();
    sorted.sort();
    assert_eq!(found, sorted, "found in address order, each once");
    for (k, id) in sorted.iter().enumerate() {
        let s = bus.slaves.iter().find(|s| s.identity() == *id).unwrap();
        assert_eq!(s.active_node_id(), Some(10 + k as u8), "{id:X?}");
        assert_eq!(s.stored_node_id(), Some(10 + k as u8));
        assert_eq!(s.state(), LssState::Waiting);
    }
    // the scan after the last one: only the reset frame went out, nobody answered
    let before = bus.sent.len();
    assert_eq!(bus.python_fast_scan(), None);
    assert_eq!(bus.sent.len(), before + 1);
}

#[test]
fn python_fast_scan_finds_one_two_and_three_slaves_in_address_order() {
    let a = u([0x123, 0x402, 0x0001_0000, 0x8000_0011]);
    let b = u([0x123, 0x402, 0x0001_0000, 0x8000_0010]); // differs in the serial's bit 0
    let c = u([0x123, 0x401, 0x0002_0000, 0x0000_0001]); // lower product code
    let d = u([0x122, 0xFFFF_FFFF, 0xFFFF_FFFF, 0xFFFF_FFFF]); // lowest vendor-ID
    let e = u([0, 0, 0, 0]);
    let f = u([u32::MAX; 4]);
    for ids in [
        vec![a],
        vec![e],
        vec![f],
        vec![a, b],
        vec![b, a],
        vec![c, a],
        vec![e, f],
        vec![a, b, c],
        vec![c, b, a],
        vec![d, a, b],
        vec![b, d, c],
        vec![e, f, a],
    ] {
        scan_all(&ids);
    }
}

/// A sweep: three slaves whose addresses share random prefixes (same vendor, same product,
/// serials differing in one low bit...), so that the scan must tell them apart at every
/// part and bit depth.
#[test]
fn python_fast_scan_sweep_over_addresses_sharing_prefixes() {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut rnd = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for _ in 0..200 {
        let base = [rnd() as u32, rnd() as u32, rnd() as u32, rnd() as u32];
        let n = 1 + (rnd() % 3) as usize;
        let mut ids: Vec<LssIdentity> = Vec::new();
        while ids.len() < n {
            let mut x = base;
            // share the first `keep` parts, then flip one random bit of the next
            let keep = (rnd() % 4) as usize;
            x[keep] ^= 1 << (rnd() % 32);
            for v in x.iter_mut().skip(keep + 1) {
                *v = rnd() as u32;
            }
            let id = u(x);
            if !ids.contains(&id) {
                ids.push(id);
            }
        }
        scan_all(&ids);
    }
}

/// A configured slave on the bus beside non-configured ones is never found and never
/// answers; the scan finds the others.
#[test]
fn python_fast_scan_skips_a_configured_slave() {
    let low = u([1, 1, 1, 1]); // lowest address on the bus, but configured
    let x = u([0x123, 0x402, 0x0001_0000, 5]);
    let mut bus = Bus::new(&[x]);
    bus.slaves.push(LssSlave::new(low, Some(3), 2).unwrap());
    assert_eq!(bus.python_fast_scan().map(u), Some(x));
    bus.assign(20);
    assert_eq!(bus.python_fast_scan(), None);
    assert_eq!(bus.slaves[1].active_node_id(), Some(3));
}

/// A scan interrupted (master restarted) resumes cleanly from the reset frame; a change of
/// LSS state in between restarts it too.
#[test]
fn an_interrupted_scan_starts_over_at_the_reset_frame() {
    let x = u([0x123, 0x402, 0x0001_0000, 5]);
    let mut bus = Bus::new(&[x]);
    // half a scan: the vendor-ID confirmed, the product code half done
    assert!(bus.fast_scan_message(0, 0x80, 0, 0));
    assert!(bus.fast_scan_message(0x123, 0, 0, 1));
    assert!(bus.fast_scan_message(0, 31, 1, 1));
    // the slave now compares the product code: a vendor-ID request is silent
    assert!(!bus.fast_scan_message(0x123, 0, 0, 1));
    send(&mut bus.slaves[0], TO_WAITING);
    assert!(
        !bus.fast_scan_message(0, 31, 1, 1),
        "restarted at the vendor-ID"
    );
    assert_eq!(bus.python_fast_scan().map(u), Some(x));
    assert_eq!(bus.slaves[0].state(), LssState::Configuration);
}
