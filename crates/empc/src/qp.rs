//! A small dense primal active-set QP solver (design time).
//!
//! `minimise 1/2 z'Hz + q'z subject to G z <= w` with `H` positive definite.
//! A feasible start comes from an LP (the most interior point); then the
//! classical primal active-set iteration: the working set only ever gains a
//! constraint that blocks a step inside the null space of the working rows,
//! so it stays linearly independent even when many constraints are active
//! at once (LICQ fails) — exactly the basis the mpQP exploration needs.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::lp::{LpStatus, LpWorkspace, slack_start};
use nalgebra::{DMatrix, DVector};

/// The optimum of a QP.
#[derive(Clone, Debug)]
pub(crate) struct QpOptimum {
    /// The minimiser.
    pub z: DVector<f64>,
    /// The final (linearly independent) working set.
    pub working: Vec<usize>,
}

/// Why a QP solve failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum QpFailure {
    Infeasible,
    NotConverged,
}

/// Solves the QP; `g` has unit-norm rows.
pub(crate) fn solve(
    h: &DMatrix<f64>,
    hinv: &DMatrix<f64>,
    q: &DVector<f64>,
    g: &DMatrix<f64>,
    w: &DVector<f64>,
    lp: &mut LpWorkspace,
) -> Result<QpOptimum, QpFailure> {
    let n = h.nrows();
    let m = g.nrows();
    let wscale = 1.0 + w.amax();
    let feas_tol = 1e-10 * wscale;
    // Feasible start: maximise the smallest slack r (capped at wscale).
    let d = n + 1;
    let mut a = vec![0.0; (m + 1) * d];
    let mut b = vec![0.0; m + 1];
    for i in 0..m {
        for j in 0..n {
            a[i * d + j] = g[(i, j)];
        }
        a[i * d + n] = 1.0;
        b[i] = w[i];
    }
    a[m * d + n] = 1.0;
    b[m] = wscale;
    let mut c = vec![0.0; d];
    c[n] = 1.0;
    let mut x0 = vec![0.0; d];
    slack_start(&a, &b, &mut x0, n);
    let (st, r) = lp.maximize_from(&c, &a, &b, &x0);
    if st != LpStatus::Optimal {
        return Err(QpFailure::NotConverged);
    }
    if r < -feas_tol {
        return Err(QpFailure::Infeasible);
    }
    let mut z = DVector::from_column_slice(&lp.x[..n]);
    // Initial working set: active constraints, kept linearly independent.
    let mut working: Vec<usize> = Vec::new();
    for i in 0..m {
        let slack = w[i] - g.row(i).dot(&z.transpose());
        if slack <= feas_tol && independent(g, &working, i) {
            working.push(i);
        }
    }
    let max_iter = 20 * (n + m) + 50;
    // After a full step (no constraint blocked it) `z` minimises on the
    // working set, and so it does with `n` working rows (a vertex): the
    // multipliers decide. Recomputing the step there gives a residual of
    // the working rows' conditioning (1e-11 at near-dependent slack rows),
    // and stepping by it again and again never converges.
    let mut stationary = false;
    let mut passed: Vec<usize> = Vec::new();
    for _ in 0..max_iter {
        let grad = h * &z + q;
        let (p, lambda) = eqp_step(hinv, g, &working, &grad).ok_or(QpFailure::NotConverged)?;
        let pnorm = p.amax();
        if stationary || working.len() >= n || pnorm <= 1e-12 * (1.0 + z.amax()) {
            stationary = false;
            // Stationary on the working set: check the multipliers.
            let mut worst = None;
            let mut wv = -1e-12 * (1.0 + grad.amax());
            for (k, &l) in lambda.iter().enumerate() {
                if l < wv {
                    wv = l;
                    worst = Some(k);
                }
            }
            match worst {
                None => return Ok(QpOptimum { z, working }),
                Some(k) => {
                    working.remove(k);
                    continue;
                }
            }
        }
        // Step with the ratio test. A row that depends on the working
        // rows cannot block a step in their null space (`g_i p` is then
        // rounding); at a degenerate vertex, where it is active too, its
        // rounding would win the test and make the working rows singular:
        // such a row is passed over and the test repeated.
        let (alpha, block) = loop {
            let mut alpha = 1.0;
            let mut block = None;
            for i in 0..m {
                if working.contains(&i) || passed.contains(&i) {
                    continue;
                }
                let gp = g.row(i).dot(&p.transpose());
                if gp > 1e-14 * (1.0 + pnorm) {
                    let slack = (w[i] - g.row(i).dot(&z.transpose())).max(0.0);
                    let t = slack / gp;
                    if t < alpha {
                        alpha = t;
                        block = Some(i);
                    }
                }
            }
            match block {
                Some(i) if !independent(g, &working, i) => passed.push(i),
                _ => break (alpha, block),
            }
        };
        passed.clear();
        z += alpha * &p;
        match block {
            Some(i) => working.push(i),
            None => stationary = true,
        }
    }
    Err(QpFailure::NotConverged)
}

