//! Output helpers shared by the subcommands: every output file is written
//! atomically, and a command that writes several writes them together.
//!
//! [`Outputs`] stages each file in a temporary file beside its destination
//! (same directory, so the final step is a rename on one file system) and
//! [`Outputs::commit`] renames them all into place once every file has been
//! written in full. Dropped without a commit (an error on the way), the
//! temporary files are removed: a failed command leaves nothing new behind.
//!
//! The temporary files come from the `tempfile` crate: unpredictable
//! names created exclusively (two outputs, two runs or two threads never
//! share one, and nothing that already exists is overwritten), removal on
//! drop, including on an early `?` return, and a well-kept crate that
//! is already in the build's dependency tree. SIGINT skips destructors, so
//! every temporary file is also registered with [`crate::interrupt`],
//! whose Ctrl-C handler removes it.

use crate::interrupt;
use anyhow::Context;
use std::io::Write;
use std::path::{Path, PathBuf};

/// One staged output.
enum Staged {
    /// A regular (or new) file: written to a temporary sibling, renamed at commit.
    File {
        tmp: tempfile::NamedTempFile,
        dest: PathBuf,
        /// Removed by a Ctrl-C until committed ([`crate::interrupt`]).
        token: interrupt::Token,
    },
    /// A device, FIFO or other non-regular file (`/dev/null`, a terminal):
    /// written in place at commit, since renaming over it would replace it.
    InPlace { dest: PathBuf, bytes: Vec<u8> },
    /// Standard output.
    Stdout(Vec<u8>),
}

/// Output files written together: each staged beside its destination by
/// [`Outputs::add`], all put in place by [`Outputs::commit`].
#[derive(Default)]
pub struct Outputs {
    staged: Vec<Staged>,
}

impl Outputs {
    /// No outputs yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Stages `bytes` for `path`, or for standard output when `path` is
    /// `None`. A file is written in full to a temporary file in the same
    /// directory now (so a full disk or a missing directory fails here,
    /// before anything is put in place); standard output is written at
    /// [`Outputs::commit`].
    pub fn add(&mut self, path: Option<&Path>, bytes: impl AsRef<[u8]>) -> anyhow::Result<()> {
        let bytes = bytes.as_ref();
        let Some(path) = path else {
            self.staged.push(Staged::Stdout(bytes.to_vec()));
            return Ok(());
        };
        // A symbolic link is followed and its target replaced.
        let dest = match std::fs::symlink_metadata(path) {
            Ok(m) if m.file_type().is_symlink() => std::fs::canonicalize(path)
                .with_context(|| format!("resolving the link {}", path.display()))?,
            _ => path.to_path_buf(),
        };
        let existing = std::fs::metadata(&dest).ok();
        if let Some(m) = &existing {
            if m.is_dir() {
                anyhow::bail!(
                    "{} is a directory; give a file name to write to",
                    path.display()
                );
            }
            if !m.is_file() {
                self.staged.push(Staged::InPlace {
                    dest,
                    bytes: bytes.to_vec(),
                });
                return Ok(());
            }
        }
        let (dir, name) = parent_and_name(&dest)
            .with_context(|| format!("{}: not a file name", path.display()))?;
        let prefix = format!(".{name}.");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".tmp");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            // As `File::create` would (0666 less the umask), not 0600.
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        // Created and registered together: a Ctrl-C removes it.
        let (mut tmp, token) = interrupt::with_registry(|reg| {
            builder.tempfile_in(dir).map(|tmp| {
                let token = reg.add(interrupt::Leftover::File(tmp.path().to_path_buf()));
                (tmp, token)
            })
        })
        .map_err(without_temp_name)
        .with_context(|| format!("writing {}", path.display()))?;
        if let Some(m) = &existing {
            // Replacing a file keeps its permissions.
            tmp.as_file()
                .set_permissions(m.permissions())
                .with_context(|| format!("writing {}", path.display()))?;
        }
        tmp.write_all(bytes)
            .and_then(|()| tmp.as_file().sync_all())
            .with_context(|| format!("writing {}", path.display()))?;
        self.staged.push(Staged::File { tmp, dest, token });
        Ok(())
    }

    /// Writes standard output and devices, then renames every staged file
    /// into place. Should a rename fail, the files not yet renamed are
    /// removed (those already in place stay: each is complete).
    pub fn commit(self) -> anyhow::Result<()> {
        let mut files = Vec::new();
        for s in self.staged {
            match s {
                Staged::Stdout(bytes) => {
                    let mut out = std::io::stdout().lock();
                    out.write_all(&bytes)
                        .and_then(|()| out.flush())
                        .context("writing to standard output")?;
                }
                Staged::InPlace { dest, bytes } => std::fs::write(&dest, bytes)
                    .with_context(|| format!("writing {}", dest.display()))?,
                Staged::File { tmp, dest, token } => files.push((tmp, dest, token)),
            }
        }
        // The renames under the interrupt lock: a Ctrl-C now waits for
        // them, so it leaves all the files in place or none.
        interrupt::with_registry(|reg| {
            for (_, _, token) in &mut files {
                reg.release(token);
            }
            for (tmp, dest, _) in files {
                tmp.persist(&dest)
                    .map_err(|e| without_temp_name(e.error))
                    .with_context(|| format!("writing {}", dest.display()))?;
            }
            Ok(())
        })
    }
}

