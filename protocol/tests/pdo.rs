//! PDOs: default mappings, dynamic remapping and its aborts, transmission types, inhibit time,
//! event timer, synchronous RPDOs, wrong-length RPDOs.
mod common;
use common::*;

const N: u32 = ID as u32;

fn i32_at(d: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([d[at], d[at + 1], d[at + 2], d[at + 3]])
}

#[test]
fn default_mappings() {
    let mut b = Bench::new();
    b.start();
    b.tick();
    b.take();
    b.drive.pos = 6553.6 * 3.0; // 3000 um
    b.tick();
    b.sync();
    let tx = b.take();
    let t2 = tx.iter().find(|f| f.id == 0x280 + N).expect("TPDO2");
    assert_eq!(t2.len, 6);
    assert_eq!(u16::from_le_bytes([t2.data[0], t2.data[1]]) & 0x4F, 0x40);
    assert_eq!(i32_at(&t2.data, 2), 3000);
    assert_eq!(
        tx.iter().find(|f| f.id == 0x380 + N).unwrap().len,
        6,
        "TPDO3 statusword + velocity"
    );
    let t4 = tx.iter().find(|f| f.id == 0x480 + N).unwrap();
    assert_eq!(i32_at(&t4.data, 2), 3000, "TPDO4 carries 0x60E4 sub 1");
    // TPDO1: statusword + mode display, on change
    b.w8(0x6060, 0, 8).unwrap();
    b.tick();
    let t1 = b
        .take()
        .into_iter()
        .filter(|f| f.id == 0x180 + N)
        .collect::<Vec<_>>();
    assert_eq!(t1.len(), 1);
    assert_eq!((t1[0].len, t1[0].data[2]), (3, 8));
    // RPDO2: controlword + target position
    b.send(f(0x300 + N, &[0x06, 0x00, 0x10, 0x27, 0, 0]));
    b.sync();
    assert_eq!(b.r32(0x6040, 0), 6);
    assert_eq!(b.ri32(0x607A, 0), 10000);
    // RPDO3: controlword + target velocity; RPDO4: controlword + target torque
    b.send(f(0x400 + N, &[0x06, 0x00, 0xFF, 0xFF, 0xFF, 0xFF]));
    b.send(f(0x500 + N, &[0x06, 0x00, 0x2C, 0x01]));
    b.sync();
    assert_eq!(b.ri32(0x60FF, 0), -1);
    assert_eq!(b.ri32(0x6071, 0), 300);
}

#[test]
fn remap_procedure() {
    let mut b = Bench::new();
    b.w32(0x1801, 1, 0x8000_0280 + N).unwrap();
    b.w8(0x1A01, 0, 0).unwrap();
    b.w32(0x1A01, 1, 0x6064_0020).unwrap();
    b.w32(0x1A01, 2, 0x60F4_0020).unwrap();
    b.w8(0x1A01, 0, 2).unwrap();
    b.w32(0x1801, 1, 0x280 + N).unwrap();
    b.start();
    b.drive.pos = 65536.0;
    b.tick();
    b.take();
    b.sync();
    let t = b.take().into_iter().find(|f| f.id == 0x280 + N).unwrap();
    assert_eq!(t.len, 8);
    assert_eq!(i32_at(&t.data, 0), 10000);
}

