//! `kestrel c2d`: zero-order-hold discretisation of a continuous-time model.

use crate::io;
use anyhow::Context;
use kestrel_core::formats::SsModel;
use std::path::PathBuf;

/// Reads a continuous-time `kestrel.ss.v1` model (`"ts": 0`) and writes the
/// zero-order-hold discretised model (`kestrel.ss.v1` with the given `ts`).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Continuous-time model file (`kestrel.ss.v1` with `"ts": 0`).
    #[arg(long)]
    pub model: PathBuf,
    /// Sample time in seconds.
    #[arg(long, allow_negative_numbers = true)]
    pub ts: f64,
    /// Output file (default: standard output).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub replace: io::Replace,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.replace.check(&[args.out.as_deref()])?;
    if !(args.ts.is_finite() && args.ts > 0.0) {
        anyhow::bail!(
            "--ts: the sample time must be a positive number of seconds, got {}",
            args.ts
        );
    }
    let model = SsModel::read(&args.model).with_context(|| format!("{}", args.model.display()))?;
    let discrete = model
        .c2d(args.ts)
        .with_context(|| format!("{}", args.model.display()))?;
    io::write_output(args.out.as_deref(), &discrete.to_json_string())
}