/// The error of a temporary-file operation without the temporary file's
/// name: tempfile appends ` at path ".name.XXXX.tmp"`, a name the user never
/// chose and cannot find afterwards (the file is gone).
fn without_temp_name(e: std::io::Error) -> std::io::Error {
    let text = e.to_string();
    match text.rsplit_once(" at path ") {
        Some((head, _)) => std::io::Error::new(e.kind(), head.to_string()),
        None => e,
    }
}

/// Writes `text` to `path`, or to standard output when `path` is `None`
/// (one [`Outputs`] entry, committed).
///
/// Only a regular file (or a new one) is replaced by a rename: a symbolic
/// link is followed and its target replaced, and anything else that exists
/// at `path` (`/dev/null`, a FIFO, a terminal) is written in place, since
/// renaming over it would replace the device itself.
pub fn write_output(path: Option<&Path>, text: &str) -> anyhow::Result<()> {
    let mut out = Outputs::new();
    out.add(path, text)?;
    out.commit()
}

/// `--force` of every subcommand that writes files: without it, an output
/// file that exists already is refused before the work starts.
#[derive(clap::Args, Debug, Clone, Copy, Default)]
pub struct Replace {
    /// Replace output files that exist already (without it, an existing
    /// file is refused before the work starts and nothing is written).
    #[arg(long)]
    pub force: bool,
}

impl Replace {
    /// Refuses, unless `--force` was given, every path among `paths` that
    /// names an existing regular file (or a symbolic link to one): a
    /// command never replaces a file it was not told it may replace,
    /// e.g. `--out` mistyped as the input data. New files, devices
    /// (`/dev/null`), FIFOs and directories pass (each command says what
    /// it does with a directory); call it before the work starts.
    ///
    /// Two of `paths` naming the same file are refused even with
    /// `--force`: one output would silently replace the other.
    pub fn check(&self, paths: &[Option<&Path>]) -> anyhow::Result<()> {
        let named: Vec<&Path> = paths.iter().flatten().copied().collect();
        for (i, a) in named.iter().enumerate() {
            for b in &named[i + 1..] {
                if same_file(a, b) {
                    anyhow::bail!(
                        "{} and {} name the same file: give each output its own (nothing was written)",
                        a.display(),
                        b.display()
                    );
                }
            }
        }
        if self.force {
            return Ok(());
        }
        for path in named {
            if std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
                anyhow::bail!(
                    "{} exists; give --force to replace it, or name another file (nothing was written)",
                    path.display()
                );
            }
        }
        Ok(())
    }
}

/// Whether `a` and `b` name one regular (or new) file: the same folder,
/// links resolved, and the same name, or the same existing file. Devices
/// (`/dev/null` twice) are not one output.
fn same_file(a: &Path, b: &Path) -> bool {
    let device = |p: &Path| std::fs::metadata(p).is_ok_and(|m| !m.is_file());
    if device(a) || device(b) {
        return false;
    }
    let id = |p: &Path| -> Option<PathBuf> {
        if let Ok(c) = std::fs::canonicalize(p) {
            return Some(c);
        }
        let (dir, name) = parent_and_name(p)?;
        Some(std::fs::canonicalize(dir).ok()?.join(name))
    };
    match (id(a), id(b)) {
        (Some(x), Some(y)) => x == y,
        _ => a == b,
    }
}

