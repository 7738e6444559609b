//! `kestrel pipeline`: the main job, the thesis workflow end to end.

use crate::pipeline::{Options, config, run as run_pipeline};
use std::path::PathBuf;

/// Runs the whole workflow of the thesis's chapter 7 on the built-in
/// tricopter and writes a report directory: the four flight experiments
/// (CSV), gyro bias, noise and trim, black-box and virtual models
/// (`kestrel.ss.v1`, fit / 5-step / residual tables), the stationary Kalman
/// filter, the thesis-sized and larger MPC problems (`kestrel.mpqp.v1`),
/// the explicit solution with its search tree, the fast-gradient
/// certificates, Table 7.2, the closed-loop runs against the baseline PI
/// (CSV traces), firmware tables, plots (SVG) and `report.md` with every
/// table and the differences from the thesis. The directory appears only
/// when every step has succeeded. `--out` must be new, empty, or (with
/// `--force`) a previous report; anything else is refused before the work
/// starts.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Report directory: a new or empty directory, or a previous report
    /// with --force (anything else is refused before the work starts).
    #[arg(long, default_value = "report")]
    pub out: PathBuf,
    /// Replace a previous report in --out (only a directory written by
    /// `kestrel pipeline`, holding nothing it did not write), when the run
    /// succeeds.
    #[arg(long)]
    pub force: bool,
    /// TOML configuration (every key documented in the built-in default,
    /// `crates/cli/kestrel.toml`; unknown keys are rejected).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Use the flight logs `flight-1-hover.csv`, `flight-2-decoupled.csv`,
    /// `flight-3-coupled.csv`, `flight-4-ground.csv` from this directory
    /// (the columns of `kestrel simulate`) instead of simulating them.
    #[arg(long)]
    pub flights: Option<PathBuf>,
    /// The shortened pipeline (the configuration's `[quick]` keys).
    #[arg(long)]
    pub quick: bool,
    /// Print the built-in configuration and exit.
    #[arg(long)]
    pub print_config: bool,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.print_config {
        print!("{}", crate::pipeline::config::DEFAULT_TOML);
        return Ok(());
    }
    let (config, config_source) = match &args.config {
        Some(p) => (config::read(p)?, p.display().to_string()),
        None => (
            config::builtin()?,
            "the built-in default (`crates/cli/kestrel.toml`)".to_string(),
        ),
    };
    let dir = run_pipeline(&Options {
        out: args.out,
        config,
        config_source,
        flights: args.flights,
        quick: args.quick,
        force: args.force,
    })?;
    eprintln!(
        "pipeline done: report in {}",
        dir.join("report.md").display()
    );
    Ok(())
}
