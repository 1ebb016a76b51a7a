//! Offline runs: the reference master and the drives on an in-process bus, driven by a virtual
//! clock in lock-step. Every frame still goes through the real protocol stack on both sides;
//! only the wire and the wall clock are replaced. Same input, same output, as fast as the CPU
//! allows.
//!
//! [`OfflineRun`] is the one lock-step loop: the demo, the offline scenario runner (its drive
//! endpoint wrapped in a fault injector, [`OfflineRun::with_drive_bus`]) and the tests all step
//! it; none re-implements the tick.

use crate::bus::inproc::{InProcBus, InProcEndpoint};
use crate::bus::CanBus;
use crate::master::Master;
use crate::runtime::{AxisSlot, Runtime, SimulatedDrive};

/// Receive-queue depth of each in-process endpoint, frames.
const QUEUE_FRAMES: usize = 4096;

/// The master and the drives in lock-step. `B`: the drives' side of the bus (the in-process
/// endpoint itself, or a wrapper such as the fault injector).
pub struct OfflineRun<D, B = InProcEndpoint> {
    pub runtime: Runtime<B, D>,
    pub master: Master,
    master_bus: InProcEndpoint,
    /// Extra endpoint an observer (or a fault injector) may read, like candump on a wire.
    monitor: Option<InProcEndpoint>,
}

impl<D: SimulatedDrive> OfflineRun<D> {
    /// Master and drives on an in-process bus, with a monitor endpoint ([`Self::take_monitor`]).
    pub fn new(axes: Vec<AxisSlot<D>>, period_us: u64, master: Master) -> Self {
        let mut eps = InProcBus::endpoints(3, QUEUE_FRAMES);
        let monitor = eps.pop();
        let master_bus = eps.pop().expect("three endpoints");
        let drive_bus = eps.pop().expect("three endpoints");
        Self::assemble(drive_bus, master_bus, monitor, axes, period_us, master)
    }
}

impl<D: SimulatedDrive, B: CanBus> OfflineRun<D, B> {
    /// Master and drives on an in-process bus whose drive side is `wrap`ped (a fault injector),
    /// without a monitor endpoint.
    pub fn with_drive_bus(
        axes: Vec<AxisSlot<D>>,
        period_us: u64,
        master: Master,
        wrap: impl FnOnce(InProcEndpoint) -> B,
    ) -> Self {
        let mut eps = InProcBus::endpoints(2, QUEUE_FRAMES);
        let master_bus = eps.pop().expect("two endpoints");
        let drive_bus = wrap(eps.pop().expect("two endpoints"));
        Self::assemble(drive_bus, master_bus, None, axes, period_us, master)
    }

    fn assemble(
        drive_bus: B,
        master_bus: InProcEndpoint,
        monitor: Option<InProcEndpoint>,
        axes: Vec<AxisSlot<D>>,
        period_us: u64,
        master: Master,
    ) -> Self {
        let mut runtime = Runtime::new(drive_bus, axes, period_us);
        runtime.boot();
        Self {
            runtime,
            master,
            master_bus,
            monitor,
        }
    }

    pub fn now_us(&self) -> u64 {
        self.runtime.sim_time_us
    }

    /// Take the monitor endpoint (every frame on the bus, in order).
    pub fn take_monitor(&mut self) -> Option<InProcEndpoint> {
        self.monitor.take()
    }

    /// One tick: the master acts, the drives act, the master hears the answers.
    pub fn step(&mut self) {
        self.master_send();
        self.runtime.tick();
        self.master_receive();
    }

    /// The master's half of a tick before the drives run: it acts and puts its frames on the bus.
    pub fn master_send(&mut self) {
        self.master.poll(self.runtime.sim_time_us);
        while let Some(f) = self.master.pop_tx() {
            // The in-process bus never refuses a send.
            let _ = self.master_bus.send(&f);
        }
    }

    /// The master's half of a tick after the drives ran: it hears their answers.
    pub fn master_receive(&mut self) {
        while let Ok(Some(f)) = self.master_bus.recv() {
            self.master.handle(&f, self.runtime.sim_time_us);
        }
    }

    /// Put a frame on the bus as if another peer had sent it.
    pub fn inject(&mut self, frame: &crate::bus::CanFrame) {
        let _ = self.master_bus.send(frame);
    }

    /// Run until the master's program is finished (or failed), or `limit_us` of simulated time.
    pub fn run_program(&mut self, limit_us: u64) {
        while !self.master.finished() && self.runtime.sim_time_us < limit_us {
            self.step();
        }
    }

    /// Run for `duration_us` of simulated time.
    pub fn run_for(&mut self, duration_us: u64) {
        let end = self.runtime.sim_time_us + duration_us;
        while self.runtime.sim_time_us < end {
            self.step();
        }
    }
}
