//! A generated file, how it compares with the tree, and what can go wrong
//! while generating one.

use std::path::{Path, PathBuf};

/// One generated file of the workspace: where it goes, what it holds and
/// what produces it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GeneratedFile {
    /// Path relative to the workspace root, with `/` separators.
    pub path: &'static str,
    /// The contents the generator produces (UTF-8 text).
    pub contents: String,
    /// What produces it: the function and its inputs.
    pub generator: &'static str,
}

/// How a file in the tree compares with what the generator produces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// The file holds exactly the generated contents.
    Fresh,
    /// The file exists with other contents.
    Stale,
    /// There is no file at the path.
    Missing,
}

impl GeneratedFile {
    /// The file's location under the workspace root `root`.
    pub fn location(&self, root: &Path) -> PathBuf {
        root.join(self.path)
    }

    /// Compares the file under `root` with the generated contents, byte
    /// for byte. Reads only.
    ///
    /// # Errors
    /// [`CodegenError::Io`] when the file exists but cannot be read.
    pub fn status(&self, root: &Path) -> Result<Status, CodegenError> {
        let path = self.location(root);
        match std::fs::read(&path) {
            Ok(bytes) if bytes == self.contents.as_bytes() => Ok(Status::Fresh),
            Ok(_) => Ok(Status::Stale),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Status::Missing),
            Err(source) => Err(CodegenError::Io { path, source }),
        }
    }
}

/// Why the generated files could not be produced.
#[derive(Debug, thiserror::Error)]
pub enum CodegenError {
    /// An input (or a file to compare) could not be read.
    #[error("reading {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// An input file is not in its format.
    #[error("{}: {source}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// The format error.
        source: kestrel_core::formats::FormatError,
    },
    /// The firmware design refused the model.
    #[error("firmware design: {0}")]
    Design(#[from] crate::firmware::DesignError),
    /// The tricopter problem could not be built from the model.
    #[error("tricopter problem: {0}")]
    Problem(#[from] crate::TricopterError),
    /// kestrel-empc refused a problem or a table.
    #[error("explicit MPC: {0}")]
    Empc(#[from] kestrel_empc::EmpcError),
    /// kestrel-fgm refused a problem.
    #[error("fast gradient: {0}")]
    Fgm(#[from] kestrel_fgm::FgmError),
    /// cbindgen could not generate kestrel-ffi's header.
    #[error("C header (cbindgen): {0}")]
    Header(String),
    /// kestrel-avr-rt has no 16-bit table for an explicit controller.
    #[error("16-bit explicit-MPC table: {0}")]
    Quantize(#[from] kestrel_avr_rt::explicit::quantize::QuantizeError),
}

/// Reads the input file `rel` (relative to `root`) as text.
pub(super) fn read_input(root: &Path, rel: &str) -> Result<String, CodegenError> {
    let path = root.join(rel);
    std::fs::read_to_string(&path).map_err(|source| CodegenError::Io { path, source })
}

/// Parses the input `rel` with `parse`, naming the file in the error.
pub(super) fn parse_input<T>(
    root: &Path,
    rel: &str,
    parse: impl FnOnce(&str) -> Result<T, kestrel_core::formats::FormatError>,
) -> Result<T, CodegenError> {
    let text = read_input(root, rel)?;
    parse(&text).map_err(|source| CodegenError::Format {
        path: root.join(rel),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_compares_bytes() {
        let root = std::env::temp_dir().join(format!("kestrel-codegen-{}", std::process::id()));
        std::fs::create_dir_all(root.join("a")).unwrap();
        let f = GeneratedFile {
            path: "a/t.rs",
            contents: "x\n".into(),
            generator: "test",
        };
        assert_eq!(f.status(&root).unwrap(), Status::Missing);
        std::fs::write(f.location(&root), "x\n").unwrap();
        assert_eq!(f.status(&root).unwrap(), Status::Fresh);
        std::fs::write(f.location(&root), "x\n\n").unwrap();
        assert_eq!(f.status(&root).unwrap(), Status::Stale);
        std::fs::remove_dir_all(&root).unwrap();
    }
}