/// The folder `path` lies in (`.` for a bare name) and its last component,
/// or `None` when it has no last component (`/`, `..`): where a temporary
/// sibling of `path` goes and what it is named after.
pub fn parent_and_name(path: &Path) -> Option<(&Path, String)> {
    let name = path.file_name()?.to_string_lossy().into_owned();
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    Some((dir, name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replace_refuses_existing_files_only_without_force() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("f.json");
        let new = dir.path().join("new.json");
        std::fs::write(&file, "mine").unwrap();
        let keep = Replace { force: false };
        let null = Path::new("/dev/null");
        keep.check(&[None, Some(&new), Some(dir.path()), Some(null)])
            .unwrap();
        let err = keep.check(&[Some(&new), Some(&file)]).unwrap_err();
        assert!(
            err.to_string().contains("f.json exists; give --force"),
            "{err}"
        );
        #[cfg(unix)]
        {
            let link = dir.path().join("link.json");
            std::os::unix::fs::symlink(&file, &link).unwrap();
            assert!(keep.check(&[Some(&link)]).is_err());
        }
        Replace { force: true }.check(&[Some(&file)]).unwrap();
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "mine");
        // One file named twice, new or existing, by another spelling too:
        // refused even with --force; /dev/null twice is fine.
        let again = dir.path().join(".").join("new.json");
        let force = Replace { force: true };
        for (a, b) in [(&new, &again), (&file, &file)] {
            let err = force.check(&[Some(a), None, Some(b)]).unwrap_err();
            assert!(err.to_string().contains("name the same file"), "{err}");
        }
        force.check(&[Some(null), Some(null)]).unwrap();
        force.check(&[Some(&new), Some(&file)]).unwrap();
    }

    #[test]
    fn devices_are_written_in_place_not_replaced() {
        let null = Path::new("/dev/null");
        if std::fs::metadata(null).is_ok_and(|m| !m.is_file()) {
            write_output(Some(null), "discarded").unwrap();
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
        write_output(Some(&link), "new").unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "new");
        write_output(Some(&file), "newer").unwrap();
        assert_eq!(std::fs::read_to_string(&link).unwrap(), "newer");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn nothing_is_written_unless_every_output_can_be() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.txt");
        let mut out = Outputs::new();
        out.add(Some(&a), "a").unwrap();
        assert!(out.add(Some(&dir.path().join("no/b.txt")), "b").is_err());
        drop(out);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        let mut out = Outputs::new();
        out.add(Some(&a), "a").unwrap();
        out.add(Some(&dir.path().join("b.txt")), "b").unwrap();
        // Staged, not yet in place.
        assert!(!a.exists());
        out.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "a");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[cfg(unix)]
    #[test]
    fn a_replaced_file_keeps_its_permissions() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.sh");
        std::fs::write(&a, "old").unwrap();
        std::fs::set_permissions(&a, std::fs::Permissions::from_mode(0o750)).unwrap();
        write_output(Some(&a), "new").unwrap();
        let mode = std::fs::metadata(&a).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o750);
        // A new file is not private to its owner like a temporary file.
        let b = dir.path().join("b.txt");
        write_output(Some(&b), "new").unwrap();
        let mode = std::fs::metadata(&b).unwrap().permissions().mode() & 0o777;
        assert_ne!(mode & 0o044, 0, "{mode:o}");
    }

    #[test]
    fn staged_files_are_registered_for_ctrl_c_until_committed() {
        let dir = tempfile::tempdir().unwrap();
        let mut out = Outputs::new();
        out.add(Some(&dir.path().join("a.txt")), "a").unwrap();
        let tmp = match &out.staged[0] {
            Staged::File { tmp, .. } => tmp.path().to_path_buf(),
            _ => unreachable!("a new file is staged in a temporary file"),
        };
        assert!(tmp.exists() && crate::interrupt::tests::registered(&tmp));
        out.commit().unwrap();
        assert!(!tmp.exists() && !crate::interrupt::tests::registered(&tmp));
        let mut out = Outputs::new();
        out.add(Some(&dir.path().join("b.txt")), "b").unwrap();
        drop(out);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn write_errors_do_not_name_the_temporary_file() {
        let missing = std::env::temp_dir()
            .join(format!("kestrel-no-such-dir-{}", std::process::id()))
            .join("p.json");
        let err = write_output(Some(&missing), "x").unwrap_err();
        let text = format!("{err:#}");
        assert!(text.contains("p.json"), "{text}");
        assert!(
            !text.contains(".tmp") && !text.contains("at path"),
            "{text}"
        );
        assert!(!missing.exists());
    }
}
