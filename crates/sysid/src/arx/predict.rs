//! k-step-ahead prediction of an ARX model and its fit.

use super::model::ArxModel;
use crate::data::{Experiment, IoData};
use crate::error::{Result, SysidError};
use nalgebra::DMatrix;

impl ArxModel {
    /// The k-step-ahead predictions `yhat(t|t-k)` of every experiment
    /// (`N x ny` each): the one-step predictor iterated `k` times from
    /// the measured outputs up to `t - k`, with the measured inputs up to
    /// `t` (the convention of
    /// [`InnovationModel::predict_k_step`](crate::InnovationModel::predict_k_step)).
    /// The first [`first_predicted`](Self::first_predicted)`(k)` rows of
    /// each experiment, whose prediction would need samples from before
    /// its start, are NaN. The work is `N k` one-step predictions.
    pub fn predict(&self, data: &IoData, k: usize) -> Result<Vec<DMatrix<f64>>> {
        self.check_data(data)?;
        if k == 0 {
            return Err(SysidError::invalid("prediction horizon k must be >= 1"));
        }
        Ok(data
            .experiments()
            .iter()
            .map(|e| self.predict_experiment(e, k))
            .collect())
    }

    /// The k-step prediction fit in percent per output, pooled over the
    /// experiments: `100 (1 - |y - yhat| / |y - mean(y)|)`, the formula of
    /// [`fit_percent`](crate::fit_percent), over the samples that have a
    /// prediction (all but the first
    /// [`first_predicted`](Self::first_predicted)`(k)` of each
    /// experiment; an error if none has).
    pub fn predict_fit(&self, data: &IoData, k: usize) -> Result<Vec<f64>> {
        let p = self.predict(data, k)?;
        let skip = self.first_predicted(k);
        let mut y = Vec::new();
        let mut yhat = Vec::new();
        for (e, p) in data.experiments().iter().zip(&p) {
            if e.len() > skip {
                let rows = e.len() - skip;
                y.push(e.y.rows(skip, rows).into_owned());
                yhat.push(p.rows(skip, rows).into_owned());
            }
        }
        if y.is_empty() {
            return Err(SysidError::TooFewSamples {
                what: format!("a {k}-step ARX prediction (per experiment)"),
                needed: skip + 1,
                found: data
                    .experiments()
                    .iter()
                    .map(|e| e.len())
                    .max()
                    .unwrap_or(0),
            });
        }
        Ok(crate::fit::fit_percent(&y, &yhat))
    }

    /// The first sample of an experiment that has a k-step prediction:
    /// `max_lag + k - 1` ([`ArxSettings::max_lag`](crate::ArxSettings::max_lag)).
    pub fn first_predicted(&self, k: usize) -> usize {
        self.settings().max_lag() + k.saturating_sub(1)
    }

    fn check_data(&self, data: &IoData) -> Result<()> {
        if data.nu() != self.nu() {
            return Err(SysidError::dim(
                "model inputs vs data",
                data.nu(),
                self.nu(),
            ));
        }
        if data.ny() != self.ny() {
            return Err(SysidError::dim(
                "model outputs vs data",
                data.ny(),
                self.ny(),
            ));
        }
        Ok(())
    }

    fn predict_experiment(&self, e: &Experiment, k: usize) -> DMatrix<f64> {
        let n = e.len();
        let ny = self.ny();
        let s = self.settings();
        let mut out = DMatrix::zeros(n, ny);
        // buf[(s - base - 1) * ny + o]: the prediction of y(s) from base.
        let mut buf = vec![0.0; k * ny];
        let held = |m: &DMatrix<f64>, t: isize, j: usize| m[(t.max(0) as usize, j)];
        let first = self.first_predicted(k).min(n);
        out.rows_mut(0, first).fill(f64::NAN);
        for t in first..n {
            let base = t as isize - k as isize;
            let first = (base + 1).max(0);
            for sidx in first..=t as isize {
                let slot = (sidx - base - 1) as usize;
                for o in 0..ny {
                    let mut v = 0.0;
                    for (i, ai) in self.a().iter().enumerate() {
                        let src = sidx - 1 - i as isize;
                        for r in 0..ny {
                            let yv = if src > base {
                                buf[(src - base - 1) as usize * ny + r]
                            } else {
                                held(&e.y, src, r)
                            };
                            v += ai[(o, r)] * yv;
                        }
                    }
                    for (j, bj) in self.b().iter().enumerate() {
                        let src = sidx - (s.nk + j) as isize;
                        for q in 0..self.nu() {
                            v += bj[(o, q)] * held(&e.u, src, q);
                        }
                    }
                    buf[slot * ny + o] = v;
                }
            }
            let last = (t as isize - base - 1) as usize;
            for o in 0..ny {
                out[(t, o)] = buf[last * ny + o];
            }
        }
        out
    }
}
