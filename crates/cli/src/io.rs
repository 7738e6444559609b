//! Output helpers shared by the subcommands.

use anyhow::Context;
use std::io::Write;
use std::path::Path;

/// Writes `text` to `path`, or to standard output when `path` is `None`.
///
/// A file is written to a temporary sibling first and renamed into place,
/// so a failed run never leaves a half-written file that looks complete.
pub fn write_output(path: Option<&Path>, text: &str) -> anyhow::Result<()> {
    match path {
        None => {
            let mut out = std::io::stdout().lock();
            out.write_all(text.as_bytes())
                .context("writing to standard output")?;
            out.flush().context("writing to standard output")
        }
        Some(p) => write_atomic(p, text.as_bytes()),
    }
}

/// Writes bytes to a file atomically (temporary file, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    std::fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("writing {}", path.display()))
}
