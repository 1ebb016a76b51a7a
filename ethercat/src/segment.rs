//! Several slaves in line order, as on a cable: a frame passes each slave in turn (each
//! executes every datagram as it passes, counting auto-increment addresses up and adding to
//! the working counters), and the last one sends it back. The returned frame carries the
//! source-address bit an ESC sets, so a master can tell it from its own.

use drive_protocol::{Clocks, Drive};

use crate::frame::{Datagrams, FrameError, MAX_DATAGRAMS, SOURCE_MAC_RETURNED};
use crate::slave::Slave;

/// Slaves on one line.
#[derive(Clone, Debug, Default)]
pub struct Segment {
    /// In line order (the first is next to the master).
    pub slaves: Vec<Slave>,
    /// Frames refused as malformed.
    pub bad_frames: u64,
    /// Frames that carried process data (a logical datagram: LRD, LWR or LRW): the
    /// master's cycles, what a lock-step run advances the drives' time by.
    pub process_data_frames: u64,
}

impl Segment {
    /// A segment of these slaves.
    pub fn new(mut slaves: Vec<Slave>) -> Segment {
        let n = slaves.len();
        for (k, s) in slaves.iter_mut().enumerate() {
            s.set_line_ports(k + 1 < n);
        }
        Segment {
            slaves,
            bad_frames: 0,
            process_data_frames: 0,
        }
    }

    /// A frame corrupted on the wire before the first slave (a flipped bit: a bad frame check
    /// sequence): the first slave counts an invalid frame (0x0300), each slave after it a
    /// forwarded RX error (0x0308); the master's port drops it. Nothing else happens to it.
    pub fn frame_corrupted(&mut self) {
        for (k, s) in self.slaves.iter_mut().enumerate() {
            s.count_rx_error(k > 0);
        }
    }

    /// Pass `frame` (a whole Ethernet frame, processed in place) along the line at `now_ns`;
    /// `drives[k]` is the drive behind slave `k`. Ok: send the frame back. A malformed or
    /// non-EtherCAT frame is an error and is not returned (a real ESC drops a frame it
    /// cannot process); nothing panics and nothing is allocated.
    pub fn process<D: Drive>(
        &mut self,
        frame: &mut [u8],
        now_ns: u64,
        drives: &mut [D],
    ) -> Result<(), FrameError> {
        let d = match Datagrams::<MAX_DATAGRAMS>::parse(frame) {
            Ok(d) => d,
            Err(e) => {
                if !matches!(e, FrameError::NotEtherCat(_) | FrameError::TooShort) {
                    self.bad_frames += 1;
                }
                return Err(e);
            }
        };
        if d.list.iter().any(|g| matches!(g.cmd, 10..=12)) {
            self.process_data_frames += 1;
        }
        for (slave, drive) in self.slaves.iter_mut().zip(drives.iter_mut()) {
            for g in &d.list {
                slave.execute(frame, g, now_ns, drive);
            }
        }
        frame[6] |= SOURCE_MAC_RETURNED;
        Ok(())
    }

    /// One drive cycle of every slave.
    pub fn cycle<D: Drive>(&mut self, clocks: Clocks, drives: &mut [D]) {
        for (slave, drive) in self.slaves.iter_mut().zip(drives.iter_mut()) {
            slave.cycle(clocks, drive);
        }
    }
}
