//! A report being written: a [`ReportDir`] and the markdown text that
//! links its tables and figures.

use super::ReportDir;
use super::table::Table;
use std::path::PathBuf;

/// The report being written: the directory and the markdown text.
pub struct Report {
    dir: ReportDir,
    md: String,
}

impl Report {
    /// An empty report in `dir`.
    pub fn new(dir: ReportDir) -> Self {
        Report {
            dir,
            md: String::new(),
        }
    }

    /// Writes the markdown as `name` and moves the directory into place.
    pub fn finish(mut self, name: &str) -> anyhow::Result<PathBuf> {
        let md = std::mem::take(&mut self.md);
        self.dir.write(name, md)?;
        self.dir.finish()
    }

    /// Appends markdown text.
    pub fn text(&mut self, s: impl AsRef<str>) {
        self.md.push_str(s.as_ref());
        if !self.md.ends_with('\n') {
            self.md.push('\n');
        }
    }

    /// Appends a table (markdown) and writes it as `tables/<name>.csv`.
    pub fn table(&mut self, name: &str, caption: &str, t: &Table) -> anyhow::Result<()> {
        self.md
            .push_str(&format!("\n**{caption}** (`tables/{name}.csv`)\n\n"));
        self.md.push_str(&t.to_markdown());
        self.md.push('\n');
        self.dir.write(&format!("tables/{name}.csv"), t.to_csv())?;
        Ok(())
    }

    /// Writes a file of the report.
    pub fn write(&self, rel: &str, bytes: impl AsRef<[u8]>) -> anyhow::Result<PathBuf> {
        self.dir.write(rel, bytes)
    }

    /// The path of a report file (in the staging directory), its folder created.
    pub fn path(&self, rel: &str) -> PathBuf {
        let p = self.dir.path(rel);
        if let Some(d) = p.parent() {
            let _ = std::fs::create_dir_all(d);
        }
        p
    }

    /// Links a figure into the markdown.
    pub fn figure(&mut self, rel: &str, caption: &str) {
        self.md.push_str(&format!(
            "\n![{caption}]({rel})\n\n*{caption}* (`{rel}`)\n\n"
        ));
    }
}
