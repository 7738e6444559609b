//! The reference solution of the parametric QP with clarabel, and the KKT
//! residuals that certify a solution.

use crate::error::MpcError;
use crate::polish::Qp;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use kestrel_core::formats::MpqpProblem;
use nalgebra::{DMatrix, DVector};

/// Settings of the clarabel reference solve.
#[derive(Clone, Debug, PartialEq)]
pub struct QpSettings {
    /// Iteration limit of the interior-point method.
    pub max_iter: u32,
    /// Absolute and relative duality-gap and feasibility tolerance.
    pub tolerance: f64,
    /// Accept clarabel's reduced-accuracy `AlmostSolved` even when the
    /// polish does not verify it (a verified polish is always accepted).
    pub accept_almost_solved: bool,
    /// Print clarabel's iteration log.
    pub verbose: bool,
    /// When set, every solution's KKT residuals are checked
    /// ([`KktResiduals::relative`]) and a solution above this relative
    /// tolerance is refused with [`MpcError::Solver`].
    pub kkt_tolerance: Option<f64>,
    /// Refine clarabel's solution by an active-set polish: the active
    /// constraints read off clarabel's solution, the KKT system of that
    /// set solved exactly and checked for primal feasibility and
    /// non-negative multipliers (the set corrected and the system solved
    /// again a bounded number of times). A verified polish is the optimum
    /// to rounding (about `1e-12` relative on well-conditioned problems);
    /// [`QpSolution::polished`] says whether it succeeded, and if not the
    /// solution is clarabel's.
    pub polish: bool,
}

impl Default for QpSettings {
    /// 200 iterations, tolerance `1e-9`, no reduced accuracy, quiet,
    /// polished.
    fn default() -> Self {
        QpSettings {
            max_iter: 200,
            tolerance: 1e-9,
            accept_almost_solved: false,
            verbose: false,
            kkt_tolerance: None,
            polish: true,
        }
    }
}

impl QpSettings {
    fn clarabel(&self) -> DefaultSettings<f64> {
        DefaultSettings {
            max_iter: self.max_iter,
            verbose: self.verbose,
            tol_gap_abs: self.tolerance,
            tol_gap_rel: self.tolerance,
            tol_feas: self.tolerance,
            presolve_enable: false,
            ..DefaultSettings::default()
        }
    }
}

/// A solution of the QP at one parameter value.
#[derive(Clone, Debug, PartialEq)]
pub struct QpSolution {
    /// The minimiser `z*` (`n`).
    pub z: DVector<f64>,
    /// Multipliers of `G z <= W + E theta` (`m`, non-negative).
    pub lambda: DVector<f64>,
    /// `1/2 z'Hz + (F'theta + f)'z` at `z*`.
    pub objective: f64,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Whether clarabel stopped short of its tolerance (`AlmostSolved`, or
    /// out of progress, iterations or time; the solution is exact anyway
    /// when [`QpSolution::polished`]).
    pub reduced_accuracy: bool,
    /// Whether the active-set polish ([`QpSettings::polish`]) verified
    /// this solution as the exact optimum of its active set; `false` when
    /// the polish was off or failed (the solution is then clarabel's, to
    /// its tolerance).
    pub polished: bool,
}

/// The KKT residuals of a primal-dual pair, all in the infinity norm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KktResiduals {
    /// `|H z + F'theta + f + G'lambda|`.
    pub stationarity: f64,
    /// `max(0, G z - W - E theta)`.
    pub primal: f64,
    /// `max(0, -lambda)`.
    pub dual: f64,
    /// `max |lambda_i (G z - W - E theta)_i|`.
    pub complementarity: f64,
    /// Scale of the gradient terms, `1 + max(|Hz|, |F'theta + f|, |G'lambda|)`.
    pub gradient_scale: f64,
    /// Scale of the constraint terms, `1 + max(|Gz|, |W + E theta|)`.
    pub constraint_scale: f64,
}

impl KktResiduals {
    /// The largest of the four residuals.
    pub fn max(&self) -> f64 {
        self.stationarity
            .max(self.primal)
            .max(self.dual)
            .max(self.complementarity)
    }
    /// The largest residual relative to the problem's scale: stationarity
    /// over the gradient scale, primal infeasibility over the constraint
    /// scale, complementarity over the constraint scale times the
    /// gradient scale (a multiplier is a gradient per constraint unit).
    pub fn relative(&self) -> f64 {
        (self.stationarity / self.gradient_scale)
            .max(self.primal / self.constraint_scale)
            .max(self.dual / self.gradient_scale)
            .max(self.complementarity / (self.constraint_scale * self.gradient_scale))
    }
}

