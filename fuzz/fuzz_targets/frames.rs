//! Any byte string becomes a sequence of frames and time steps (forward, back, and to the end
//! of the u64 clock range); the node must never panic, must keep the `Node::poll_at` contract
//! after every poll (`None` or later than the poll's `now`), and must answer a valid SDO
//! afterwards (given back its node-ID by LSS if the frames changed it).
//!
//! Each input is at most [`MAX_STEPS`] steps (13 bytes each; the rest of a longer input is
//! not read), so that an input costs a bounded time and 10^6 inputs run in minutes, not
//! hours: the checks are the same for every prefix. The node is built once (Node::new
//! resolves 2 x 512 PDO numbers in the dictionary, 6 ms an input here) and each input starts
//! from a clone of it, as fresh as a new one: Node::new is deterministic and a Node holds no
//! shared state.
//!
//! Run: cargo fuzz run --sanitizer none --debug-assertions frames (stable; ./test-all.sh
//! runs it for FUZZ_SECONDS), or cargo +nightly fuzz run frames (AddressSanitizer).
#![no_main]

use drive_protocol::od::{Access, DataType, DefaultValue, Entry, ObjectDictionary};
use drive_protocol::{
    CanFrame, Drive, DriveCommand, DriveInfo, Feedback, FrameEvent, Node, NodeConfig, Setpoint,
};
use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

const ID: u8 = 4;

/// Most steps (frame, clock move, poll) one input drives: 96 x 13 = 1248 bytes.
const MAX_STEPS: usize = 96;

#[derive(Default)]
struct Model {
    pos: f64,
    vel: f64,
    fault: Option<u16>,
}

