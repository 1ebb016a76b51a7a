//! Drive supervision and the emulator's own objects as a master sees them over CANopen:
//! parameter writes that would make the axis unphysical are refused with the CiA 301 abort
//! codes, a runaway faults with the proper EMCY before any value becomes absurd, NMT reset node
//! gives back a usable axis; the parameter objects convert engineering units to SI, the loop
//! statistics are published read-only, an injected fault refuses its reset while it lasts,
//! and the objects move with their base.

use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::drive::{build_node, AxisParam, NodeOptions};
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::SimulatedDrive;
use drive_protocol::{CanFrame, Node};

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
        Bench::with_options(preset, &NodeOptions::new(NODE))
    }

    fn with_options(preset: &str, opts: &NodeOptions) -> Self {
        let mut drive = AxisDrive::from_config(&AxisConfig::from_preset(preset).unwrap()).unwrap();
        let mut node = build_node(&mut drive, opts).unwrap();
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

/// The parameter objects speak engineering units (mm, N/um, ms) and the drive SI; a value the
/// axis cannot take is refused with the abort code of its side, NaN as out of range, and a
/// refused value changes nothing. A rotary axis names and scales them in degrees.
#[test]
fn parameter_objects_convert_units_and_refuse_what_the_axis_cannot_take() {
    let mut b = Bench::new("cnc1");
    b.write_f32(0x2000, 0.05).unwrap();
    let si = b.drive.param(AxisParam::Backlash);
    assert!((si - 5e-5).abs() < 1e-9, "{si}");
    assert!((b.read_f32(0x2000) - 0.05).abs() < 1e-6);
    assert_eq!(
        b.write_f32(0x2000, 20.0),
        Err(ABORT_VALUE_HIGH),
        "over 10 mm"
    );
    assert_eq!(b.write_f32(0x2000, -1.0), Err(ABORT_VALUE_LOW));
    assert_eq!(b.write_f32(0x2000, f32::NAN), Err(0x0609_0030));
    assert!(
        (b.drive.param(AxisParam::Backlash) - 5e-5).abs() < 1e-9,
        "refused: unchanged"
    );
    b.write_f32(0x2009, 10.0).unwrap();
    assert!((b.drive.param(AxisParam::SpeedTi) - 0.01).abs() < 1e-9);
    b.write_f32(0x2001, 200.0).unwrap();
    assert!((b.drive.param(AxisParam::Stiffness) - 2e8).abs() < 1.0);
    let mut r = Bench::new("cnc3");
    r.write_f32(0x2000, 0.01).unwrap();
    let rad = r.drive.param(AxisParam::Backlash);
    assert!((rad - 0.01f64.to_radians()).abs() < 1e-9, "{rad}");
    let od = r.node.od();
    assert_eq!(od.get(0x2000, 0).unwrap().1.name, "backlash_deg");
}

/// The runtime's statistics reach the record at base + 0x100, read-only.
#[test]
fn loop_statistics_are_published_read_only() {
    use drive_emu::bus::inproc::InProcBus;
    use drive_emu::runtime::{AxisSlot, Runtime};
    let b = Bench::new("cnc1");
    let bus = InProcBus::endpoints(1, 64).pop().unwrap();
    let mut rt = Runtime::new(
        bus,
        vec![AxisSlot {
            node: b.node,
            drive: b.drive,
        }],
        1000,
    );
    rt.boot();
    for _ in 0..42 {
        rt.tick();
    }
    rt.stats.ticks = 42;
    rt.stats.sync_period_us = 1000;
    rt.publish_stats();
    let ax = &mut rt.axes[0];
    let (slot, _) = ax.node.od().get(0x2100, 1).unwrap();
    assert_eq!(ax.node.value(slot), Some(42));
    let (slot, _) = ax.node.od().get(0x2100, 10).unwrap();
    assert_eq!(ax.node.value(slot), Some(1000));
    let mut b = Bench::new("cnc1");
    assert_eq!(b.write(0x2100, 1, [0; 4], 4), Err(0x0601_0002));
}

/// A fault injected through 0x2101 stays while it is injected: the fault reset is refused
/// (the statusword stays FAULT, no EMCY 0000, no second 0x1003 entry), and accepted once 0 is
/// written.
#[test]
fn an_injected_fault_refuses_its_reset_while_it_lasts() {
    let mut b = Bench::new("cnc1");
    b.nmt(0x01);
    b.enable(8);
    b.write_u16(0x2101, 0x5441);
    b.ticks(20);
    assert!(is_fault(b.statusword()));
    assert_eq!(b.emcys, vec![0x5441]);
    let history = u8::from_le_bytes([b.read(0x1003, 0)[0]]);
    assert_eq!(history, 1);
    for _ in 0..3 {
        b.write_u16(0x6040, 0x00);
        b.ticks(2);
        b.write_u16(0x6040, 0x80);
        b.ticks(20);
        assert!(is_fault(b.statusword()), "reset refused while injected");
    }
    assert_eq!(b.emcys, vec![0x5441], "one fault, one EMCY");
    assert_eq!(
        u8::from_le_bytes([b.read(0x1003, 0)[0]]),
        1,
        "one history entry"
    );
    b.write_u16(0x2101, 0);
    b.write_u16(0x6040, 0x00);
    b.ticks(2);
    b.write_u16(0x6040, 0x80);
    b.ticks(5);
    assert!(!is_fault(b.statusword()), "accepted once the cause is gone");
    assert_eq!(b.emcys, vec![0x5441, 0x0000]);
}

/// The emulator's objects sit at another base when asked (a vendor's EDS has objects at
/// 0x2000): 0x3000 is the backlash, 0x2000 no object.
#[test]
fn the_emulators_objects_move_with_their_base() {
    let opts = NodeOptions {
        objects_base: Some(0x3000),
        ..NodeOptions::new(NODE)
    };
    let mut b = Bench::with_options("cnc1", &opts);
    b.write_f32(0x3000, 0.02).unwrap();
    assert!((b.drive.param(AxisParam::Backlash) - 2e-5).abs() < 1e-9);
    assert_eq!(b.write_f32(0x2000, 0.02), Err(0x0602_0000));
    assert_eq!(
        u16::from_le_bytes([b.read(0x3100, 0)[0], 0]),
        13,
        "statistics record"
    );
}
