//! Helpers shared by the integration tests.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus,
};
use kestrel_core::formats::MpqpProblem;
use nalgebra::{DMatrix, DVector};

/// clarabel's solution of the QP at `theta` (tight tolerances), `None` if
/// infeasible; panics on any other non-solved status.
#[allow(dead_code)] // not every test binary uses both
pub fn clarabel_qp(prob: &MpqpProblem, theta: &[f64]) -> Option<Vec<f64>> {
    clarabel_qp_checked(prob, theta).unwrap_or_else(|e| panic!("clarabel: {e}"))
}

/// [`clarabel_qp`] with any other status (e.g. `InsufficientProgress` at
/// these tight tolerances) as an error, for long sweeps that count them.
pub fn clarabel_qp_checked(prob: &MpqpProblem, theta: &[f64]) -> Result<Option<Vec<f64>>, String> {
    let n = prob.n();
    let th = DVector::from_column_slice(theta);
    let q = prob.linear_term(&th);
    let rhs = prob.rhs(&th);
    let rows = |m: &DMatrix<f64>| -> Vec<Vec<f64>> {
        (0..m.nrows())
            .map(|i| m.row(i).iter().copied().collect())
            .collect()
    };
    let (hr, gr) = (rows(&prob.h), rows(&prob.g));
    let pm = CscMatrix::from(&hr).to_triu();
    let am = CscMatrix::from(&gr);
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-13)
        .tol_gap_rel(1e-13)
        .tol_feas(1e-13)
        .tol_ktratio(1e-10)
        .max_iter(400)
        .build()
        .unwrap();
    let cones = [NonnegativeConeT(prob.m())];
    let qv: Vec<f64> = q.iter().copied().collect();
    let bv: Vec<f64> = rhs.iter().copied().collect();
    let mut s = DefaultSolver::new(&pm, &qv, &am, &bv, &cones, settings).unwrap();
    s.solve();
    match s.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => Ok(Some(s.solution.x[..n].to_vec())),
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => Ok(None),
        other => Err(format!("{other:?}")),
    }
}
