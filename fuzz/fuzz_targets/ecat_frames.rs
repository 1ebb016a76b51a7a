//! The EtherCAT frame path: any byte string becomes a sequence of Ethernet frames (some forced
//! to EtherType 0x88A4 with a consistent EtherCAT header, so the datagram, register, SII,
//! AL, mailbox and CoE paths are reached, not only the frame check) and drive cycles, passed
//! along a line of two slaves. Nothing may panic; afterwards a master can still set the line
//! up again (station addresses, INIT, mailbox sync managers, PRE-OP) and read 0x1018:1 of
//! each slave over CoE.
//!
//! Run: cargo fuzz run --sanitizer none --debug-assertions ecat_frames (stable), or
//! cargo +nightly fuzz run ecat_frames (AddressSanitizer).
#![no_main]

use drive_ethercat::frame::{self, Returned};
use drive_ethercat::slave::{MBX_IN_START, MBX_OUT_START};
use drive_ethercat::{Segment, Slave};
use drive_protocol::od::ObjectDictionary;
use drive_protocol::{Clocks, Drive, DriveCommand, DriveInfo, Feedback, NodeConfig, Setpoint};
use libfuzzer_sys::fuzz_target;

const SLAVES: usize = 2;
const MBX: usize = 128;

#[derive(Clone, Default)]
struct Model {
    pos: f64,
}

fn info() -> DriveInfo {
    DriveInfo {
        encoder_increments_per_rev: 4096,
        gear_motor_revs: 3,
        gear_shaft_revs: 1,
        feed_user_units: 5000,
        feed_shaft_revs: 1,
        rated_torque_mnm: 1000,
        rated_current_ma: 1000,
        max_motor_speed_rpm: 6000,
        rotary: false,
    }
}

impl Drive for Model {
    fn info(&self) -> DriveInfo {
        info()
    }
    fn feedback(&self) -> Feedback {
        Feedback {
            motor_position_inc: self.pos as i64,
            direct_position_inc: self.pos as i64,
            ..Feedback::default()
        }
    }
    fn command(&mut self, c: &DriveCommand) {
        if let Setpoint::Position { position_inc, .. } = c.setpoint {
            if position_inc.is_finite() {
                self.pos += (position_inc - self.pos).clamp(-1e6, 1e6) * 0.5;
            }
        }
    }
    fn reset_fault(&mut self) -> bool {
        true
    }
}

#[derive(Clone)]
struct Line {
    seg: Segment,
    drives: Vec<Model>,
    now_ns: u64,
}

impl Line {
    fn new() -> Line {
        let mut drives = vec![Model::default(); SLAVES];
        let slaves = drives
            .iter_mut()
            .enumerate()
            .map(|(k, d)| {
                let mut cfg = NodeConfig::new(k as u8 + 1, info())
                    .with_od(ObjectDictionary::standard(&info()));
                cfg.lss = None;
                Slave::new(cfg, d).expect("the slave builds")
            })
            .collect();
        Line {
            seg: Segment::new(slaves),
            drives,
            now_ns: 0,
        }
    }

    fn cycle(&mut self) {
        self.now_ns = self.now_ns.saturating_add(1_000_000);
        let us = self.now_ns / 1000;
        self.seg.cycle(Clocks::same(us), &mut self.drives);
    }

    /// One datagram; the frame must come back.
    fn one(&mut self, cmd: u8, adp: u16, ado: u16, data: &[u8]) -> Returned {
        let addr = u32::from(adp) | u32::from(ado) << 16;
        let mut f = frame::build([0x01; 6], &[(cmd, 0, addr, data)]);
        self.now_ns = self.now_ns.saturating_add(10_000);
        self.seg
            .process(&mut f, self.now_ns, &mut self.drives)
            .expect("a well-formed frame comes back");
        frame::read_back(&f).expect("it reads back").remove(0)
    }

