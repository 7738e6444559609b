//! Reference solves with clarabel (interior point), for tests, the CLI and
//! the benchmarks.

use crate::{BoxQp, FgmError};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::DVector;

/// A reusable clarabel formulation of a [`BoxQp`]: `P = H`, `A = [I; -I]`.
#[derive(Clone, Debug)]
pub struct ReferenceSolver {
    p: CscMatrix<f64>,
    a: CscMatrix<f64>,
    settings: DefaultSettings<f64>,
}

/// A reference solution.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceSolution {
    /// The minimiser.
    pub z: DVector<f64>,
    /// The optimal cost `1/2 z'Hz + (F'theta + f)'z`.
    pub cost: f64,
}

impl ReferenceSolver {
    /// Builds the formulation (tolerances tightened to 1e-10).
    pub fn new(problem: &BoxQp) -> Self {
        let n = problem.n();
        // Upper triangle of H, column by column.
        let mut colptr = vec![0];
        let mut rowval = Vec::new();
        let mut nzval = Vec::new();
        for j in 0..n {
            for i in 0..=j {
                let v = 0.5 * (problem.h[(i, j)] + problem.h[(j, i)]);
                if v != 0.0 {
                    rowval.push(i);
                    nzval.push(v);
                }
            }
            colptr.push(rowval.len());
        }
        let p = CscMatrix::new(n, n, colptr, rowval, nzval);
        let a = CscMatrix::new(
            2 * n,
            n,
            (0..=n).map(|j| 2 * j).collect(),
            (0..n).flat_map(|j| [j, n + j]).collect(),
            (0..n).flat_map(|_| [1.0, -1.0]).collect(),
        );
        let settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .tol_gap_abs(1e-10)
            .tol_gap_rel(1e-10)
            .tol_feas(1e-10)
            .build()
            .unwrap_or_default();
        ReferenceSolver { p, a, settings }
    }

    /// Solves at `theta`.
    ///
    /// # Errors
    /// [`FgmError::Solver`] unless clarabel reports the problem solved.
    pub fn solve(
        &self,
        problem: &BoxQp,
        theta: &DVector<f64>,
    ) -> Result<ReferenceSolution, FgmError> {
        let n = problem.n();
        let q = problem.linear_term(theta);
        let bounds = problem.bounds(theta);
        let mut b = bounds.hi.as_slice().to_vec();
        b.extend(bounds.lo.iter().map(|v| -v));
        let cones = [SupportedConeT::NonnegativeConeT(2 * n)];
        let mut solver = DefaultSolver::new(
            &self.p,
            q.as_slice(),
            &self.a,
            &b,
            &cones,
            self.settings.clone(),
        )
        .map_err(|e| FgmError::Solver(format!("{e:?}")))?;
        solver.solve();
        match solver.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                // Clean up tiny bound violations of the interior point.
                let z = DVector::from_fn(n, |i, _| {
                    solver.solution.x[i].clamp(bounds.lo[i], bounds.hi[i])
                });
                let cost = problem.cost(&z, theta);
                Ok(ReferenceSolution { z, cost })
            }
            other => Err(FgmError::Solver(format!("reference QP: {other:?}"))),
        }
    }
}
