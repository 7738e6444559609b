//! `kestrel`: model-based control of small rotorcraft, from flight logs to
//! firmware tables. Every step is a subcommand reading and writing the
//! interchange files of `shared/FORMATS.md`.

use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod commands;
mod guards;
mod interrupt;
mod io;
mod logs;
mod pipeline;
mod progress;
mod report;

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
    /// Fly a thesis experiment in the tricopter simulator; write the CSV log.
    Simulate(commands::simulate::Args),
    /// Build the condensed MPC problem of a model; write `kestrel.mpqp.v1`.
    Mpc(commands::mpc::Args),
    /// Fly a rate controller (MPC or PI) in the closed-loop simulator; write the CSV trace.
    ClosedLoop(commands::closed_loop::Args),
    /// Explicit MPC: solve an mpQP, evaluate the solution, export flash tables.
    Empc(commands::empc::Args),
    /// Identify a state-space model from a CSV log (N4SID, PEM); write `kestrel.ss.v1`.
    Identify(commands::identify::Args),
    /// Import a flight log (Betaflight blackbox, Crazyflie uSD, PX4 ULog) as kestrel's CSV on one grid.
    Import(commands::import::Args),
    /// Fast gradient method: certify iteration counts, solve, export firmware tables.
    Fgm(commands::fgm::Args),
    /// Stationary Kalman filter design (dlqe); write `kestrel.kalman.v1`.
    Kalman(commands::kalman::Args),
    /// The main job: the thesis workflow end to end, written as a report directory.
    Pipeline(commands::pipeline::Args),
    /// Firmware tables from design files: model (+ Kalman filter, MPC problem) to `generated.rs`.
    Export(commands::export::Args),
    /// Write every generated file (firmware tables, golden files) from its inputs; `--check` compares only.
    Codegen(commands::codegen::Args),
    /// Online dual active-set QP solver: certify its worst-case iterations.
    Qp(commands::qp::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    interrupt::install();
    let result = match cli.command {
        Command::C2d(args) => commands::c2d::run(args),
        Command::Simulate(args) => commands::simulate::run(args),
        Command::Mpc(args) => commands::mpc::run(args),
        Command::ClosedLoop(args) => commands::closed_loop::run(args),
        Command::Empc(args) => commands::empc::run(args),
        Command::Identify(args) => commands::identify::run(args),
        Command::Import(args) => commands::import::run(args),
        Command::Fgm(args) => commands::fgm::run(args),
        Command::Kalman(args) => commands::kalman::run(args),
        Command::Pipeline(args) => commands::pipeline::run(args),
        Command::Export(args) => commands::export::run(args),
        Command::Codegen(args) => commands::codegen::run(args),
        Command::Qp(args) => commands::qp::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes as one line, `outer: inner: ...`, each text
/// once: a cause whose message already includes the one below it (a
/// library error that prints its source) replaces it, and a context that
/// the message already starts with (the file name added twice) is left out.
fn error_chain(e: &anyhow::Error) -> String {
    let parts: Vec<String> = e.chain().map(ToString::to_string).collect();
    let mut msg = String::new();
    for part in parts.iter().rev() {
        if msg.is_empty() || part.ends_with(msg.as_str()) {
            msg.clone_from(part);
        } else if msg
            .strip_prefix(part.as_str())
            .is_some_and(|rest| rest.starts_with(':'))
        {
            // The context is already the message's own prefix.
        } else {
            msg = format!("{part}: {msg}");
        }
    }
    msg
}
