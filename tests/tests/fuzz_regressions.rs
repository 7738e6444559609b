//! The fuzz corpus kept as regression tests: every file under
//! `fuzz/regressions/<target>/` goes through the fuzz target's entry point
//! (`fuzz/src/harness.rs`, the very code the cargo-fuzz targets run) on
//! the stable toolchain, and must come back `Ok` or as a clean error, never
//! a panic.
//!
//! - `seed-*` files are valid inputs: they must read (`Ok`).
//! - Any other file (an input fuzzing found) has a `<file>.expected`
//!   beside it: `ok`, or `err: <text>` with text the error must contain.

#[allow(dead_code)]
#[path = "../../fuzz/src/harness.rs"]
mod harness;

use std::path::{Path, PathBuf};

fn regressions() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/regressions")
}

/// The inputs of one target, sorted (the `.expected` files left out).
fn inputs(target: &str) -> Vec<PathBuf> {
    let dir = regressions().join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_none_or(|x| x != "expected"))
        .collect();
    files.sort();
    files
}

/// Runs one input through its entry point, naming the file on a panic.
fn run(entry: harness::Entry, file: &Path) -> harness::Outcome {
    let data = std::fs::read(file).unwrap();
    std::panic::catch_unwind(|| entry(&data))
        .unwrap_or_else(|_| panic!("{}: the entry point panicked", file.display()))
}

#[test]
fn every_regression_input_reads_or_fails_cleanly() {
    let mut checked = 0;
    for (target, entry) in harness::TARGETS {
        let files = inputs(target);
        assert!(
            files.iter().any(|f| name(f).starts_with("seed-")),
            "{target}: no seed input"
        );
        for file in files {
            let outcome = run(entry, &file);
            let expected = file.with_file_name(format!("{}.expected", name(&file)));
            if name(&file).starts_with("seed-") {
                assert_eq!(outcome, Ok(()), "{}: a seed must read", file.display());
            } else {
                let want = std::fs::read_to_string(&expected).unwrap_or_else(|e| {
                    panic!(
                        "{}: {e} (a found input needs its expected outcome)",
                        expected.display()
                    )
                });
                check(&file, &outcome, want.trim());
            }
            checked += 1;
        }
    }
    assert!(checked >= harness::TARGETS.len());
}

fn name(file: &Path) -> String {
    file.file_name().unwrap().to_string_lossy().into_owned()
}

/// `want` is `ok` or `err: <text the error contains>`.
fn check(file: &Path, outcome: &harness::Outcome, want: &str) {
    match (want.strip_prefix("err:"), outcome) {
        (None, _) => assert_eq!(
            (want, outcome),
            ("ok", &Ok(())),
            "{}: expected outcome",
            file.display()
        ),
        (Some(text), Err(e)) => assert!(
            e.contains(text.trim()),
            "{}: error {e:?} does not contain {:?}",
            file.display(),
            text.trim()
        ),
        (Some(text), Ok(())) => panic!(
            "{}: read, but expected an error with {text:?}",
            file.display()
        ),
    }
}
