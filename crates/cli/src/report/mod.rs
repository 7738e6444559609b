//! The report layer of `kestrel pipeline`: a report directory that appears
//! only when complete, markdown tables and SVG plots.

pub mod document;
pub mod plot;
pub mod table;

use crate::interrupt;
use anyhow::{Context, bail};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The file in every report that marks it as one and lists the files the
/// report wrote (first line [`MARKER_HEADER`], then one relative path, with
/// `/` separators, per line).
pub const MARKER: &str = ".kestrel-report";

/// The first line of [`MARKER`].
pub const MARKER_HEADER: &str = "kestrel pipeline report";

/// A report directory written in a hidden staging directory beside its
/// final place and moved there by [`ReportDir::finish`]; dropped unfinished
/// (an error on the way), the staging directory is removed, so a failed
/// run never leaves a half-written report that looks complete.
///
/// Nothing the command did not create is replaced: [`ReportDir::create`]
/// accepts a new or empty directory, and a previous report (one with a
/// [`MARKER`] listing every file in it) only when `force` is set; anything
/// else is refused before the work starts.
#[derive(Debug)]
pub struct ReportDir {
    final_dir: PathBuf,
    staging: PathBuf,
    /// Parent directories [`ReportDir::create`] made, deepest first.
    made_parents: Vec<PathBuf>,
    force: bool,
    finished: bool,
    /// The staging directory and the parents made, removed by a Ctrl-C
    /// until finished ([`crate::interrupt`]).
    tokens: [interrupt::Token; 2],
}

/// What is at a report's destination.
#[derive(Debug, PartialEq)]
enum Destination {
    /// Nothing, or an empty directory: the report is renamed there.
    Free,
    /// A previous report to be replaced (`--force`).
    PreviousReport,
}

/// Checks what is at `dir`: see [`ReportDir`].
fn check_destination(dir: &Path, force: bool) -> anyhow::Result<Destination> {
    let shown = dir.display();
    let meta = match std::fs::symlink_metadata(dir) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Destination::Free),
        Err(e) => return Err(e).with_context(|| format!("--out {shown}")),
    };
    if meta.file_type().is_symlink() {
        bail!(
            "--out {shown} is a symbolic link; give the directory it points to, or a new directory (nothing was written)"
        );
    }
    if !meta.is_dir() {
        bail!(
            "--out {shown} exists and is not a directory; give a new or empty directory for the report (nothing was written)"
        );
    }
    let mut entries = std::fs::read_dir(dir).with_context(|| format!("reading --out {shown}"))?;
    if entries.next().is_none() {
        return Ok(Destination::Free);
    }
    let Some(listed) = read_marker(dir)? else {
        let md = std::fs::read_to_string(dir.join("report.md")).unwrap_or_default();
        if md.starts_with("# kestrel pipeline report") {
            bail!(
                "--out {shown} holds a report of an earlier kestrel version (it has no {MARKER} listing its files); remove it yourself, or give another directory (nothing was written)"
            );
        }
        bail!(
            "--out {shown} is not empty and is not a kestrel report (it has no {MARKER}); give a new or empty directory, or move its contents away (nothing was written)"
        );
    };
    if !force {
        bail!(
            "--out {shown} holds a previous kestrel report; add --force to replace it, or give another directory (nothing was written)"
        );
    }
    let foreign: Vec<String> = files_in(dir)?
        .into_iter()
        .filter(|f| f != MARKER && !listed.contains(f))
        .collect();
    if !foreign.is_empty() {
        let shown_list: Vec<&str> = foreign.iter().take(5).map(String::as_str).collect();
        bail!(
            "--out {shown} holds a previous kestrel report and {} file(s) the report did not write ({}{}); move them away before replacing it with --force (nothing was written)",
            foreign.len(),
            shown_list.join(", "),
            if foreign.len() > 5 { ", ..." } else { "" }
        );
    }
    Ok(Destination::PreviousReport)
}

/// The files listed in `dir`'s [`MARKER`], or `None` if it has none.
fn read_marker(dir: &Path) -> anyhow::Result<Option<BTreeSet<String>>> {
    let path = dir.join(MARKER);
    match std::fs::symlink_metadata(&path) {
        Ok(m) if m.is_file() => {}
        _ => return Ok(None),
    }
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let mut lines = text.lines();
    if lines.next() != Some(MARKER_HEADER) {
        return Ok(None);
    }
    Ok(Some(lines.map(str::to_string).collect()))
}

