//! `kestrel pipeline`: the thesis workflow of chapter 7 end to end on the
//! built-in tricopter (or on given flight logs), composed from the crates'
//! library APIs, written as a report directory that appears only when
//! every step has succeeded.

pub mod config;
pub mod flights;
mod steps;

use crate::report::ReportDir;
use crate::report::table::Table;
use anyhow::Context;
use config::Config;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to run.
#[derive(Clone, Debug)]
pub struct Options {
    /// Report directory.
    pub out: PathBuf,
    /// The configuration.
    pub config: Config,
    /// Where the configuration came from (for the report).
    pub config_source: String,
    /// Flight logs to use instead of simulating (directory with
    /// `flight-1-hover.csv` ... `flight-4-ground.csv`).
    pub flights: Option<PathBuf>,
    /// The shortened pipeline.
    pub quick: bool,
}

/// The report being written: the directory, the markdown text and the
/// machine-readable summary.
pub struct Report {
    dir: ReportDir,
    md: String,
    summary: serde_json::Map<String, serde_json::Value>,
    progress: indicatif::ProgressBar,
    timings: Vec<(String, f64)>,
}

impl Report {
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

    /// Records a value in `summary.json`.
    pub fn summary(&mut self, key: &str, v: serde_json::Value) {
        self.summary.insert(key.to_string(), v);
    }

    /// Shows the step on the progress bar.
    pub fn step(&self, msg: &str) {
        self.progress.set_message(msg.to_string());
    }
}

/// Runs the pipeline.
pub fn run(opts: &Options) -> anyhow::Result<PathBuf> {
    let cfg = if opts.quick {
        opts.config.clone().quick()
    } else {
        opts.config.clone()
    };
    let dir = ReportDir::create(&opts.out)?;
    let progress = if std::io::stderr().is_terminal() {
        let pb = indicatif::ProgressBar::new(11);
        pb.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        pb.enable_steady_tick(std::time::Duration::from_millis(200));
        pb
    } else {
        indicatif::ProgressBar::hidden()
    };
    let mut r = Report {
        dir,
        md: String::new(),
        summary: serde_json::Map::new(),
        progress,
        timings: Vec::new(),
    };
    r.text(format!(
        "# kestrel pipeline report\n\nThe workflow of chapter 7 of *Model Predictive Control of a Tricopter* \
         on {}, produced by `kestrel pipeline` (kestrel-tools {}){}. Configuration: {}.\n\
         Every table is also a CSV file under `tables/`; `summary.json` holds the key figures.\n",
        if opts.flights.is_some() {
            "the given flight logs"
        } else {
            "kestrel-tricopter-model's built-in tricopter"
        },
        env!("CARGO_PKG_VERSION"),
        if opts.quick { ", shortened (`--quick`)" } else { "" },
        opts.config_source
    ));
    r.write("config.toml", toml_text(opts)?)?;
    let t_all = Instant::now();

    macro_rules! timed {
        ($name:expr, $e:expr) => {{
            r.step($name);
            let t0 = Instant::now();
            let v = $e;
            r.timings
                .push(($name.to_string(), t0.elapsed().as_secs_f64()));
            r.progress.inc(1);
            v
        }};
    }

    let flights = timed!(
        "1. experiments",
        steps::experiments(&mut r, &cfg, opts.flights.as_deref())?
    );
    let sensor = timed!("2. sensor", steps::sensor(&mut r, &cfg, &flights)?);
    let ident = timed!(
        "3. identification",
        steps::identification(&mut r, &cfg, &flights)?
    );
    timed!(
        "4. Kalman filter",
        steps::kalman(&mut r, &cfg, &flights, &ident, &sensor)?
    );
    let problems = timed!("5. MPC problems", steps::mpc(&mut r, &cfg, &ident)?);
    let explicit = timed!("6. explicit MPC", steps::explicit(&mut r, &cfg, &problems)?);
    let fgm = timed!(
        "7. fast gradient",
        steps::fast_gradient(&mut r, &cfg, &problems)?
    );
    timed!(
        "8. Table 7.2",
        steps::table_7_2(&mut r, &cfg, &ident, &problems, &explicit, &fgm)?
    );
    timed!(
        "9. closed loop",
        steps::closed_loop(&mut r, &cfg, &ident, &problems, &explicit, &fgm)?
    );
    timed!(
        "10. firmware tables",
        steps::firmware(&mut r, &cfg, &problems, &explicit, &fgm)?
    );
    timed!("11. differences", steps::differences(&mut r, &cfg)?);

    let total = t_all.elapsed().as_secs_f64();
    let mut t = Table::new(["step", "seconds"]);
    for (name, s) in &r.timings {
        t.row([name.clone(), format!("{s:.2}")]);
    }
    t.row(["total".to_string(), format!("{total:.2}")]);
    r.text("\n## Run time\n");
    r.table(
        "timings",
        "Wall-clock time of each step on this machine",
        &t,
    )?;
    r.summary("seconds", serde_json::json!(total));
    r.summary("quick", serde_json::json!(opts.quick));
    let md = std::mem::take(&mut r.md);
    r.write("report.md", md)?;
    let summary =
        serde_json::to_string_pretty(&serde_json::Value::Object(std::mem::take(&mut r.summary)))?
            + "\n";
    r.write("summary.json", summary)?;
    r.progress.finish_and_clear();
    r.dir.finish()
}

fn toml_text(opts: &Options) -> anyhow::Result<String> {
    if opts.config_source.starts_with("the built-in") {
        Ok(config::DEFAULT_TOML.to_string())
    } else {
        std::fs::read_to_string(Path::new(&opts.config_source))
            .with_context(|| format!("reading {}", opts.config_source))
    }
}