    /// Set the line up as a master does after a reset and read 0x1018:1 of each slave.
    fn still_answers(&mut self) {
        // every slave counts in a broadcast read
        assert_eq!(self.one(7, 0, 0x0000, &[0, 0]).wkc, SLAVES as u16);
        // what SOEM's config_init clears first: DL control, alias, FMMUs, sync managers
        for (ado, len) in [(0x0101u16, 1usize), (0x0012, 2), (0x0600, 48), (0x0800, 32)] {
            assert_eq!(self.one(8, 0, ado, &vec![0; len]).wkc, SLAVES as u16);
        }
        for k in 0..SLAVES as u16 {
            let st = 0x1001 + k;
            assert_eq!(
                self.one(2, 0u16.wrapping_sub(k), 0x0010, &st.to_le_bytes())
                    .wkc,
                1
            );
        }
        for k in 0..SLAVES {
            let st = 0x1001 + k as u16;
            // INIT (acknowledging any error), mailbox SMs from the defaults, PRE-OP
            assert_eq!(self.one(5, st, 0x0120, &[0x11, 0]).wkc, 1);
            let mut sm = Vec::new();
            sm.extend_from_slice(&MBX_OUT_START.to_le_bytes());
            sm.extend_from_slice(&(MBX as u16).to_le_bytes());
            sm.extend_from_slice(&[0x26, 0, 1, 0]);
            sm.extend_from_slice(&MBX_IN_START.to_le_bytes());
            sm.extend_from_slice(&(MBX as u16).to_le_bytes());
            sm.extend_from_slice(&[0x22, 0, 1, 0]);
            assert_eq!(self.one(5, st, 0x0800, &sm).wkc, 1);
            assert_eq!(self.one(5, st, 0x0120, &[0x12, 0]).wkc, 1);
            let al = self.one(4, st, 0x0130, &[0, 0]).data;
            assert_eq!(al[0] & 0x1F, 0x02, "slave {k}: PRE-OP, AL status {al:?}");
            // CoE SDO upload of 0x1018:1, counter 1
            let mut m = vec![0u8; MBX];
            m[0] = 10;
            m[5] = 0x03 | 1 << 4;
            m[6..16].copy_from_slice(&[0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]);
            assert_eq!(self.one(5, st, MBX_OUT_START, &m).wkc, 1, "mailbox write");
            let mut answer = None;
            for _ in 0..4 {
                let r = self.one(4, st, MBX_IN_START, &[0u8; MBX]);
                if r.wkc == 1 && r.data[5] & 0x0F == 0x03 && r.data[8] & 0xE0 == 0x40 {
                    answer = Some(r.data);
                    break;
                }
                self.cycle();
            }
            let a = answer.unwrap_or_else(|| panic!("slave {k}: no CoE answer to 0x1018:1"));
            let want = self.seg.slaves[k].node().object_raw(0x1018, 1).unwrap();
            assert_eq!(a[12..16], want.to_le_bytes(), "slave {k}: 0x1018:1");
        }
    }
}

thread_local! {
    /// The line as built, cloned for each input (building the dictionaries and the SII
    /// each time would cost most of the run).
    static TEMPLATE: Line = Line::new();
}

fuzz_target!(|data: &[u8]| {
    let mut line = TEMPLATE.with(Line::clone);
    let mut rest = data;
    let mut frames = 0;
    // chunks: [flags, len_lo, len_hi, bytes...]; flags bit 0: force an EtherCAT header,
    // bit 1: a drive cycle after the frame, bit 2: jump the clock
    while rest.len() >= 3 && frames < 64 {
        let flags = rest[0];
        let len = (usize::from(rest[1]) | usize::from(rest[2]) << 8) % 1600;
        rest = &rest[3..];
        let take = len.min(rest.len());
        let mut f = rest[..take].to_vec();
        rest = &rest[take..];
        if flags & 1 != 0 && f.len() >= 16 {
            f[12] = 0x88;
            f[13] = 0xA4;
            // the EtherCAT length: what follows the header, type 1
            let n = (f.len() - 16).min(0x7FF) as u16;
            let h = n | 0x1000;
            f[14..16].copy_from_slice(&h.to_le_bytes());
        }
        if flags & 4 != 0 {
            line.now_ns = line.now_ns.saturating_add(u64::from(flags) << 32);
        }
        let _ = line.seg.process(&mut f, line.now_ns, &mut line.drives);
        if flags & 2 != 0 {
            line.cycle();
        }
        frames += 1;
    }
    line.still_answers();
});
