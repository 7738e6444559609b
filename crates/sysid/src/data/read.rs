//! CSV logs: column selection, the time column's sample time and the
//! experiment column.

use super::{CsvColumns, Experiment, IoData};
use crate::error::{Result, SysidError};
use nalgebra::DMatrix;
use std::path::Path;

/// The nominal sample time behind a measured step: time columns written
/// with a few decimals (or accumulated in floating point) give steps like
/// `0.019999999999999574`; the step is rounded to 6 significant digits,
/// which is far finer than any clock jitter the 1 % uniformity check lets
/// through, so `0.02` comes back as `0.02` exactly.
pub(super) fn snap_sample_time(step: f64) -> f64 {
    if !(step.is_finite() && step > 0.0) {
        return step;
    }
    let scale = 10f64.powi(5 - step.log10().floor() as i32);
    let snapped = (step * scale).round() / scale;
    if snapped > 0.0 { snapped } else { step }
}

impl IoData {
    /// Reads a CSV log (one header row) with the given columns. A time
    /// column, when present, gives the sample time (median step; sampling
    /// must be uniform within 1 %), in `columns.time_unit` (converted to
    /// seconds); a `columns.ts` given as well must agree with it to 1 %.
    /// Without a time column the sample time is `columns.ts`, which is then
    /// required (nothing is guessed), and times are row indices. An
    /// experiment column,
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
        // A name the header holds twice is ambiguous: refused when used.
        let find = |name: &str| -> Result<Option<usize>> {
            let mut at = headers
                .iter()
                .enumerate()
                .filter(|(_, h)| *h == name)
                .map(|(i, _)| i + 1);
            match (at.next(), at.next()) {
                (Some(a), Some(b)) => Err(err(format!(
                    "column \"{name}\" appears more than once in the header (columns {a} and {b}): rename one"
                ))),
                (a, _) => Ok(a.map(|i| i - 1)),
            }
        };
        let pick = |names: &[String]| -> Result<Vec<usize>> {
            names
                .iter()
                .map(|n| {
                    find(n)?.ok_or_else(|| {
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
        let all: Vec<&String> = columns.inputs.iter().chain(&columns.outputs).collect();
        if let Some(n) = all
            .iter()
            .copied()
            .find(|n| all.iter().filter(|m| *m == n).count() > 1)
        {
            let count = |list: &[String]| list.iter().filter(|c| *c == n).count();
            let role = match (count(&columns.inputs), count(&columns.outputs)) {
                (i, o) if i > 0 && o > 0 => "both an input and an output",
                (i, _) if i > 1 => "an input twice",
                _ => "an output twice",
            };
            return Err(SysidError::invalid(format!(
                "column \"{n}\" is selected as {role}: each column can be one signal only"
            )));
        }
        let ui = pick(&columns.inputs)?;
        let yi = pick(&columns.outputs)?;
        let ti = find(&columns.time)?;
        if let Some(ts) = columns.ts.filter(|ts| !(ts.is_finite() && *ts > 0.0)) {
            return Err(SysidError::invalid(format!(
                "the sample time must be a positive number of seconds, got {ts}"
            )));
        }
        if ti.is_none() && columns.ts.is_none() {
            return Err(err(format!(
                "no time column \"{}\" (columns: {}) and no sample time given: give the sample time in seconds (`CsvColumns::ts`, `--ts` on the command line)",
                columns.time,
                headers.iter().collect::<Vec<_>>().join(", ")
            )));
        }
        let ei = find(&columns.experiment)?;
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
                Some(i) => get(i, &columns.time)? * columns.time_unit.seconds(),
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
            let ts = snap_sample_time(median);
            if let Some(given) = columns.ts.filter(|g| ((g - ts) / ts).abs() > 0.01) {
                return Err(err(format!(
                    "the sample time given, {given} s, disagrees with the time column \"{}\", whose step is {ts} s; leave the sample time out or correct it",
                    columns.time
                )));
            }
            ts
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
}
