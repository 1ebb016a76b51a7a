//! What the command line attaches to the API's live run ([`run_live`]): the terminal status
//! line and the ready line (the watch thread), read from the observation bus, the LSS store
//! service between the loop and the watch thread, and the panel.

use super::args::RunArgs;
use crate::api::live::{Attach, LiveBus, LiveOutcome, LiveRun, TickHook};
use crate::drive::axis_drive::AxisDrive;
use crate::drive::machine;
use crate::observe::{AxisSnapshot, Observation};
use crate::runtime::Runtime;
use crate::scenario::Scenario;
use anyhow::Result;
use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;

/// The LSS store service of one axis between the loop and the watch thread: plain atomics,
/// no locks.
#[derive(Default)]
struct LssSlot {
    /// LSS store configuration to write: 0 none, else `1 << 32 | node_id << 8 | bit timing`.
    lss_store_request: AtomicU64,
    /// Its outcome for the loop: 0 none, 1 written, 2 failed.
    lss_store_result: AtomicU8,
    /// LSS activate bit timing to report: 0 none, else `1 << 32 | index << 16 | delay_ms`.
    lss_activation: AtomicU64,
}

/// The wear an axis runs with now (`backlash 0.03 mm`), `None` on a healthy axis.
fn wear(a: &AxisSnapshot) -> Option<String> {
    machine::wear_text(a.gap_si, a.rotary)
}

/// Run the drive(s) on the bus as `drive-emu run` does: the options as the API's request
/// (with a scenario, its timeline injected into axis 0), the panel and the LSS store service
/// attached, the status line and the ready line until the run stops, its outcome.
pub fn run_live(args: &RunArgs, scenario: Option<&Scenario>) -> Result<LiveOutcome> {
    crate::panel::check_args(&args.panel)?;
    let req = args.request(scenario.cloned())?;
    let mut panel = None;
    let mut status = None;
    let run = req
        .start_with(|at: Attach<'_>| {
            // The live panel (--panel): bound before the loop starts; it takes the scenario's
            // injections into its own injector.
            let context = crate::panel::RunContext {
                bus: crate::panel::PanelBus::Can,
                iface: at.socketcand.is_none().then_some(args.iface.as_str()),
                node: args.node,
                lockstep: args.lockstep,
                json: args.json,
                machine: at.machine,
                scenario: at.scenario,
            };
            let (p, panel_loop) =
                crate::panel::start_for_run(&args.panel, context, (at.link, at.obs), at.injector)?
                    .unzip();
            panel = p;
            let st = Arc::new(Status::new(Arc::clone(at.obs)));
            status = Some(Arc::clone(&st));
            Ok(Some(Box::new(CliHook {
                panel: panel_loop,
                status: st,
            })))
        })
        .map_err(crate::cli::api_error)?;
    let watched = match &status {
        Some(st) => watch(args, &run, st),
        None => Ok(()),
    };
    run.stop();
    if std::io::stderr().is_terminal() {
        eprintln!();
    }
    let outcome = run.wait();
    if let Some(p) = panel {
        p.stop();
    }
    watched?;
    outcome.map_err(crate::cli::api_error)
}

/// The command line's part of the loop's hook, after every tick: the panel's injections, the
/// LSS store exchange. No allocation, lock or I/O.
struct CliHook {
    panel: Option<crate::panel::PanelLoop>,
    status: Arc<Status>,
}

impl TickHook for CliHook {
    fn on_tick(&mut self, rt: &mut Runtime<LiveBus, AxisDrive>) {
        if let Some(p) = self.panel.as_mut() {
            p.on_tick(rt);
        }
        self.status.lss_exchange(rt);
    }
}

/// The watch thread's side of the run: the LSS store service; what it shows (status line,
/// ready line) it reads from the observation bus.
pub(super) struct Status {
    axes: Vec<LssSlot>,
    obs: Arc<Observation>,
}

/// The loop line of the status block, as the observation bus's board has it.
#[derive(Debug, Default, Clone, Copy)]
struct LoopLine {
    sim_time_us: u64,
    ticks: u64,
    overruns: u64,
    sync_lock: u64,
    sync_phase_error_us: u64,
    rx_overflows: u64,
    link_up: bool,
}

