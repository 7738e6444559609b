//! The ARX baseline of the fit tables: the best of several lag counts at
//! each prediction horizon.

use super::estimate::arx;
use super::model::ArxSettings;
use crate::data::IoData;
use crate::error::{Result, SysidError};
use std::ops::RangeInclusive;

/// One lag count of [`arx_baseline`].
#[derive(Clone, Debug, PartialEq)]
pub struct ArxBaselineCandidate {
    /// `na = nb = lags`, `nk = 1`.
    pub lags: usize,
    /// Validation fit per horizon (in the order of the `horizons`
    /// argument), per output, percent.
    pub fits: Vec<Vec<f64>>,
}

/// The best candidate at one horizon.
#[derive(Clone, Debug, PartialEq)]
pub struct ArxBaselineRow {
    /// The prediction horizon `k`.
    pub horizon: usize,
    /// The lag count with the highest mean fit at this horizon.
    pub lags: usize,
    /// Its fit per output, percent.
    pub fit: Vec<f64>,
    /// Its mean fit over the outputs.
    pub mean: f64,
}

/// Result of [`arx_baseline`].
#[derive(Clone, Debug, PartialEq)]
pub struct ArxBaseline {
    /// One row per horizon, in the order given.
    pub rows: Vec<ArxBaselineRow>,
    /// Every lag count that could be fitted, ascending.
    pub candidates: Vec<ArxBaselineCandidate>,
    /// Lag counts skipped because the estimation data are too short for
    /// them.
    pub skipped: Vec<usize>,
}

impl ArxBaseline {
    /// The row of horizon `k`.
    pub fn row(&self, k: usize) -> Option<&ArxBaselineRow> {
        self.rows.iter().find(|r| r.horizon == k)
    }
}

/// The ARX baseline of a fit table: for every lag count `l` in `lags` an
/// ARX model with `na = nb = l`, `nk = 1` ([`ArxSettings::lags`]) is
/// fitted on `est` by least squares ([`arx`](crate::arx())) and its
/// k-step prediction fit ([`ArxModel::predict_fit`](crate::ArxModel::predict_fit)) computed on `val` for
/// every horizon; each row reports the lag count with the highest mean
/// fit at that horizon.
///
/// The choice looks at `val`: the baseline is the best any of these
/// ARX models does on the validation data, an upper bound on what a
/// user would get from ARX, which makes it the harder baseline to beat.
/// Lag counts that need more samples than `est` has are skipped
/// (listed in [`ArxBaseline::skipped`]); if none remains, that error is
/// returned. Remove the operating point of both sets first (ARX has no
/// constant term).
///
/// ```
/// use kestrel_sysid::{arx_baseline, synthetic};
/// let truth = synthetic::random_model(3, 2, 2, 5, 0.9);
/// let data = synthetic::simulate(&truth, 2000, 0.1, 2).unwrap();
/// let (est, val) = data.split(0.5).unwrap();
/// let b = arx_baseline(&est, &val, 2..=10, &[1, 5]).unwrap();
/// assert_eq!(b.rows.len(), 2);
/// let one = b.row(1).unwrap();
/// assert!((2..=10).contains(&one.lags) && one.mean > 50.0);
/// ```
pub fn arx_baseline(
    est: &IoData,
    val: &IoData,
    lags: RangeInclusive<usize>,
    horizons: &[usize],
) -> Result<ArxBaseline> {
    if lags.is_empty() || *lags.start() == 0 {
        return Err(SysidError::invalid(format!(
            "ARX baseline lags {}..={} must be a non-empty range of counts >= 1",
            lags.start(),
            lags.end()
        )));
    }
    if horizons.is_empty() || horizons.contains(&0) {
        return Err(SysidError::invalid(
            "ARX baseline horizons must be a non-empty list of steps >= 1",
        ));
    }
    let mut candidates = Vec::new();
    let mut skipped = Vec::new();
    let mut short = None;
    for l in lags {
        let model = match arx(est, &ArxSettings::lags(l)) {
            Ok(m) => m,
            Err(e @ SysidError::TooFewSamples { .. }) => {
                skipped.push(l);
                short.get_or_insert(e);
                continue;
            }
            Err(e) => return Err(e),
        };
        let fits = horizons
            .iter()
            .map(|&k| model.predict_fit(val, k))
            .collect::<Result<Vec<_>>>()?;
        candidates.push(ArxBaselineCandidate { lags: l, fits });
    }
    if candidates.is_empty() {
        return Err(short.unwrap_or_else(|| SysidError::invalid("no ARX lag count fitted")));
    }
    let mean = |f: &[f64]| f.iter().sum::<f64>() / f.len().max(1) as f64;
    let rows = horizons
        .iter()
        .enumerate()
        .map(|(h, &k)| {
            let best = candidates
                .iter()
                .max_by(|x, y| mean(&x.fits[h]).total_cmp(&mean(&y.fits[h])))
                .unwrap_or(&candidates[0]);
            ArxBaselineRow {
                horizon: k,
                lags: best.lags,
                fit: best.fits[h].clone(),
                mean: mean(&best.fits[h]),
            }
        })
        .collect();
    Ok(ArxBaseline {
        rows,
        candidates,
        skipped,
    })
}
