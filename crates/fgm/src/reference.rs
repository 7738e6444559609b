//! The exact optimum of a [`BoxQp`], for checking certificates: kestrel-mpc's
//! polished clarabel reference ([`kestrel_mpc::ReferenceSolver`]) on the
//! problem written as `G = [I; -I]` ([`BoxQp::to_mpqp`]).

use crate::{BoxQp, FgmError};
use kestrel_mpc::QpSettings;
use nalgebra::DVector;

/// The reference solver of one [`BoxQp`], set up once and solved at any
/// parameter.
///
/// ```
/// use kestrel_fgm::{BoxQp, reference::ReferenceSolver};
/// use kestrel_core::formats::MpqpProblem;
/// use nalgebra::dvector;
/// // min 1/2 z^2 + theta z  s.t.  -1 <= z <= 1
/// let p = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
///   "H": [[1]], "F": [[1]], "G": [[1], [-1]], "W": [1, 1], "E": [[0], [0]],
///   "theta_lb": [-5], "theta_ub": [5]}"#).unwrap();
/// let mut reference = ReferenceSolver::new(&BoxQp::from_mpqp(&p).unwrap()).unwrap();
/// let best = reference.solve(&dvector![-3.0]).unwrap(); // the bound z <= 1 is active
/// assert!(best.polished && (best.z[0] - 1.0).abs() < 1e-14 && (best.cost + 2.5).abs() < 1e-14);
/// ```
#[derive(Debug)]
pub struct ReferenceSolver {
    problem: BoxQp,
    solver: kestrel_mpc::ReferenceSolver,
}

/// A reference solution.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceSolution {
    /// The minimiser.
    pub z: DVector<f64>,
    /// The optimal cost `1/2 z'Hz + (F'theta + f)'z` ([`BoxQp::cost`]).
    pub cost: f64,
    /// Whether the active-set polish verified `z` as the exact optimum
    /// (see [`kestrel_mpc::QpSolution::polished`]); if not, `z` is the
    /// interior-point solution, to about `1e-9` relative in the duality gap.
    pub polished: bool,
}

impl ReferenceSolver {
    /// Sets up the reference of `problem` with kestrel-mpc's default
    /// settings (tolerance `1e-9`, polished).
    ///
    /// # Errors
    /// [`FgmError::Solver`] when the problem is refused (its Hessian must be
    /// positive definite).
    pub fn new(problem: &BoxQp) -> Result<Self, FgmError> {
        let solver = kestrel_mpc::ReferenceSolver::new(&problem.to_mpqp(), QpSettings::default())
            .map_err(|e| FgmError::Solver(format!("reference QP: {e}")))?;
        Ok(ReferenceSolver {
            problem: problem.clone(),
            solver,
        })
    }

    /// The problem.
    pub fn problem(&self) -> &BoxQp {
        &self.problem
    }

    /// Solves at `theta`.
    ///
    /// # Errors
    /// [`FgmError::Solver`] unless the problem is solved.
    pub fn solve(&mut self, theta: &DVector<f64>) -> Result<ReferenceSolution, FgmError> {
        let sol = self
            .solver
            .solve(theta)
            .map_err(|e| FgmError::Solver(format!("reference QP: {e}")))?;
        let cost = self.problem.cost(&sol.z, theta);
        Ok(ReferenceSolution {
            z: sol.z,
            cost,
            polished: sol.polished,
        })
    }
}
