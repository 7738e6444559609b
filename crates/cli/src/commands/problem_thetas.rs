//! The inputs of the solve commands that take a problem and a file of
//! parameters (`kestrel fgm solve`, `kestrel qp solve`).

use anyhow::Context;
use kestrel_core::formats::{NumberedRows, numbered_parameter_rows};
use std::path::PathBuf;

/// `--problem` and `--thetas`.
#[derive(clap::Args, Debug)]
pub struct ProblemThetas {
    /// Problem file (`kestrel.mpqp.v1`).
    #[arg(long)]
    pub problem: PathBuf,
    /// CSV file, one theta per row (p numbers), no header.
    #[arg(long)]
    pub thetas: PathBuf,
}

impl ProblemThetas {
    /// The parameter rows of `--thetas`, each `p` numbers, with their
    /// lines in the file (so messages name a row's line, blank lines
    /// counted); errors name the file and the line.
    pub fn read_thetas(&self, p: usize) -> anyhow::Result<NumberedRows> {
        let name = || self.thetas.display().to_string();
        let text = std::fs::read_to_string(&self.thetas).with_context(name)?;
        numbered_parameter_rows(&text, p).with_context(name)
    }
}
