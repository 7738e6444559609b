//! `kestrel codegen`: every generated file of the workspace, written or checked.

use crate::io;
use anyhow::{Context, bail};
use kestrel_tricopter::codegen::{
    GeneratedFile, Status, find_workspace_root, generated_files, is_workspace_root,
};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Writes every generated file of the workspace from its inputs: the
/// example firmware's tables (`avr/firmware/src/generated*.rs`, from the
/// design model `models/tricopter-blackbox-5.json`), the libraries' golden
/// tables (kestrel-empc's `tests/generated/box2_*.rs`, kestrel-fgm's
/// `tests/data/fgm_q16.rs`) and the fixtures derived from the design model.
///
/// Only files whose contents changed are written, each to a temporary file
/// beside it and renamed into place; nothing is deleted. With `--check`
/// nothing is written: the command fails, naming every stale or missing
/// file (CI runs it).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Compare only: fail, listing every stale or missing file; write nothing.
    #[arg(long)]
    pub check: bool,
    /// Workspace root: a folder with a `Cargo.toml` holding `[workspace]`
    /// and an `avr/firmware` folder (default: the first such folder at or
    /// above the current one).
    #[arg(long)]
    pub root: Option<PathBuf>,
}

/// Runs `kestrel codegen`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let root = match args.root {
        Some(root) if is_workspace_root(&root) => root,
        Some(root) => bail!(
            "--root {}: not a workspace root (a Cargo.toml with [workspace] and an avr/firmware folder); nothing written",
            root.display()
        ),
        None => {
            let cwd = std::env::current_dir().context("reading the current directory")?;
            find_workspace_root(&cwd).with_context(|| {
                format!(
                    "no workspace root (Cargo.toml with [workspace] and avr/firmware) at or above {}; give --root",
                    cwd.display()
                )
            })?
        }
    };
    let spinner = crate::progress::Spinner::new("generating the firmware tables and golden files");
    let files = generated_files(&root)
        .with_context(|| format!("generating the files of {}", root.display()))?;
    drop(spinner);
    let mut changed: Vec<(&GeneratedFile, Status)> = Vec::new();
    for f in &files {
        let status = f.status(&root)?;
        if status != Status::Fresh {
            changed.push((f, status));
        }
    }
    if args.check {
        if changed.is_empty() {
            println!(
                "codegen: all {} generated files are up to date",
                files.len()
            );
            return Ok(());
        }
        let mut list = String::new();
        for (f, status) in &changed {
            let _ = write!(
                list,
                "\n  {}: {} ({})",
                f.path,
                describe(*status),
                f.generator
            );
        }
        bail!(
            "{} of {} generated files are stale or missing (run `kestrel codegen`):{list}",
            changed.len(),
            files.len()
        );
    }
    // Every changed file is staged, then all are renamed into place.
    let mut outputs = io::Outputs::new();
    for (f, _) in &changed {
        let path = f.location(&root);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        outputs.add(Some(&path), f.contents.as_bytes())?;
    }
    outputs.commit()?;
    for (f, status) in &changed {
        println!("wrote {} (was {})", f.path, describe(*status));
    }
    println!(
        "codegen: {} written, {} up to date",
        changed.len(),
        files.len() - changed.len()
    );
    Ok(())
}

/// How a file that is not fresh is named in the output.
fn describe(status: Status) -> &'static str {
    match status {
        Status::Fresh => "up to date",
        Status::Stale => "stale",
        Status::Missing => "missing",
    }
}