#[test]
fn remap_aborts() {
    let mut b = Bench::new();
    // mapping may not change while the PDO is valid
    assert_eq!(b.w8(0x1A01, 0, 0), Err(0x0601_0000));
    assert_eq!(b.w32(0x1A01, 1, 0x6064_0020), Err(0x0601_0000));
    b.w32(0x1801, 1, 0x8000_0280 + N).unwrap();
    // entries only while sub 0 is 0
    assert_eq!(b.w32(0x1A01, 1, 0x6064_0020), Err(0x0601_0000));
    b.w8(0x1A01, 0, 0).unwrap();
    // not mappable: no PDO flag, not existing, wrong length, read-only into an RPDO
    assert_eq!(b.w32(0x1A01, 1, 0x1000_0020), Err(0x0604_0041));
    assert_eq!(b.w32(0x1A01, 1, 0x1234_0020), Err(0x0604_0041));
    assert_eq!(b.w32(0x1A01, 1, 0x6064_0010), Err(0x0604_0041));
    b.w32(0x1400, 1, 0x8000_0200 + N).unwrap();
    b.w8(0x1600, 0, 0).unwrap();
    assert_eq!(b.w32(0x1600, 1, 0x6041_0010), Err(0x0604_0041));
    // more than 64 bits
    for s in 1..=3 {
        b.w32(0x1A01, s, 0x6064_0020).unwrap();
    }
    assert_eq!(b.w8(0x1A01, 0, 3), Err(0x0604_0042));
    assert_eq!(b.w8(0x1A01, 0, 9), Err(0x0609_0031));
    b.w8(0x1A01, 0, 2).unwrap();
    // COB-ID of a valid PDO cannot change
    b.w32(0x1801, 1, 0x280 + N).unwrap();
    assert_eq!(b.w32(0x1801, 1, 0x290 + N), Err(0x0609_0030));
    assert_eq!(
        b.w32(0x1801, 1, 0x2000_0000 | (0x280 + N)),
        Err(0x0609_0030),
        "29-bit"
    );
    // inhibit time only while invalid
    assert_eq!(b.w16(0x1801, 3, 10), Err(0x0601_0000));
    // RPDO transmission types 252/253 do not exist
    assert_eq!(b.w8(0x1401, 2, 252), Err(0x0609_0030));
}

fn sync_n(b: &mut Bench, n: usize, id: u32) -> usize {
    let mut count = 0;
    for _ in 0..n {
        b.take();
        b.sync();
        b.tick();
        count += b.take().iter().filter(|f| f.id == id).count();
    }
    count
}

#[test]
fn synchronous_types_0_and_n() {
    let mut b = Bench::new();
    b.w8(0x1801, 2, 3).unwrap();
    b.w8(0x1802, 2, 0).unwrap();
    b.start();
    assert_eq!(sync_n(&mut b, 12, 0x280 + N), 4, "type 3: every third SYNC");
    // type 0: only when the data changed
    assert!(sync_n(&mut b, 5, 0x380 + N) <= 1);
    b.drive.vel = 1000.0;
    b.tick();
    assert_eq!(sync_n(&mut b, 1, 0x380 + N), 1);
}

/// CiA 301 synchronous window (0x1007): a SYNC handled after its window closed sends no
/// synchronous TPDO (types 0 and 1-240); one handled inside it does; 0 means no window. The
/// missed ones are counted (the emulator publishes the count in 0x2100 sub 12).
#[test]
fn synchronous_window_1007_suppresses_late_synchronous_tpdos() {
    let mut b = Bench::new();
    assert_eq!(b.r32(0x1007, 0), 0, "no window by default");
    b.start();
    b.tick();
    let sync = f(0x80, &[]);
    let late_sync = |b: &mut Bench, late_us: u64| {
        b.take();
        b.node.handle_late(&sync, b.now, late_us, &mut b.drive);
        b.drain();
        let tx = b.take();
        b.tick();
        tx
    };
    // No window: even a SYNC read a second late gets its TPDOs.
    let tx = late_sync(&mut b, 1_000_000);
    assert!(tx.iter().any(|f| f.id == 0x280 + N), "{tx:?}");
    assert!(tx.iter().any(|f| f.id == 0x380 + N), "{tx:?}");
    b.w32(0x1007, 0, 500).unwrap();
    let synchronous = |tx: &[drive_protocol::CanFrame]| {
        tx.iter()
            .filter(|f| f.id == 0x280 + N || f.id == 0x380 + N || f.id == 0x480 + N)
            .count() as u32
    };
    let mut per_sync = 0;
    for late in [0, 200, 500] {
        let tx = late_sync(&mut b, late);
        assert!(tx.iter().any(|f| f.id == 0x280 + N), "late {late}: {tx:?}");
        assert!(tx.iter().any(|f| f.id == 0x380 + N), "late {late}: {tx:?}");
        per_sync = synchronous(&tx);
    }
    let before = b.node.sync_window_missed();
    for late in [501, 5_000, 1_000_000] {
        let tx = late_sync(&mut b, late);
        assert_eq!(
            synchronous(&tx),
            0,
            "late {late}: window closed, yet {tx:?}"
        );
    }
    assert_eq!(per_sync, 3, "TPDO2-4 are synchronous by default");
    assert_eq!(
        b.node.sync_window_missed(),
        before + 3 * per_sync,
        "3 SYNCs' TPDOs missed"
    );
    // Window open again: the next SYNC in time is answered.
    let tx = late_sync(&mut b, 10);
    assert!(tx.iter().any(|f| f.id == 0x280 + N), "{tx:?}");
}

