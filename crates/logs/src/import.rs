//! From logs to identification data: signals selected, segments found,
//! everything resampled onto one grid, written as kestrel's CSV.

use crate::error::{LogError, Result};
use crate::model::{Issue, Log, LogFormat, ReadOptions, Unit};
use crate::read::read_file;
use crate::resample::{Grid, gaps, resample};
use crate::segments::{AirborneSettings, Span, airborne};
use crate::select::{Resolved, SignalSpec, default_signals, resolve};
use std::fmt::Write as _;
use std::path::Path;

/// Which part of each log becomes experiments.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SegmentChoice {
    /// The airborne segments ([`AirborneSettings`]), each an experiment.
    #[default]
    Airborne,
    /// The whole log (split only at gaps).
    All,
}

/// What to import and how.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportSettings {
    /// Grid rate in Hz (default 50).
    pub rate_hz: f64,
    /// Inputs; `None`: the format's default ([`default_signals`]).
    pub inputs: Option<Vec<SignalSpec>>,
    /// Outputs; `None`: the format's default.
    pub outputs: Option<Vec<SignalSpec>>,
    /// Airborne segments or the whole log.
    pub segment: SegmentChoice,
    /// Airborne detection (from the inputs, the motor commands).
    pub airborne: AirborneSettings,
    /// A stretch longer than this (seconds) without a sample of some
    /// signal splits the experiment (default 0.1 s; at least two cells and
    /// 2.5 times the signal's median sample interval, so a slow topic's
    /// own rate is no gap). Shorter ones are interpolated and counted.
    pub max_gap_s: f64,
    /// How the file is read.
    pub read: ReadOptions,
}

impl Default for ImportSettings {
    fn default() -> Self {
        ImportSettings {
            rate_hz: 50.0,
            inputs: None,
            outputs: None,
            segment: SegmentChoice::Airborne,
            airborne: AirborneSettings::default(),
            max_gap_s: 0.1,
            read: ReadOptions::default(),
        }
    }
}

/// One output column.
#[derive(Clone, Debug, PartialEq)]
pub struct SignalInfo {
    /// Column name.
    pub name: String,
    /// `topic.field` it came from.
    pub source: String,
    /// Unit.
    pub unit: Unit,
    /// Command range, where stated.
    pub range: Option<[f64; 2]>,
}

/// One contiguous stretch on the grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Experiment {
    /// Index of the log in the file (0-based).
    pub log: usize,
    /// Cell centres, seconds in the log's clock.
    pub t: Vec<f64>,
    /// One column per signal (inputs, then outputs), `t.len()` values each.
    pub columns: Vec<Vec<f64>>,
    /// Cells that held no sample of some signal and were interpolated.
    pub filled: usize,
}

/// What one log of the file gave.
#[derive(Clone, Debug, PartialEq)]
pub struct LogSummary {
    /// Samples of the first input's topic.
    pub samples: usize,
    /// Mean sample rate of that topic, Hz.
    pub native_rate_hz: f64,
    /// Time span in which every selected signal has samples, seconds
    /// (NaN when one has none: the log gives no experiment).
    pub span: Span,
    /// The segments kept (airborne or the whole span).
    pub segments: Vec<Span>,
    /// Gaps that split experiments.
    pub gaps: Vec<Span>,
    /// Damage read past (salvage only).
    pub issues: Vec<Issue>,
}

/// The result of an import.
#[derive(Clone, Debug, PartialEq)]
pub struct Imported {
    /// The file's format.
    pub format: LogFormat,
    /// Grid rate, Hz.
    pub rate_hz: f64,
    /// The columns: `n_inputs` inputs, then the outputs.
    pub signals: Vec<SignalInfo>,
    /// How many of `signals` are inputs.
    pub n_inputs: usize,
    /// The experiments, in time order per log.
    pub experiments: Vec<Experiment>,
    /// One per log in the file.
    pub logs: Vec<LogSummary>,
}

/// Reads `path` ([`read_file`]) and [`import`]s it.
pub fn import_file(path: &Path, settings: &ImportSettings) -> Result<Imported> {
    let logs = read_file(path, &settings.read)?;
    import(&logs, settings)
}

