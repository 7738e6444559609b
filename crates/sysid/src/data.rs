//! Input/output data sets: several experiments kept apart (as MATLAB's
//! `merge`), CSV loading with column selection, selection of time
//! intervals, offset and trend removal, linear input maps (mixers).

use crate::error::{Result, SysidError};
use crate::filter::Butterworth;
use nalgebra::{DMatrix, DVector};
use std::path::Path;

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
    /// The time column (seconds); used when present in the file.
    pub time: String,
    /// The column that tells experiments apart (integers); used when present.
    pub experiment: String,
    /// Sample time when the file has no time column (default 1).
    pub ts: Option<f64>,
}

impl CsvColumns {
    /// Selects inputs and outputs; time column `t`, experiment column `experiment`.
    pub fn new(inputs: &[&str], outputs: &[&str]) -> Self {
        CsvColumns {
            inputs: inputs.iter().map(|s| s.to_string()).collect(),
            outputs: outputs.iter().map(|s| s.to_string()).collect(),
            time: "t".into(),
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

/// The nominal sample time behind a measured step: time columns written
/// with a few decimals (or accumulated in floating point) give steps like
/// `0.019999999999999574`; the step is rounded to 6 significant digits,
/// which is far finer than any clock jitter the 1 % uniformity check lets
/// through, so `0.02` comes back as `0.02` exactly.
pub(crate) fn snap_sample_time(step: f64) -> f64 {
    if !(step.is_finite() && step > 0.0) {
        return step;
    }
    let scale = 10f64.powi(5 - step.log10().floor() as i32);
    let snapped = (step * scale).round() / scale;
    if snapped > 0.0 { snapped } else { step }
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

    /// Reads a CSV log (one header row) with the given columns. A time
    /// column, when present, gives the sample time (median step; sampling
    /// must be uniform within 1 %); without one, times are row indices and
    /// the sample time is `columns.ts` (default 1). An experiment column,
    /// when present, splits the rows into experiments (consecutive rows
    /// with the same value).
    pub fn read_csv(path: &Path, columns: &CsvColumns) -> Result<IoData> {
        let file = std::fs::File::open(path).map_err(|e| SysidError::Csv {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        IoData::from_csv_reader(file, columns, &path.display().to_string())
    }

    /// As [`IoData::read_csv`] from any reader; `label` names the source in errors.
    pub fn from_csv_reader<R: std::io::Read>(
        reader: R,
        columns: &CsvColumns,
        label: &str,
    ) -> Result<IoData> {
        let err = |reason: String| SysidError::Csv {
            path: label.to_string(),
            reason,
        };
        let mut rdr = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_reader(reader);
        let headers = rdr
            .headers()
            .map_err(|e| err(format!("header: {e}")))?
            .clone();
        let find = |name: &str| headers.iter().position(|h| h == name);
        let pick = |names: &[String]| -> Result<Vec<usize>> {
            names
                .iter()
                .map(|n| {
                    find(n).ok_or_else(|| {
                        err(format!(
                            "no column \"{n}\" (columns: {})",
                            headers.iter().collect::<Vec<_>>().join(", ")
                        ))
                    })
                })
                .collect()
        };
        if columns.outputs.is_empty() {
            return Err(SysidError::invalid("select at least one output column"));
        }
        let ui = pick(&columns.inputs)?;
        let yi = pick(&columns.outputs)?;
        let ti = find(&columns.time);
        let ei = find(&columns.experiment);
        let mut rows: Vec<(f64, f64, Vec<f64>, Vec<f64>)> = Vec::new();
        for (r, rec) in rdr.records().enumerate() {
            let line = r + 2;
            let rec = rec.map_err(|e| err(format!("line {line}: {e}")))?;
            let get = |i: usize, name: &str| -> Result<f64> {
                let s = rec
                    .get(i)
                    .ok_or_else(|| err(format!("line {line}: missing column \"{name}\"")))?;
                let v: f64 = s.parse().map_err(|_| {
                    err(format!(
                        "line {line}, column \"{name}\": \"{s}\" is not a number"
                    ))
                })?;
                if !v.is_finite() {
                    return Err(err(format!(
                        "line {line}, column \"{name}\": non-finite value \"{s}\""
                    )));
                }
                Ok(v)
            };
            let t = match ti {
                Some(i) => get(i, &columns.time)?,
                None => r as f64,
            };
            let ex = match ei {
                Some(i) => get(i, &columns.experiment)?,
                None => 0.0,
            };
            let u = ui
                .iter()
                .zip(&columns.inputs)
                .map(|(&i, n)| get(i, n))
                .collect::<Result<Vec<_>>>()?;
            let y = yi
                .iter()
                .zip(&columns.outputs)
                .map(|(&i, n)| get(i, n))
                .collect::<Result<Vec<_>>>()?;
            rows.push((t, ex, u, y));
        }
        if rows.is_empty() {
            return Err(err("no data rows".into()));
        }
        // Split into experiments.
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for (i, r) in rows.iter().enumerate() {
            match groups.last_mut() {
                Some(g) if rows[g[0]].1 == r.1 => g.push(i),
                _ => groups.push(vec![i]),
            }
        }
        let ts = if ti.is_some() {
            let mut steps = Vec::new();
            for g in &groups {
                for w in g.windows(2) {
                    let d = rows[w[1]].0 - rows[w[0]].0;
                    if d <= 0.0 {
                        return Err(err(format!(
                            "line {}: time does not increase ({} after {})",
                            w[1] + 2,
                            rows[w[1]].0,
                            rows[w[0]].0
                        )));
                    }
                    steps.push(d);
                }
            }
            if steps.is_empty() {
                return Err(err(
                    "need at least two samples to find the sample time".into()
                ));
            }
            steps.sort_by(f64::total_cmp);
            let median = steps[steps.len() / 2];
            if let Some(bad) = steps.iter().find(|d| ((*d - median) / median).abs() > 0.01) {
                return Err(err(format!(
                    "non-uniform sampling: step {bad} differs from the median {median} by more than 1 %"
                )));
            }
            snap_sample_time(median)
        } else {
            columns.ts.unwrap_or(1.0)
        };
        let experiments = groups
            .iter()
            .map(|g| Experiment {
                t: g.iter().map(|&i| rows[i].0).collect(),
                u: DMatrix::from_fn(g.len(), ui.len(), |r, c| rows[g[r]].2[c]),
                y: DMatrix::from_fn(g.len(), yi.len(), |r, c| rows[g[r]].3[c]),
            })
            .collect();
        IoData::from_experiments(
            ts,
            columns.inputs.clone(),
            columns.outputs.clone(),
            experiments,
        )
    }

    /// Selects time intervals: every part of every experiment whose time
    /// lies in an interval becomes its own experiment of the result (like
    /// picking estimation and validation sets and merging them). Intervals
    /// that cover no sample are an error.
    pub fn select(&self, intervals: &[TimeInterval]) -> Result<IoData> {
        let mut out = Vec::new();
        for iv in intervals {
            let before = out.len();
            for e in &self.experiments {
                let idx: Vec<usize> = (0..e.len())
                    .filter(|&k| e.t[k] >= iv.start - 1e-9 && e.t[k] <= iv.end + 1e-9)
                    .collect();
                if let (Some(&a), Some(&b)) = (idx.first(), idx.last()) {
                    out.push(Experiment {
                        t: e.t[a..=b].to_vec(),
                        u: e.u.rows(a, b - a + 1).into_owned(),
                        y: e.y.rows(a, b - a + 1).into_owned(),
                    });
                }
            }
            if out.len() == before {
                return Err(SysidError::invalid(format!(
                    "interval {}:{} contains no sample",
                    iv.start, iv.end
                )));
            }
        }
        IoData::from_experiments(
            self.ts,
            self.input_names.clone(),
            self.output_names.clone(),
            out,
        )
    }

    /// Splits every experiment at the sample fraction `frac` (0..1) into
    /// an estimation part and a validation part.
    pub fn split(&self, frac: f64) -> Result<(IoData, IoData)> {
        if !(frac > 0.0 && frac < 1.0) {
            return Err(SysidError::invalid(format!(
                "split fraction must lie in (0, 1), found {frac}"
            )));
        }
        let mut a = Vec::new();
        let mut b = Vec::new();
        for e in &self.experiments {
            let n = e.len();
            let k = ((n as f64) * frac).round() as usize;
            if k == 0 || k >= n {
                return Err(SysidError::TooFewSamples {
                    what: "a split".into(),
                    needed: 2,
                    found: n,
                });
            }
            a.push(Experiment {
                t: e.t[..k].to_vec(),
                u: e.u.rows(0, k).into_owned(),
                y: e.y.rows(0, k).into_owned(),
            });
            b.push(Experiment {
                t: e.t[k..].to_vec(),
                u: e.u.rows(k, n - k).into_owned(),
                y: e.y.rows(k, n - k).into_owned(),
            });
        }
        let mk = |x| {
            IoData::from_experiments(
                self.ts,
                self.input_names.clone(),
                self.output_names.clone(),
                x,
            )
        };
        Ok((mk(a)?, mk(b)?))
    }

    /// Means of inputs and outputs over all samples of all experiments.
    pub fn means(&self) -> Offsets {
        let n = self.n_samples() as f64;
        let mut u0 = DVector::zeros(self.nu());
        let mut y0 = DVector::zeros(self.ny());
        for e in &self.experiments {
            for j in 0..self.nu() {
                u0[j] += e.u.column(j).sum() / n;
            }
            for j in 0..self.ny() {
                y0[j] += e.y.column(j).sum() / n;
            }
        }
        Offsets { u0, y0 }
    }

    /// Subtracts a known operating point: `u - u0`, `y - y0` (the
    /// linearisation point, the gyro bias).
    pub fn subtract(&self, offsets: &Offsets) -> Result<IoData> {
        if offsets.u0.len() != self.nu() {
            return Err(SysidError::dim("u0", self.nu(), offsets.u0.len()));
        }
        if offsets.y0.len() != self.ny() {
            return Err(SysidError::dim("y0", self.ny(), offsets.y0.len()));
        }
        if offsets
            .u0
            .iter()
            .chain(offsets.y0.iter())
            .any(|v| !v.is_finite())
        {
            return Err(SysidError::invalid("offsets must be finite"));
        }
        let mut out = self.clone();
        for e in &mut out.experiments {
            for mut r in e.u.row_iter_mut() {
                r -= offsets.u0.transpose();
            }
            for mut r in e.y.row_iter_mut() {
                r -= offsets.y0.transpose();
            }
        }
        Ok(out)
    }

    /// Removes the common mean of every signal (one operating point for all
    /// experiments) and returns it, to be stored as `u0`/`y0`.
    pub fn remove_means(&self) -> Result<(IoData, Offsets)> {
        let o = self.means();
        Ok((self.subtract(&o)?, o))
    }

    /// Removes a least-squares straight line from every signal of every
    /// experiment separately (MATLAB's `detrend`).
    pub fn detrend(&self) -> IoData {
        let mut out = self.clone();
        for e in &mut out.experiments {
            let n = e.len();
            let tm = (n as f64 - 1.0) / 2.0;
            let stt: f64 = (0..n).map(|k| (k as f64 - tm).powi(2)).sum();
            for m in [&mut e.u, &mut e.y] {
                for mut col in m.column_iter_mut() {
                    let mean = col.sum() / n as f64;
                    let slope = if stt > 0.0 {
                        col.iter()
                            .enumerate()
                            .map(|(k, v)| (k as f64 - tm) * (v - mean))
                            .sum::<f64>()
                            / stt
                    } else {
                        0.0
                    };
                    for (k, v) in col.iter_mut().enumerate() {
                        *v -= mean + slope * (k as f64 - tm);
                    }
                }
            }
        }
        out
    }

    /// Replaces the inputs by `M u` (`M` is `nv x nu`), e.g. the virtual
    /// inputs of the thesis (3.28) computed from the motor signals.
    pub fn map_inputs(&self, m: &DMatrix<f64>, names: Vec<String>) -> Result<IoData> {
        if m.ncols() != self.nu() {
            return Err(SysidError::dim("input map columns", self.nu(), m.ncols()));
        }
        if names.len() != m.nrows() {
            return Err(SysidError::dim("input map names", m.nrows(), names.len()));
        }
        let exps = self
            .experiments
            .iter()
            .map(|e| Experiment {
                t: e.t.clone(),
                u: &e.u * m.transpose(),
                y: e.y.clone(),
            })
            .collect();
        IoData::from_experiments(self.ts, names, self.output_names.clone(), exps)
    }

    /// Applies a zero-phase (forward-backward) low-pass filter to the
    /// selected signals of every experiment.
    pub fn lowpass(&self, filter: &Butterworth, which: SignalSelection) -> IoData {
        let mut out = self.clone();
        for e in &mut out.experiments {
            let mut targets: Vec<&mut DMatrix<f64>> = Vec::new();
            match which {
                SignalSelection::Outputs => targets.push(&mut e.y),
                SignalSelection::Inputs => targets.push(&mut e.u),
                SignalSelection::Both => {
                    targets.push(&mut e.u);
                    targets.push(&mut e.y);
                }
            }
            for m in targets {
                for mut col in m.column_iter_mut() {
                    let x: Vec<f64> = col.iter().copied().collect();
                    let f = filter.filtfilt(&x);
                    for (v, n) in col.iter_mut().zip(f) {
                        *v = n;
                    }
                }
            }
        }
        out
    }

    /// Standard deviations of inputs and outputs over all data (about the
    /// common mean).
    pub fn stds(&self) -> (DVector<f64>, DVector<f64>) {
        let o = self.means();
        let n = self.n_samples().max(1) as f64;
        let mut su = DVector::zeros(self.nu());
        let mut sy = DVector::zeros(self.ny());
        for e in &self.experiments {
            for j in 0..self.nu() {
                su[j] +=
                    e.u.column(j)
                        .iter()
                        .map(|v| (v - o.u0[j]).powi(2))
                        .sum::<f64>();
            }
            for j in 0..self.ny() {
                sy[j] +=
                    e.y.column(j)
                        .iter()
                        .map(|v| (v - o.y0[j]).powi(2))
                        .sum::<f64>();
            }
        }
        (
            su.map(|v: f64| (v / n).sqrt()),
            sy.map(|v: f64| (v / n).sqrt()),
        )
    }

    /// Checks that every input varies and every output varies; returns the
    /// standard deviations `(inputs, outputs)`.
    pub fn check_excitation(&self) -> Result<(DVector<f64>, DVector<f64>)> {
        let (su, sy) = self.stds();
        let o = self.means();
        for j in 0..self.nu() {
            if su[j].is_nan() || su[j] <= 1e-9 * (1.0 + o.u0[j].abs()) {
                return Err(SysidError::ConstantInput {
                    name: self.input_names[j].clone(),
                    std: su[j],
                });
            }
        }
        for j in 0..self.ny() {
            if sy[j].is_nan() || sy[j] <= 1e-12 * (1.0 + o.y0[j].abs()) {
                return Err(SysidError::ConstantOutput {
                    name: self.output_names[j].clone(),
                });
            }
        }
        Ok((su, sy))
    }

    /// Scales every input and output column by the given factors.
    pub(crate) fn scaled(&self, su: &DVector<f64>, sy: &DVector<f64>) -> IoData {
        let mut out = self.clone();
        for e in &mut out.experiments {
            for (j, mut c) in e.u.column_iter_mut().enumerate() {
                c *= su[j];
            }
            for (j, mut c) in e.y.column_iter_mut().enumerate() {
                c *= sy[j];
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CSV: &str = "t,experiment,a,b,p,q\n\
        0.00,2,1,5,0.1,0.2\n0.02,2,2,5,0.2,0.1\n0.04,2,3,6,0.3,0.0\n0.06,2,4,6,0.4,0.1\n\
        0.00,3,1,1,0.5,0.5\n0.02,3,1,2,0.6,0.4\n0.04,3,2,2,0.7,0.3\n";

    fn cols() -> CsvColumns {
        CsvColumns::new(&["b", "a"], &["q"])
    }

    #[test]
    fn csv_selects_columns_and_splits_experiments() {
        let d = IoData::from_csv_reader(CSV.as_bytes(), &cols(), "mem").unwrap();
        assert!((d.ts() - 0.02).abs() < 1e-12);
        assert_eq!(d.experiments().len(), 2);
        assert_eq!(d.input_names(), &["b".to_string(), "a".to_string()]);
        let e0 = &d.experiments()[0];
        assert_eq!(e0.len(), 4);
        assert_eq!(e0.u[(2, 0)], 6.0);
        assert_eq!(e0.u[(2, 1)], 3.0);
        assert_eq!(e0.y[(3, 0)], 0.1);
    }

    #[test]
    fn csv_sample_time_is_snapped_to_the_nominal_value() {
        // A time column accumulated in floating point and printed in full,
        // like 0.019999999999999574 steps.
        let mut text = String::from("t,a,q\n");
        let mut t = 25.0f64;
        for k in 0..200 {
            text.push_str(&format!("{t:?},{},{}\n", k % 3, k % 5));
            t += 0.02;
        }
        let d = IoData::from_csv_reader(text.as_bytes(), &CsvColumns::new(&["a"], &["q"]), "f")
            .unwrap();
        assert_eq!(d.ts(), 0.02);
        assert_eq!(format!("{}", d.ts()), "0.02");
        assert_eq!(snap_sample_time(0.019999999999999574), 0.02);
        assert_eq!(snap_sample_time(0.0010000000000000009), 0.001);
        assert_eq!(snap_sample_time(1.0), 1.0);
        assert_eq!(snap_sample_time(0.1 + 0.2), 0.3);
        // A genuinely odd sample time keeps its 6 significant digits.
        assert_eq!(snap_sample_time(0.0123457), 0.0123457);
    }

    #[test]
    fn csv_errors_are_clear() {
        let bad = CSV.replace("0.3,0.0", "0.3,NaN");
        let e = IoData::from_csv_reader(bad.as_bytes(), &cols(), "f.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("f.csv") && e.contains("line 4") && e.contains("non-finite"),
            "{e}"
        );
        let e = IoData::from_csv_reader(CSV.as_bytes(), &CsvColumns::new(&["zz"], &["q"]), "f")
            .unwrap_err()
            .to_string();
        assert!(e.contains("no column \"zz\""), "{e}");
        let ragged = "t,a,q\n0,1,2\n1,2\n";
        assert!(
            IoData::from_csv_reader(ragged.as_bytes(), &CsvColumns::new(&["a"], &["q"]), "f")
                .is_err()
        );
        let nonuni = "t,a,q\n0,1,2\n1,2,3\n3,1,1\n";
        let e = IoData::from_csv_reader(nonuni.as_bytes(), &CsvColumns::new(&["a"], &["q"]), "f")
            .unwrap_err()
            .to_string();
        assert!(e.contains("non-uniform"), "{e}");
    }

    #[test]
    fn mismatched_lengths_and_nan_rejected() {
        let e = IoData::new(1.0, DMatrix::zeros(5, 1), DMatrix::zeros(4, 1)).unwrap_err();
        assert!(matches!(e, SysidError::Dimension { .. }), "{e}");
        let mut y = DMatrix::zeros(5, 1);
        y[(3, 0)] = f64::NAN;
        let e = IoData::new(1.0, DMatrix::zeros(5, 1), y).unwrap_err();
        assert!(matches!(e, SysidError::NonFinite { sample: 3, .. }), "{e}");
    }

    #[test]
    fn select_intervals_make_experiments() {
        let d = IoData::from_csv_reader(CSV.as_bytes(), &cols(), "mem").unwrap();
        let s = d
            .select(&TimeInterval::parse_list("0.01:0.05").unwrap())
            .unwrap();
        assert_eq!(s.experiments().len(), 2);
        assert_eq!(s.experiments()[0].len(), 2);
        assert_eq!(s.experiments()[1].t, vec![0.02, 0.04]);
        assert!(d.select(&TimeInterval::parse_list("5:6").unwrap()).is_err());
        assert!(TimeInterval::parse_list("3:1").is_err());
        assert!(TimeInterval::parse_list("a:1").is_err());
    }

    #[test]
    fn offsets_and_trends() {
        let n = 100;
        let u = DMatrix::from_fn(n, 1, |k, _| 3.0 + 0.5 * k as f64 + ((k * 13) % 7) as f64);
        let y = DMatrix::from_fn(n, 1, |k, _| -2.0 + ((k * 5) % 3) as f64);
        let d = IoData::new(0.1, u, y).unwrap();
        let (z, o) = d.remove_means().unwrap();
        assert!(z.means().u0.norm() < 1e-12 && z.means().y0.norm() < 1e-12);
        let back = z
            .subtract(&Offsets {
                u0: -o.u0.clone(),
                y0: -o.y0.clone(),
            })
            .unwrap();
        assert!((&back.experiments()[0].u - &d.experiments()[0].u).norm() < 1e-9);
        let dt = d.detrend();
        // A detrended signal is orthogonal to 1 and to k.
        let c = dt.experiments()[0].u.column(0).clone_owned();
        let s1: f64 = c.iter().sum();
        let sk: f64 = c.iter().enumerate().map(|(k, v)| k as f64 * v).sum();
        assert!(s1.abs() < 1e-9 && sk.abs() < 1e-7);
    }

    #[test]
    fn constant_input_detected() {
        let u = DMatrix::from_fn(50, 2, |k, j| if j == 0 { k as f64 } else { 4.0 });
        let d = IoData::new(1.0, u, DMatrix::from_fn(50, 1, |k, _| k as f64)).unwrap();
        let e = d.check_excitation().unwrap_err();
        assert!(e.to_string().contains("\"u2\" is constant"), "{e}");
    }

    #[test]
    fn merge_and_map_inputs() {
        let d = IoData::new(
            1.0,
            DMatrix::from_fn(10, 2, |k, j| (k + j) as f64),
            DMatrix::zeros(10, 1),
        )
        .unwrap();
        let m = IoData::merge(&[d.clone(), d.clone()]).unwrap();
        assert_eq!(m.experiments().len(), 2);
        assert_eq!(m.n_samples(), 20);
        let v = d
            .map_inputs(
                &DMatrix::from_row_slice(1, 2, &[1.0, -1.0]),
                vec!["diff".into()],
            )
            .unwrap();
        assert!(
            v.experiments()[0]
                .u
                .iter()
                .all(|x| (*x + 1.0).abs() < 1e-15)
        );
        let other = IoData::new(2.0, DMatrix::zeros(3, 2), DMatrix::zeros(3, 1)).unwrap();
        assert!(IoData::merge(&[d, other]).is_err());
    }
}