/// The KKT residuals of `(z, lambda)` for `problem` at `theta`.
///
/// The optimality conditions (6.27) with the errata: `Hz + F'theta + f +
/// G'lambda = 0`, `Gz <= W + E theta`, `lambda >= 0`, complementarity.
pub fn kkt_residuals(
    problem: &MpqpProblem,
    theta: &DVector<f64>,
    z: &DVector<f64>,
    lambda: &DVector<f64>,
) -> KktResiduals {
    let hz = &problem.h * z;
    let q = problem.linear_term(theta);
    let gl = problem.g.tr_mul(lambda);
    let gz = &problem.g * z;
    let rhs = problem.rhs(theta);
    let grad = &hz + &q + &gl;
    let slack = &gz - &rhs;
    KktResiduals {
        gradient_scale: 1.0 + hz.amax().max(q.amax()).max(gl.amax()),
        constraint_scale: 1.0 + gz.amax().max(rhs.amax()),
        stationarity: grad.amax(),
        primal: slack.iter().fold(0.0, |a: f64, &s| a.max(s)),
        dual: lambda.iter().fold(0.0, |a: f64, &l| a.max(-l)),
        complementarity: slack
            .iter()
            .zip(lambda.iter())
            .fold(0.0, |a: f64, (s, l)| a.max((s * l).abs())),
    }
}

/// Dense matrix to clarabel's compressed-column form (upper triangle only
/// when `upper` is set, as clarabel wants for `P`).
pub(crate) fn to_csc(m: &DMatrix<f64>, upper: bool) -> CscMatrix<f64> {
    let (rows, cols) = m.shape();
    let mut colptr = Vec::with_capacity(cols + 1);
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    colptr.push(0);
    for j in 0..cols {
        let last = if upper { (j + 1).min(rows) } else { rows };
        for i in 0..last {
            let v = m[(i, j)];
            if v != 0.0 {
                rowval.push(i);
                nzval.push(v);
            }
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(rows, cols, colptr, rowval, nzval)
}

fn status_error(status: SolverStatus) -> MpcError {
    match status {
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
            MpcError::Infeasible
        }
        other => MpcError::Solver(format!("{other:?}")),
    }
}

/// The clarabel reference solver of a parametric QP, set up once and then
/// solved at any parameter (only `q` and `b` change between solves), its
/// solution refined by an active-set polish ([`QpSettings::polish`]) to
/// the exact optimum.
///
/// This is the reference other solvers are checked against (kestrel-fgm's
/// certificates, kestrel-empc's explicit laws); a box-constrained QP is
/// the special case `G = [I; -I]`.
///
/// ```
/// use kestrel_core::formats::MpqpProblem;
/// use kestrel_mpc::{QpSettings, ReferenceSolver};
/// use nalgebra::dvector;
/// // min 1/2 z^2 + theta z  s.t.  z <= 1, -z <= 1
/// let p = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
///   "H": [[1]], "F": [[1]], "G": [[1], [-1]], "W": [1, 1], "E": [[0], [0]],
///   "theta_lb": [-5], "theta_ub": [5]}"#).unwrap();
/// let mut s = ReferenceSolver::new(&p, QpSettings::default()).unwrap();
/// let free = s.solve(&dvector![0.5]).unwrap();
/// assert!(free.polished && (free.z[0] + 0.5).abs() < 1e-12);
/// let bound = s.solve(&dvector![-3.0]).unwrap(); // z <= 1 active
/// assert!(bound.polished && (bound.z[0] - 1.0).abs() < 1e-12);
/// assert!((bound.lambda[0] - 2.0).abs() < 1e-12 && bound.lambda[1] == 0.0);
/// ```
pub struct ReferenceSolver {
    problem: MpqpProblem,
    settings: QpSettings,
    solver: DefaultSolver<f64>,
}

impl std::fmt::Debug for ReferenceSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReferenceSolver")
            .field("n", &self.problem.n())
            .field("m", &self.problem.m())
            .field("p", &self.problem.p())
            .field("settings", &self.settings)
            .finish()
    }
}

impl ReferenceSolver {
    /// Sets up the solver; checks the problem's shapes and that `H` is
    /// positive definite.
    pub fn new(problem: &MpqpProblem, settings: QpSettings) -> Result<Self, MpcError> {
        problem.validate()?;
        crate::design::check_hessian(&problem.h)?;
        let theta = (&problem.theta_lb + &problem.theta_ub) * 0.5;
        let solver = Self::make(problem, &settings, &theta)?;
        Ok(ReferenceSolver {
            problem: problem.clone(),
            settings,
            solver,
        })
    }

    fn make(
        problem: &MpqpProblem,
        settings: &QpSettings,
        theta: &DVector<f64>,
    ) -> Result<DefaultSolver<f64>, MpcError> {
        let p = to_csc(&problem.h, true);
        let a = to_csc(&problem.g, false);
        let q = problem.linear_term(theta);
        let b = problem.rhs(theta);
        let cones = [SupportedConeT::NonnegativeConeT(problem.m())];
        DefaultSolver::new(
            &p,
            q.as_slice(),
            &a,
            b.as_slice(),
            &cones,
            settings.clarabel(),
        )
        .map_err(|e| MpcError::Solver(format!("setup failed: {e}")))
    }

