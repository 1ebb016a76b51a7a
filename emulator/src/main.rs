use clap::Parser;
use std::process::ExitCode;

use drive_emu::cli::{self, Cli, Command};

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
        Command::Contour(args) => ok(cli::contour::run(&args)),
        Command::Sweep(args) => ok(cli::sweep::run(&args)),
        Command::Figures(args) => ok(cli::figures::run(&args)),
        Command::Scenario(args) => cli::scenario::run(&args),
        Command::Analyze(args) => cli::analyze::run(&args),
        Command::Eds(args) => ok(cli::eds::run_eds(&args)),
        Command::Esi(args) => ok(cli::esi::run_esi(&args)),
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
