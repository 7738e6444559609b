//! The criterion as weights on the residuals: the whitening of the
//! determinant criterion, the `1 / rms` group weights of the fit
//! criterion, and the objective of one search (which residual belongs to
//! which output and step, which steps count, the simulation term's
//! weight).

use super::series::Series;
use super::settings::{Criterion, PemSettings};
use nalgebra::{DMatrix, DVector};

/// Cholesky factor inverse `L^-1` of the residual covariance (`ny x ny`).
fn whitener(res: &DVector<f64>, ny: usize) -> DMatrix<f64> {
    let m = res.len() / ny;
    let e = DMatrix::from_column_slice(ny, m, res.as_slice());
    let mut cov = &e * e.transpose() / m.max(1) as f64;
    let ridge = 1e-12 * cov.trace().max(1e-300);
    for i in 0..ny {
        cov[(i, i)] += ridge;
    }
    match cov.cholesky() {
        Some(ch) => ch
            .l()
            .try_inverse()
            .unwrap_or_else(|| DMatrix::identity(ny, ny)),
        None => DMatrix::identity(ny, ny),
    }
}

/// Group of every residual for [`Criterion::Fit`]: `step * ny + output`,
/// in the `[t][step][output]` order of [`residuals_and_jacobian`].
pub(super) fn fit_groups(data: &[Series], ny: usize, h: usize) -> Vec<usize> {
    let mut g = Vec::new();
    for s in data {
        for t in 0..s.n {
            for j in 0..h.min(s.n - t) {
                g.extend((0..ny).map(|o| j * ny + o));
            }
        }
    }
    g
}

/// Weights `1 / rms(e_g)` of the groups of [`fit_groups`] (`ng` groups).
pub(super) fn fit_weights(res: &DVector<f64>, groups: &[usize], ng: usize) -> Vec<f64> {
    let mut sum = vec![0.0; ng];
    let mut count = vec![0usize; ng];
    for (e, &g) in res.iter().zip(groups) {
        sum[g] += e * e;
        count[g] += 1;
    }
    let rms: Vec<f64> = sum
        .iter()
        .zip(&count)
        .map(|(s, &c)| (s / c.max(1) as f64).sqrt())
        .collect();
    let floor = 1e-12 * rms.iter().copied().fold(0.0, f64::max).max(1e-300);
    rms.iter().map(|r| 1.0 / r.max(floor)).collect()
}

/// The square roots of the group weights `w` (what multiplies the
/// residuals and the Jacobian rows).
fn roots(w: &[f64]) -> Vec<f64> {
    w.iter().map(|v| v.sqrt()).collect()
}

/// The weighting of the residuals in force during one iteration.
pub(super) enum ResidualWeights {
    /// Plain trace.
    None,
    /// `L^-1` of the residual covariance ([`Criterion::Determinant`]).
    Whiten(DMatrix<f64>),
    /// The square roots of the group weights (`1 / rms` for
    /// [`Criterion::Fit`]), one factor per group of residuals.
    Groups(Vec<f64>),
}

impl ResidualWeights {
    /// The weighting of `criterion` at the residuals `res`.
    pub(super) fn at(
        criterion: Criterion,
        res: &DVector<f64>,
        ny: usize,
        groups: &[usize],
        ng: usize,
    ) -> Self {
        match criterion {
            Criterion::Trace => ResidualWeights::None,
            Criterion::Determinant => ResidualWeights::Whiten(whitener(res, ny)),
            Criterion::Fit => ResidualWeights::Groups(roots(&fit_weights(res, groups, ng))),
        }
    }
    pub(super) fn apply(&self, groups: &[usize], res: &mut DVector<f64>) {
        match self {
            ResidualWeights::None => {}
            ResidualWeights::Whiten(w) => {
                // `L^-1` applied to every sample's block of residuals.
                let ny = w.nrows();
                let e = w * DMatrix::from_column_slice(ny, res.len() / ny, res.as_slice());
                res.copy_from_slice(e.as_slice());
            }
            ResidualWeights::Groups(sw) => {
                for (e, &g) in res.iter_mut().zip(groups) {
                    *e *= sw[g];
                }
            }
        }
    }

    /// The same weighting of the columns of a whole Jacobian `jt`
    /// (`p x residuals`): the tests' reference for the accumulated normal
    /// equations, which weigh the rows as they are formed.
    #[cfg(test)]
    pub(super) fn apply_to_jacobian(&self, groups: &[usize], jt: &mut DMatrix<f64>) {
        match self {
            ResidualWeights::None => {}
            ResidualWeights::Whiten(w) => {
                let ny = w.nrows();
                for t in 0..jt.ncols() / ny {
                    let wb = jt.columns(t * ny, ny).into_owned() * w.transpose();
                    jt.columns_mut(t * ny, ny).copy_from(&wb);
                }
            }
            ResidualWeights::Groups(sw) => {
                for (i, &g) in groups.iter().enumerate() {
                    jt.column_mut(i).scale_mut(sw[g]);
                }
            }
        }
    }
}