#[test]
fn event_driven_with_inhibit_time_and_event_timer() {
    let mut b = Bench::new();
    // TPDO2 event-driven, inhibit 10 ms
    b.w32(0x1801, 1, 0x8000_0280 + N).unwrap();
    b.w8(0x1801, 2, 254).unwrap();
    b.w16(0x1801, 3, 100).unwrap();
    b.w32(0x1801, 1, 0x280 + N).unwrap();
    // TPDO3 event timer 20 ms, data constant
    b.w8(0x1802, 2, 255).unwrap();
    b.w16(0x1802, 5, 20).unwrap();
    b.start();
    b.take();
    let mut times = Vec::new();
    for k in 0..100 {
        b.drive.pos += 10.0; // position changes every tick
        b.tick();
        if b.take().iter().any(|f| f.id == 0x280 + N) {
            times.push(k);
        }
        let _ = k;
    }
    assert!(times.len() >= 9 && times.len() <= 11, "{times:?}");
    assert!(
        times.windows(2).all(|w| w[1] - w[0] >= 10),
        "inhibit time respected: {times:?}"
    );
    // event timer: TPDO3 every 20 ms although nothing changes
    b.drive.vel = 0.0;
    let mut n3 = 0;
    for _ in 0..200 {
        b.tick();
        n3 += b.take().iter().filter(|f| f.id == 0x380 + N).count();
    }
    assert!((9..=11).contains(&n3), "{n3}");
}

#[test]
fn synchronous_rpdo_applied_at_next_sync() {
    let mut b = Bench::new();
    b.start();
    b.send(f(0x300 + N, &[0x00, 0x00, 0x39, 0x30, 0, 0]));
    b.tick();
    assert_eq!(b.ri32(0x607A, 0), 0, "not before SYNC");
    b.sync();
    assert_eq!(b.ri32(0x607A, 0), 12345);
}

#[test]
fn wrong_length_rpdo_gives_emcy_8210() {
    let mut b = Bench::new();
    b.start();
    b.send(f(0x200 + N, &[0x06]));
    b.tick();
    assert!(b.emcys().contains(&0x8210));
    assert_eq!(b.r32(0x6040, 0), 0, "not applied");
    let hist = b.r32(0x1003, 1);
    assert_eq!(hist & 0xFFFF, 0x8210);
}

#[test]
fn rtr_tpdo_type_253() {
    let mut b = Bench::new();
    b.w32(0x1801, 1, 0x8000_0280 + N).unwrap();
    b.w8(0x1801, 2, 253).unwrap();
    b.w32(0x1801, 1, 0x280 + N).unwrap();
    b.start();
    b.take();
    b.sync();
    b.tick();
    assert!(b.take().iter().all(|f| f.id != 0x280 + N));
    b.send(drive_protocol::CanFrame::remote(0x280 + N, 6));
    assert_eq!(b.take().iter().filter(|f| f.id == 0x280 + N).count(), 1);
}

#[test]
fn rtr_is_not_answered_when_the_cob_id_forbids_it() {
    // A master sets bit 30 ("no RTR allowed on this PDO"): a remote request for that TPDO
    // gets no answer, whatever its transmission type; clearing the bit enables it again.
    for ttype in [252u8, 253] {
        let mut b = Bench::new();
        b.w32(0x1801, 1, 0x8000_0280 + N).unwrap();
        b.w8(0x1801, 2, ttype).unwrap();
        b.w32(0x1801, 1, 0x4000_0280 + N).unwrap();
        b.start();
        b.sync();
        b.tick();
        b.take();
        b.send(drive_protocol::CanFrame::remote(0x280 + N, 6));
        b.tick();
        assert!(
            b.take().iter().all(|f| f.id != 0x280 + N),
            "type {ttype}: RTR answered although bit 30 forbids it"
        );
        b.w32(0x1801, 1, 0x8000_0280 + N).unwrap();
        b.w32(0x1801, 1, 0x280 + N).unwrap();
        b.sync();
        b.take();
        b.send(drive_protocol::CanFrame::remote(0x280 + N, 6));
        assert_eq!(
            b.take().iter().filter(|f| f.id == 0x280 + N).count(),
            1,
            "type {ttype}: RTR answered once bit 30 is clear"
        );
    }
}

