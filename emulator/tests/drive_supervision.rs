//! Drive supervision as a master sees it over CANopen: parameter writes that would make the
//! axis unphysical are refused with the CiA 301 abort codes, a runaway faults with the proper
//! EMCY before any value becomes absurd, and NMT reset node gives back a usable axis.

use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::SimulatedDrive;
use drive_protocol::{CanFrame, Drive, Node};

const NODE: u8 = 5;
const ABORT_VALUE_HIGH: u32 = 0x0609_0031;
const ABORT_VALUE_LOW: u32 = 0x0609_0032;

struct Bench {
    node: Node,
    drive: AxisDrive,
    now: u64,
    emcys: Vec<u16>,
    bootups: usize,
    sdo_reply: Option<CanFrame>,
}

impl Bench {
    fn new(preset: &str) -> Self {
        let drive = AxisDrive::from_config(&AxisConfig::from_preset(preset).unwrap()).unwrap();
        let mut node = Node::new(NODE, drive.info()).unwrap();
        node.boot(0);
        let mut b = Bench {
            node,
            drive,
            now: 0,
            emcys: Vec::new(),
            bootups: 0,
            sdo_reply: None,
        };
        b.tick();
        b
    }

    fn drain(&mut self) {
        while let Some(f) = self.node.pop_tx() {
            let id = f.id;
            if id == 0x80 + u32::from(NODE) {
                self.emcys.push(u16::from_le_bytes([f.data[0], f.data[1]]));
            } else if id == 0x700 + u32::from(NODE) && f.data[0] == 0 {
                self.bootups += 1;
            } else if id == 0x580 + u32::from(NODE) {
                self.sdo_reply = Some(f);
            }
        }
    }

    fn send(&mut self, f: CanFrame) {
        self.node.handle(&f, self.now, &mut self.drive);
        self.drain();
    }

    fn tick(&mut self) {
        self.node.poll(self.now, &mut self.drive);
        self.drive.advance(1000);
        self.now += 1000;
        self.drain();
    }

    fn ticks(&mut self, n: u32) {
        for _ in 0..n {
            self.tick();
        }
    }

    /// Expedited download; the abort code if refused.
    fn write(&mut self, index: u16, sub: u8, data: [u8; 4], len: u8) -> Result<(), u32> {
        let cs = 0x23 | ((4 - len) << 2);
        let [lo, hi] = index.to_le_bytes();
        let f = CanFrame::new(
            0x600 + u32::from(NODE),
            &[cs, lo, hi, sub, data[0], data[1], data[2], data[3]],
        );
        self.sdo_reply = None;
        self.send(f);
        self.tick();
        let r = self.sdo_reply.take().expect("no SDO answer");
        match r.data[0] {
            0x60 => Ok(()),
            0x80 => Err(u32::from_le_bytes(r.data[4..8].try_into().unwrap())),
            c => panic!("unexpected SDO answer {c:#x}"),
        }
    }

    fn write_f32(&mut self, index: u16, v: f32) -> Result<(), u32> {
        self.write(index, 0, v.to_le_bytes(), 4)
    }

    fn write_u16(&mut self, index: u16, v: u16) {
        let b = v.to_le_bytes();
        self.write(index, 0, [b[0], b[1], 0, 0], 2)
            .unwrap_or_else(|a| panic!("write {index:#x} = {v}: abort {a:#x}"));
    }

    fn write_i32(&mut self, index: u16, v: i32) {
        self.write(index, 0, v.to_le_bytes(), 4)
            .unwrap_or_else(|a| panic!("write {index:#x} = {v}: abort {a:#x}"));
    }

    fn write_i8(&mut self, index: u16, v: i8) {
        self.write(index, 0, [v as u8, 0, 0, 0], 1)
            .unwrap_or_else(|a| panic!("write {index:#x} = {v}: abort {a:#x}"));
    }

    fn read(&mut self, index: u16, sub: u8) -> [u8; 4] {
        let [lo, hi] = index.to_le_bytes();
        self.sdo_reply = None;
        self.send(CanFrame::new(
            0x600 + u32::from(NODE),
            &[0x40, lo, hi, sub, 0, 0, 0, 0],
        ));
        self.tick();
        let r = self.sdo_reply.take().expect("no SDO answer");
        assert_eq!(r.data[0] & 0xF0, 0x40, "read {index:#x}: {:?}", r.data);
        r.data[4..8].try_into().unwrap()
    }

    fn read_i32(&mut self, index: u16) -> i32 {
        i32::from_le_bytes(self.read(index, 0))
    }

    fn read_f32(&mut self, index: u16) -> f32 {
        f32::from_le_bytes(self.read(index, 0))
    }

    fn statusword(&mut self) -> u16 {
        let b = self.read(0x6041, 0);
        u16::from_le_bytes([b[0], b[1]])
    }

    fn nmt(&mut self, cs: u8) {
        self.send(CanFrame::new(0, &[cs, NODE]));
        self.tick();
    }

