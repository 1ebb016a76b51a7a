//! The runtime's transmit path: frames go to the bus in batches (one `sendmmsg` each on
//! SocketCAN); a batch the bus takes only in part, or refuses as full, loses no frame and
//! keeps the order.

use drive_emu::bus::inproc::{InProcBus, InProcEndpoint};
use drive_emu::bus::{CanBus, CanFrame, RecvError, SendError};
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::{AxisSlot, Runtime};

/// A bus that takes at most 5 frames per batch and refuses every third batch as full.
struct Grudging {
    inner: InProcEndpoint,
    calls: u32,
}

impl CanBus for Grudging {
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        self.inner.send(frame)
    }
    fn send_batch(&mut self, frames: &[CanFrame]) -> (usize, Option<SendError>) {
        self.calls += 1;
        if self.calls.is_multiple_of(3) {
            return (0, Some(SendError::Full));
        }
        let n = frames.len().min(5);
        for f in &frames[..n] {
            self.inner.send(f).expect("in-process bus has room");
        }
        (n, None)
    }
    fn recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        self.inner.recv()
    }
    fn wait_readable(&mut self, _timeout_us: u64) {}
}

/// 100 axes boot at once: flush_tx hands their boot-ups over in batches, waits out the
/// refusals (counted) and loses none; they arrive in node order.
#[test]
fn flush_sends_every_frame_in_order_across_partial_and_refused_batches() {
    let cfg = AxisConfig::from_preset("cnc1").unwrap();
    let axes = (1..=100u8)
        .map(|id| {
            let mut drive = AxisDrive::from_config(&cfg).unwrap();
            let node = drive_emu::drive::node(&mut drive, id).unwrap();
            AxisSlot { node, drive }
        })
        .collect();
    let mut eps = InProcBus::endpoints(2, 1024);
    let mut master = eps.pop().unwrap();
    let bus = Grudging {
        inner: eps.pop().unwrap(),
        calls: 0,
    };
    let mut rt = Runtime::new(bus, axes, 1000);
    rt.boot();
    rt.finish_boots();
    let mut ids = Vec::new();
    while let Ok(Some(f)) = master.recv() {
        ids.push(f.id);
    }
    let want: Vec<u32> = (1..=100).map(|n| 0x700 + n).collect();
    assert_eq!(ids, want);
    assert_eq!(rt.stats.tx_dropped, 0);
    assert!(rt.stats.tx_full_waits >= 6, "{}", rt.stats.tx_full_waits);
}