impl LoopLine {
    fn of(obs: &Observation) -> Self {
        let b = &obs.board;
        let ld = |a: &AtomicU64| a.load(Ordering::Relaxed);
        LoopLine {
            sim_time_us: ld(&b.sim_time_us),
            ticks: ld(&b.loop_ticks),
            overruns: ld(&b.overruns),
            sync_lock: ld(&b.sync_lock),
            sync_phase_error_us: ld(&b.sync_phase_error_us),
            rx_overflows: ld(&b.rx_overflows),
            link_up: b.link_up.load(Ordering::Relaxed),
        }
    }
}

impl Status {
    /// After every tick (loop thread): hand LSS store requests and bit timing activations
    /// out to the watch thread, and its store outcomes back to the nodes. Atomics only.
    pub(super) fn lss_exchange<B: crate::bus::CanBus>(&self, rt: &mut Runtime<B, AxisDrive>) {
        for (a, st) in rt.axes.iter_mut().zip(&self.axes) {
            let n = &mut a.node;
            if let Some(s) = n.take_lss_store() {
                let id = u64::from(s.node_id.unwrap_or(255));
                st.lss_store_request.store(
                    1 << 32 | id << 8 | u64::from(s.bit_timing_index),
                    Ordering::Release,
                );
            }
            match st.lss_store_result.swap(0, Ordering::Acquire) {
                1 => n.lss_store_done(true),
                2 => n.lss_store_done(false),
                _ => {}
            }
            if let Some((index, delay_ms)) = n.take_lss_bit_timing_activation() {
                st.lss_activation.store(
                    1 << 32 | u64::from(index) << 16 | u64::from(delay_ms),
                    Ordering::Release,
                );
            }
        }
    }

    /// Watch thread: write the LSS stores the loop handed out (to `path`; a node asks only
    /// when it has one) and say what the masters did.
    fn lss_service(&self, path: Option<&std::path::Path>) {
        for (k, st) in self.axes.iter().enumerate() {
            let node = self.obs.latest(k).map_or(0, |a| a.node_id);
            let req = st.lss_store_request.swap(0, Ordering::Acquire);
            if req != 0 {
                let s = drive_protocol::LssStore {
                    node_id: Some((req >> 8) as u8).filter(|&n| n != 255),
                    bit_timing_index: req as u8,
                };
                let ok = match path.map(|p| (p, crate::cli::lss_store::save(p, &s))) {
                    Some((p, Ok(()))) => {
                        eprintln!(
                            "drive-emu: node {node}: LSS store configuration: node-ID {}, bit \
                             timing {} written to {}",
                            (req >> 8) as u8,
                            crate::cli::lss_store::bit_timing_text(s.bit_timing_index),
                            p.display()
                        );
                        true
                    }
                    Some((_, Err(e))) => {
                        eprintln!("drive-emu: node {node}: LSS store configuration failed: {e:#}");
                        false
                    }
                    None => false,
                };
                st.lss_store_result
                    .store(if ok { 1 } else { 2 }, Ordering::Release);
            }
            let act = st.lss_activation.swap(0, Ordering::Acquire);
            if act != 0 {
                eprintln!(
                    "drive-emu: node {node}: LSS activate bit timing {} after {} ms: a real \
                     drive switches its CAN controller then; drive-emu cannot change the \
                     interface's bit rate (set it with `ip link`), it keeps running as before",
                    crate::cli::lss_store::bit_timing_text((act >> 16) as u8),
                    act as u16
                );
            }
        }
    }

    pub(super) fn new(obs: Arc<Observation>) -> Self {
        Self {
            axes: (0..obs.rings.len()).map(|_| LssSlot::default()).collect(),
            obs,
        }
    }

    /// Every axis's newest snapshot (an axis not published yet: a default one).
    fn snapshots(&self) -> Vec<AxisSnapshot> {
        (0..self.axes.len())
            .map(|k| self.obs.latest(k).unwrap_or_default())
            .collect()
    }
}