/// Selects, segments and resamples every log.
pub fn import(logs: &[Log], settings: &ImportSettings) -> Result<Imported> {
    let rate = settings.rate_hz;
    if !(rate.is_finite() && rate > 0.0 && rate <= 1e5) {
        return Err(LogError::Invalid(format!(
            "the rate must be in (0, 100000] Hz, found {rate}"
        )));
    }
    if !(settings.max_gap_s.is_finite() && settings.max_gap_s > 0.0) {
        return Err(LogError::Invalid(format!(
            "the largest gap must be > 0 s, found {}",
            settings.max_gap_s
        )));
    }
    let Some(first) = logs.first() else {
        return Err(LogError::Empty("the file holds no log".into()));
    };
    let mut out = Imported {
        format: first.format,
        rate_hz: rate,
        signals: Vec::new(),
        n_inputs: 0,
        experiments: Vec::new(),
        logs: Vec::new(),
    };
    for (k, log) in logs.iter().enumerate() {
        let d = default_signals(log);
        let ins = resolve(log, settings.inputs.as_ref().unwrap_or(&d.inputs))?;
        let outs = resolve(log, settings.outputs.as_ref().unwrap_or(&d.outputs))?;
        let signals: Vec<SignalInfo> = ins
            .iter()
            .chain(&outs)
            .map(|(name, r)| SignalInfo {
                name: name.clone(),
                source: format!("{}.{}", r.topic.name, r.field.name),
                unit: r.field.unit.clone(),
                range: r.field.range,
            })
            .collect();
        if k == 0 {
            out.signals = signals;
            out.n_inputs = ins.len();
        } else if signals
            .iter()
            .map(|s| &s.name)
            .ne(out.signals.iter().map(|s| &s.name))
        {
            return Err(LogError::Invalid(format!(
                "log {} of the file has other signals than log 1",
                k + 1
            )));
        }
        let summary = import_log(k, &ins, &outs, settings, &mut out.experiments)?;
        out.logs.push(LogSummary {
            issues: log.issues.clone(),
            ..summary
        });
    }
    if out.experiments.is_empty() {
        let what = match settings.segment {
            SegmentChoice::Airborne => format!(
                "no airborne segment found (mean motor level above {} of the command range for at least {} s once {} s are trimmed from each end); lower --threshold, --min-duration or --trim, or import --segment all",
                settings.airborne.threshold,
                settings.airborne.min_duration_s,
                settings.airborne.trim_s
            ),
            SegmentChoice::All => "no samples common to all the selected signals".into(),
        };
        return Err(LogError::Empty(what));
    }
    Ok(out)
}

fn import_log(
    k: usize,
    ins: &[(String, Resolved)],
    outs: &[(String, Resolved)],
    settings: &ImportSettings,
    experiments: &mut Vec<Experiment>,
) -> Result<LogSummary> {
    let all: Vec<&(String, Resolved)> = ins.iter().chain(outs).collect();
    let finite_span = |r: &Resolved| {
        let ok = |i: &usize| r.field.values.get(*i).is_some_and(|v| v.is_finite());
        let a = (0..r.topic.t.len()).find(ok);
        let b = (0..r.topic.t.len()).rev().find(ok);
        a.zip(b).map(|(a, b)| (r.topic.t[a], r.topic.t[b]))
    };
    let mut span = Span {
        start: f64::NEG_INFINITY,
        end: f64::INFINITY,
    };
    for (_, r) in &all {
        // A signal without a number (a log armed and disarmed at once, an
        // unused output): the log gives no experiment.
        let (a, b) = finite_span(r).unwrap_or((f64::NAN, f64::NAN));
        span.start = if a.is_nan() { a } else { span.start.max(a) };
        span.end = if b.is_nan() { b } else { span.end.min(b) };
    }
    let (samples, native_rate_hz) = all.first().map_or((0, 0.0), |(_, r)| {
        let t = &r.topic.t;
        let n = t.len();
        let dur = t.last().copied().unwrap_or(0.0) - t.first().copied().unwrap_or(0.0);
        (n, if dur > 0.0 { (n - 1) as f64 / dur } else { 0.0 })
    });
    let segments = if span.end > span.start {
        match settings.segment {
            SegmentChoice::Airborne => airborne(ins, span, &settings.airborne)?,
            SegmentChoice::All => vec![span],
        }
    } else {
        Vec::new()
    };
    let rate = settings.rate_hz;
    let max_gap = settings.max_gap_s.max(2.0 / rate);
    let mut all_gaps: Vec<Span> = Vec::new();
    for seg in &segments {
        let mut cuts: Vec<[f64; 2]> = all
            .iter()
            .flat_map(|(_, r)| {
                // A slow topic's own interval (up to 1 s) is no gap.
                let own = (2.5 * median_interval(&r.topic.t)).min(1.0);
                gaps(
                    &r.topic.t,
                    &r.field.values,
                    seg.start,
                    seg.end,
                    max_gap.max(own),
                )
            })
            .collect();
        cuts.sort_by(|a, b| a[0].total_cmp(&b[0]));
        let mut start = seg.start;
        for [a, b] in cuts.iter().copied().chain([[seg.end, seg.end]]) {
            if a > start {
                push_experiment(k, &all, Grid::covering(start, a, rate), experiments)?;
            }
            if b > a {
                all_gaps.push(Span { start: a, end: b });
            }
            start = start.max(b);
        }
    }
    Ok(LogSummary {
        samples,
        native_rate_hz,
        span,
        segments,
        gaps: all_gaps,
        issues: Vec::new(),
    })
}

