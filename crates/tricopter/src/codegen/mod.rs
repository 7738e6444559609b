//! Every generated file committed to the workspace, from its inputs.
//!
//! [`generated_files`] lists them: the example firmware's tables
//! (`avr/firmware/src/generated*.rs`, [`firmware`]), the libraries' golden
//! tables and the fixtures derived from the design model ([`golden`]),
//! and kestrel-ffi's C header ([`header`]).
//! Inputs are read from the workspace root given (the design model
//! `models/tricopter-blackbox-5.json`, the golden problems in the
//! libraries' `tests/` folders); nothing is written here. `kestrel codegen`
//! writes the files that changed, and `kestrel codegen --check` (run by
//! CI) fails on a stale or missing one; tests only compare.
//!
//! ```no_run
//! use kestrel_tricopter::codegen::{Status, find_workspace_root, generated_files};
//! let root = find_workspace_root(&std::env::current_dir().unwrap()).unwrap();
//! for f in generated_files(&root).unwrap() {
//!     if f.status(&root).unwrap() != Status::Fresh {
//!         println!("stale: {} ({})", f.path, f.generator);
//!     }
//! }
//! ```

mod file;
pub mod firmware;
pub mod golden;
pub mod header;

pub use file::{CodegenError, GeneratedFile, Status};

use std::path::{Path, PathBuf};

/// Every generated file of the workspace rooted at `root`, computed from
/// the inputs under `root`: the firmware tables first, then the golden
/// files and model fixtures, then the C header, in a fixed order.
///
/// # Errors
/// The first [`CodegenError`] of [`firmware::files`], [`golden::empc_files`],
/// [`golden::fgm_file`], [`golden::model_files`] and [`header::header_file`].
pub fn generated_files(root: &Path) -> Result<Vec<GeneratedFile>, CodegenError> {
    let mut files = firmware::files(root)?;
    files.extend(golden::empc_files(root)?);
    files.push(golden::fgm_file(root)?);
    files.extend(golden::model_files(root)?);
    files.push(header::header_file(root)?);
    Ok(files)
}

/// The workspace root at or above `start`: the first directory holding a
/// `Cargo.toml` with a `[workspace]` table and an `avr/firmware` folder.
pub fn find_workspace_root(start: &Path) -> Option<PathBuf> {
    start
        .ancestors()
        .find(|dir| is_workspace_root(dir))
        .map(Path::to_path_buf)
}

/// Whether `dir` is a workspace root: a `Cargo.toml` with a `[workspace]`
/// table and an `avr/firmware` folder.
pub fn is_workspace_root(dir: &Path) -> bool {
    dir.join("avr/firmware").is_dir()
        && std::fs::read_to_string(dir.join("Cargo.toml"))
            .is_ok_and(|t| t.lines().any(|l| l.trim() == "[workspace]"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workspace_root_is_found_from_a_crate_folder() {
        let here = Path::new(env!("CARGO_MANIFEST_DIR"));
        let root = find_workspace_root(here).expect("workspace root");
        assert_eq!(
            root.canonicalize().unwrap(),
            here.join("../..").canonicalize().unwrap()
        );
        assert!(find_workspace_root(&root.join("avr")).is_some());
        assert_eq!(find_workspace_root(Path::new("/")), None);
    }
}
