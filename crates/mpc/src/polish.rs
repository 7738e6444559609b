//! Active-set polish of an interior-point solution.
//!
//! An interior-point method stops at a point that is optimal to its
//! tolerance (about `1e-9` relative in the duality gap, which can be far
//! coarser in `z` and in the cost of an ill-conditioned QP). The polish
//! guesses the active constraints from the interior-point pair `(z,
//! lambda)`, solves the equality-constrained KKT system of that active set
//! exactly (LU with iterative refinement), and accepts the result only if
//! it is primal feasible and its multipliers are non-negative, i.e. if it
//! satisfies the KKT conditions of the inequality-constrained QP to
//! rounding. Otherwise the violated constraint with the largest violation
//! is added, or the active constraint with the most negative multiplier
//! removed, and the system solved again, a bounded number of times.

use nalgebra::{DMatrix, DVector};

/// Relative tolerance of the feasibility and dual-sign checks.
const CHECK_TOL: f64 = 1e-10;
/// A constraint row whose component orthogonal to the rows already taken
/// is below this (relative) is linearly dependent on them and left out of
/// the KKT system.
const DEPENDENT_TOL: f64 = 1e-9;

/// A KKT point of `min 1/2 z'Hz + q'z s.t. G z <= b` found by the polish.
#[derive(Clone, Debug)]
pub(crate) struct Polished {
    /// The minimiser.
    pub z: DVector<f64>,
    /// The multipliers (`m`, zero off the active set).
    pub lambda: DVector<f64>,
}

/// The QP data of one solve: `min 1/2 z'Hz + q'z s.t. G z <= b`.
pub(crate) struct Qp<'a> {
    pub h: &'a DMatrix<f64>,
    pub q: &'a DVector<f64>,
    pub g: &'a DMatrix<f64>,
    pub b: &'a DVector<f64>,
}

impl Qp<'_> {
    /// Polishes the interior-point pair `(z, lambda)`; `None` when no
    /// active set within `max_steps` changes gives a verified KKT point.
    pub(crate) fn polish(
        &self,
        z: &DVector<f64>,
        lambda: &DVector<f64>,
        max_steps: usize,
    ) -> Option<Polished> {
        let m = self.g.nrows();
        let norms: Vec<f64> = (0..m).map(|i| self.g.row(i).norm()).collect();
        let hz = self.h * z;
        let gz = self.g * z;
        let grad_scale = 1.0 + hz.amax().max(self.q.amax());
        let cons_scale = 1.0 + gz.amax().max(self.b.amax());
        // Active: the (normalised) multiplier outweighs the (normalised)
        // slack; at an interior-point optimum one of the two is tiny.
        let mut active: Vec<bool> = (0..m)
            .map(|i| {
                if norms[i] == 0.0 {
                    return false;
                }
                let slack = (self.b[i] - gz[i]) / norms[i] / cons_scale;
                let mult = lambda[i] * norms[i] / grad_scale;
                mult > slack
            })
            .collect();
        for _ in 0..max_steps {
            let (zp, lam, used) = self.solve_kkt(&active, &norms, lambda)?;
            let gz = self.g * &zp;
            let cons_scale = 1.0 + gz.amax().max(self.b.amax());
            let grad_scale = 1.0
                + (self.h * &zp)
                    .amax()
                    .max(self.q.amax())
                    .max(self.g.tr_mul(&lam).amax());
            // Worst primal violation among the rows outside the KKT system
            // and worst multiplier sign violation among those in it,
            // normalised.
            let mut worst_primal = (0.0, None);
            let mut worst_dual = (0.0, None);
            for i in 0..m {
                if norms[i] == 0.0 {
                    continue;
                }
                let viol = (gz[i] - self.b[i]) / norms[i] / cons_scale;
                if !used[i] && viol > worst_primal.0 {
                    worst_primal = (viol, Some(i));
                }
                let neg = -lam[i] * norms[i] / grad_scale;
                if used[i] && neg > worst_dual.0 {
                    worst_dual = (neg, Some(i));
                }
            }
            match (worst_primal, worst_dual) {
                ((p, _), (d, _)) if p <= CHECK_TOL && d <= CHECK_TOL => {
                    // Feasible and dual feasible: a KKT point of the convex
                    // QP, hence its minimiser. Multipliers within the
                    // tolerance of zero are zero.
                    let lambda = lam.map(|l| l.max(0.0));
                    return Some(Polished { z: zp, lambda });
                }
                // A violated row already marked active was left out as
                // linearly dependent: this active set cannot be repaired.
                ((p, Some(i)), (d, _)) if p >= d && active[i] => return None,
                ((p, Some(i)), (d, _)) if p >= d => active[i] = true,
                (_, (_, Some(i))) => active[i] = false,
                _ => return None,
            }
        }
        None
    }

    /// Solves the KKT system of the rows marked active (leaving out rows
    /// linearly dependent on the ones taken, in order of decreasing
    /// interior-point multiplier); returns `z`, the full multiplier vector
    /// and which rows are in the system, or `None` when the system is
    /// singular or not finite.
    fn solve_kkt(
        &self,
        active: &[bool],
        norms: &[f64],
        lambda_ip: &DVector<f64>,
    ) -> Option<(DVector<f64>, DVector<f64>, Vec<bool>)> {
        let n = self.h.nrows();
        let mut order: Vec<usize> = (0..active.len()).filter(|&i| active[i]).collect();
        order.sort_by(|&a, &b| (lambda_ip[b] * norms[b]).total_cmp(&(lambda_ip[a] * norms[a])));
        // Greedy independent subset by Gram-Schmidt on the normalised rows.
        let mut basis: Vec<DVector<f64>> = Vec::new();
        let mut rows = Vec::new();
        for i in order {
            let mut v = self.g.row(i).transpose() / norms[i];
            for _ in 0..2 {
                for e in &basis {
                    let c = e.dot(&v);
                    v.axpy(-c, e, 1.0);
                }
            }
            let r = v.norm();
            if r > DEPENDENT_TOL && basis.len() < n {
                basis.push(v / r);
                rows.push(i);
            }
        }
        let k = rows.len();
        let mut kkt = DMatrix::zeros(n + k, n + k);
        kkt.view_mut((0, 0), (n, n)).copy_from(self.h);
        let mut rhs = DVector::zeros(n + k);
        rhs.rows_mut(0, n).copy_from(&(-self.q));
        for (j, &i) in rows.iter().enumerate() {
            for c in 0..n {
                kkt[(n + j, c)] = self.g[(i, c)];
                kkt[(c, n + j)] = self.g[(i, c)];
            }
            rhs[n + j] = self.b[i];
        }
        let lu = kkt.clone().lu();
        let mut x = lu.solve(&rhs)?;
        // Iterative refinement against the rounding of the factorisation.
        for _ in 0..2 {
            let r = &rhs - &kkt * &x;
            x += lu.solve(&r)?;
        }
        if x.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let z = x.rows(0, n).into_owned();
        let mut lambda = DVector::zeros(active.len());
        let mut used = vec![false; active.len()];
        for (j, &i) in rows.iter().enumerate() {
            lambda[i] = x[n + j];
            used[i] = true;
        }
        Some((z, lambda, used))
    }
}
