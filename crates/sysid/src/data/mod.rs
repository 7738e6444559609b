//! Input/output data sets: several experiments kept apart (as MATLAB's
//! `merge`), CSV loading with column selection, selection of time
//! intervals, offset and trend removal, linear input maps (mixers).//!
//! The types live here; [`read`] loads CSV logs and [`preprocess`] selects
//! intervals, removes offsets and trends, maps inputs and filters.

mod preprocess;
mod read;
#[cfg(test)]
mod tests;

use crate::error::{Result, SysidError};
use nalgebra::{DMatrix, DVector};

/// One contiguous experiment: a time column and the sampled signals.
#[derive(Clone, Debug, PartialEq)]
pub struct Experiment {
    /// Sample times (seconds of the `t` column, or row indices when the
    /// source had no time column), one per sample.
    pub t: Vec<f64>,
    /// Inputs, `N x nu` (one row per sample).
    pub u: DMatrix<f64>,
    /// Outputs, `N x ny`.
    pub y: DMatrix<f64>,
}

impl Experiment {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.u.nrows()
    }
    /// True when the experiment has no samples.
    pub fn is_empty(&self) -> bool {
        self.u.nrows() == 0
    }
}

/// An input/output data set with sample time, signal names and one or
/// more experiments that are never joined end to end.
#[derive(Clone, Debug, PartialEq)]
pub struct IoData {
    ts: f64,
    input_names: Vec<String>,
    output_names: Vec<String>,
    experiments: Vec<Experiment>,
}

/// A closed time interval `[start, end]` in the units of the time column.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeInterval {
    /// Start (inclusive).
    pub start: f64,
    /// End (inclusive).
    pub end: f64,
}

impl TimeInterval {
    /// An interval, checked to be finite and ordered.
    pub fn new(start: f64, end: f64) -> Result<Self> {
        if !(start.is_finite() && end.is_finite() && start < end) {
            return Err(SysidError::invalid(format!(
                "time interval {start}:{end} must be finite with start < end"
            )));
        }
        Ok(TimeInterval { start, end })
    }

    /// Parses `"25.66:50.28,108.9:165.8"`.
    pub fn parse_list(text: &str) -> Result<Vec<TimeInterval>> {
        text.split(',')
            .filter(|s| !s.trim().is_empty())
            .map(|part| {
                let (a, b) = part.split_once(':').ok_or_else(|| {
                    SysidError::invalid(format!("interval \"{part}\" is not start:end"))
                })?;
                let p = |s: &str| {
                    s.trim().parse::<f64>().map_err(|_| {
                        SysidError::invalid(format!("interval \"{part}\": \"{s}\" is not a number"))
                    })
                };
                TimeInterval::new(p(a)?, p(b)?)
            })
            .collect()
    }
}

/// Which columns of a CSV log to read.
#[derive(Clone, Debug, PartialEq)]
pub struct CsvColumns {
    /// Input column names, in model order.
    pub inputs: Vec<String>,
    /// Output column names, in model order.
    pub outputs: Vec<String>,
    /// The time column; used when present in the file.
    pub time: String,
    /// The unit of the time column (default seconds); times and the sample
    /// time are converted to seconds.
    pub time_unit: TimeUnit,
    /// The column that tells experiments apart (integers); used when present.
    pub experiment: String,
    /// Sample time in seconds: required when the file has no time column
    /// (nothing is guessed); with one, it must agree with the column's
    /// step to 1 %.
    pub ts: Option<f64>,
}

/// The unit of a CSV time column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TimeUnit {
    /// Seconds.
    #[default]
    Seconds,
    /// Milliseconds.
    Milliseconds,
}

impl TimeUnit {
    /// Seconds per unit.
    pub fn seconds(self) -> f64 {
        match self {
            TimeUnit::Seconds => 1.0,
            TimeUnit::Milliseconds => 1e-3,
        }
    }
}

impl CsvColumns {
    /// Selects inputs and outputs; time column `t` in seconds, experiment
    /// column `experiment`, no sample time given.
    pub fn new(inputs: &[&str], outputs: &[&str]) -> Self {
        CsvColumns {
            inputs: inputs.iter().map(|s| s.to_string()).collect(),
            outputs: outputs.iter().map(|s| s.to_string()).collect(),
            time: "t".into(),
            time_unit: TimeUnit::Seconds,
            experiment: "experiment".into(),
            ts: None,
        }
    }
}

/// Operating point removed from a data set: the model maps `u - u0` to `y - y0`.
#[derive(Clone, Debug, PartialEq)]
pub struct Offsets {
    /// Input offsets, `nu`.
    pub u0: DVector<f64>,
    /// Output offsets, `ny`.
    pub y0: DVector<f64>,
}

/// Which signals a filter is applied to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SignalSelection {
    /// Outputs only.
    #[default]
    Outputs,
    /// Inputs only.
    Inputs,
    /// Inputs and outputs (keeps the input-output relation unchanged).
    Both,
}

fn default_names(prefix: &str, n: usize) -> Vec<String> {
    (1..=n).map(|i| format!("{prefix}{i}")).collect()
}
impl IoData {
    /// A single-experiment data set from `N x nu` inputs and `N x ny`
    /// outputs, named `u1..`, `y1..`, times `k * ts`.
    pub fn new(ts: f64, u: DMatrix<f64>, y: DMatrix<f64>) -> Result<Self> {
        let n = u.nrows();
        let t = (0..n).map(|k| k as f64 * ts).collect();
        let (nu, ny) = (u.ncols(), y.ncols());
        IoData::from_experiments(
            ts,
            default_names("u", nu),
            default_names("y", ny),
            vec![Experiment { t, u, y }],
        )
    }

