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
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Sim(args) => cli::sim::run(&args),
    }
}
