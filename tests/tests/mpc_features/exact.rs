//! Solving the uncondensed reference exactly: clarabel at a tight
//! tolerance, then the equality-constrained KKT system of the active set
//! read off its solution solved by LU (with iterative refinement), checked
//! for primal feasibility and multiplier signs, and the set corrected and
//! solved again when a check fails.

use super::reference::{DenseQp, Family};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::{DMatrix, DVector};

/// Relative tolerance of the feasibility and sign checks of a KKT point.
const CHECK_TOL: f64 = 1e-10;

/// The exact optimum of a [`DenseQp`].
#[derive(Clone, Debug)]
pub struct Exact {
    /// The minimiser.
    pub v: DVector<f64>,
    /// `1/2 v'Pv + q'v + c0`.
    pub cost: f64,
    /// The rows in the final KKT system (active set).
    pub active: Vec<bool>,
    /// Active-set corrections after clarabel's guess.
    pub corrections: usize,
}

impl Exact {
    /// Whether some row of `family` is active with a positive multiplier
    /// or at its bound.
    pub fn family_active(&self, qp: &DenseQp, family: Family) -> bool {
        (0..qp.family.len()).any(|i| qp.family[i] == family && self.active[i])
    }
}

/// What the reference says at one parameter.
#[derive(Clone, Debug)]
pub enum Outcome {
    Optimal(Exact),
    Infeasible,
}

