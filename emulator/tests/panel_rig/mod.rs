//! A drive with the live panel, on an in-process bus, for the host tests of the panel: the
//! reference master moves axis 0, the loop runs in a thread of its own at about the wall
//! clock's pace (a tick, then a sleep of one period), the panel's loop half is called after
//! every tick as in `drive-emu run --panel`, and a third endpoint of the bus is an SDO client
//! (`Rig::sdo_read`), as a master's tool would read the drive.
#![allow(dead_code)]

use drive_emu::bus::fault::FaultyBus;
use drive_emu::bus::inproc::{InProcBus, InProcEndpoint};
use drive_emu::bus::{CanBus, CanFrame};
use drive_emu::cli::demo_panel::tick_with_master;
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::master::{Master, MasterConfig, Step};
use drive_emu::panel::{self, Panel, PanelAxis, PanelLoop, PanelSetup};
use drive_emu::presets::AxisConfig;
use drive_emu::runtime::{AxisSlot, Runtime};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;
use std::time::Duration;

pub const NODE: u8 = 5;

enum Cmd {
    SdoRead(u16, u8, mpsc::Sender<Option<(u32, u64)>>),
}

pub struct Rig {
    pub panel: Option<Panel>,
    pub base: String,
    cmd: mpsc::Sender<Cmd>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    pub sim_time_us: Arc<AtomicU64>,
    pub record_dir: std::path::PathBuf,
}

/// Options of a rig.
pub struct RigOptions {
    pub program: Vec<Step>,
    pub token: Option<String>,
    pub preset: &'static str,
    pub overrides: Vec<(&'static str, &'static str)>,
    /// Sleep this long after each tick (0: as fast as the CPU allows).
    pub sleep_per_tick: Duration,
    /// Tell the panel the run is lock-step (its statistics then say so).
    pub lockstep: bool,
}

impl Default for RigOptions {
    fn default() -> Self {
        RigOptions {
            program: vec![
                Step::Enable {
                    mode: drive_emu::master::MODE_PP,
                },
                Step::Dwell { duration_s: 3600.0 },
            ],
            token: None,
            preset: "cnc1",
            overrides: vec![],
            sleep_per_tick: Duration::from_millis(1),
            lockstep: false,
        }
    }
}

/// The reference master's program of the panel's tests: enable in CSP, then cruise at
/// 10 mm/s (10 000 uu/s on cnc1) for an hour.
pub fn cruise_csp_10_mm_s() -> Vec<Step> {
    vec![
        Step::Enable {
            mode: drive_emu::master::MODE_CSP,
        },
        Step::Cruise {
            velocity_uu_s: 10_000.0,
            accel_uu_s2: 100_000.0,
            duration_s: 3600.0,
        },
    ]
}

fn sdo_read(
    rt: &mut Runtime<FaultyBus<InProcEndpoint>, AxisDrive>,
    client: &mut InProcEndpoint,
    index: u16,
    sub: u8,
    step: &mut impl FnMut(&mut Runtime<FaultyBus<InProcEndpoint>, AxisDrive>),
) -> Option<(u32, u64)> {
    while let Ok(Some(_)) = client.recv() {}
    let req = CanFrame::new(
        0x600 + u32::from(NODE),
        &[0x40, index as u8, (index >> 8) as u8, sub, 0, 0, 0, 0],
    );
    client.send(&req).ok()?;
    for _ in 0..50 {
        let t = rt.sim_time_us;
        step(rt);
        while let Ok(Some(f)) = client.recv() {
            if f.id == 0x580 + u32::from(NODE)
                && f.data[1] == index as u8
                && f.data[2] == (index >> 8) as u8
                && f.data[3] == sub
            {
                if f.data[0] & 0xE0 == 0x40 {
                    let v = u32::from_le_bytes([f.data[4], f.data[5], f.data[6], f.data[7]]);
                    return Some((v, t));
                }
                return None;
            }
        }
    }
    None
}