    /// The problem being solved.
    pub fn problem(&self) -> &MpqpProblem {
        &self.problem
    }

    /// Solves the QP at `theta` (`p` entries, finite).
    pub fn solve(&mut self, theta: &DVector<f64>) -> Result<QpSolution, MpcError> {
        if theta.len() != self.problem.p() {
            return Err(MpcError::dim(
                "theta",
                format!("{} entries", self.problem.p()),
                format!("{}", theta.len()),
            ));
        }
        if theta.iter().any(|v| !v.is_finite()) {
            return Err(MpcError::NonFinite("theta".into()));
        }
        let q = self.problem.linear_term(theta);
        let b = self.problem.rhs(theta);
        let updated = self.solver.update_q(&q.as_slice().to_vec()).is_ok()
            && self.solver.update_b(&b.as_slice().to_vec()).is_ok();
        if !updated {
            self.solver = Self::make(&self.problem, &self.settings, theta)?;
        }
        self.solver.solve();
        let sol = &self.solver.solution;
        // Stopped short of the tolerance: the iterate may still polish to
        // a verified optimum.
        let reduced = match sol.status {
            SolverStatus::Solved => false,
            SolverStatus::AlmostSolved
            | SolverStatus::InsufficientProgress
            | SolverStatus::MaxIterations
            | SolverStatus::MaxTime => true,
            other => return Err(status_error(other)),
        };
        let status = sol.status;
        let mut z = DVector::from_column_slice(&sol.x);
        let mut lambda = DVector::from_column_slice(&sol.z);
        let iterations = sol.iterations;
        let mut polished = false;
        if self.settings.polish {
            let qp = Qp {
                h: &self.problem.h,
                q: &q,
                g: &self.problem.g,
                b: &b,
            };
            let steps = self.problem.m() + self.problem.n() + 10;
            if let Some(p) = qp.polish(&z, &lambda, steps) {
                z = p.z;
                lambda = p.lambda;
                polished = true;
            }
        }
        // A reduced-accuracy solution is refused unless the polish
        // verified it or the settings accept an `AlmostSolved`.
        let accepted = status == SolverStatus::AlmostSolved && self.settings.accept_almost_solved;
        if reduced && !polished && !accepted {
            return Err(status_error(status));
        }
        if let Some(tol) = self.settings.kkt_tolerance {
            let kkt = kkt_residuals(&self.problem, theta, &z, &lambda);
            if kkt.relative().is_nan() || kkt.relative() > tol {
                return Err(MpcError::Solver(format!(
                    "KKT check failed: relative residual {:e} above {tol:e} ({kkt:?})",
                    kkt.relative()
                )));
            }
        }
        let objective = 0.5 * z.dot(&(&self.problem.h * &z)) + q.dot(&z);
        Ok(QpSolution {
            lambda,
            z,
            objective,
            iterations,
            reduced_accuracy: reduced,
            polished,
        })
    }
}

/// A dense QP with equality and inequality constraints, solved once with
/// clarabel: minimise `1/2 v'Pv + q'v` s.t. `A_eq v = b_eq`, `A_in v <= b_in`.
/// Used for the uncondensed check of the condensing.
#[cfg(test)]
pub(crate) fn solve_dense(
    p: &DMatrix<f64>,
    q: &DVector<f64>,
    a_eq: &DMatrix<f64>,
    b_eq: &DVector<f64>,
    a_in: &DMatrix<f64>,
    b_in: &DVector<f64>,
) -> Result<DVector<f64>, MpcError> {
    let n = p.nrows();
    let mut a = DMatrix::zeros(a_eq.nrows() + a_in.nrows(), n);
    a.view_mut((0, 0), a_eq.shape()).copy_from(a_eq);
    a.view_mut((a_eq.nrows(), 0), a_in.shape()).copy_from(a_in);
    let mut b = DVector::zeros(a.nrows());
    b.rows_mut(0, b_eq.len()).copy_from(b_eq);
    b.rows_mut(b_eq.len(), b_in.len()).copy_from(b_in);
    let cones = [
        SupportedConeT::ZeroConeT(a_eq.nrows()),
        SupportedConeT::NonnegativeConeT(a_in.nrows()),
    ];
    let mut s = DefaultSolver::new(
        &to_csc(p, true),
        q.as_slice(),
        &to_csc(&a, false),
        b.as_slice(),
        &cones,
        QpSettings::default().clarabel(),
    )
    .map_err(|e| MpcError::Solver(format!("setup failed: {e}")))?;
    s.solve();
    match s.solution.status {
        SolverStatus::Solved => Ok(DVector::from_column_slice(&s.solution.x)),
        other => Err(status_error(other)),
    }
}
