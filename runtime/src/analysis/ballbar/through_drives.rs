//! The ballbar's two axes (and a line contour's two or three, [`super::line`]) as a CNC drives
//! them: each axis a drive (the CANopen node and the
//! simulated axis behind it, as `drive-emu run` serves one) on an in-process bus in lock-step,
//! the master sending one target position per SYNC in the drive's user units (integers, as
//! on the wire) in cyclic synchronous position mode. The drive's CSP path is therefore the
//! one a bus master meets: its interpolation of the target over the SYNC period, the
//! target's slope as velocity feed-forward, and the set-point's rounding to user units.
//!
//! The master's sequence is the one of `tests/python/ballbar_master.py` (a master on a real
//! bus): NMT start, 0x60C2 the SYNC period, 0x6060 = 8, then per SYNC both set-points (RPDO2:
//! controlword and 0x607A) and the SYNC; shutdown, switch on and enable operation 50 SYNCs
//! each at the start point; the circle; 20 SYNCs at its end. The axes stand at the circle's
//! start point, so the circle's centre in drive coordinates is minus that point.

use std::sync::atomic::{AtomicBool, Ordering};

use crate::bus::inproc::{InProcBus, InProcEndpoint};
use crate::bus::{CanBus, CanFrame};
use crate::drive::axis_drive::AxisDrive;
use crate::runtime::{AxisSlot, Runtime};
use drive_protocol::wire::cob;
use drive_protocol::wire::sdo::{Initiate, Mux, SdoRequest};

/// Node-IDs of the drives on the in-process bus, in axis order (X, Y, Z).
pub const NODES: [u8; 3] = [1, 2, 3];
/// SYNCs at each step of the enable sequence (shutdown, switch on, enable operation).
const ENABLE_SYNCS: usize = 50;
/// SYNCs after the circle's end, the axes at rest.
pub const TAIL_SYNCS: usize = 20;

/// `N` drives (1..=3) on an in-process bus, stepped one SYNC at a time.
pub struct Drives<const N: usize> {
    rt: Runtime<InProcEndpoint, AxisDrive>,
    master: InProcEndpoint,
    period_us: u64,
    /// Drive coordinates of the program's origin (the circle's centre), user units per axis
    /// (from where they stand).
    origin_uu: [f64; N],
    /// Metres per user unit, per axis.
    user_unit_m: [f64; N],
    syncs: u64,
}

/// The ballbar's two drives.
pub type DrivePair = Drives<2>;

/// An expedited SDO download request, as a master sends it.
fn sdo_write(node: u8, index: u16, sub: u8, value: &[u8]) -> CanFrame {
    let req = SdoRequest::InitiateDownload {
        mux: Mux::new(index, sub),
        data: Initiate::expedited(value),
    };
    CanFrame::new(cob::SDO_RX + u32::from(node), &req.emit())
}

