//! Command-line subcommands, and the command line itself ([`Cli`]: the binary parses it, the
//! docs test checks every command the README and the book show against it).

pub mod analyze;
pub mod analyze_ballbar;
pub mod ballbar;
pub mod contour;
pub mod demo;
pub mod demo_panel;
pub mod eds;
pub mod esi;
pub mod exit;
pub mod figures;
pub mod fmu;
pub mod lss_store;
pub mod param_flags;
pub mod profiles;
pub mod run;
pub mod scenario;
pub mod sim;
pub mod sweep;

use clap::{Parser, Subcommand};

/// A request's error ([`crate::api::ApiError`]) as the command line reports it: its text and
/// causes, marked with its exit status ([`crate::api::ApiError::exit_code`]).
pub fn api_error(e: crate::api::ApiError) -> anyhow::Error {
    let code = e.exit_code();
    let e = e.into_anyhow();
    match code {
        exit::USAGE => exit::usage(e),
        exit::UNREADABLE => exit::unreadable(e),
        _ => e,
    }
}

/// Hardware-in-the-loop CiA 402 servo-drive emulator with a backlashed CNC axis behind it.
#[derive(Parser, Debug)]
#[command(name = "drive-emu", version, about, after_help = exit::HELP)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Master and drive in one process, no CAN hardware: enable, move, and the backlash
    /// vibration seen from the wire.
    Demo(demo::DemoArgs),
    /// Answer on a CAN bus as one or several CiA 402 drives, a simulated axis behind each.
    Run(Box<run::RunArgs>),
    /// Run a preset axis offline at constant velocity and analyse its vibration.
    Sim(sim::SimArgs),
    /// The virtual ballbar (ISO 230-4): a circle both ways on two linear axes, with the
    /// master's backlash compensation; circular deviation, reversal spikes, backlash estimate.
    Ballbar(ballbar::BallbarArgs),
    /// Straight lines (G1, exact stop) on two or three linear axes through the drives, with
    /// the master's backlash compensation; contour error, lost motion at reversals, end points.
    Contour(Box<contour::ContourArgs>),
    /// Sweep k_v x backlash x preset on all cores; one CSV/JSON row per case.
    Sweep(sweep::SweepArgs),
    /// The paper's Fig. 3, 10 and 11 from simulated runs (PNG + JSON).
    Figures(figures::FiguresArgs),
    /// Run a scenario (wear, faults, expectations) offline and write its report.
    Scenario(scenario::ScenarioArgs),
    /// Run the backlash detector on a trace: trace CSV, sample log or candump log.
    Analyze(analyze::AnalyzeArgs),
    /// Write the drive's EDS (CiA 306) to stdout.
    Eds(eds::EdsArgs),
    /// Write the drive's ESI (EtherCAT slave information, ETG.2000) as `run --ethercat` serves it.
    Esi(Box<esi::EsiArgs>),
    /// Write the preset axis as an FMI 2.0 co-simulation FMU (for Simulink, VeriStand, FMPy).
    Fmu(fmu::FmuArgs),
    /// List the axis presets.
    Presets,
    /// List the vendor behaviour profiles and switches (docs/quirks.md), or show one.
    Profiles(profiles::ProfilesArgs),
}

impl Command {
    /// Whether the command writes only to its standard streams and to files: no socket a
    /// peer could close under it (the panel, socketcand, a live scenario's bus).
    pub fn offline(&self) -> bool {
        match self {
            Command::Demo(a) => a.panel.panel.is_none() && a.iface.is_none(),
            Command::Scenario(a) => a.iface.is_none(),
            Command::Run(_) => false,
            Command::Sim(_)
            | Command::Ballbar(_)
            | Command::Contour(_)
            | Command::Sweep(_)
            | Command::Figures(_)
            | Command::Analyze(_)
            | Command::Eds(_)
            | Command::Esi(_)
            | Command::Fmu(_)
            | Command::Presets
            | Command::Profiles(_) => true,
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_api_exit_statuses_are_the_command_line_s() {
        use crate::api::error::status;
        assert_eq!(status::FAILED, super::exit::FAILED);
        assert_eq!(status::USAGE, super::exit::USAGE);
        assert_eq!(status::UNREADABLE, super::exit::UNREADABLE);
        let e = super::api_error(crate::api::ApiError::invalid("--node 0"));
        assert_eq!(super::exit::code_of(&e), super::exit::USAGE);
        assert_eq!(e.to_string(), "--node 0");
    }
}
