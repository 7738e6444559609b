//! Helpers shared by the integration tests.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus,
};
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::mpqp::Rng;
use nalgebra::{DMatrix, DVector};

/// clarabel's solution of the QP at `theta` (tight tolerances), `None` if
/// infeasible; panics on any other non-solved status.
#[allow(dead_code)] // not every test binary uses both
pub fn clarabel_qp(prob: &MpqpProblem, theta: &[f64]) -> Option<Vec<f64>> {
    clarabel_qp_checked(prob, theta).unwrap_or_else(|e| panic!("clarabel: {e}"))
}

/// [`clarabel_qp`] with any other status (e.g. `InsufficientProgress` at
/// these tight tolerances) as an error, for long sweeps that count them.
#[allow(dead_code)] // not every binary uses it (the examples include this file)
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

/// kestrel-qp's dual active-set solution of the QP at `theta` (a second
/// algorithm, exact at its optimum), `None` if infeasible; panics on any
/// other failure.
#[allow(dead_code)] // not every test binary uses it
pub fn active_set_qp(prob: &MpqpProblem, theta: &[f64]) -> Option<Vec<f64>> {
    use kestrel_qp::parametric::ParametricQp;
    use kestrel_qp::{QpError, QpSettings, Start};
    let par = ParametricQp::from_mpqp(prob).unwrap();
    let (ns, ni) = par.workspace_len();
    let (mut scalars, mut indices) = (vec![0.0; ns], vec![0; ni]);
    let mut qp = par
        .solver::<f64>(QpSettings::default(), &mut scalars, &mut indices)
        .unwrap();
    let mut buf = par.buffers::<f64>();
    par.fill(theta, &mut buf).unwrap();
    match qp.solve(&buf.data(), Start::Cold) {
        Ok(_) => {}
        Err(QpError::Infeasible) => return None,
        Err(e) => panic!("kestrel-qp at {theta:?}: {e:?}"),
    }
    let mut z = vec![0.0; par.n()];
    qp.solution(&mut z).unwrap();
    Some(z)
}

/// The QP's objective `1/2 z'Hz + (F'theta + f)'z` at `z` and the largest
/// violation of `G z <= W + E theta` (0 when feasible).
#[allow(dead_code)] // not every test binary uses it
pub fn objective_and_violation(prob: &MpqpProblem, theta: &[f64], z: &[f64]) -> (f64, f64) {
    let th = DVector::from_column_slice(theta);
    let z = DVector::from_column_slice(z);
    let j = 0.5 * z.dot(&(&prob.h * &z)) + prob.linear_term(&th).dot(&z);
    let v = (&prob.g * &z - prob.rhs(&th)).max().max(0.0);
    (j, v)
}

/// Whether the full `z` of the explicit law is at least as good as
/// clarabel's `x` at `theta`: feasible (to 1e-9 of the right-hand side's
/// size) with an objective not above clarabel's (to 1e-12 relative). The
/// QP is strictly convex, so this makes `z` the closer to the optimum
/// where the two differ (clarabel stopping short of its tolerances).
#[allow(dead_code)] // not every test binary uses it
pub fn law_at_least_as_good(prob: &MpqpProblem, theta: &[f64], z: &[f64], x: &[f64]) -> bool {
    let (jz, vz) = objective_and_violation(prob, theta, z);
    let (jx, _) = objective_and_violation(prob, theta, x);
    let rhs = prob.rhs(&DVector::from_column_slice(theta)).amax();
    vz <= 1e-9 * (1.0 + rhs) && (jz - jx) / (1.0 + jx.abs()) <= 1e-12
}

/// A point of the box `[lb, ub]`: `lb + (ub - lb) * unit()` per entry,
/// `unit` uniform in `[0, 1)`.
#[allow(dead_code)] // not every test binary uses it
pub fn box_point_with(lb: &[f64], ub: &[f64], mut unit: impl FnMut() -> f64) -> Vec<f64> {
    lb.iter()
        .zip(ub)
        .map(|(lo, hi)| lo + (hi - lo) * unit())
        .collect()
}

/// [`box_point_with`] from `rng` (the sequence the tests and the examples
/// sample with).
#[allow(dead_code)] // not every test binary uses it
pub fn box_point(lb: &[f64], ub: &[f64], rng: &mut Rng) -> Vec<f64> {
    box_point_with(lb, ub, || 0.5 * (rng.sym() + 1.0))
}

/// `n` points of the box `[lb, ub]` ([`box_point_with`]).
#[allow(dead_code)] // not every test binary uses it
pub fn box_samples_with(
    lb: &[f64],
    ub: &[f64],
    n: usize,
    mut unit: impl FnMut() -> f64,
) -> Vec<Vec<f64>> {
    (0..n).map(|_| box_point_with(lb, ub, &mut unit)).collect()
}

/// `n` points of the box `[lb, ub]` ([`box_point`]) from `Rng::new(seed)`.
#[allow(dead_code)] // not every test binary uses it
pub fn box_samples(lb: &[f64], ub: &[f64], n: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = Rng::new(seed);
    (0..n).map(|_| box_point(lb, ub, &mut rng)).collect()
}

/// The largest relative difference `|a - b| / (1 + |a|)`.
#[allow(dead_code)] // not every test binary uses it
pub fn rel(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / (1.0 + x.abs()))
        .fold(0.0, f64::max)
}

/// Every case `(pointer, value, message)`: the solution file `good` with
/// the entry at the JSON `pointer` inside `good[key]` set to `value` is
/// rejected by `read` with an error that contains `message`.
#[allow(dead_code)] // not every test binary uses it
pub fn assert_corruptions_rejected<T, E: std::fmt::Display>(
    good: &serde_json::Value,
    key: &str,
    cases: Vec<(&str, serde_json::Value, &str)>,
    read: impl Fn(&str) -> Result<T, E>,
) {
    for (ptr, value, msg) in cases {
        let mut v = good.clone();
        *v[key].pointer_mut(&format!("/{ptr}")).unwrap() = value;
        match read(&v.to_string()) {
            Ok(_) => panic!("{ptr}: accepted"),
            Err(e) => {
                let err = e.to_string();
                assert!(err.contains(msg), "{ptr}: {err}");
            }
        }
    }
}
