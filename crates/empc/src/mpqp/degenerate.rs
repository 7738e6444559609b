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
            let rows = Subsets::new(&self.g, &zset, &grad);
            let mut sub: Vec<usize> = Vec::with_capacity(kz);
            for mask in 0u64..(1u64 << kz) {
                if mask.count_ones() as usize > self.n {
                    continue;
                }
                sub.clear();
                sub.extend((0..kz).filter(|&b| mask >> b & 1 == 1).map(|b| zset[b]));
                if sets.contains(&sub) {
                    continue;
                }
                if rows.represents(mask) {
                    sets.push(sub.clone());
                }
            }
        }
        Ok(Some(sets))
    }
}

/// The constraints active at a degenerate optimum, as columns, with the
/// products every subset's test needs computed once: their Gram matrix
/// and their products with the gradient. Each entry is the same dot
/// product of the same two columns that a subset's own `G_S' G_S` and
/// `G_S' grad` compute, so every subset's test gives the bits it gave when
/// each subset built its own products.
struct Subsets {
    /// `n x kz`: column `c` is row `zset[c]` of `G`.
    cols: DMatrix<f64>,
    gram: DMatrix<f64>,
    g_grad: DVector<f64>,
    grad: DVector<f64>,
    gnorm: f64,
}

impl Subsets {
    fn new(g: &DMatrix<f64>, zset: &[usize], grad: &DVector<f64>) -> Self {
        let cols = DMatrix::from_fn(g.ncols(), zset.len(), |r, c| g[(zset[c], r)]);
        let gram = cols.tr_mul(&cols);
        let g_grad = cols.tr_mul(grad);
        Subsets {
            cols,
            gram,
            g_grad,
            grad: grad.clone(),
            gnorm: 1.0 + grad.amax(),
        }
    }

    /// Whether `-grad = G_S' lambda` with `lambda >= 0` and independent
    /// rows `S` (the columns whose bits are set in `mask`).
    fn represents(&self, mask: u64) -> bool {
        let idx: Vec<usize> = (0..self.cols.ncols())
            .filter(|&b| mask >> b & 1 == 1)
            .collect();
        let k = idx.len();
        if k == 0 {
            return self.grad.amax() <= 1e-8 * self.gnorm;
        }
        let gtg = DMatrix::from_fn(k, k, |i, j| self.gram[(idx[i], idx[j])]);
        let Some(ch) = gtg.cholesky() else {
            return false;
        };
        let minp = (0..k)
            .map(|i| ch.l()[(i, i)].powi(2))
            .fold(f64::INFINITY, f64::min);
        if minp <= 1e-10 {
            return false;
        }
        let rhs = DVector::from_fn(k, |i, _| self.g_grad[idx[i]]);
        let lam = ch.solve(&(-rhs));
        let gs = self.cols.select_columns(&idx);
        let resid = &gs * &lam + &self.grad;
        resid.amax() <= 1e-7 * self.gnorm && lam.iter().all(|&l| l >= -1e-9 * self.gnorm)
    }
}