/// The objective of one search: which output and step every residual
/// belongs to, which of them count, and the weight of every group.
pub(super) struct Objective {
    /// The criterion of the settings.
    criterion: Criterion,
    /// Outputs.
    ny: usize,
    /// Whether only some steps count ([`PemSettings::steps`]).
    selected: bool,
    /// Whether a simulation term follows the prediction errors.
    sim: bool,
    /// Group of every residual (`step * ny + output`, the simulation
    /// errors `h * ny + output`); empty for the plain trace.
    pub(super) groups: Vec<usize>,
    /// Number of groups.
    ng: usize,
    /// Weight of every group's squared errors besides 1 / rms (fit).
    group_weight: Vec<f64>,
    /// Whether a group's errors count (those of the steps left out are
    /// zeroed, with their Jacobian columns).
    keep: Vec<bool>,
}

impl Objective {
    /// The objective of `settings` on `series` (`ny` outputs).
    pub(super) fn new(settings: &PemSettings, series: &[Series], ny: usize) -> Self {
        let h = settings.horizon;
        let ws = settings.simulation_weight;
        let sim = ws > 0.0;
        let selected = !settings.steps.is_empty();
        let mut groups = if settings.criterion == Criterion::Fit || selected || sim {
            fit_groups(series, ny, h)
        } else {
            Vec::new()
        };
        // The simulation errors form groups `h * ny + output`.
        let ng = h * ny + if sim { ny } else { 0 };
        if sim {
            for s in series {
                for _ in 0..s.n {
                    groups.extend((0..ny).map(|o| h * ny + o));
                }
            }
        }
        // Weight of every group's squared errors besides 1 / rms (fit).
        let group_weight: Vec<f64> = (0..ng)
            .map(|g| if g >= h * ny { ws } else { 1.0 })
            .collect();
        // Errors of the steps left out are zeroed (with their Jacobian columns).
        let keep: Vec<bool> = (0..ng)
            .map(|g| !selected || g >= h * ny || settings.steps.contains(&(g / ny + 1)))
            .collect();
        Objective {
            criterion: settings.criterion,
            ny,
            selected,
            sim,
            groups,
            ng,
            group_weight,
            keep,
        }
    }

    /// Zeroes the errors of the steps left out.
    pub(super) fn mask(&self, res: &mut DVector<f64>) {
        if !self.selected {
            return;
        }
        for (e, &g) in res.iter_mut().zip(&self.groups) {
            if !self.keep[g] {
                *e = 0.0;
            }
        }
    }

    /// Zeroes the Jacobian columns (of `jt`, `p x residuals`) of the steps
    /// left out: the tests' reference, as
    /// [`ResidualWeights::apply_to_jacobian`].
    #[cfg(test)]
    pub(super) fn mask_jacobian(&self, jt: &mut DMatrix<f64>) {
        if !self.selected {
            return;
        }
        for (i, &g) in self.groups.iter().enumerate() {
            if !self.keep[g] {
                jt.column_mut(i).fill(0.0);
            }
        }
    }

    /// Whether the errors of step `j + 1` count, for `j < h` (the
    /// prediction horizon).
    pub(super) fn kept_steps(&self, h: usize) -> Vec<bool> {
        (0..h).map(|j| self.keep[j * self.ny]).collect()
    }

    /// The weighting of the criterion at the residuals `res`.
    pub(super) fn weights_at(&self, res: &DVector<f64>) -> ResidualWeights {
        match (self.criterion, self.sim) {
            (Criterion::Trace, true) => ResidualWeights::Groups(roots(&self.group_weight)),
            (Criterion::Fit, true) => {
                let w = fit_weights(res, &self.groups, self.ng);
                let w: Vec<f64> = w
                    .iter()
                    .zip(&self.group_weight)
                    .map(|(a, b)| a * b)
                    .collect();
                ResidualWeights::Groups(roots(&w))
            }
            (criterion, _) => ResidualWeights::at(criterion, res, self.ny, &self.groups, self.ng),
        }
    }

    /// The number of residuals that count, of `len` (at least 1): the
    /// divisor of the mean squared error.
    pub(super) fn count(&self, len: usize) -> f64 {
        if self.selected || self.sim {
            self.groups.iter().filter(|&&g| self.keep[g]).count().max(1) as f64
        } else {
            len.max(1) as f64
        }
    }
}