/// Dense matrix to clarabel's compressed columns (upper triangle when `upper`).
fn csc(m: &DMatrix<f64>, upper: bool) -> CscMatrix<f64> {
    let (rows, cols) = m.shape();
    let mut colptr = vec![0];
    let (mut rowval, mut nzval) = (Vec::new(), Vec::new());
    for j in 0..cols {
        let last = if upper { (j + 1).min(rows) } else { rows };
        for i in 0..last {
            if m[(i, j)] != 0.0 {
                rowval.push(i);
                nzval.push(m[(i, j)]);
            }
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(rows, cols, colptr, rowval, nzval)
}

/// Runs clarabel on `min 1/2 v'Pv + q'v` s.t. `A_eq v = b_eq`, `A_in v <= b_in`;
/// returns the status, `v` and the inequality multipliers.
pub fn clarabel_solve(
    p: &DMatrix<f64>,
    q: &DVector<f64>,
    a_eq: &DMatrix<f64>,
    b_eq: &DVector<f64>,
    a_in: &DMatrix<f64>,
    b_in: &DVector<f64>,
    tol: f64,
) -> (SolverStatus, DVector<f64>, DVector<f64>) {
    let n = p.nrows();
    let (me, mi) = (a_eq.nrows(), a_in.nrows());
    let mut a = DMatrix::zeros(me + mi, n);
    a.view_mut((0, 0), (me, n)).copy_from(a_eq);
    a.view_mut((me, 0), (mi, n)).copy_from(a_in);
    let mut b = DVector::zeros(me + mi);
    b.rows_mut(0, me).copy_from(b_eq);
    b.rows_mut(me, mi).copy_from(b_in);
    let settings = DefaultSettings {
        max_iter: 500,
        verbose: false,
        tol_gap_abs: tol,
        tol_gap_rel: tol,
        tol_feas: tol,
        tol_ktratio: 1e-8,
        ..DefaultSettings::default()
    };
    let cones = [
        SupportedConeT::ZeroConeT(me),
        SupportedConeT::NonnegativeConeT(mi),
    ];
    let mut s = DefaultSolver::new(
        &csc(p, true),
        q.as_slice(),
        &csc(&a, false),
        b.as_slice(),
        &cones,
        settings,
    )
    .expect("clarabel setup");
    s.solve();
    let x = DVector::from_column_slice(&s.solution.x);
    let z = DVector::from_column_slice(&s.solution.z[me..]);
    (s.solution.status, x, z)
}

/// The exact optimum of `qp`, or its infeasibility (clarabel's verdict).
/// Panics when no active set near clarabel's answer verifies.
pub fn solve_exact(qp: &DenseQp) -> Outcome {
    let (status, v, z) =
        clarabel_solve(&qp.p, &qp.q, &qp.a_eq, &qp.b_eq, &qp.a_in, &qp.b_in, 1e-11);
    match status {
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
            return Outcome::Infeasible;
        }
        SolverStatus::Solved
        | SolverStatus::AlmostSolved
        | SolverStatus::InsufficientProgress
        | SolverStatus::MaxIterations => {}
        other => panic!("clarabel on the uncondensed reference: {other:?}"),
    }
    match polish(qp, &v, &z) {
        Ok(e) => Outcome::Optimal(e),
        Err(why) => {
            panic!("uncondensed reference: no verified active set ({why}); clarabel {status:?}")
        }
    }
}

/// Orthonormal basis of the equality rows (Gram-Schmidt, twice).
fn add_to_basis(basis: &mut Vec<DVector<f64>>, row: DVector<f64>) -> bool {
    let norm = row.norm();
    if norm == 0.0 {
        return false;
    }
    let mut w = row / norm;
    for _ in 0..2 {
        for e in basis.iter() {
            let c = e.dot(&w);
            w.axpy(-c, e, 1.0);
        }
    }
    let r = w.norm();
    if r > 1e-9 {
        basis.push(w / r);
        true
    } else {
        false
    }
}

/// The active-set refinement of clarabel's pair `(v, z)`.
fn polish(qp: &DenseQp, v0: &DVector<f64>, z0: &DVector<f64>) -> Result<Exact, String> {
    let n = qp.p.nrows();
    let me = qp.a_eq.nrows();
    let mi = qp.a_in.nrows();
    let norms: Vec<f64> = (0..mi).map(|i| qp.a_in.row(i).norm()).collect();
    let mut eq_basis = Vec::new();
    for i in 0..me {
        assert!(
            add_to_basis(&mut eq_basis, qp.a_eq.row(i).transpose()),
            "dependent equality rows in the reference"
        );
    }
    let av = &qp.a_in * v0;
    let cs = 1.0 + av.amax().max(qp.b_in.amax());
    let gs = 1.0 + (&qp.p * v0).amax().max(qp.q.amax());
    let mut active: Vec<bool> = (0..mi)
        .map(|i| z0[i] * norms[i] / gs > (qp.b_in[i] - av[i]) / norms[i] / cs)
        .collect();
    for corrections in 0..40 {
        // Active rows in decreasing multiplier order, independent of the
        // equalities and of each other.
        let mut order: Vec<usize> = (0..mi).filter(|&i| active[i]).collect();
        order.sort_by(|&a, &b| (z0[b] * norms[b]).total_cmp(&(z0[a] * norms[a])));
        let mut basis = eq_basis.clone();
        let mut rows = Vec::new();
        for i in order {
            if basis.len() < n && add_to_basis(&mut basis, qp.a_in.row(i).transpose()) {
                rows.push(i);
            }
        }
        let k = rows.len();
        let dim = n + me + k;
        let mut kkt = DMatrix::zeros(dim, dim);
        let mut rhs = DVector::zeros(dim);
        kkt.view_mut((0, 0), (n, n)).copy_from(&qp.p);
        rhs.rows_mut(0, n).copy_from(&(-&qp.q));
        kkt.view_mut((n, 0), (me, n)).copy_from(&qp.a_eq);
        kkt.view_mut((0, n), (n, me))
            .copy_from(&qp.a_eq.transpose());
        rhs.rows_mut(n, me).copy_from(&qp.b_eq);
        for (r, &i) in rows.iter().enumerate() {
            for c in 0..n {
                kkt[(n + me + r, c)] = qp.a_in[(i, c)];
                kkt[(c, n + me + r)] = qp.a_in[(i, c)];
            }
            rhs[n + me + r] = qp.b_in[i];
        }
        let lu = kkt.clone().lu();
        let mut x = lu.solve(&rhs).ok_or("singular KKT system")?;
        for _ in 0..3 {
            let res = &rhs - &kkt * &x;
            x += lu.solve(&res).ok_or("singular KKT system")?;
        }
        let v = x.rows(0, n).into_owned();
        let mut lambda = DVector::zeros(mi);
        let mut in_system = vec![false; mi];
        for (r, &i) in rows.iter().enumerate() {
            lambda[i] = x[n + me + r];
            in_system[i] = true;
        }
        let av = &qp.a_in * &v;
        let cs = 1.0 + av.amax().max(qp.b_in.amax());
        let gs = 1.0
            + (&qp.p * &v)
                .amax()
                .max(qp.q.amax())
                .max(qp.a_in.tr_mul(&lambda).amax());
        let mut worst_p = (CHECK_TOL, None);
        let mut worst_d = (CHECK_TOL, None);
        for i in 0..mi {
            let viol = (av[i] - qp.b_in[i]) / norms[i] / cs;
            if !in_system[i] && viol > worst_p.0 {
                worst_p = (viol, Some(i));
            }
            let neg = -lambda[i] * norms[i] / gs;
            if in_system[i] && neg > worst_d.0 {
                worst_d = (neg, Some(i));
            }
        }
        match (worst_p, worst_d) {
            ((_, None), (_, None)) => {
                // Sanity: stationarity and equalities hold to rounding.
                let grad = &qp.p * &v
                    + &qp.q
                    + qp.a_in.tr_mul(&lambda)
                    + qp.a_eq.tr_mul(&x.rows(n, me).into_owned());
                assert!(grad.amax() <= 1e-9 * gs, "stationarity {}", grad.amax());
                let eq = (&qp.a_eq * &v - &qp.b_eq).amax();
                assert!(eq <= 1e-10 * (1.0 + qp.b_eq.amax()), "equalities {eq}");
                let cost = 0.5 * v.dot(&(&qp.p * &v)) + qp.q.dot(&v) + qp.c0;
                let active = (0..mi)
                    .map(|i| {
                        in_system[i]
                            && (lambda[i] * norms[i] > 1e-9 * gs
                                || (qp.b_in[i] - av[i]).abs() / norms[i] <= 1e-9 * cs)
                    })
                    .collect();
                return Ok(Exact {
                    v,
                    cost,
                    active,
                    corrections,
                });
            }
            ((p, Some(i)), (d, _)) if p >= d => {
                if active[i] {
                    return Err(format!("violated row {i} is dependent on the active set"));
                }
                active[i] = true;
            }
            (_, (_, Some(i))) => active[i] = false,
            _ => unreachable!(),
        }
    }
    Err("no verified active set in 40 corrections".into())
}

/// The least uniform violation `t*` of the constraints of `qp` (rows
/// normalised): `min t` s.t. the equalities and `a_i v - |a_i| t <= b_i`,
/// `t >= -1`. Negative: strictly feasible; positive: infeasible.
pub fn least_violation(qp: &DenseQp) -> f64 {
    let n = qp.p.nrows();
    let mi = qp.a_in.nrows();
    let mut a_in = DMatrix::zeros(mi + 1, n + 1);
    a_in.view_mut((0, 0), (mi, n)).copy_from(&qp.a_in);
    for i in 0..mi {
        a_in[(i, n)] = -qp.a_in.row(i).norm();
    }
    a_in[(mi, n)] = -1.0;
    let mut b_in = DVector::zeros(mi + 1);
    b_in.rows_mut(0, mi).copy_from(&qp.b_in);
    b_in[mi] = 1.0;
    let mut a_eq = DMatrix::zeros(qp.a_eq.nrows(), n + 1);
    a_eq.view_mut((0, 0), qp.a_eq.shape()).copy_from(&qp.a_eq);
    let mut c = DVector::zeros(n + 1);
    c[n] = 1.0;
    let (status, x, _) = clarabel_solve(
        &DMatrix::zeros(n + 1, n + 1),
        &c,
        &a_eq,
        &qp.b_eq,
        &a_in,
        &b_in,
        1e-11,
    );
    assert!(
        matches!(status, SolverStatus::Solved | SolverStatus::AlmostSolved),
        "least-violation LP: {status:?}"
    );
    x[n]
}

/// `min c'v` over the constraints of `qp` (an LP by clarabel); returns the
/// optimal value.
pub fn lp_min(qp: &DenseQp, c: &DVector<f64>) -> f64 {
    let n = qp.p.nrows();
    let (status, x, _) = clarabel_solve(
        &DMatrix::zeros(n, n),
        c,
        &qp.a_eq,
        &qp.b_eq,
        &qp.a_in,
        &qp.b_in,
        1e-12,
    );
    assert!(matches!(status, SolverStatus::Solved), "LP: {status:?}");
    c.dot(&x)
}