/// Every file under `dir` (relative, `/`-separated, sorted; symbolic links
/// not followed), and every empty directory as `name/`.
fn files_in(dir: &Path) -> anyhow::Result<Vec<String>> {
    fn walk(dir: &Path, rel: &str, out: &mut Vec<String>) -> anyhow::Result<()> {
        let mut empty = true;
        for e in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
            let e = e.with_context(|| format!("reading {}", dir.display()))?;
            empty = false;
            let name = e.file_name().to_string_lossy().into_owned();
            let r = if rel.is_empty() {
                name
            } else {
                format!("{rel}/{name}")
            };
            let t = e
                .file_type()
                .with_context(|| format!("reading {}", e.path().display()))?;
            if t.is_dir() {
                walk(&e.path(), &r, out)?;
            } else {
                out.push(r);
            }
        }
        if empty && !rel.is_empty() {
            out.push(format!("{rel}/"));
        }
        Ok(())
    }
    let mut out = Vec::new();
    walk(dir, "", &mut out)?;
    out.sort();
    Ok(out)
}

impl ReportDir {
    /// Starts a report that will end up in `final_dir`, after checking that
    /// nothing but a previous report (with `force`) would be replaced.
    pub fn create(final_dir: &Path, force: bool) -> anyhow::Result<Self> {
        check_destination(final_dir, force)?;
        let (parent, name) = crate::io::parent_and_name(final_dir)
            .with_context(|| format!("--out {}: not a directory name", final_dir.display()))?;
        let mut made_parents = Vec::new();
        let mut p = parent;
        while !p.as_os_str().is_empty() && std::fs::symlink_metadata(p).is_err() {
            made_parents.push(p.to_path_buf());
            p = p.parent().unwrap_or(Path::new(""));
        }
        // Made and registered together: a Ctrl-C removes them.
        let (staging, tokens) = interrupt::with_registry(|reg| {
            let mut parents = reg.add(interrupt::Leftover::EmptyDirs(made_parents.clone()));
            if let Err(e) = std::fs::create_dir_all(parent) {
                reg.release(&mut parents);
                return Err(e).with_context(|| format!("creating {}", parent.display()));
            }
            let mut n = 0u32;
            let staging = loop {
                let s = parent.join(format!(".{name}.partial-{}-{n}", std::process::id()));
                match std::fs::create_dir(&s) {
                    Ok(()) => break s,
                    Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && n < 1000 => n += 1,
                    Err(e) => {
                        remove_made(&made_parents);
                        reg.release(&mut parents);
                        return Err(e).with_context(|| format!("creating {}", s.display()));
                    }
                }
            };
            let tree = reg.add(interrupt::Leftover::Tree(staging.clone()));
            anyhow::Ok((staging, [tree, parents]))
        })?;
        Ok(ReportDir {
            final_dir: final_dir.to_path_buf(),
            staging,
            made_parents,
            force,
            finished: false,
            tokens,
        })
    }

    /// Where a file of the report is written while the report is built.
    pub fn path(&self, rel: &str) -> PathBuf {
        self.staging.join(rel)
    }

    /// Writes a file of the report (creating subdirectories).
    pub fn write(&self, rel: &str, bytes: impl AsRef<[u8]>) -> anyhow::Result<PathBuf> {
        let p = self.path(rel);
        if let Some(dir) = p.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        std::fs::write(&p, bytes).with_context(|| format!("writing {}", p.display()))?;
        Ok(p)
    }

    /// Writes the [`MARKER`] and moves the finished report into place,
    /// replacing a previous report (checked again: see [`ReportDir::create`]).
    /// Should the move fail, the previous report is put back.
    pub fn finish(mut self) -> anyhow::Result<PathBuf> {
        let mut marker = format!("{MARKER_HEADER}\n");
        for f in files_in(&self.staging)? {
            marker.push_str(&f);
            marker.push('\n');
        }
        self.write(MARKER, marker)?;
        // The moves under the interrupt lock: a Ctrl-C now waits for them.
        interrupt::with_registry(|reg| {
            for t in &mut self.tokens {
                reg.release(t);
            }
            self.move_into_place()
        })?;
        self.finished = true;
        Ok(self.final_dir.clone())
    }

