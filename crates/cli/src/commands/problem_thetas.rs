//! The inputs of the solve commands that take a problem and a file of
//! parameters (`kestrel fgm solve`, `kestrel qp solve`), and the reader of
//! parameter files they and `kestrel empc eval` share, with its memory
//! guard.

use anyhow::{Context, bail};
use kestrel_core::formats::{NumberedRows, numbered_parameter_rows};
use std::path::{Path, PathBuf};

/// The most memory a command's parameter rows, their results and the
/// output text may take together, estimated before the rows are parsed:
/// 2 GB. A million rows of 9 parameters (the tricopter problems' theta) with 4
/// results take about 0.5 GB.
pub const MAX_PARAMETER_ROWS_BYTES: f64 = 2e9;

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
    /// The parameter rows of `--thetas` ([`read_parameter_rows`]).
    pub fn read_thetas(&self, p: usize, outputs: usize) -> anyhow::Result<NumberedRows> {
        read_parameter_rows(&self.thetas, p, outputs)
    }
}

/// Estimated bytes of `rows` parameter rows of `p` numbers, `outputs`
/// result numbers per row, and the text they came from and go to: each
/// row a vector (`8 p` bytes and about 48 of bookkeeping), its result
/// (as much again for `outputs` numbers) and its output text (about 25
/// characters a number).
fn rows_bytes(text_bytes: u64, rows: u64, p: usize, outputs: usize) -> f64 {
    text_bytes as f64 + rows as f64 * (8.0 * p as f64 + 48.0 + 33.0 * outputs as f64 + 48.0)
}

/// The parameter rows of the file `path`, each `p` numbers, with their
/// lines in the file (so messages name a row's line, blank lines
/// counted), for a command that writes `outputs` numbers per row.
///
/// # Errors
/// The file cannot be read or is malformed (naming the file and the
/// line); or its rows would take more than [`MAX_PARAMETER_ROWS_BYTES`]
/// (from the file's size before it is read, then from its rows, the lines
/// that are not blank, before they are parsed), with the estimate and
/// what to do.
pub fn read_parameter_rows(path: &Path, p: usize, outputs: usize) -> anyhow::Result<NumberedRows> {
    let name = || path.display().to_string();
    let refuse = |what: String, bytes: f64| -> anyhow::Result<NumberedRows> {
        bail!(
            "{}: {what} would take about {} of memory with the results (at most {} per call); split the file and run the command on each part",
            name(),
            kestrel_mpc::human_bytes(bytes),
            kestrel_mpc::human_bytes(MAX_PARAMETER_ROWS_BYTES)
        )
    };
    if let Ok(meta) = std::fs::metadata(path)
        && meta.is_file()
        && meta.len() as f64 > MAX_PARAMETER_ROWS_BYTES
    {
        return refuse(format!("{} bytes of text", meta.len()), meta.len() as f64);
    }
    let text = std::fs::read_to_string(path).with_context(name)?;
    // The rows are the lines that are not blank (lines end in \n, \r\n or \r).
    let rows = text
        .split(['\n', '\r'])
        .filter(|l| !l.trim().is_empty())
        .count() as u64;
    let bytes = rows_bytes(text.len() as u64, rows, p, outputs);
    if bytes > MAX_PARAMETER_ROWS_BYTES {
        return refuse(
            format!("{rows} rows of {p} parameters ({outputs} results each)"),
            bytes,
        );
    }
    numbered_parameter_rows(&text, p).with_context(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_estimate_counts_rows_results_and_text() {
        // A million thesis-sized rows (9 parameters of about 20 characters,
        // 4 results): 180 MB of text and 72 + 48 + 132 + 48 bytes a row,
        // well inside the budget; 50 million one-number rows are not.
        let thesis = rows_bytes(180_000_000, 1_000_000, 9, 4);
        assert_eq!(thesis, 480e6);
        assert!(rows_bytes(100_000_000, 50_000_000, 1, 1) > MAX_PARAMETER_ROWS_BYTES);
    }
}