/// The status block: the loop (time, ticks, overruns, SYNC lock, drops, link), then one line
/// per axis with its node ID, NMT state, CiA 402 state, mode name, position and following
/// error (in user units, uu), and under a worn axis the wear it runs with.
fn status_lines(lp: &LoopLine, axes: &[AxisSnapshot], iface: &str, lockstep: bool) -> Vec<String> {
    let mut head = format!(
        "{iface} t={:.1} s | ticks {} overruns {}",
        lp.sim_time_us as f64 * 1e-6,
        lp.ticks,
        lp.overruns
    );
    if lockstep {
        head += " | lock-step";
    } else {
        head += " | ";
        head += crate::runtime::stats::lock_name(lp.sync_lock as u32);
        if lp.sync_lock == 2 {
            head += &format!(" (phase error {} us)", lp.sync_phase_error_us);
        }
    }
    if lp.rx_overflows > 0 {
        head += &format!(" | rx overflow {}", lp.rx_overflows);
    }
    if !lp.link_up {
        head += " | LINK DOWN";
    }
    let axes = axes.iter().flat_map(|a| {
        let line = format!(
            "node {:<3} {:<15} {:<21} {:<7} pos {} ferr {} uu",
            a.node_id,
            // The heartbeat's 0x00 is the boot-up; the state before it is initialising,
            // or, without a node-ID, waiting for one by LSS.
            if a.nmt == 0 && a.node_id == 255 {
                "UNCONFIGURED"
            } else if a.nmt == 0 {
                "INITIALISING"
            } else {
                crate::master::nmt_name(a.nmt)
            },
            crate::master::state_name(a.sample.statusword),
            crate::master::mode_short(a.sample.mode_display),
            a.sample.position_uu,
            a.sample.following_error_uu,
        );
        // a worn axis: a line of its own under it (the axis line fills 80 columns)
        let wear = wear(a).map(|w| format!("         WORN: {w} (healthy: without --worn)"));
        std::iter::once(line).chain(wear)
    });
    std::iter::once(head).chain(axes).collect()
}

/// Draw the status block on a terminal over the one drawn before (`drawn` lines): up to its
/// first line, then each line cleared and rewritten, cut to `width` characters (a wrapped
/// line would break the redraw). Returns the lines now drawn.
fn redraw(
    out: &mut impl Write,
    drawn: usize,
    lines: &[String],
    width: usize,
) -> std::io::Result<usize> {
    if drawn > 1 {
        write!(out, "\x1b[{}A", drawn - 1)?;
    }
    for (i, l) in lines.iter().enumerate() {
        let cut: String = l.chars().take(width.saturating_sub(1)).collect();
        write!(out, "{}\r\x1b[2K{cut}", if i > 0 { "\n" } else { "" })?;
    }
    out.flush()?;
    Ok(lines.len())
}