/// CiA 301 restricted CAN-IDs, at the edges of each range.
const RESTRICTED: [u32; 15] = [
    0x000, 0x001, 0x07F, 0x101, 0x180, 0x581, 0x5FF, 0x601, 0x67F, 0x6E0, 0x6FF, 0x701, 0x77F,
    0x780, 0x7FF,
];

#[test]
fn restricted_can_ids_are_refused_for_every_pdo_cob_id() {
    let mut b = Bench::new();
    for k in 0..4u16 {
        for comm in [0x1400 + k, 0x1800 + k] {
            let cur = b.r32(comm, 1);
            b.w32(comm, 1, cur | 0x8000_0000).unwrap();
            for id in RESTRICTED {
                assert_eq!(
                    b.w32(comm, 1, id),
                    Err(0x0609_0030),
                    "{comm:04X}sub1 = {id:#05x}"
                );
            }
            // 29-bit frames are not supported either
            assert_eq!(
                b.w32(comm, 1, 0x2000_0000 | (cur & 0x7FF)),
                Err(0x0609_0030)
            );
            assert_eq!(b.r32(comm, 1), cur | 0x8000_0000, "value unchanged");
            // an invalid PDO may hold any CAN-ID; it is checked when the PDO is validated
            b.w32(comm, 1, 0x8000_0000).unwrap();
            assert_eq!(b.w32(comm, 1, 0x000), Err(0x0609_0030));
            b.w32(comm, 1, cur & 0x7FF).unwrap();
        }
    }
}

#[test]
fn a_tpdo_cannot_be_moved_onto_the_nmt_id() {
    // The case: TPDO1 on COB-ID 0 would send the statusword as an NMT command to
    // every node ("reset all nodes").
    let mut b = Bench::new();
    b.w32(0x1800, 1, 0x8000_0180 + N).unwrap();
    assert_eq!(b.w32(0x1800, 1, 0x000), Err(0x0609_0030));
    b.w32(0x1800, 1, 0x180 + N).unwrap();
    b.start();
    b.enable(1);
    b.ticks(5);
    b.sync();
    assert!(
        b.take()
            .iter()
            .all(|f| f.id != 0 && !(0x701..=0x7FF).contains(&f.id)),
        "nothing on the NMT or heartbeat IDs"
    );
}

#[test]
fn rpdo_longer_than_its_mapping_is_used_and_reported_with_8220() {
    let mut b = Bench::new();
    b.start();
    b.take();
    // RPDO1 maps the controlword (2 bytes); the master sends 8
    b.send(f(
        0x200 + N,
        &[0x06, 0x00, 0xAA, 0xBB, 0xCC, 0xDD, 0xEE, 0xFF],
    ));
    b.tick();
    assert_eq!(b.emcys(), vec![0x8220], "PDO length exceeded");
    assert_eq!(b.r32(0x6040, 0), 0x06, "the mapped bytes are used");
    assert_eq!(b.r32(0x1003, 1) & 0xFFFF, 0x8220);
    assert_eq!(b.r32(0x1001, 0) & 0x11, 0x11, "communication error active");
    // again: already reported, no second EMCY; the value is still taken
    b.send(f(0x200 + N, &[0x07, 0x00, 0, 0, 0, 0, 0, 0]));
    b.tick();
    assert_eq!(b.emcys(), vec![], "reported once");
    assert_eq!(b.r32(0x6040, 0), 0x07);
    // the right length clears it: EMCY 0x0000
    b.send(f(0x200 + N, &[0x0F, 0x00]));
    b.tick();
    assert_eq!(b.emcys(), vec![0x0000]);
    assert_eq!(b.r32(0x1001, 0), 0);
    assert_eq!(b.r32(0x6040, 0), 0x0F);
}

#[test]
fn rpdo_shorter_than_its_mapping_is_ignored_and_reported_again_after_an_nmt_reset() {
    let mut b = Bench::new();
    b.start();
    b.take();
    b.send(f(0x300 + N, &[0x06, 0x00, 1, 2])); // RPDO2 maps 6 bytes
    b.tick();
    assert_eq!(b.emcys(), vec![0x8210]);
    b.send(f(0x300 + N, &[0x06, 0x00, 1, 2]));
    b.tick();
    assert_eq!(b.emcys(), vec![0x8210], "reported once while it lasts");
    assert_eq!(b.r32(0x6040, 0), 0, "not applied");
    assert_eq!(b.ri32(0x607A, 0), 0);
    for cs in [0x82u8, 0x81] {
        // reset communication, then reset node: the master restarts and repeats its mistake
        b.nmt(cs, ID);
        b.start();
        b.take();
        b.send(f(0x300 + N, &[0x06, 0x00, 1, 2]));
        b.tick();
        assert_eq!(b.emcys(), vec![0x8210], "reported again after NMT {cs:#x}");
    }
}