impl Rig {
    pub fn start(o: RigOptions) -> Rig {
        let mut cfg = AxisConfig::from_preset(o.preset).unwrap();
        for (k, v) in &o.overrides {
            cfg = cfg.with_override(k, v).unwrap();
        }
        let mut drive = AxisDrive::from_config(&cfg).unwrap();
        let node = drive_emu::drive::node(&mut drive, NODE).unwrap();
        let mut eps = InProcBus::endpoints(3, 4096);
        let mut client = eps.pop().unwrap();
        let mut master_bus = eps.pop().unwrap();
        let drive_bus = FaultyBus::new(eps.pop().unwrap(), 1);
        let mut rt = Runtime::new(drive_bus, vec![AxisSlot { node, drive }], 1000);
        rt.boot();
        let setup = PanelSetup {
            bus: drive_emu::panel::PanelBus::Can,
            axes: vec![PanelAxis {
                node_id: NODE,
                preset: o.preset.to_string(),
                config: cfg,
                overrides: o
                    .overrides
                    .iter()
                    .map(|(k, v)| (k.to_string(), v.to_string()))
                    .collect(),
            }],
            iface: None,
            tick_hz: 1000,
            lockstep: o.lockstep,
            master_id: MasterConfig::default().master_id,
            json_stdout: false,
        };
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let record_dir = std::env::temp_dir().join(format!(
            "drive-emu-panel-test-{}-{}",
            std::process::id(),
            listener.local_addr().unwrap().port()
        ));
        let (mut observer, obs) =
            drive_emu::observe::channel(1, drive_emu::observe::ring_capacity(1000));
        let (panel, mut panel_loop): (Panel, PanelLoop) =
            panel::start_on(listener, o.token.clone(), record_dir.clone(), setup, obs).unwrap();
        let base = format!("http://{}", panel.addr);
        let (cmd, rx) = mpsc::channel::<Cmd>();
        let stop = Arc::new(AtomicBool::new(false));
        let sim_time_us = Arc::new(AtomicU64::new(0));
        let mut master = Master::new(MasterConfig::default(), o.program);
        let thread = {
            let (stop, sim_time_us) = (Arc::clone(&stop), Arc::clone(&sim_time_us));
            let sleep = o.sleep_per_tick;
            std::thread::spawn(move || {
                let mut step = |rt: &mut Runtime<FaultyBus<InProcEndpoint>, AxisDrive>| {
                    tick_with_master(
                        &mut master,
                        &mut master_bus,
                        rt,
                        (&mut observer, &mut panel_loop),
                    );
                    sim_time_us.store(rt.sim_time_us, Ordering::Relaxed);
                    if !sleep.is_zero() {
                        std::thread::sleep(sleep);
                    }
                };
                while !stop.load(Ordering::Relaxed) {
                    match rx.try_recv() {
                        Ok(Cmd::SdoRead(i, s, reply)) => {
                            let v = sdo_read(&mut rt, &mut client, i, s, &mut step);
                            let _ = reply.send(v);
                        }
                        Err(_) => {
                            step(&mut rt);
                            // Nobody else reads the client's endpoint: keep it from filling.
                            while let Ok(Some(_)) = client.recv() {}
                        }
                    }
                }
            })
        };
        Rig {
            panel: Some(panel),
            base,
            cmd,
            stop,
            thread: Some(thread),
            sim_time_us,
            record_dir,
        }
    }

    /// Read an object over SDO (expedited upload), between two ticks.
    pub fn sdo_read(&self, index: u16, sub: u8) -> Option<u32> {
        self.sdo_read_at(index, sub).map(|(v, _)| v)
    }

    /// An SDO read and the drive's time at the start of the tick that answered it, us.
    pub fn sdo_read_at(&self, index: u16, sub: u8) -> Option<(u32, u64)> {
        let (tx, rx) = mpsc::channel();
        self.cmd.send(Cmd::SdoRead(index, sub, tx)).ok()?;
        rx.recv_timeout(Duration::from_secs(10)).ok().flatten()
    }

    pub fn now_s(&self) -> f64 {
        self.sim_time_us.load(Ordering::Relaxed) as f64 * 1e-6
    }

    /// Wait (up to `limit`) until `f` holds.
    pub fn wait_for(&self, limit: Duration, mut f: impl FnMut() -> bool) -> bool {
        let t0 = std::time::Instant::now();
        while t0.elapsed() < limit {
            if f() {
                return true;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }

    pub fn panel(&self) -> &Panel {
        self.panel.as_ref().unwrap()
    }

    /// Stop the loop and the panel.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        if let Some(p) = self.panel.take() {
            p.stop();
        }
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.shutdown();
        let _ = std::fs::remove_dir_all(&self.record_dir);
    }
}

/// Read server-sent events from a response body: (event name, data) pairs.
pub struct SseReader<R: std::io::BufRead> {
    pub reader: R,
}

impl<R: std::io::BufRead> SseReader<R> {
    /// The next event, or `None` at the end of the stream.
    pub fn next_event(&mut self) -> Option<(String, String)> {
        let (mut event, mut data) = (String::from("message"), String::new());
        let mut line = String::new();
        loop {
            line.clear();
            if self.reader.read_line(&mut line).ok()? == 0 {
                return None;
            }
            let l = line.trim_end_matches(['\r', '\n']);
            if l.is_empty() {
                if !data.is_empty() {
                    return Some((event, data));
                }
                continue;
            }
            if let Some(v) = l.strip_prefix("event:") {
                event = v.trim().to_string();
            } else if let Some(v) = l.strip_prefix("data:") {
                if !data.is_empty() {
                    data.push('\n');
                }
                data.push_str(v.strip_prefix(' ').unwrap_or(v));
            }
        }
    }
}

/// The expedited REAL32 of an SDO read, as f32.
pub fn real32(v: u32) -> f32 {
    f32::from_bits(v)
}

/// Params used by some tests.
pub fn backlash_mm(rig: &Rig) -> Option<f32> {
    rig.sdo_read(0x2000, 0).map(real32)
}