    /// Moves the staging directory to the final place: see [`ReportDir::finish`].
    fn move_into_place(&self) -> anyhow::Result<()> {
        let shown = self.final_dir.display().to_string();
        match check_destination(&self.final_dir, self.force)? {
            Destination::Free => {
                // Onto nothing or an empty directory (rename replaces one).
                std::fs::rename(&self.staging, &self.final_dir)
                    .with_context(|| format!("moving the report to {shown}"))?;
            }
            Destination::PreviousReport => {
                let aside = self
                    .staging
                    .with_file_name(format!("{}.previous", self.staging_name()));
                std::fs::rename(&self.final_dir, &aside)
                    .with_context(|| format!("moving the previous report in {shown} aside"))?;
                if let Err(e) = std::fs::rename(&self.staging, &self.final_dir) {
                    let back = std::fs::rename(&aside, &self.final_dir);
                    return Err(e).with_context(|| match back {
                        Ok(()) => format!("moving the report to {shown} (the previous one is kept)"),
                        Err(b) => format!(
                            "moving the report to {shown}; putting the previous one back also failed ({b}): it is in {}",
                            aside.display()
                        ),
                    });
                }
                std::fs::remove_dir_all(&aside).with_context(|| {
                    format!(
                        "the report is in {shown}, but removing the previous one from {} failed",
                        aside.display()
                    )
                })?;
            }
        }
        Ok(())
    }

    fn staging_name(&self) -> String {
        self.staging
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    }
}

/// Removes the directories in `made` (deepest first) while they are empty.
fn remove_made(made: &[PathBuf]) {
    for d in made {
        if std::fs::remove_dir(d).is_err() {
            break;
        }
    }
}

impl Drop for ReportDir {
    fn drop(&mut self) {
        if !self.finished {
            let _ = std::fs::remove_dir_all(&self.staging);
            remove_made(&self.made_parents);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn report_appears_only_when_finished() {
        let tmp = tempfile::tempdir().unwrap();
        let base = tmp.path();
        let dest = base.join("report");
        {
            let r = ReportDir::create(&dest, false).unwrap();
            r.write("a/b.txt", "x").unwrap();
            assert!(!dest.exists());
            // dropped without finish: nothing left behind
        }
        assert!(!dest.exists());
        assert_eq!(std::fs::read_dir(base).unwrap().count(), 0);
        let r = ReportDir::create(&dest, false).unwrap();
        r.write("report.md", "# one").unwrap();
        r.finish().unwrap();
        assert_eq!(
            std::fs::read_to_string(dest.join("report.md")).unwrap(),
            "# one"
        );
        let err = ReportDir::create(&dest, false).unwrap_err().to_string();
        assert!(err.contains("--force"), "{err}");
        let r = ReportDir::create(&dest, true).unwrap();
        r.write("report.md", "# two").unwrap();
        r.finish().unwrap();
        assert_eq!(
            std::fs::read_to_string(dest.join("report.md")).unwrap(),
            "# two"
        );
        assert_eq!(std::fs::read_dir(base).unwrap().count(), 1);
        let listed = std::fs::read_to_string(dest.join(MARKER)).unwrap();
        assert_eq!(listed, format!("{MARKER_HEADER}\nreport.md\n"));
        // A file the report did not write stops even --force.
        std::fs::write(dest.join("mine.txt"), "mine").unwrap();
        let err = ReportDir::create(&dest, true).unwrap_err().to_string();
        assert!(err.contains("mine.txt"), "{err}");
    }

    #[test]
    fn an_empty_directory_takes_the_report_and_a_file_is_refused() {
        let base = tempfile::tempdir().unwrap();
        let dest = base.path().join("empty");
        std::fs::create_dir(&dest).unwrap();
        let r = ReportDir::create(&dest, false).unwrap();
        r.write("report.md", "# one").unwrap();
        r.finish().unwrap();
        assert!(dest.join("report.md").is_file());
        let file = base.path().join("notes.txt");
        std::fs::write(&file, "notes").unwrap();
        let err = ReportDir::create(&file, true).unwrap_err().to_string();
        assert!(err.contains("not a directory"), "{err}");
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "notes");
        assert_eq!(std::fs::read_dir(base.path()).unwrap().count(), 2);
    }

    #[test]
    fn parents_made_for_a_failed_report_are_removed() {
        let base = tempfile::tempdir().unwrap();
        let dest = base.path().join("a/b/report");
        drop(ReportDir::create(&dest, false).unwrap());
        assert_eq!(std::fs::read_dir(base.path()).unwrap().count(), 0);
    }

    #[test]
    fn a_report_replaced_while_building_is_checked_again() {
        let base = tempfile::tempdir().unwrap();
        let dest = base.path().join("report");
        let r = ReportDir::create(&dest, true).unwrap();
        r.write("report.md", "# new").unwrap();
        // The user fills the destination in the meantime.
        std::fs::create_dir(&dest).unwrap();
        std::fs::write(dest.join("keep.txt"), "keep").unwrap();
        let err = r.finish().unwrap_err().to_string();
        assert!(err.contains("not a kestrel report"), "{err}");
        assert_eq!(
            std::fs::read_to_string(dest.join("keep.txt")).unwrap(),
            "keep"
        );
        assert_eq!(std::fs::read_dir(base.path()).unwrap().count(), 1);
    }
}