/// Until the run stops: the ready line on stdout once booted (`--ready`), the status line on
/// stderr (a terminal only, so stdout stays clean for --json and pipes).
fn watch(args: &RunArgs, run: &LiveRun, status: &Status) -> Result<()> {
    let (label, socketcand) = (run.bus_label(), run.socketcand_addr());
    let (machine, lockstep) = (run.machine(), run.lockstep());
    let tty = std::io::stderr().is_terminal();
    let mut ready_sent = !args.ready;
    let mut drawn = 0;
    let mut drawn_at = std::time::Instant::now();
    while !run.stop_flag().load(Ordering::Relaxed) && !run.is_finished() {
        // LSS store configuration: the master waits for the answer (python canopen 0.5 s).
        status.lss_service(args.lss_store.as_deref());
        let published = status.obs.board.ticks.load(Ordering::Acquire) > 0;
        if !ready_sent && run.booted() {
            ready_sent = true;
            let line = serde_json::json!({
                "event": "ready",
                "iface": socketcand.is_none().then_some(&args.iface),
                "socketcand": socketcand.map(|a| serde_json::json!({
                    "host": a.ip().to_string(), "port": a.port(),
                    "channel": crate::bus::socketcand::CHANNEL,
                })),
                "nodes": machine.axes.iter().zip(run.wear_at_boot()).map(|(a, w)| serde_json::json!({
                    "node_id": a.node_id, "preset": a.preset,
                    // the wear the axis runs with (null: healthy, no gap)
                    "worn": w,
                    "eds": a.eds.as_ref().map(|p| p.display().to_string()),
                    "objects_base": a.objects_base.map(|b| format!("0x{b:04X}")),
                    "profile": a.quirk_profile.as_ref().and_then(|b| b.profile.clone()),
                    "quirks": a.quirk_profile.as_ref().map_or(vec![], |b| b.quirks.on().collect()),
                })).collect::<Vec<_>>(),
                "tick_hz": machine.tick_hz,
                "lockstep": args.lockstep,
                "sync_period_us": lockstep.and_then(|l| l.sync_period_us),
                "boot_delay_ms": args.boot_delay_ms,
                "pid": std::process::id(),
            });
            let mut out = std::io::stdout().lock();
            writeln!(out, "{line}")?;
            out.flush()?;
        }
        // 5 ms until the ready line is out, then 50 ms: an LSS store configuration is still
        // answered well within a master's wait (python canopen: 0.5 s), and this thread wakes
        // 20 times a second beside the loop, not 200 (one CPU under user-mode Linux).
        std::thread::sleep(std::time::Duration::from_millis(
            if ready_sent && run.booted() { 50 } else { 5 },
        ));
        // Nothing to show before the loop's first tick has published the axes; redrawn every
        // 200 ms.
        if tty && published && drawn_at.elapsed() >= std::time::Duration::from_millis(200) {
            drawn_at = std::time::Instant::now();
            let lines = status_lines(
                &LoopLine::of(&status.obs),
                &status.snapshots(),
                label,
                lockstep.is_some(),
            );
            drawn = redraw(
                &mut std::io::stderr().lock(),
                drawn,
                &lines,
                terminal_width(),
            )
            .unwrap_or(drawn);
        }
    }
    Ok(())
}