/// The median interval between samples (0 for fewer than two).
fn median_interval(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    *d.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Most grid cells per sample of the densest selected signal.
const MAX_CELLS_PER_SAMPLE: usize = 64;

fn push_experiment(
    k: usize,
    all: &[&(String, Resolved)],
    grid: Grid,
    out: &mut Vec<Experiment>,
) -> Result<()> {
    if grid.len < 2 {
        return Ok(());
    }
    // Memory follows the log, not its clock: a damaged clock (or a rate
    // far above the log's) cannot ask for a grid out of all proportion.
    let end = grid.start + grid.len as f64 / grid.rate_hz;
    let densest = all
        .iter()
        .map(|(_, r)| {
            let t = &r.topic.t;
            t.partition_point(|&x| x < end) - t.partition_point(|&x| x < grid.start)
        })
        .max()
        .unwrap_or(0);
    if grid.len > MAX_CELLS_PER_SAMPLE * densest + 1000 {
        return Err(LogError::Invalid(format!(
            "{:.3}-{end:.3} s would take {} cells at {} Hz for at most {densest} samples of a signal (a damaged clock, or a rate far above the log's): choose a lower rate",
            grid.start, grid.len, grid.rate_hz
        )));
    }
    let mut filled = 0;
    let columns = all
        .iter()
        .map(|(_, r)| {
            let m = resample(&r.topic.t, &r.field.values, &grid);
            filled = filled.max(m.filled);
            m.values
        })
        .collect();
    out.push(Experiment {
        log: k,
        t: grid.times(),
        columns,
        filled,
    });
    Ok(())
}

impl Imported {
    /// Kestrel's CSV (`../shared/FORMATS.md`): a header `t,<signals>` and,
    /// with several experiments, an `experiment` column (1, 2, ...) that
    /// `kestrel identify` keeps apart. Times in seconds of the log's clock
    /// (cell centres, 9 decimals), values in the units of [`Imported::signals`].
    pub fn to_csv(&self) -> String {
        let several = self.experiments.len() > 1;
        let mut s = String::from("t");
        for sig in &self.signals {
            s.push(',');
            s.push_str(&sig.name);
        }
        if several {
            s.push_str(",experiment");
        }
        s.push('\n');
        for (e, exp) in self.experiments.iter().enumerate() {
            for (i, t) in exp.t.iter().enumerate() {
                let _ = write!(s, "{t:.9}");
                for c in &exp.columns {
                    let _ = write!(s, ",{}", c[i]);
                }
                if several {
                    let _ = write!(s, ",{}", e + 1);
                }
                s.push('\n');
            }
        }
        s
    }

    /// Number of grid samples over all experiments.
    pub fn n_samples(&self) -> usize {
        self.experiments.iter().map(|e| e.t.len()).sum()
    }
}
