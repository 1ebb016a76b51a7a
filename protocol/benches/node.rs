//! Cost of the hot paths: a SYNC that applies an RPDO and emits 4 TPDOs (plus the tick that
//! follows it), and an expedited SDO round trip; and of building a node (`Node::new` on the
//! standard dictionary, which `drive-emu analyze` and every drive pay once).
//!
//! cargo bench -p drive-protocol --bench node -- --warm-up-time 1 --measurement-time 3

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use drive_protocol::{CanFrame, Drive, DriveCommand, DriveInfo, Feedback, Node, NodeConfig};

const ID: u8 = 3;

#[derive(Default)]
struct Ideal {
    pos: f64,
}

impl Drive for Ideal {
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
        if let drive_protocol::Setpoint::Position { position_inc, .. } = c.setpoint {
            self.pos = position_inc;
        }
    }
    fn reset_fault(&mut self) -> bool {
        true
    }
}

fn info() -> DriveInfo {
    DriveInfo {
        encoder_increments_per_rev: 1 << 20,
        gear_motor_revs: 1,
        gear_shaft_revs: 1,
        feed_user_units: 10_000,
        feed_shaft_revs: 1,
        rated_torque_mnm: 5000,
        rated_current_ma: 8000,
        max_motor_speed_rpm: 3000,
        rotary: false,
    }
}

fn operational(drive: &mut Ideal) -> (Node, u64) {
    let mut n = Node::new(NodeConfig::new(ID, info())).unwrap();
    n.boot(0);
    let mut now = 0;
    let id = ID as u32;
    n.handle(&CanFrame::new(0, &[1, ID]), now, drive);
    n.handle(
        &CanFrame::new(0x600 + id, &[0x2F, 0x60, 0x60, 0, 8, 0, 0, 0]),
        now,
        drive,
    );
    // TPDO1 synchronous too, so every SYNC emits 4 TPDOs
    n.handle(
        &CanFrame::new(0x600 + id, &[0x2F, 0x00, 0x18, 2, 1, 0, 0, 0]),
        now,
        drive,
    );
    for cw in [0x06u8, 0x07, 0x0F] {
        n.handle(&CanFrame::new(0x200 + id, &[cw, 0]), now, drive);
        now += 1000;
        n.poll(now, drive);
    }
    while n.pop_tx().is_some() {}
    n.handle(&CanFrame::new(0x80, &[]), now, drive);
    let mut tpdos = 0;
    while let Some(f) = n.pop_tx() {
        tpdos += (0x180..0x500).contains(&(f.id & !0x7F)) as usize;
    }
    assert_eq!(tpdos, 4, "4 TPDOs per SYNC");
    (n, now)
}

fn bench(c: &mut Criterion) {
    let id = ID as u32;
    c.bench_function("Node::new (standard dictionary)", |b| {
        b.iter(|| black_box(Node::new(NodeConfig::new(ID, info())).unwrap()))
    });
    let mut drive = Ideal::default();
    let (mut node, mut now) = operational(&mut drive);
    let mut k = 0i32;
    c.bench_function("sync: apply RPDO + 4 TPDOs (handle SYNC, pop_tx)", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let t = k.to_le_bytes();
            node.handle(
                &CanFrame::new(0x300 + id, &[0x0F, 0, t[0], t[1], t[2], t[3]]),
                now,
                &mut drive,
            );
            node.handle(&CanFrame::new(0x80, &[]), now, &mut drive);
            let mut n = 0;
            while let Some(f) = node.pop_tx() {
                n += black_box(f).len as usize;
            }
            now += 1000;
            black_box(n)
        })
    });
    c.bench_function("sync + poll tick (CSP)", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let t = k.to_le_bytes();
            node.handle(
                &CanFrame::new(0x300 + id, &[0x0F, 0, t[0], t[1], t[2], t[3]]),
                now,
                &mut drive,
            );
            node.handle(&CanFrame::new(0x80, &[]), now, &mut drive);
            now += 1000;
            node.poll(now, &mut drive);
            let mut n = 0;
            while let Some(f) = node.pop_tx() {
                n += black_box(f).len as usize;
            }
            black_box(n)
        })
    });
    c.bench_function("expedited SDO round trip (read 0x6041)", |b| {
        b.iter(|| {
            node.handle(
                &CanFrame::new(0x600 + id, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]),
                now,
                &mut drive,
            );
            black_box(node.pop_tx())
        })
    });
    c.bench_function("expedited SDO round trip (write 0x6081)", |b| {
        b.iter(|| {
            node.handle(
                &CanFrame::new(0x600 + id, &[0x23, 0x81, 0x60, 0, 0x10, 0x27, 0, 0]),
                now,
                &mut drive,
            );
            black_box(node.pop_tx())
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
