use clap::{Parser, Subcommand};

use drive_emu::cli;

/// Hardware-in-the-loop CiA 402 servo-drive emulator with a backlashed CNC axis behind it.
#[derive(Parser, Debug)]
#[command(name = "drive-emu", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a preset axis offline at constant velocity and analyse its vibration.
    Sim(cli::sim::SimArgs),
    /// Answer on a CAN bus as CiA 402 drive(s) with simulated axes behind them.
    Run(cli::run::RunArgs),
    /// Write the drive's EDS (CiA 306) to stdout.
    Eds(cli::eds::EdsArgs),
    /// List the axis presets.
    Presets,
    /// Master and drive in one process, no CAN hardware: enable, move, and the backlash
    /// vibration seen from the wire.
    Demo(cli::demo::DemoArgs),
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Sim(args) => cli::sim::run(&args),
        Command::Run(args) => cli::run::run(&args),
        Command::Eds(args) => cli::eds::run_eds(&args),
        Command::Presets => cli::eds::run_presets(),
        Command::Demo(args) => cli::demo::run(&args),
    }
}
