//! What an ARX model is and what [`arx`](crate::arx()) fits.

use crate::data::IoData;
use crate::error::{Result, SysidError};
use nalgebra::DMatrix;

/// The structure of a MIMO ARX model
///
/// `y(t) = a_1 y(t-1) + ... + a_na y(t-na)
///        + b_0 u(t-nk) + ... + b_(nb-1) u(t-nk-nb+1) + e(t)`
///
/// with full `ny x ny` matrices `a_i` (every output's past enters every
/// output) and `ny x nu` matrices `b_j`. In MATLAB's notation
/// `A(q) = I - a_1 q^-1 - ... - a_na q^-na`, `B(q) = q^-nk (b_0 + ...)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArxSettings {
    /// Number of output lags `na` (0: a finite impulse response model).
    pub na: usize,
    /// Number of input lags `nb` (0: an autoregressive model).
    pub nb: usize,
    /// Input delay `nk` in samples (0: a feed-through `b_0 u(t)`).
    pub nk: usize,
}

impl Default for ArxSettings {
    /// Two output and two input lags, one sample of delay.
    fn default() -> Self {
        ArxSettings::lags(2)
    }
}

impl ArxSettings {
    /// `na = nb = lags`, `nk = 1`: the structure of the baselines.
    pub fn lags(lags: usize) -> Self {
        ArxSettings {
            na: lags,
            nb: lags,
            nk: 1,
        }
    }

    /// The largest lag of the model, `max(na, nk + nb - 1)`: the number
    /// of past samples one prediction needs (at least 1).
    pub fn max_lag(&self) -> usize {
        let input = if self.nb > 0 {
            self.nk + self.nb - 1
        } else {
            0
        };
        self.na.max(input).max(1)
    }

    /// Parameters per output: `ny na + nu nb`.
    pub fn parameters_per_output(&self, nu: usize, ny: usize) -> usize {
        ny * self.na + nu * self.nb
    }

    /// Regression rows on `data`: every experiment's samples after its
    /// first [`max_lag`](Self::max_lag), which enter only as history.
    pub fn regression_rows(&self, data: &IoData) -> usize {
        data.rows_after(self.max_lag())
    }

    /// Whether [`arx`](crate::arx()) has rows enough on `data` (at least
    /// one more than the parameters per output); it may still fail on
    /// dependent regressors.
    pub fn has_rows_on(&self, data: &IoData) -> bool {
        self.regression_rows(data) > self.parameters_per_output(data.nu(), data.ny())
    }

    pub(crate) fn check(&self) -> Result<()> {
        if self.na == 0 && self.nb == 0 {
            return Err(SysidError::invalid(
                "an ARX model needs na > 0 or nb > 0 (it would predict zero)",
            ));
        }
        if self.max_lag() > 10_000 {
            return Err(SysidError::invalid(format!(
                "ARX lags na = {}, nk + nb - 1 = {} exceed 10000",
                self.na,
                self.nk + self.nb
            )));
        }
        Ok(())
    }
}

/// The lag count of an automatic default on `data`: `preferred` where the
/// ARX `structure(preferred)` has rows enough to be fitted at all, else
/// (a record too short for it) the largest `l` in `least..preferred`
/// whose ARX has at least twice as many regression rows as parameters per
/// output, so that its residuals still stand for the noise; `preferred`
/// again when none has, and the fit's own error then names what the
/// data lack.
pub(crate) fn default_lags(
    data: &IoData,
    preferred: usize,
    least: usize,
    structure: impl Fn(usize) -> ArxSettings,
) -> usize {
    if structure(preferred).has_rows_on(data) {
        return preferred;
    }
    let (nu, ny) = (data.nu(), data.ny());
    (least.max(1)..preferred)
        .rev()
        .find(|&l| {
            let s = structure(l);
            s.regression_rows(data) >= 2 * s.parameters_per_output(nu, ny)
        })
        .unwrap_or(preferred)
}