    /// A data set from named signals and experiments, checked: sample time
    /// finite and positive, sizes consistent, every value finite, every
    /// experiment non-empty.
    pub fn from_experiments(
        ts: f64,
        input_names: Vec<String>,
        output_names: Vec<String>,
        experiments: Vec<Experiment>,
    ) -> Result<Self> {
        if !(ts.is_finite() && ts > 0.0) {
            return Err(SysidError::invalid(format!(
                "sample time must be finite and > 0, found {ts}"
            )));
        }
        if experiments.is_empty() {
            return Err(SysidError::TooFewSamples {
                what: "a data set".into(),
                needed: 1,
                found: 0,
            });
        }
        if output_names.is_empty() {
            return Err(SysidError::invalid("a data set needs at least one output"));
        }
        let (nu, ny) = (input_names.len(), output_names.len());
        for (ei, e) in experiments.iter().enumerate() {
            if e.u.ncols() != nu {
                return Err(SysidError::dim(
                    format!("input columns of experiment {ei}"),
                    nu,
                    e.u.ncols(),
                ));
            }
            if e.y.ncols() != ny {
                return Err(SysidError::dim(
                    format!("output columns of experiment {ei}"),
                    ny,
                    e.y.ncols(),
                ));
            }
            if e.y.nrows() != e.u.nrows() {
                return Err(SysidError::dim(
                    format!(
                        "output samples of experiment {ei} (inputs have {})",
                        e.u.nrows()
                    ),
                    e.u.nrows(),
                    e.y.nrows(),
                ));
            }
            if e.t.len() != e.u.nrows() {
                return Err(SysidError::dim(
                    format!("time samples of experiment {ei}"),
                    e.u.nrows(),
                    e.t.len(),
                ));
            }
            if e.u.nrows() == 0 {
                return Err(SysidError::TooFewSamples {
                    what: format!("experiment {ei}"),
                    needed: 1,
                    found: 0,
                });
            }
            for (names, m) in [(&input_names, &e.u), (&output_names, &e.y)] {
                for (j, name) in names.iter().enumerate().take(m.ncols()) {
                    if let Some(k) = m.column(j).iter().position(|v| !v.is_finite()) {
                        return Err(SysidError::NonFinite {
                            what: name.clone(),
                            experiment: ei,
                            sample: k,
                        });
                    }
                }
            }
            if let Some(k) = e.t.iter().position(|v| !v.is_finite()) {
                return Err(SysidError::NonFinite {
                    what: "time".into(),
                    experiment: ei,
                    sample: k,
                });
            }
        }
        Ok(IoData {
            ts,
            input_names,
            output_names,
            experiments,
        })
    }

    /// Renames the signals (counts must match).
    pub fn with_names(mut self, inputs: Vec<String>, outputs: Vec<String>) -> Result<Self> {
        if inputs.len() != self.nu() {
            return Err(SysidError::dim("input names", self.nu(), inputs.len()));
        }
        if outputs.len() != self.ny() {
            return Err(SysidError::dim("output names", self.ny(), outputs.len()));
        }
        self.input_names = inputs;
        self.output_names = outputs;
        Ok(self)
    }

    /// Joins data sets into one with all their experiments kept apart
    /// (MATLAB's `merge`). Sample times and signal counts must agree.
    pub fn merge(sets: &[IoData]) -> Result<IoData> {
        let first = sets
            .first()
            .ok_or_else(|| SysidError::invalid("merge needs at least one data set"))?;
        let mut exps = Vec::new();
        for s in sets {
            if (s.ts - first.ts).abs() > 1e-9 * first.ts {
                return Err(SysidError::invalid(format!(
                    "merge: sample times differ ({} and {})",
                    first.ts, s.ts
                )));
            }
            exps.extend(s.experiments.iter().cloned());
        }
        IoData::from_experiments(
            first.ts,
            first.input_names.clone(),
            first.output_names.clone(),
            exps,
        )
    }

    /// Sample time in seconds.
    pub fn ts(&self) -> f64 {
        self.ts
    }
    /// Input names.
    pub fn input_names(&self) -> &[String] {
        &self.input_names
    }
    /// Output names.
    pub fn output_names(&self) -> &[String] {
        &self.output_names
    }
    /// The experiments.
    pub fn experiments(&self) -> &[Experiment] {
        &self.experiments
    }
    /// Number of inputs.
    pub fn nu(&self) -> usize {
        self.input_names.len()
    }
    /// Number of outputs.
    pub fn ny(&self) -> usize {
        self.output_names.len()
    }
    /// Total number of samples over all experiments.
    pub fn n_samples(&self) -> usize {
        self.experiments.iter().map(|e| e.len()).sum()
    }
    /// Regression rows of a model that needs `lag` past samples: every
    /// experiment's samples after its first `lag`, which enter only as
    /// history (experiments are never joined).
    pub(crate) fn rows_after(&self, lag: usize) -> usize {
        self.experiments
            .iter()
            .map(|e| e.len().saturating_sub(lag))
            .sum()
    }
}
