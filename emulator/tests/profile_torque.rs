//! Profile torque mode (0x6060 = 4) on the simulated axes (the presets' mechanics, not a test
//! model): over a sweep of slopes 0x6087 and targets 0x6071, the torque demand 0x6074 rises at
//! the slope (measured from every tick's sample), the actual torque 0x6077 follows it, the
//! axis accelerates with the torque's sign, and halt brings the demand to 0 at the slope.

use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::drive::{build_node, NodeOptions};
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::SimulatedDrive;
use drive_protocol::{CanFrame, Node};

const NODE: u8 = 5;
const TICK_US: u64 = 1000;

struct Bench {
    node: Node,
    drive: AxisDrive,
    now: u64,
}

impl Bench {
    fn new(preset: &str) -> Self {
        let mut drive = AxisDrive::from_config(&AxisConfig::from_preset(preset).unwrap()).unwrap();
        let mut node = build_node(&mut drive, &NodeOptions::new(NODE)).unwrap();
        node.boot(0);
        let mut b = Bench {
            node,
            drive,
            now: 0,
        };
        b.tick();
        b
    }

    fn tick(&mut self) {
        self.node.poll(self.now, &mut self.drive);
        self.drive.advance(TICK_US);
        self.now += TICK_US;
        while self.node.pop_tx().is_some() {}
    }

    /// Expedited download, answered.
    fn write(&mut self, index: u16, value: i64, len: u8) {
        let b = value.to_le_bytes();
        let cs = 0x23 | ((4 - len) << 2);
        let [lo, hi] = index.to_le_bytes();
        let f = CanFrame::new(
            0x600 + u32::from(NODE),
            &[cs, lo, hi, 0, b[0], b[1], b[2], b[3]],
        );
        self.node.handle(&f, self.now, &mut self.drive);
        let mut answered = false;
        while let Some(r) = self.node.pop_tx() {
            if r.id == 0x580 + u32::from(NODE) {
                assert_eq!(r.data[0], 0x60, "write {index:#x} = {value}: {:x?}", r.data);
                answered = true;
            }
        }
        assert!(answered, "no answer to {index:#x}");
    }

    fn i16_of(&self, index: u16) -> i32 {
        self.node.object_raw(index, 0).unwrap() as u16 as i16 as i32
    }

    fn i32_of(&self, index: u16) -> i32 {
        self.node.object_raw(index, 0).unwrap() as i32
    }

    fn enable_pt(&mut self, slope_permille_per_s: u32) {
        self.write(0x6087, i64::from(slope_permille_per_s), 4);
        self.write(0x6060, 4, 1);
        self.node
            .handle(&CanFrame::new(0, &[0x01, NODE]), self.now, &mut self.drive);
        for cw in [0x06, 0x07, 0x0F] {
            self.write(0x6040, cw, 2);
            for _ in 0..5 {
                self.tick();
            }
        }
        assert_eq!(self.node.statusword() & 0x6F, 0x27, "OPERATION ENABLED");
        assert_eq!(self.node.mode(), 4, "0x6061 = PT");
    }
}

#[test]
fn the_demand_follows_the_slope_and_the_axis_the_torques_sign() {
    for preset in ["cnc1", "cnc3"] {
        for slope in [1_000u32, 5_000, 20_000] {
            for target in [100i32, -250] {
                let what = format!("{preset}, slope {slope}, target {target}");
                let mut b = Bench::new(preset);
                b.enable_pt(slope);
                let v0 = b.i32_of(0x606C);
                b.write(0x6071, i64::from(target), 2);
                // 0x6074 every tick until it is there
                let mut demand = Vec::new();
                for _ in 0..2_000 {
                    b.tick();
                    demand.push(b.i16_of(0x6074));
                    if *demand.last().unwrap() == target {
                        break;
                    }
                }
                assert_eq!(*demand.last().unwrap(), target, "{what}: {demand:?}");
                let ramp_s = demand.len() as f64 * TICK_US as f64 * 1e-6;
                let measured = f64::from(target.abs()) / ramp_s;
                assert!(
                    (measured - f64::from(slope)).abs() <= 0.05 * f64::from(slope),
                    "{what}: {measured:.0} per mille/s over {} ticks",
                    demand.len()
                );
                for w in demand.windows(2) {
                    let step = (w[1] - w[0]).abs() as f64;
                    assert!(
                        step <= f64::from(slope) * 1e-3 + 1.0,
                        "{what}: a jump of {step}: {demand:?}"
                    );
                    assert!(
                        (w[1] - w[0]) * target.signum() >= 0,
                        "{what}: not monotonic"
                    );
                }
                assert!(b.node.statusword() & 0x400 != 0, "{what}: target reached");
                for _ in 0..50 {
                    b.tick();
                }
                let t = b.i16_of(0x6077);
                assert!(
                    t.signum() == target.signum() && t.abs() >= target.abs() / 2,
                    "{what}: actual torque {t}"
                );
                let v = b.i32_of(0x606C);
                assert!(
                    (v - v0).signum() == target.signum(),
                    "{what}: velocity {v0} -> {v}"
                );
                // halt: the demand back to 0 at the slope
                b.write(0x6040, 0x10F, 2);
                let mut n = 0;
                while b.i16_of(0x6074) != 0 && n < 2_000 {
                    b.tick();
                    n += 1;
                }
                assert_eq!(b.i16_of(0x6074), 0, "{what}: halt");
                let want = (f64::from(target.abs()) / (f64::from(slope) * 1e-3)).ceil() as i32;
                assert!(
                    (n - want).abs() <= 1,
                    "{what}: halt took {n} ticks, the slope says {want}"
                );
            }
        }
    }
}
