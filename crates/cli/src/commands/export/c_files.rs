//! `kestrel export --lang c`: the two C files written into a folder,
//! together and atomically, replacing only files an earlier export wrote.

use crate::io::Outputs;
use anyhow::{Context, bail};
use kestrel_tricopter::firmware::c_tables::{C_GENERATED_MARKER, C_HEADER_NAME, C_SOURCE_NAME};
use std::path::Path;

/// Whether `path` may be written: nothing there, or a regular file (or a
/// link to one) that starts with [`C_GENERATED_MARKER`].
fn check_replaceable(path: &Path) -> anyhow::Result<()> {
    let shown = path.display();
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            // A dangling symbolic link is not ours to replace either.
            if std::fs::symlink_metadata(path).is_ok() {
                bail!(
                    "{shown} is a broken symbolic link; remove it or give another --out folder (nothing was written)"
                );
            }
            return Ok(());
        }
        Err(e) => return Err(e).with_context(|| format!("{shown}")),
    };
    if !meta.is_file() {
        bail!("{shown} exists and is not a file; give another --out folder (nothing was written)");
    }
    let mut head = [0u8; 128];
    let n = std::io::Read::read(
        &mut std::fs::File::open(path).with_context(|| format!("reading {shown}"))?,
        &mut head,
    )
    .with_context(|| format!("reading {shown}"))?;
    if !head[..n].starts_with(C_GENERATED_MARKER.as_bytes()) {
        bail!(
            "{shown} exists and was not written by `kestrel export --lang c`; move it away or give another --out folder (nothing was written)"
        );
    }
    Ok(())
}

/// Writes `files` (name, text) into the folder `dir` (created when
/// missing, with its parent existing): all or none.
pub fn write(dir: &Path, files: &[(&str, &str)]) -> anyhow::Result<()> {
    let shown = dir.display();
    let made = match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => false,
        Ok(_) => bail!(
            "--out {shown} exists and is not a folder; with --lang c, --out names the folder for {C_HEADER_NAME} and {C_SOURCE_NAME} (nothing was written)"
        ),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            // (A Ctrl-C before the files are in place leaves it empty.)
            std::fs::create_dir(dir)
                .with_context(|| format!("creating the --out folder {shown}"))?;
            true
        }
        Err(e) => return Err(e).with_context(|| format!("--out {shown}")),
    };
    let result = (|| {
        for (name, _) in files {
            check_replaceable(&dir.join(name))?;
        }
        let mut out = Outputs::new();
        for (name, text) in files {
            out.add(Some(&dir.join(name)), text)?;
        }
        out.commit()
    })();
    if result.is_err() && made {
        // Empty unless a commit failed half-way; then keep what is there.
        let _ = std::fs::remove_dir(dir);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_texts(dir: &Path, text: &str) -> anyhow::Result<()> {
        let h = format!("{C_GENERATED_MARKER} h {text}");
        let c = format!("{C_GENERATED_MARKER} c {text}");
        write(dir, &[(C_HEADER_NAME, &h), (C_SOURCE_NAME, &c)])
    }

    #[test]
    fn writes_a_new_folder_and_replaces_its_own_files_only() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        write_texts(&dir, "1").unwrap();
        write_texts(&dir, "2").unwrap();
        let h = dir.join(C_HEADER_NAME);
        assert!(std::fs::read_to_string(&h).unwrap().ends_with(" 2"));
        std::fs::write(&h, "/* mine */").unwrap();
        let err = format!("{:#}", write_texts(&dir, "3").unwrap_err());
        assert!(err.contains("was not written by"), "{err}");
        assert_eq!(std::fs::read_to_string(&h).unwrap(), "/* mine */");
        let c = std::fs::read_to_string(dir.join(C_SOURCE_NAME)).unwrap();
        assert!(c.ends_with(" 2"), "the other file was kept too: {c}");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
    }

    #[test]
    fn refuses_a_file_as_folder_and_a_missing_parent() {
        let root = tempfile::tempdir().unwrap();
        let file = root.path().join("f");
        std::fs::write(&file, "x").unwrap();
        assert!(write_texts(&file, "1").is_err());
        let deep = root.path().join("no/such");
        assert!(write_texts(&deep, "1").is_err());
        assert!(!root.path().join("no").exists());
    }
}