/// Whether row `i` of `g` is linearly independent of the rows in `set`.
pub(crate) fn independent(g: &DMatrix<f64>, set: &[usize], i: usize) -> bool {
    let n = g.ncols();
    let mut v: DVector<f64> = g.row(i).transpose();
    // Gram-Schmidt against an orthonormal basis of the set's rows.
    let mut basis: Vec<DVector<f64>> = Vec::new();
    for &j in set {
        let mut u: DVector<f64> = g.row(j).transpose();
        for e in &basis {
            let c = e.dot(&u);
            u.axpy(-c, e, 1.0);
        }
        let nu = u.norm();
        if nu > 1e-9 {
            basis.push(u / nu);
        }
    }
    for e in &basis {
        let c = e.dot(&v);
        v.axpy(-c, e, 1.0);
    }
    let _ = n;
    v.norm() > 1e-8 * g.row(i).norm().max(1e-300)
}

/// The equality-constrained step: `p = -H^-1 (grad + G_W' lambda)` with `G_W p = 0`.
fn eqp_step(
    hinv: &DMatrix<f64>,
    g: &DMatrix<f64>,
    working: &[usize],
    grad: &DVector<f64>,
) -> Option<(DVector<f64>, Vec<f64>)> {
    let n = hinv.nrows();
    let k = working.len();
    if k == 0 {
        return Some((-(hinv * grad), Vec::new()));
    }
    let mut gw = DMatrix::zeros(k, n);
    for (r, &i) in working.iter().enumerate() {
        gw.row_mut(r).copy_from(&g.row(i));
    }
    let hg = hinv * gw.transpose(); // n x k
    let s = &gw * &hg; // k x k
    let rhs = -(&gw * (hinv * grad));
    let lambda = s.cholesky()?.solve(&rhs);
    let p = -(hinv * grad) - &hg * &lambda;
    Some((p, lambda.iter().copied().collect()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_qp_matches_projection() {
        // min 1/2|z|^2 - c'z on the unit box: z = clamp(c).
        let h = DMatrix::identity(3, 3);
        let hinv = h.clone();
        let c = DVector::from_vec(vec![2.0, -0.5, -3.0]);
        let mut g = DMatrix::zeros(6, 3);
        for j in 0..3 {
            g[(j, j)] = 1.0;
            g[(3 + j, j)] = -1.0;
        }
        let w = DVector::from_element(6, 1.0);
        let mut lp = LpWorkspace::default();
        let sol = solve(&h, &hinv, &(-&c), &g, &w, &mut lp).unwrap();
        let want = [1.0, -0.5, -1.0];
        for j in 0..3 {
            assert!((sol.z[j] - want[j]).abs() < 1e-10);
        }
        let mut ws = sol.working.clone();
        ws.sort();
        assert_eq!(ws, vec![0, 5]);
    }

    #[test]
    fn infeasible() {
        let h = DMatrix::identity(1, 1);
        let g = DMatrix::from_row_slice(2, 1, &[1.0, -1.0]);
        let w = DVector::from_vec(vec![-1.0, -1.0]);
        let mut lp = LpWorkspace::default();
        let r = solve(&h, &h, &DVector::zeros(1), &g, &w, &mut lp);
        assert_eq!(r.unwrap_err(), QpFailure::Infeasible);
    }
}
