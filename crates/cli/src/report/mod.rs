//! The report layer of `kestrel pipeline`: a report directory that appears
//! only when complete, markdown tables and SVG plots.

pub mod document;
pub mod plot;
pub mod table;

use anyhow::Context;
use std::path::{Path, PathBuf};

/// A report directory written in a hidden staging directory beside its
/// final place and moved there by [`ReportDir::finish`]; dropped unfinished
/// (an error on the way), the staging directory is removed, so a failed
/// run never leaves a half-written report that looks complete.
#[derive(Debug)]
pub struct ReportDir {
    final_dir: PathBuf,
    staging: PathBuf,
    finished: bool,
}

impl ReportDir {
    /// Starts a report that will end up in `final_dir`.
    pub fn create(final_dir: &Path) -> anyhow::Result<Self> {
        let parent = final_dir
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
        let name = final_dir
            .file_name()
            .with_context(|| format!("{}: not a directory name", final_dir.display()))?
            .to_string_lossy()
            .into_owned();
        let staging = parent.join(format!(".{name}.partial-{}", std::process::id()));
        if staging.exists() {
            std::fs::remove_dir_all(&staging)
                .with_context(|| format!("removing {}", staging.display()))?;
        }
        std::fs::create_dir_all(&staging)
            .with_context(|| format!("creating {}", staging.display()))?;
        Ok(ReportDir {
            final_dir: final_dir.to_path_buf(),
            staging,
            finished: false,
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

    /// Moves the finished report into place, replacing an older one.
    pub fn finish(mut self) -> anyhow::Result<PathBuf> {
        if self.final_dir.exists() {
            let old = self.staging.with_extension("old");
            std::fs::rename(&self.final_dir, &old).with_context(|| {
                format!("moving the previous {} aside", self.final_dir.display())
            })?;
            std::fs::remove_dir_all(&old).with_context(|| format!("removing {}", old.display()))?;
        }
        std::fs::rename(&self.staging, &self.final_dir)
            .with_context(|| format!("moving the report to {}", self.final_dir.display()))?;
        self.finished = true;
        Ok(self.final_dir.clone())
    }
}

impl Drop for ReportDir {
    fn drop(&mut self) {
        if !self.finished {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn report_appears_only_when_finished() {
        let base = std::env::temp_dir().join(format!("kestrel-report-test-{}", std::process::id()));
        let dest = base.join("report");
        {
            let r = ReportDir::create(&dest).unwrap();
            r.write("a/b.txt", "x").unwrap();
            assert!(!dest.exists());
            // dropped without finish: nothing left behind
        }
        assert!(!dest.exists());
        assert_eq!(std::fs::read_dir(&base).unwrap().count(), 0);
        let r = ReportDir::create(&dest).unwrap();
        r.write("report.md", "# one").unwrap();
        r.finish().unwrap();
        assert_eq!(
            std::fs::read_to_string(dest.join("report.md")).unwrap(),
            "# one"
        );
        let r = ReportDir::create(&dest).unwrap();
        r.write("report.md", "# two").unwrap();
        r.finish().unwrap();
        assert_eq!(
            std::fs::read_to_string(dest.join("report.md")).unwrap(),
            "# two"
        );
        assert_eq!(std::fs::read_dir(&base).unwrap().count(), 1);
        std::fs::remove_dir_all(&base).unwrap();
    }
}
