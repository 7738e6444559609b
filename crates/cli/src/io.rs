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
///
/// Only a regular file (or a new one) is replaced that way: a symbolic link
/// is followed and its target replaced, and anything else that exists at
/// `path` (`/dev/null`, a FIFO, a terminal) is written in place, since
/// renaming over it would replace the device itself.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let target = match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => std::fs::canonicalize(path)
            .with_context(|| format!("resolving the link {}", path.display()))?,
        _ => path.to_path_buf(),
    };
    let path = target.as_path();
    if let Ok(m) = std::fs::metadata(path)
        && !m.is_file()
    {
        return std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()));
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_are_written_in_place_not_replaced() {
        let null = Path::new("/dev/null");
        if std::fs::metadata(null).is_ok_and(|m| !m.is_file()) {
            write_atomic(null, b"discarded").unwrap();
            assert!(
                !std::fs::metadata(null).unwrap().is_file(),
                "/dev/null was replaced"
            );
        }
    }

    #[test]
    fn links_are_followed_and_files_replaced() {
        let dir = std::env::temp_dir().join(format!("kestrel-io-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("target.txt");
        let link = dir.join("link.txt");
        std::fs::write(&file, "old").unwrap();
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(&file, &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "new");
        write_atomic(&file, b"newer").unwrap();
        assert_eq!(std::fs::read_to_string(&link).unwrap(), "newer");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
