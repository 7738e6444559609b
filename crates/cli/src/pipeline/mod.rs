//! `kestrel pipeline`: the thesis workflow of chapter 7 end to end on the
//! built-in tricopter (or on given flight logs), run by kestrel-tricopter's
//! typed pipeline and rendered here as a report directory that appears
//! only when every stage has succeeded.

pub mod config;
pub mod flights;
mod render;

use crate::report::ReportDir;
use crate::report::document::Report;
use crate::report::table::Table;
use anyhow::Context;
use config::Config;
use kestrel_tricopter::pipeline::{self, PipelineResult, Progress, Stage};
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
    /// Replace a previous report in `out` (`--force`).
    pub force: bool,
}

/// The progress bar on a terminal.
struct Bar(indicatif::ProgressBar);

impl Progress for Bar {
    fn stage(&mut self, stage: Stage) {
        if self.0.position() < Stage::ALL.len() as u64 && stage != Stage::Experiments {
            self.0.inc(1);
        }
        self.0.set_message(stage.title());
    }
    fn step(&mut self, message: &str) {
        self.0.set_message(message.to_string());
    }
}

fn progress_bar() -> Bar {
    Bar(if std::io::stderr().is_terminal() {
        let pb = indicatif::ProgressBar::new(Stage::ALL.len() as u64);
        pb.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        pb.enable_steady_tick(std::time::Duration::from_millis(200));
        crate::progress::show(&pb);
        pb
    } else {
        indicatif::ProgressBar::hidden()
    })
}

/// Runs the pipeline and writes its report.
pub fn run(opts: &Options) -> anyhow::Result<PathBuf> {
    let cfg = if opts.quick {
        opts.config.clone().quick()
    } else {
        opts.config.clone()
    };
    let dir = ReportDir::create(&opts.out, opts.force)?;
    let t_all = Instant::now();
    let flights = opts.flights.as_deref().map(flights::read_dir).transpose()?;
    let mut bar = progress_bar();
    let result = pipeline::run_with(&cfg, flights, &mut bar)?;
    let total = t_all.elapsed().as_secs_f64();
    bar.0.finish_and_clear();
    let mut r = Report::new(dir);
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
    render::all(&mut r, &result, opts.flights.as_deref())?;
    timings(&mut r, &result, total)?;
    r.write("summary.json", summary_json(&result, total, opts.quick)?)?;
    r.finish("report.md")
}

/// `summary.json`: the result's key figures, the run time and `quick`.
fn summary_json(result: &PipelineResult, seconds: f64, quick: bool) -> anyhow::Result<String> {
    let mut v = serde_json::to_value(result.summary())?;
    if let Some(m) = v.as_object_mut() {
        m.insert("seconds".into(), serde_json::json!(seconds));
        m.insert("quick".into(), serde_json::json!(quick));
    }
    Ok(serde_json::to_string_pretty(&v)? + "\n")
}

fn timings(r: &mut Report, result: &PipelineResult, total: f64) -> anyhow::Result<()> {
    let mut t = Table::new(["step", "seconds"]);
    for (stage, s) in &result.seconds {
        t.row([stage.title().to_string(), format!("{s:.2}")]);
    }
    t.row(["total".to_string(), format!("{total:.2}")]);
    r.text("\n## Run time\n");
    r.table(
        "timings",
        "Wall-clock time of each step on this machine",
        &t,
    )
}

fn toml_text(opts: &Options) -> anyhow::Result<String> {
    if opts.config_source.starts_with("the built-in") {
        Ok(config::DEFAULT_TOML.to_string())
    } else {
        std::fs::read_to_string(Path::new(&opts.config_source))
            .with_context(|| format!("reading {}", opts.config_source))
    }
}
