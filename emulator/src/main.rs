use clap::{Parser, Subcommand};
use std::process::ExitCode;

use drive_emu::cli;

/// Hardware-in-the-loop CiA 402 servo-drive emulator with a backlashed CNC axis behind it.
#[derive(Parser, Debug)]
#[command(name = "drive-emu", version, about, after_help = cli::exit::HELP)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Master and drive in one process, no CAN hardware: enable, move, and the backlash
    /// vibration seen from the wire.
    Demo(cli::demo::DemoArgs),
    /// Answer on a CAN bus as one or several CiA 402 drives, a simulated axis behind each.
    Run(Box<cli::run::RunArgs>),
    /// Run a preset axis offline at constant velocity and analyse its vibration.
    Sim(cli::sim::SimArgs),
    /// The virtual ballbar (ISO 230-4): a circle both ways on two linear axes, with the
    /// master's backlash compensation; circular deviation, reversal spikes, backlash estimate.
    Ballbar(cli::ballbar::BallbarArgs),
    /// Sweep k_v x backlash x preset on all cores; one CSV/JSON row per case.
    Sweep(cli::sweep::SweepArgs),
    /// The paper's Fig. 3, 10 and 11 from simulated runs (PNG + JSON).
    Figures(cli::figures::FiguresArgs),
    /// Run a scenario (wear, faults, expectations) offline and write its report.
    Scenario(cli::scenario::ScenarioArgs),
    /// Run the backlash detector on a trace: trace CSV, sample log or candump log.
    Analyze(cli::analyze::AnalyzeArgs),
    /// Write the drive's EDS (CiA 306) to stdout.
    Eds(cli::eds::EdsArgs),
    /// Write the preset axis as an FMI 2.0 co-simulation FMU (for Simulink, VeriStand, FMPy).
    Fmu(cli::fmu::FmuArgs),
    /// List the axis presets.
    Presets,
    /// List the vendor behaviour profiles and switches (docs/quirks.md), or show one.
    Profiles(cli::profiles::ProfilesArgs),
}

impl Command {
    /// Whether the command writes only to its standard streams and to files: no socket a
    /// peer could close under it (the panel, socketcand, a live scenario's bus).
    fn offline(&self) -> bool {
        match self {
            Command::Demo(a) => a.panel.panel.is_none() && a.iface.is_none(),
            Command::Scenario(a) => a.iface.is_none(),
            Command::Run(_) => false,
            Command::Sim(_)
            | Command::Ballbar(_)
            | Command::Sweep(_)
            | Command::Figures(_)
            | Command::Analyze(_)
            | Command::Eds(_)
            | Command::Fmu(_)
            | Command::Presets
            | Command::Profiles(_) => true,
        }
    }
}

/// An offline command whose reader goes away (`drive-emu demo | head`) ends quietly, as a
/// Unix filter does, instead of panicking on "failed printing to stdout: Broken pipe". The
/// Rust runtime ignores SIGPIPE; the default action is restored only for offline commands,
/// since a drive serving sockets must not die when a peer closes one.
fn end_quietly_on_broken_pipe() {
    // SAFETY: setting a signal's disposition to its default, before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    let ok = |r: anyhow::Result<()>| r.map(|()| ExitCode::SUCCESS);
    let cli = Cli::parse();
    if cli.command.offline() {
        end_quietly_on_broken_pipe();
    }
    let result = match cli.command {
        Command::Demo(args) => ok(cli::demo::run(&args)),
        Command::Run(args) => ok(cli::run::run(&args)),
        Command::Sim(args) => ok(cli::sim::run(&args)),
        Command::Ballbar(args) => ok(cli::ballbar::run(&args)),
        Command::Sweep(args) => ok(cli::sweep::run(&args)),
        Command::Figures(args) => ok(cli::figures::run(&args)),
        Command::Scenario(args) => cli::scenario::run(&args),
        Command::Analyze(args) => cli::analyze::run(&args),
        Command::Eds(args) => ok(cli::eds::run_eds(&args)),
        Command::Presets => ok(cli::eds::run_presets()),
        Command::Fmu(args) => ok(cli::fmu::fmu(&args)),
        Command::Profiles(args) => ok(cli::profiles::run(&args)),
    };
    match result {
        Ok(code) => code,
        // A user error: the message and its causes, no backtrace (even with RUST_BACKTRACE).
        Err(e) => {
            let mut shown = e.to_string();
            eprintln!("error: {shown}");
            // A cause the message already quotes is not repeated.
            for cause in e.chain().skip(1).map(|c| c.to_string()) {
                if !shown.contains(&cause) {
                    eprintln!("  caused by: {cause}");
                    shown += &cause;
                }
            }
            ExitCode::from(cli::exit::code_of(&e))
        }
    }
}
