//! The exact state-space realisation of an ARX model.

use super::model::ArxModel;
use crate::data::Experiment;
use crate::error::Result;
use crate::model::InnovationModel;
use nalgebra::{DMatrix, DVector};

impl ArxModel {
    /// The model as an innovation form of order `ny n`, `n` =
    /// [`ArxSettings::max_lag`](crate::ArxSettings::max_lag), with the
    /// same one-step (and so k-step) predictions: the observer canonical
    /// form with state blocks
    /// `x_j(t) = sum_(i >= j) a_i y(t+j-1-i) + b_i u(t+j-1-i)`,
    ///
    /// `A` block companion (`a_1 .. a_n` in the first block column,
    /// identities above the diagonal), `B_j = b_j + a_j b_0`, `C = [I 0 ..]`,
    /// `D = b_0` (the coefficient of `u(t)`, zero unless `nk = 0`),
    /// `K_j = a_j`; here `a_i`, `b_i` are the coefficients of lag `i`
    /// (zero where the structure has none). `A - K C` is the block shift
    /// (nilpotent): the predictor forgets its initial state after `n`
    /// samples. The realisation need not be minimal.
    pub fn to_innovation_model(&self) -> Result<InnovationModel> {
        let (nu, ny) = (self.nu(), self.ny());
        let n = self.settings().max_lag();
        let nx = ny * n;
        let zero_a = DMatrix::zeros(ny, ny);
        let zero_b = DMatrix::zeros(ny, nu);
        let b0 = self.b_at_lag(0).unwrap_or(&zero_b).clone();
        let mut a = DMatrix::zeros(nx, nx);
        let mut b = DMatrix::zeros(nx, nu);
        let mut k = DMatrix::zeros(nx, ny);
        for j in 1..=n {
            let aj = self.a_at_lag(j).unwrap_or(&zero_a);
            let bj = self.b_at_lag(j).unwrap_or(&zero_b);
            let r = (j - 1) * ny;
            a.view_mut((r, 0), (ny, ny)).copy_from(aj);
            if j < n {
                a.view_mut((r, j * ny), (ny, ny))
                    .copy_from(&DMatrix::identity(ny, ny));
            }
            b.view_mut((r, 0), (ny, nu)).copy_from(&(bj + aj * &b0));
            k.view_mut((r, 0), (ny, ny)).copy_from(aj);
        }
        let mut c = DMatrix::zeros(ny, nx);
        c.view_mut((0, 0), (ny, ny))
            .copy_from(&DMatrix::identity(ny, ny));
        InnovationModel::new(self.ts(), a, b, c, b0, k)
    }

    /// The state of [`to_innovation_model`](Self::to_innovation_model)'s
    /// realisation at sample `t` of an experiment, computed from the
    /// measured data before `t`; `None` when `t < max_lag` (the state
    /// needs samples from before the start) or `t` is past the end.
    pub fn realisation_state(&self, e: &Experiment, t: usize) -> Option<DVector<f64>> {
        let ny = self.ny();
        let n = self.settings().max_lag();
        if t < n || t > e.len() {
            return None;
        }
        let mut x = DVector::zeros(ny * n);
        for j in 1..=n {
            let mut xj = DVector::<f64>::zeros(ny);
            for i in j..=n {
                // Sample t + j - 1 - i <= t - 1 (as i >= j) and >= t - n >= 0.
                let s = t + j - 1 - i;
                if let Some(ai) = self.a_at_lag(i) {
                    xj += ai * e.y.row(s).transpose();
                }
                if let Some(bi) = self.b_at_lag(i) {
                    xj += bi * e.u.row(s).transpose();
                }
            }
            x.rows_mut((j - 1) * ny, ny).copy_from(&xj);
        }
        Some(x)
    }
}
