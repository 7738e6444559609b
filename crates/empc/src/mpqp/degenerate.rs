//! Degeneracy: where the facet rule fails, the QP at the probe point and
//! every linearly independent subset of its active constraints that
//! represents the optimum.

use crate::error::EmpcError;
use crate::lp::LpWorkspace;
use crate::mpqp::prepare::Prepared;
use crate::mpqp::region::RegionData;
use crate::qp;
use nalgebra::{DMatrix, DVector};

impl Prepared {
    /// All linearly independent subsets of the active constraints at the QP
    /// optimum of `theta` that represent the optimum with non-negative
    /// multipliers, and have a full-dimensional region.
    pub(super) fn regions_at(
        &self,
        theta: &[f64],
        max_set: usize,
        lp: &mut LpWorkspace,
    ) -> Result<Option<Vec<RegionData>>, EmpcError> {
        Ok(self
            .sets_at(theta, max_set, lp)?
            .map(|sets| sets.iter().filter_map(|s| self.region(s, lp)).collect()))
    }

    /// The candidate active sets of [`Self::regions_at`], before their
    /// regions are computed: the QP's final working set first, then every
    /// other linearly independent subset of the constraints active at the
    /// optimum (up to `max_set` of them) that represents it with
    /// non-negative multipliers, in the order of the subsets' bit masks.
    /// `None` where the QP is infeasible.
    pub(super) fn sets_at(
        &self,
        theta: &[f64],
        max_set: usize,
        lp: &mut LpWorkspace,
    ) -> Result<Option<Vec<Vec<usize>>>, EmpcError> {
        let th = DVector::from_column_slice(theta);
        let q = self.ft.tr_mul(&th) + &self.f;
        let rhs = &self.w + &self.e * &th;
        let opt = match qp::solve(&self.h, &self.hinv, &q, &self.g, &rhs, lp) {
            Ok(o) => o,
            Err(qp::QpFailure::Infeasible) => return Ok(None),
            Err(qp::QpFailure::NotConverged) => {
                return Err(EmpcError::Numerical(format!(
                    "the QP at theta = {theta:?} did not converge"
                )));
            }
        };
        let z = &opt.z;
        let slack = &rhs - &self.g * z;
        let tol = 1e-8 * (1.0 + rhs.amax());
        let zset: Vec<usize> = (0..self.m).filter(|&i| slack[i] <= tol).collect();
        let grad = &self.h * z + &q;
        let mut sets: Vec<Vec<usize>> = Vec::new();
        let mut ws = opt.working.clone();
        ws.sort_unstable();
        sets.push(ws);
        if zset.len() <= max_set {
            let kz = zset.len();
            for mask in 0u64..(1u64 << kz) {
                let sub: Vec<usize> = (0..kz)
                    .filter(|&b| mask >> b & 1 == 1)
                    .map(|b| zset[b])
                    .collect();
                if sub.len() > self.n || sets.contains(&sub) {
                    continue;
                }
                if represents(&self.g, &sub, &grad) {
                    sets.push(sub);
                }
            }
        }
        Ok(Some(sets))
    }
}

/// Whether `-grad = G_S' lambda` with `lambda >= 0` and independent rows `S`.
fn represents(g: &DMatrix<f64>, set: &[usize], grad: &DVector<f64>) -> bool {
    let n = g.ncols();
    let k = set.len();
    let gnorm = 1.0 + grad.amax();
    if k == 0 {
        return grad.amax() <= 1e-8 * gnorm;
    }
    let mut gs = DMatrix::zeros(n, k);
    for (c, &i) in set.iter().enumerate() {
        gs.column_mut(c).copy_from(&g.row(i).transpose());
    }
    let gtg = gs.tr_mul(&gs);
    let Some(ch) = gtg.clone().cholesky() else {
        return false;
    };
    let minp = (0..k)
        .map(|i| ch.l()[(i, i)].powi(2))
        .fold(f64::INFINITY, f64::min);
    if minp <= 1e-10 {
        return false;
    }
    let lam = ch.solve(&(-gs.tr_mul(grad)));
    let resid = &gs * &lam + grad;
    resid.amax() <= 1e-7 * gnorm && lam.iter().all(|&l| l >= -1e-9 * gnorm)
}
