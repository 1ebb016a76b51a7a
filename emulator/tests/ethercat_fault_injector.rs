//! The EtherCAT fault injector (`drive_emu::bus::ethercat::EcatFaults`), sans-IO: each wire
//! fault does to the frames what a master will see (lost, held, working counters not
//! incremented) and ends on time; shares are deterministic for a seed.

use drive_emu::bus::ethercat::{Answer, EcatFault, EcatFaults, HELD_FRAMES};

fn frame() -> Vec<u8> {
    // one LRW of 4 bytes, working counter 0 as a master sends it
    drive_ethercat::frame::build([2, 0, 0, 0, 0, 0], &[(12, 0x80, 0x1000, &[0u8; 4])])
}

#[test]
fn lost_frames_are_counted_down_then_pass() {
    let mut f = EcatFaults::new(1);
    f.start(
        EcatFault::Lost {
            frames: 3,
            share: 0.0,
        },
        None,
        0,
    );
    let fr = frame();
    let seen: Vec<bool> = (0..5).map(|t| f.admit(&fr, t)).collect();
    assert_eq!(seen, [false, false, false, true, true]);
    assert_eq!(f.stats().lost, 3);
}

#[test]
fn corrupted_frames_are_refused_and_said_to_be_corrupted_not_lost() {
    let mut f = EcatFaults::new(1);
    f.start(
        EcatFault::Corrupt {
            frames: 2,
            share: 0.0,
        },
        None,
        0,
    );
    let fr = frame();
    let seen: Vec<(bool, bool)> = (0..4).map(|t| (f.admit(&fr, t), f.corrupted())).collect();
    assert_eq!(
        seen,
        [(false, true), (false, true), (true, false), (true, false)]
    );
    assert_eq!((f.stats().corrupted, f.stats().lost), (2, 0));
    // a lost frame is not a corrupted one
    f.start(
        EcatFault::Lost {
            frames: 1,
            share: 0.0,
        },
        None,
        4,
    );
    assert!(!f.admit(&fr, 5));
    assert!(!f.corrupted());
}

#[test]
fn a_share_of_lost_frames_is_near_the_share_and_ends_on_time() {
    let mut f = EcatFaults::new(7);
    f.start(
        EcatFault::Lost {
            frames: 0,
            share: 0.25,
        },
        Some(4000),
        0,
    );
    let fr = frame();
    let passed = (0..4000).filter(|&t| f.admit(&fr, t)).count();
    assert!((2850..=3150).contains(&passed), "{passed}");
    assert!((4000..4100).all(|t| f.admit(&fr, t)), "over at 4000 us");
}

#[test]
fn the_link_down_loses_everything_until_its_end() {
    let mut f = EcatFaults::new(1);
    f.start(EcatFault::LinkDown, Some(100), 1000);
    let fr = frame();
    assert!(!f.admit(&fr, 1000) && !f.admit(&fr, 1099));
    assert!(f.admit(&fr, 1100));
    f.start(EcatFault::LinkDown, None, 2000);
    assert!(!f.admit(&fr, 1_000_000_000));
    f.clear();
    assert!(f.admit(&fr, 1_000_000_001));
}

#[test]
fn a_bad_wkc_frame_comes_back_with_the_counters_it_was_sent_with() {
    let mut f = EcatFaults::new(1);
    f.start(EcatFault::BadWkc { share: 1.0 }, None, 0);
    let mut fr = frame();
    assert!(f.admit(&fr, 0));
    // the datagram's working counter: after the Ethernet, EtherCAT and datagram headers and
    // its 4 bytes of data (the frame is padded to 60 bytes after it)
    let w = 14 + 2 + 10 + 4;
    // the slave incremented the working counter
    fr[w] = 3;
    assert_eq!(f.answer(&mut fr, 0), Answer::Send);
    assert_eq!(&fr[w..w + 2], [0, 0]);
    assert_eq!(f.stats().bad_wkc, 1);
    // without the fault the counter stays as the slave left it
    f.clear();
    assert!(f.admit(&fr, 1));
    fr[w] = 3;
    assert_eq!(f.answer(&mut fr, 1), Answer::Send);
    assert_eq!(fr[w], 3);
}

#[test]
fn late_frames_go_out_when_due_in_order_and_a_full_hold_loses_them() {
    let mut f = EcatFaults::new(1);
    f.start(EcatFault::Late { hold_us: 500 }, Some(10_000), 0);
    for k in 0..(HELD_FRAMES + 2) {
        let mut fr = frame();
        fr[20] = k as u8;
        assert!(f.admit(&fr, k as u64));
        assert_eq!(f.answer(&mut fr, k as u64), Answer::Kept);
    }
    assert_eq!(f.stats().hold_full, 2);
    assert_eq!(f.next_due_us(), Some(500));
    let mut out = Vec::new();
    f.due(499, |b| out.push(b[20]));
    assert!(out.is_empty());
    f.due(510, |b| out.push(b[20]));
    assert_eq!(out, (0..=10).collect::<Vec<u8>>());
    f.due(u64::MAX, |b| out.push(b[20]));
    assert_eq!(out.len(), HELD_FRAMES);
    // after its end, frames are answered at once
    let mut fr = frame();
    assert!(f.admit(&fr, 10_000));
    assert_eq!(f.answer(&mut fr, 10_000), Answer::Send);
}