#[test]
fn rpdo_values_pass_the_checks_of_an_sdo_write() {
    // 0x6060 = 2 (vl) or 5 (reserved) is refused by SDO; through an RPDO it must be refused too:
    // the drive keeps its mode, 0x6061 does not show the value, EMCY 0x6320 tells the master.
    let mut b = Bench::new();
    assert_eq!(b.w8(0x6060, 0, 2), Err(0x0609_0030));
    b.w32(0x1401, 1, 0x8000_0300 + N).unwrap();
    b.w8(0x1601, 0, 0).unwrap();
    b.w32(0x1601, 1, 0x6040_0010).unwrap();
    b.w32(0x1601, 2, 0x6060_0008).unwrap();
    b.w8(0x1601, 0, 2).unwrap();
    b.w8(0x1401, 2, 255).unwrap();
    b.w32(0x1401, 1, 0x300 + N).unwrap();
    b.start();
    b.send(f(0x300 + N, &[0x06, 0x00, 1]));
    b.tick();
    b.take();
    assert_eq!(b.ri32(0x6061, 0), 1);
    for bad in [2u8, 5, 0x80, 11] {
        b.take();
        b.send(f(0x300 + N, &[0x07, 0x00, bad]));
        b.tick();
        b.tick();
        let e = b.emcys();
        assert_eq!(
            b.ri32(0x6060, 0),
            1,
            "mode {bad} refused, previous value kept"
        );
        assert_eq!(b.ri32(0x6061, 0), 1, "0x6061 does not show {bad}");
        assert_eq!(b.r32(0x6040, 0), 0x07, "the valid controlword is applied");
        if bad == 2 {
            assert_eq!(e, vec![0x6320], "EMCY parameter error");
        } else {
            assert!(e.is_empty(), "reported once while it lasts: {e:04X?}");
        }
    }
    // a valid mode again: taken, and the error clears (EMCY 0x0000)
    b.take();
    b.send(f(0x300 + N, &[0x07, 0x00, 8]));
    b.tick();
    b.tick();
    assert_eq!(b.emcys(), vec![0x0000]);
    assert_eq!(b.ri32(0x6061, 0), 8);
    // a synchronous RPDO is checked when it is applied at SYNC
    b.w32(0x1401, 1, 0x8000_0300 + N).unwrap();
    b.w8(0x1401, 2, 1).unwrap();
    b.w32(0x1401, 1, 0x300 + N).unwrap();
    b.take();
    b.send(f(0x300 + N, &[0x07, 0x00, 2]));
    b.sync();
    b.tick();
    assert_eq!(b.emcys(), vec![0x6320]);
    assert_eq!(b.ri32(0x6060, 0), 8);
}

/// TPDO1 (statusword + mode display) is event-driven with a default event timer, so a master
/// that waits for its next reception (python canopen `BaseNode402.op_mode`, 0.2 s) gets one
/// although nothing changed; the SYNC-driven TPDOs have none.
#[test]
fn tpdo1_has_a_default_event_timer() {
    let mut b = Bench::new();
    assert_eq!(b.r32(0x1800, 2), 255);
    let timer_ms = b.r32(0x1800, 5);
    assert!(
        (1..200).contains(&timer_ms),
        "TPDO1 event timer {timer_ms} ms"
    );
    for k in 1..4 {
        assert_eq!(b.r32(0x1800 + k, 5), 0);
    }
    b.start();
    b.take();
    let mut times = Vec::new();
    let ticks = 2000u64; // DT_US = 1 ms, constant data
    for k in 0..ticks {
        b.tick();
        if b.take().iter().any(|f| f.id == 0x180 + N) {
            times.push(k);
        }
    }
    let expect = ticks / u64::from(timer_ms);
    assert!(
        (expect - 1..=expect + 1).contains(&(times.len() as u64)),
        "{} TPDO1 in {ticks} ms, timer {timer_ms} ms: {times:?}",
        times.len()
    );
    assert!(times
        .windows(2)
        .all(|w| w[1] - w[0] <= u64::from(timer_ms) + 1));
}
