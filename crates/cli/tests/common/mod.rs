//! Helpers shared by the `kestrel` end-to-end tests (each test file that
//! uses them declares `mod common;`).
// Each test file uses a subset of these helpers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs the `kestrel` binary with `args` and returns whether it succeeded,
/// its standard output and its standard error.
pub fn kestrel(args: &[&str]) -> (bool, String, String) {
    output_of(Command::new(env!("CARGO_BIN_EXE_kestrel")).args(args))
}

/// [`kestrel`] run in the working directory `dir`.
pub fn kestrel_in(dir: &Path, args: &[&str]) -> (bool, String, String) {
    output_of(
        Command::new(env!("CARGO_BIN_EXE_kestrel"))
            .args(args)
            .current_dir(dir),
    )
}

fn output_of(cmd: &mut Command) -> (bool, String, String) {
    let out = cmd.output().expect("runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A temporary directory `kestrel-<name>-<pid>`, created if missing.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("kestrel-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}