    /// Through the CiA 402 state machine to OPERATION ENABLED in `mode`.
    fn enable(&mut self, mode: i8) {
        self.write_i8(0x6060, mode);
        for cw in [0x80, 0x06, 0x07, 0x0F] {
            self.write_u16(0x6040, cw);
            self.ticks(5);
        }
        assert_eq!(self.statusword() & 0x6F, 0x27, "not OPERATION ENABLED");
    }
}

fn is_fault(sw: u16) -> bool {
    sw & 0x4F == 0x08
}

#[test]
fn unphysical_axis_parameters_are_refused_with_value_too_low_or_too_high() {
    let mut b = Bench::new("cnc1");
    let k = b.read_f32(0x2001);
    let c = b.read_f32(0x2002);
    assert_eq!(b.write_f32(0x2002, 0.0), Err(ABORT_VALUE_LOW), "damping 0");
    assert_eq!(
        b.write_f32(0x2001, 1e-30),
        Err(ABORT_VALUE_LOW),
        "stiffness 1e-30 N/um"
    );
    assert_eq!(
        b.write_f32(0x2001, 1e9),
        Err(ABORT_VALUE_HIGH),
        "too stiff for the step"
    );
    assert_eq!(
        b.write_f32(0x2006, 1e7),
        Err(ABORT_VALUE_HIGH),
        "load 1e7 N"
    );
    assert_eq!(
        b.write_f32(0x2006, -1e7),
        Err(ABORT_VALUE_LOW),
        "load -1e7 N"
    );
    assert_eq!(
        b.write_f32(0x2003, -1.0),
        Err(ABORT_VALUE_LOW),
        "negative friction"
    );
    assert_eq!(
        b.write_f32(0x2005, -1.0),
        Err(ABORT_VALUE_LOW),
        "negative friction"
    );
    assert_eq!(b.read_f32(0x2001), k, "refused writes change nothing");
    assert_eq!(b.read_f32(0x2002), c);
    assert_eq!(b.read_f32(0x2006), 0.0);
    // In range: accepted.
    b.write_f32(0x2006, 1e4).unwrap();
    b.write_f32(0x2002, c * 0.5).unwrap();
}

#[test]
fn the_issue_sequence_faults_on_overspeed_and_reset_node_gives_a_usable_axis() {
    // Damping 0 and stiffness 1e-30 refused; a 10 kN load on the unheld axis for 5 s; the
    // stiffness written back; then NMT reset node, enable, a PP move.
    let mut b = Bench::new("cnc1");
    let k = b.read_f32(0x2001);
    assert!(b.write_f32(0x2002, 0.0).is_err());
    assert!(b.write_f32(0x2001, 1e-30).is_err());
    b.write_f32(0x2006, 1e4).unwrap();
    b.ticks(5000);
    assert_eq!(
        b.emcys.first(),
        Some(&0x8400),
        "EMCY overspeed: {:x?}",
        b.emcys
    );
    assert!(is_fault(b.statusword()), "FAULT");
    assert_eq!(b.read(0x603F, 0)[..2], 0x8400u16.to_le_bytes());
    // Nothing runs away: speed at rest, position where it stopped.
    let v = b.read_i32(0x606C);
    assert!(v.abs() < 10, "0x606C = {v} while in FAULT");
    let p = b.read_i32(0x6064);
    assert!(p.abs() < 10_000_000, "0x6064 = {p} um");
    b.write_f32(0x2001, k).unwrap();

    let boots = b.bootups;
    b.nmt(0x81);
    assert_eq!(b.bootups, boots + 1, "boot-up after reset node");
    assert_eq!(b.read_f32(0x2006), 0.0, "load back to the preset's");
    assert_eq!(b.read(0x603F, 0)[..2], [0, 0]);
    assert!(!is_fault(b.statusword()));
    b.nmt(0x01);
    b.enable(1);
    let start = b.read_i32(0x6064);
    b.write_i32(0x607A, start + 2000); // 2 mm
    b.write_u16(0x6040, 0x1F);
    b.ticks(3000);
    let end = b.read_i32(0x6064);
    assert!(
        (end - (start + 2000)).abs() <= 60,
        "moved to {end}, wanted {}",
        start + 2000
    );
    assert_eq!(b.emcys, vec![0x8400], "no further EMCY");
}

#[test]
fn cst_at_full_torque_for_100_s_faults_on_overspeed() {
    for preset in ["cnc1", "cnc3"] {
        let mut b = Bench::new(preset);
        b.nmt(0x01);
        b.enable(10);
        b.write_u16(0x6072, 3000);
        b.write_u16(0x6071, 3000);
        b.ticks(100_000);
        assert_eq!(b.emcys.first(), Some(&0x8400), "{preset}: {:x?}", b.emcys);
        assert!(is_fault(b.statusword()), "{preset}");
        let v = b.read_i32(0x606C);
        assert!(v.abs() < 10, "{preset}: 0x606C = {v} in FAULT");
        // Fault reset: usable again, at rest.
        b.write_u16(0x6040, 0x80);
        b.ticks(5);
        assert!(!is_fault(b.statusword()), "{preset}: fault reset");
    }
}