/// Columns of the terminal on stderr (TIOCGWINSZ), 80 when it does not say.
fn terminal_width() -> usize {
    let mut ws = libc::winsize {
        ws_row: 0,
        ws_col: 0,
        ws_xpixel: 0,
        ws_ypixel: 0,
    };
    // SAFETY: TIOCGWINSZ writes a winsize into the struct we pass; fd 2 is ours.
    let ok = unsafe { libc::ioctl(libc::STDERR_FILENO, libc::TIOCGWINSZ, &mut ws) } == 0;
    if ok && ws.ws_col > 0 {
        usize::from(ws.ws_col)
    } else {
        80
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::NodeOptions;
    use crate::presets::AxisConfig;
    use crate::runtime::AxisSlot;

    fn axis(node: u8, nmt: u8, statusword: u16, mode: i8) -> AxisSnapshot {
        let mut a = AxisSnapshot {
            node_id: node,
            nmt,
            ..AxisSnapshot::default()
        };
        a.sample.statusword = statusword;
        a.sample.mode_display = mode;
        a.sample.position_uu = -1234;
        a
    }

    fn up() -> LoopLine {
        LoopLine {
            link_up: true,
            ..LoopLine::default()
        }
    }

    #[test]
    fn status_block_has_one_named_line_per_axis() {
        let axes = [axis(20, 0x05, 0x0637, 8), axis(21, 0x7F, 0x0250, 0)];
        let lines = status_lines(&up(), &axes, "vcan0", true);
        assert_eq!(lines.len(), 3, "{lines:#?}");
        assert!(lines[0].starts_with("vcan0 t=") && lines[0].contains("lock-step"));
        for (l, want) in lines[1..].iter().zip([
            ["node 20 ", "OPERATIONAL", "OPERATION ENABLED", "CSP"],
            [
                "node 21 ",
                "PRE-OPERATIONAL",
                "SWITCH ON DISABLED",
                "no mode",
            ],
        ]) {
            for w in want {
                assert!(l.contains(w), "{w:?} missing in {l:?}");
            }
            assert!(l.contains("pos -1234 ferr 0 uu"), "{l:?}");
        }
        // Mode names, not numbers; no Debug text.
        for l in &lines {
            assert!(!l.contains("mode 8") && !l.contains("mode 0"), "{l:?}");
            assert!(!l.contains('{') && !l.contains("::"), "{l:?}");
        }
        // The columns line up: the NMT, CiA 402 state and mode columns start at the same
        // place on every axis line.
        let col = |l: &str, w: &str| l.find(w).unwrap();
        assert_eq!(
            col(&lines[1], "OPERATIONAL"),
            col(&lines[2], "PRE-OPERATIONAL")
        );
        assert_eq!(
            col(&lines[1], "OPERATION ENABLED"),
            col(&lines[2], "SWITCH ON DISABLED")
        );
        assert_eq!(col(&lines[1], "CSP"), col(&lines[2], "no mode"));
    }

    #[test]
    fn status_of_one_axis_is_the_loop_line_and_the_axis_line() {
        let mut a = axis(5, 0x00, 0x0000, 3);
        a.sample.position_uu = -123_456;
        a.sample.following_error_uu = -789;
        let lines = status_lines(&LoopLine::default(), &[a], "can0", false);
        assert_eq!(lines.len(), 2, "{lines:#?}");
        assert!(lines[0].starts_with("can0 t=") && lines[0].contains("LINK DOWN"));
        for w in ["node 5 ", "INITIALISING", "NOT READY TO SWITCH ON", "PV"] {
            assert!(lines[1].contains(w), "{w:?} missing in {:?}", lines[1]);
        }
        // Each line fits an 80-column terminal with a six-digit position.
        assert!(lines.iter().all(|l| l.chars().count() <= 80), "{lines:#?}");
        let mut a = axis(5, 0x05, 0x0637, -2);
        assert!(
            status_lines(&up(), &[a], "can0", true)[1].contains("manufacturer-specific mode -2")
        );
        // a worn axis (issue 33, item 4): a line under it says so, and fits the terminal
        a.gap_si = 3e-5;
        let lines = status_lines(&up(), &[a], "can0", false);
        assert_eq!(lines.len(), 3, "{lines:#?}");
        assert!(lines[2].contains("WORN: backlash 0.03 mm"), "{lines:#?}");
        assert!(lines[2].chars().count() <= 80, "{lines:#?}");
        a.rotary = true;
        a.gap_si = 0.02f64.to_radians();
        assert!(status_lines(&up(), &[a], "can0", false)[2].contains("WORN: backlash 0.02 deg"));
        a.gap_si = 0.0;
        assert_eq!(
            status_lines(&up(), &[a], "can0", false).len(),
            2,
            "healthy: no wear line"
        );
    }

    #[test]
    fn a_non_configured_axis_is_shown_as_such() {
        let line = &status_lines(&up(), &[axis(255, 0x00, 0x0000, 0)], "can0", false)[1];
        assert!(line.contains("node 255 UNCONFIGURED"), "{line}");
        let line = &status_lines(&up(), &[axis(12, 0x00, 0x0000, 0)], "can0", false)[1];
        assert!(line.contains("INITIALISING"));
    }

    /// The status line reads the observation bus: what the loop published (board and
    /// snapshot) is what it shows, and nothing before the first tick.
    #[test]
    fn the_status_line_shows_what_the_loop_published() {
        use crate::bus::inproc::InProcBus;
        let mut drive = AxisDrive::from_config(&AxisConfig::from_preset("cnc1").unwrap()).unwrap();
        let node = crate::drive::node(&mut drive, 9).unwrap();
        let bus = InProcBus::endpoints(1, 16).remove(0);
        let mut rt = Runtime::new(bus, vec![AxisSlot { node, drive }], 1000);
        rt.boot();
        let (mut observer, obs) = crate::observe::channel(1, 1024);
        let status = Status::new(Arc::clone(&obs));
        assert_eq!(status.obs.latest(0), None, "nothing published yet");
        for _ in 0..3 {
            rt.tick();
            rt.stats.record_tick(5, 20);
            observer.publish(&mut rt);
        }
        observer.set_link_up(false);
        let lines = status_lines(&LoopLine::of(&obs), &status.snapshots(), "can0", false);
        assert!(
            lines[0].contains("ticks 3 ") && lines[0].contains("LINK DOWN"),
            "{lines:?}"
        );
        assert!(lines[1].starts_with("node 9 "), "{lines:?}");
        assert_eq!(status.snapshots()[0].t_us, rt.sim_time_us);
    }

    /// LSS store configuration from a node on the loop to the file and the answer back:
    /// the loop hands the request out, the watch thread writes FILE, the loop queues the
    /// answer (error 0); an unwritable FILE gives error 2.
    #[test]
    fn an_lss_store_goes_from_the_loop_to_the_file_and_back() {
        use crate::bus::inproc::{InProcBus, InProcEndpoint};
        use drive_protocol::CanFrame;
        let dir = std::env::temp_dir().join(format!("run-lss-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("drive.lss");
        let mut drive = AxisDrive::from_config(&AxisConfig::from_preset("cnc1").unwrap()).unwrap();
        let opts = NodeOptions {
            lss: drive_protocol::LssConfig {
                store_external: true,
                ..Default::default()
            },
            ..NodeOptions::new(255)
        };
        let mut node = crate::drive::build_node(&mut drive, &opts).unwrap();
        node.boot(0);
        let bus = InProcBus::endpoints(1, 16).remove(0);
        let mut rt = Runtime::new(bus, vec![AxisSlot { node, drive }], 1000);
        let status = Status::new(crate::observe::channel(1, 1024).1);
        let lss = |rt: &mut Runtime<InProcEndpoint, AxisDrive>, d: [u8; 8]| {
            let ax = &mut rt.axes[0];
            ax.node.handle(&CanFrame::new(0x7E5, &d), 0, &mut ax.drive);
        };
        let answers = |rt: &mut Runtime<InProcEndpoint, AxisDrive>| {
            let mut v = Vec::new();
            while let Some(f) = rt.axes[0].node.pop_tx() {
                v.push(f.data);
            }
            v
        };
        lss(&mut rt, [0x04, 1, 0, 0, 0, 0, 0, 0]);
        lss(&mut rt, [0x11, 12, 0, 0, 0, 0, 0, 0]);
        lss(&mut rt, [0x13, 0, 3, 0, 0, 0, 0, 0]);
        answers(&mut rt);
        for (file, answer) in [(path.clone(), 0u8), (dir.join("no/such/dir/x"), 2)] {
            lss(&mut rt, [0x17, 0, 0, 0, 0, 0, 0, 0]);
            assert!(answers(&mut rt).is_empty(), "answered after the write");
            status.lss_exchange(&mut rt); // loop: hands the request out
            status.lss_service(Some(&file)); // watch thread: writes
            assert!(answers(&mut rt).is_empty());
            status.lss_exchange(&mut rt); // loop: the answer
            assert_eq!(answers(&mut rt), [[0x17, answer, 0, 0, 0, 0, 0, 0]]);
        }
        assert_eq!(
            crate::cli::lss_store::load(&path).unwrap(),
            Some(crate::cli::lss_store::Stored {
                node_id: Some(12),
                bit_timing_index: 3
            })
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn redraw_goes_back_over_the_block_it_drew() {
        let lines: Vec<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
        let mut out = Vec::new();
        let drawn = redraw(&mut out, 0, &lines, 80).unwrap();
        assert_eq!(drawn, 3);
        assert_eq!(out, b"\r\x1b[2Ka\n\r\x1b[2Kb\n\r\x1b[2Kc");
        out.clear();
        redraw(&mut out, drawn, &lines, 80).unwrap();
        assert!(out.starts_with(b"\x1b[2A\r\x1b[2Ka"), "{out:?}");
        // A line wider than the terminal is cut, so it cannot wrap.
        out.clear();
        redraw(&mut out, 0, &["µ".repeat(100)], 40).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            format!("\r\x1b[2K{}", "µ".repeat(39))
        );
    }
}