/// A MIMO ARX model estimated by [`arx`](crate::arx()) (or built from
/// its coefficients by [`ArxModel::new`]): the coefficient matrices of
/// [`ArxSettings`], in the units of the data. There is no constant term:
/// remove the operating point first, e.g. by
/// [`IoData::remove_means`](crate::IoData::remove_means).
#[derive(Clone, Debug, PartialEq)]
pub struct ArxModel {
    ts: f64,
    settings: ArxSettings,
    nu: usize,
    ny: usize,
    a: Vec<DMatrix<f64>>,
    b: Vec<DMatrix<f64>>,
    noise_covariance: DMatrix<f64>,
}

impl ArxModel {
    /// A model from its coefficients, checked: `na` matrices `a_i`
    /// (`ny x ny`), `nb` matrices `b_j` (`ny x nu`), all finite, `ts`
    /// finite and positive. The noise covariance is set to zero.
    pub fn new(
        ts: f64,
        settings: ArxSettings,
        nu: usize,
        ny: usize,
        a: Vec<DMatrix<f64>>,
        b: Vec<DMatrix<f64>>,
    ) -> Result<Self> {
        settings.check()?;
        if !(ts.is_finite() && ts > 0.0) {
            return Err(SysidError::invalid(format!(
                "sample time must be finite and > 0, found {ts}"
            )));
        }
        if ny == 0 {
            return Err(SysidError::invalid(
                "an ARX model needs at least one output",
            ));
        }
        if a.len() != settings.na {
            return Err(SysidError::dim("ARX a matrices (na)", settings.na, a.len()));
        }
        if b.len() != settings.nb {
            return Err(SysidError::dim("ARX b matrices (nb)", settings.nb, b.len()));
        }
        for (what, ms, cols) in [("a", &a, ny), ("b", &b, nu)] {
            for m in ms {
                if m.nrows() != ny {
                    return Err(SysidError::dim(format!("ARX {what} rows"), ny, m.nrows()));
                }
                if m.ncols() != cols {
                    return Err(SysidError::dim(
                        format!("ARX {what} columns"),
                        cols,
                        m.ncols(),
                    ));
                }
                if m.iter().any(|v| !v.is_finite()) {
                    return Err(SysidError::invalid(format!(
                        "ARX {what} matrix has a non-finite entry"
                    )));
                }
            }
        }
        Ok(ArxModel {
            ts,
            settings,
            nu,
            ny,
            a,
            b,
            noise_covariance: DMatrix::zeros(ny, ny),
        })
    }

    pub(crate) fn with_noise_covariance(mut self, lambda: DMatrix<f64>) -> Self {
        self.noise_covariance = lambda;
        self
    }

    /// Sample time in seconds.
    pub fn ts(&self) -> f64 {
        self.ts
    }
    /// The structure.
    pub fn settings(&self) -> ArxSettings {
        self.settings
    }
    /// Number of inputs.
    pub fn nu(&self) -> usize {
        self.nu
    }
    /// Number of outputs.
    pub fn ny(&self) -> usize {
        self.ny
    }
    /// `a_1 .. a_na`, each `ny x ny`: `a()[i]` multiplies `y(t-1-i)`.
    pub fn a(&self) -> &[DMatrix<f64>] {
        &self.a
    }
    /// `b_0 .. b_(nb-1)`, each `ny x nu`: `b()[j]` multiplies `u(t-nk-j)`.
    pub fn b(&self) -> &[DMatrix<f64>] {
        &self.b
    }
    /// Covariance of the one-step residuals on the estimation data
    /// (`ny x ny`, sum of squares over the number of regression rows);
    /// zero for a model built by [`ArxModel::new`].
    pub fn noise_covariance(&self) -> &DMatrix<f64> {
        &self.noise_covariance
    }

    /// The coefficient of `u(t - lag)` (`b_(lag-nk)`, or `None` outside
    /// `nk..nk+nb`).
    pub fn b_at_lag(&self, lag: usize) -> Option<&DMatrix<f64>> {
        lag.checked_sub(self.settings.nk)
            .and_then(|j| self.b.get(j))
    }

    /// The coefficient of `y(t - lag)` (`a_lag`, or `None` outside `1..=na`).
    pub fn a_at_lag(&self, lag: usize) -> Option<&DMatrix<f64>> {
        lag.checked_sub(1).and_then(|i| self.a.get(i))
    }
}
