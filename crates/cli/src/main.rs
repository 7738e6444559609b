//! `kestrel`: model-based control of small rotorcraft, from flight logs to
//! firmware tables. Every step is a subcommand reading and writing the
//! interchange files of `shared/FORMATS.md`.

use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod commands;
mod io;

/// Model predictive control for small rotorcraft on tiny processors.
#[derive(Parser, Debug)]
#[command(name = "kestrel", version, about, long_about = None, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The subcommands. To add one: a module in `commands/` with an `Args`
/// struct and a `run` function, one variant here and one arm in `main`.
#[derive(Subcommand, Debug)]
enum Command {
    /// Discretise a continuous-time `kestrel.ss.v1` model (zero-order hold).
    C2d(commands::c2d::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::C2d(args) => commands::c2d::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