impl Drive for Model {
    fn info(&self) -> DriveInfo {
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
    fn feedback(&self) -> Feedback {
        Feedback {
            motor_position_inc: self.pos as i64,
            direct_position_inc: self.pos as i64,
            motor_velocity_inc_per_s: self.vel,
            drive_fault: self.fault,
            ..Feedback::default()
        }
    }
    fn command(&mut self, c: &DriveCommand) {
        match c.setpoint {
            Setpoint::Position { position_inc, .. } if position_inc.is_finite() => {
                self.vel = (position_inc - self.pos) * 1000.0;
                self.pos = position_inc;
            }
            Setpoint::Velocity {
                velocity_inc_per_s, ..
            } if velocity_inc_per_s.is_finite() => {
                self.vel = velocity_inc_per_s;
                self.pos += velocity_inc_per_s * 1e-3;
            }
            _ => self.vel = 0.0,
        }
        self.pos = self.pos.clamp(-1e15, 1e15);
    }
    fn read_object(&mut self, _: u16, _: u16, _: u8, out: &mut [u8]) -> Result<usize, u32> {
        out[..4].copy_from_slice(&1.0f32.to_le_bytes());
        Ok(4)
    }
    fn write_object(&mut self, _: u16, _: u16, _: u8, data: &[u8]) -> Result<(), u32> {
        let v = f32::from_le_bytes(data.try_into().map_err(|_| 0x0607_0010u32)?);
        if v.abs() > 1e6 {
            Err(0x0609_0030)
        } else {
            Ok(())
        }
    }
    fn reset_fault(&mut self) -> bool {
        self.fault = None;
        true
    }
}

/// The standard objects plus one of each kind a vendor dictionary brings: a handler REAL32,
/// a string with room to grow, a 64-bit and a 24-bit integer (mappable), a DOMAIN.
fn dictionary(info: &DriveInfo) -> ObjectDictionary {
    let mut od = ObjectDictionary::standard(info);
    let entries = [
        Entry::var(0x2000, "param", DataType::Real32, Access::Rw).with_handler(1),
        Entry::var(0x2001, "name", DataType::VisibleString, Access::Rw)
            .with_default(DefaultValue::Bytes(b"axis".to_vec()))
            .with_capacity(200),
        Entry::var(0x2002, "counter", DataType::U64, Access::Rw).with_pdo(true),
        Entry::var(0x2003, "small", DataType::I24, Access::Rw)
            .with_pdo(true)
            .with_limits(Some(-1000), Some(1000)),
        Entry::var(0x2004, "blob", DataType::Domain, Access::Rw).with_capacity(1024),
    ];
    for e in entries {
        od.insert(e).expect("a fresh index");
    }
    od
}

/// Poll, then check the `Node::poll_at` contract: no deadline, or one after `now`.
fn poll(node: &mut Node, now: u64, drive: &mut Model) {
    node.poll(now, drive);
    if let Some(at) = node.poll_at() {
        assert!(
            at > now,
            "poll_at() = {at} <= now = {now} right after poll(now)"
        );
    }
}

/// The node before boot, built once.
fn fresh_node() -> Node {
    static NODE: OnceLock<Node> = OnceLock::new();
    NODE.get_or_init(|| {
        let info = Model::default().info();
        let cfg = NodeConfig::new(ID, info).with_od(dictionary(&info));
        Node::new(cfg).unwrap()
    })
    .clone()
}

fuzz_target!(|data: &[u8]| {
    let mut node = fresh_node();
    let mut drive = Model::default();
    let mut now = 0u64;
    // The latest time the node has seen: an SDO transfer's time-out runs from its last frame,
    // which a clock moved back afterwards does not undo.
    let mut latest = now;
    node.boot(now);
    // 13 bytes per step: id (2), flags (1), dlc (1), data (8), dt (1). Flags: 0x80 fold the
    // ID onto this node, 0x01 extended, 0x02 RTR, 0x04 drive fault, 0x08 poll after the
    // frame (0x40: the communication timers alone, poll_comm), 0x10 the clock jumps to
    // dt x 50 ms before u64::MAX, 0x20 it goes back dt x 10 ms.
    for chunk in data.chunks_exact(13).take(MAX_STEPS) {
        let raw_id = u16::from_le_bytes([chunk[0], chunk[1]]) as u32;
        // fold IDs onto this node's channels half of the time
        let id = if chunk[2] & 0x80 != 0 {
            (raw_id & 0x780) | ID as u32
        } else {
            raw_id & 0x7FF
        };
        let f = CanFrame {
            id,
            extended: chunk[2] & 0x01 != 0,
            rtr: chunk[2] & 0x02 != 0,
            len: chunk[3] % 9,
            data: chunk[4..12].try_into().unwrap(),
        };
        if chunk[2] & 0x04 != 0 {
            drive.fault = Some(0x7300);
        }
        let dt = chunk[12] as u64;
        now = if chunk[2] & 0x10 != 0 {
            u64::MAX - dt * 50_000
        } else if chunk[2] & 0x20 != 0 {
            now.saturating_sub(dt * 10_000)
        } else {
            now.saturating_add(dt * 200)
        };
        latest = latest.max(now);
        let _ = node.handle(&f, now, &mut drive);
        if chunk[2] & 0x08 != 0 {
            if chunk[2] & 0x40 != 0 {
                node.poll_comm(now, &mut drive);
                if let Some(at) = node.poll_at_comm() {
                    assert!(at > now, "poll_at_comm() = {at} <= {now} after poll_comm");
                }
            } else {
                poll(&mut node, now, &mut drive);
            }
        }
        while node.pop_tx().is_some() {}
    }
    // LSS (0x7E5) may have given the node another node-ID or none: the master gives it back
    // by LSS and resets its communication.
    if node.node_id() != ID {
        for d in [
            [0x04, 1, 0, 0, 0, 0, 0, 0],
            [0x11, ID, 0, 0, 0, 0, 0, 0],
            [0x04, 0, 0, 0, 0, 0, 0, 0],
        ] {
            node.handle(&CanFrame::new(0x7E5, &d), now, &mut drive);
        }
        node.handle(&CanFrame::new(0, &[0x82, 0]), now, &mut drive);
        poll(&mut node, now, &mut drive);
        assert_eq!(node.node_id(), ID, "node-ID given back by LSS");
    }
    node.handle(&CanFrame::new(0, &[0x80, ID]), now, &mut drive);
    // 2 s after the latest time seen (not after `now`, which may have gone back: a transfer
    // begun later would still be running, and take the SDO below as one of its segments).
    let end_of_range = latest > u64::MAX - 4_000_000;
    now = latest.saturating_add(2_000_000);
    poll(&mut node, now, &mut drive);
    if end_of_range {
        // A stalled SDO transfer is not aborted by a timeout that would end beyond u64::MAX
        // (Node::poll_at): the client aborts it.
        node.handle(
            &CanFrame::new(0x600 + ID as u32, &[0x80, 0, 0, 0, 0, 0, 0, 0x08]),
            now,
            &mut drive,
        );
    }
    while node.pop_tx().is_some() {}
    let ev = node.handle(
        &CanFrame::new(0x600 + ID as u32, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]),
        now,
        &mut drive,
    );
    assert_eq!(ev, FrameEvent::Handled);
    let mut answered = false;
    while let Some(f) = node.pop_tx() {
        if f.id == 0x580 + ID as u32 && f.data[0] == 0x43 {
            answered = true;
        }
    }
    assert!(answered, "SDO answered after the fuzz sequence");
});