impl<const N: usize> Drives<N> {
    /// Build, boot and configure the drives (CSP, the SYNC period `period_us`); the axes
    /// stand at `start_m` (X, Y, ...), the program's start point relative to its origin (the
    /// circle's start point relative to its centre).
    pub fn new(drives: [AxisDrive; N], period_us: u64, start_m: [f64; N]) -> anyhow::Result<Self> {
        anyhow::ensure!(period_us > 0, "the SYNC period must be positive");
        anyhow::ensure!(
            (1..=NODES.len()).contains(&N),
            "{N} axes: the in-process bus serves 1 to {} drives",
            NODES.len()
        );
        let mut slots = Vec::with_capacity(N);
        let mut user_unit_m = [0.0; N];
        for (k, mut drive) in drives.into_iter().enumerate() {
            user_unit_m[k] = drive.user_unit;
            let node = crate::drive::node(&mut drive, NODES[k])?;
            slots.push(AxisSlot { node, drive });
        }
        let mut eps = InProcBus::endpoints(2, 1 << 12);
        let master = eps.pop().expect("two endpoints");
        let mut rt = Runtime::new(eps.pop().expect("two endpoints"), slots, period_us);
        rt.boot();
        let mut pair = Drives::<N> {
            rt,
            master,
            period_us,
            origin_uu: std::array::from_fn(|k| -start_m[k] / user_unit_m[k]),
            user_unit_m,
            syncs: 0,
        };
        let (period_value, exponent) = if period_us.is_multiple_of(1000) && period_us / 1000 <= 255
        {
            ((period_us / 1000) as u8, -3i8)
        } else {
            anyhow::ensure!(
                period_us <= 255,
                "a SYNC period of {period_us} us is neither whole ms up to 255 nor up to 255 us \
                 (0x60C2 holds one byte)"
            );
            (period_us as u8, -6i8)
        };
        let mut setup = Vec::new();
        for &node in &NODES[..N] {
            setup.push(sdo_write(node, 0x60C2, 1, &[period_value]));
            setup.push(sdo_write(node, 0x60C2, 2, &exponent.to_le_bytes()));
            setup.push(sdo_write(node, 0x6060, 0, &[8]));
        }
        setup.push(CanFrame::new(0x000, &[0x01, 0])); // NMT start, all nodes
        pair.send_all(&setup)?;
        for control in [0x06u16, 0x07, 0x0F] {
            for _ in 0..ENABLE_SYNCS {
                pair.cycle(control, start_m)?;
            }
        }
        let sw: Vec<u16> = pair.rt.axes.iter().map(|a| a.node.statusword()).collect();
        anyhow::ensure!(
            sw.iter().all(|s| s & 0x6F == 0x27),
            "the drives did not reach operation enabled (statusword {sw:04X?})"
        );
        Ok(pair)
    }

    fn send_all(&mut self, frames: &[CanFrame]) -> anyhow::Result<()> {
        for f in frames {
            self.master
                .send(f)
                .map_err(|e| anyhow::anyhow!("in-process bus: {e:?}"))?;
        }
        Ok(())
    }

    /// One SYNC period: every axis's set-point (`xy_m` relative to the origin), the SYNC, the
    /// drives' tick(s); what the drives sent is dropped.
    pub fn cycle(&mut self, control: u16, xy_m: [f64; N]) -> anyhow::Result<()> {
        let mut frames = [CanFrame::new(0x080, &[]); 4];
        for k in 0..N {
            let uu = (self.origin_uu[k] + xy_m[k] / self.user_unit_m[k]).round();
            anyhow::ensure!(
                uu.abs() < f64::from(i32::MAX),
                "a set-point of {uu} user units is outside 0x607A's range"
            );
            let mut d = [0u8; 6];
            d[..2].copy_from_slice(&control.to_le_bytes());
            d[2..].copy_from_slice(&(uu as i32).to_le_bytes());
            frames[k] = CanFrame::new(0x300 + u32::from(NODES[k]), &d);
        }
        // the set-points, then the SYNC
        frames[N] = CanFrame::new(0x080, &[]);
        self.send_all(&frames[..=N])?;
        self.syncs += 1;
        let end_us = self.syncs * self.period_us;
        let stop = AtomicBool::new(false);
        self.rt.run_lockstep(self.period_us, &stop, |rt| {
            if rt.sim_time_us >= end_us {
                stop.store(true, Ordering::Relaxed);
            }
        });
        while let Ok(Some(_)) = self.master.recv() {}
        Ok(())
    }

    /// The axes' direct encoders, m, relative to the origin (the circle's centre).
    pub fn direct_m(&self) -> [f64; N] {
        self.relative(|d| d.servo.direct_encoder_position())
    }

    /// The axes' motor encoders at the load, m, relative to the origin (the circle's centre).
    pub fn motor_m(&self) -> [f64; N] {
        self.relative(|d| d.servo.motor_encoder_position())
    }

    /// A position of each axis (m, drive coordinates) relative to the origin.
    fn relative(&self, position_m: impl Fn(&AxisDrive) -> f64) -> [f64; N] {
        std::array::from_fn(|k| {
            position_m(&self.rt.axes[k].drive) - self.origin_uu[k] * self.user_unit_m[k]
        })
    }

    /// The drives' statuswords (fault bit 3).
    pub fn statuswords(&self) -> [u16; N] {
        std::array::from_fn(|k| self.rt.axes[k].node.statusword())
    }
}
