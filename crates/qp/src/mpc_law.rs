//! The dual active-set solver as a solver of kestrel-mpc's condensed QP
//! (feature `mpc`), so `kestrel_mpc::MpcLaw` and closed-loop simulations
//! fly the exact online solver like the clarabel reference.

use crate::parametric::{ParametricError, ParametricQp, QpBuffers};
use crate::{ActiveConstraint, QpSettings, Start};
use kestrel_core::Error;
use kestrel_core::formats::MpqpProblem;
use kestrel_mpc::{MpcError, MpcLaw, MpcProblem, ParametricQpSolver};

/// The MPC law with the dual active-set solver ([`ActiveSetSolver`]).
pub type ActiveSetMpc = MpcLaw<ActiveSetSolver>;

/// kestrel-qp's dual active-set solver on a `kestrel.mpqp.v1` problem,
/// in f64, owning its workspaces: each call solves the QP at `theta`
/// exactly, from a cold start or ([`Start::Warm`]) from the previous
/// call's final active set, as a controller does from one period to the
/// next. A failed solve makes the next one start cold.
///
/// Each call sets the solver up afresh on the owned workspaces (the
/// factorisation of `H`, `O(n^3 + m n^2)`, the same numbers every time)
/// and then starts from the kept active set, so the iterations are those
/// of a solver kept across periods; on a target, keep one
/// [`crate::QpSolver`] on static workspaces instead.
///
/// ```
/// use kestrel_core::{ControlLaw, Matrix, StateSpace};
/// use kestrel_mpc::{Bounds, MpcLaw, MpcProblem, MpcSettings, QpSettings, Terminal};
/// use kestrel_qp::{ActiveSetSolver, Start};
/// use nalgebra::dvector;
/// // A double integrator sampled at 0.1 s, |u| <= 1, horizon 10.
/// let m = StateSpace::new(Matrix::from_rows([[1.0, 0.1], [0.0, 1.0]]),
///     Matrix::from_rows([[0.005], [0.1]]), Matrix::from_rows([[1.0, 0.0]]),
///     Matrix::from_rows([[0.0]]), 0.1);
/// let p = MpcProblem::build(&m, &MpcSettings { horizon: 10, terminal: Terminal::Lq,
///     input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0])),
///     ..MpcSettings::default() }).unwrap();
/// let mut exact = ActiveSetSolver::mpc_law(&p, kestrel_qp::QpSettings::default(), Start::Warm)
///     .unwrap();
/// let mut reference = MpcLaw::clarabel(&p, QpSettings::default()).unwrap();
/// let (mut u, mut u_ref) = ([0.0], [0.0]);
/// exact.control(&[0.0, 0.0], &[1.0], &mut u).unwrap();
/// reference.control(&[0.0, 0.0], &[1.0], &mut u_ref).unwrap();
/// assert!((u[0] - 1.0).abs() < 1e-12 && (u[0] - u_ref[0]).abs() < 1e-9);
/// assert!(exact.solver().last_iterations() >= 1);
/// ```
#[derive(Debug, Clone)]
pub struct ActiveSetSolver {
    qp: ParametricQp,
    settings: QpSettings,
    start: Start,
    scalars: Vec<f64>,
    indices: Vec<usize>,
    buffers: QpBuffers<f64>,
    /// The final active set of the last successful solve (empty before
    /// the first and after a failure: a warm start from it is cold).
    previous: Vec<ActiveConstraint>,
    last_iterations: usize,
    worst_iterations: usize,
    solves: usize,
}

impl ActiveSetSolver {
    /// A solver of `problem` (mapped by [`ParametricQp::from_mpqp`]) with
    /// the given settings, starting every solve from `start`. The set-up
    /// is tried once here, so a problem whose `H` is not positive definite
    /// is refused now, not at the first solve.
    ///
    /// # Errors
    /// [`MpcError::ExternalSolver`] naming why: a malformed problem, bad
    /// settings, `H` not positive definite.
    pub fn new(
        problem: &MpqpProblem,
        settings: QpSettings,
        start: Start,
    ) -> Result<Self, MpcError> {
        let err = |reason: String| MpcError::ExternalSolver {
            solver: "dual active-set QP",
            reason,
        };
        let qp =
            ParametricQp::from_mpqp(problem).map_err(|e: ParametricError| err(e.to_string()))?;
        let (ns, ni) = qp.workspace_len();
        let mut s = ActiveSetSolver {
            buffers: qp.buffers(),
            qp,
            settings,
            start,
            scalars: vec![0.0; ns],
            indices: vec![0; ni],
            previous: Vec::new(),
            last_iterations: 0,
            worst_iterations: 0,
            solves: 0,
        };
        s.qp.solver::<f64>(settings, &mut s.scalars, &mut s.indices)
            .map_err(|e| err(e.to_string()))?;
        Ok(s)
    }

    /// The MPC law of `problem` solved by this solver.
    ///
    /// # Errors
    /// As [`ActiveSetSolver::new`].
    pub fn mpc_law(
        problem: &MpcProblem,
        settings: QpSettings,
        start: Start,
    ) -> Result<ActiveSetMpc, MpcError> {
        MpcLaw::new(problem, Self::new(&problem.to_mpqp(), settings, start)?)
    }

    /// The problem in the solver's form.
    pub fn problem(&self) -> &ParametricQp {
        &self.qp
    }

    /// Active-set changes of the last successful solve.
    pub fn last_iterations(&self) -> usize {
        self.last_iterations
    }

    /// The most active-set changes of any successful solve so far (to
    /// compare with the certified worst case, `kestrel qp certify`).
    pub fn worst_iterations(&self) -> usize {
        self.worst_iterations
    }

    /// Successful solves so far.
    pub fn solves(&self) -> usize {
        self.solves
    }

    /// Forgets the kept active set: the next solve starts cold.
    pub fn reset(&mut self) {
        self.previous.clear();
    }

    fn solve_at(&mut self, theta: &[f64], z: &mut [f64]) -> Result<usize, Error> {
        self.qp
            .fill(theta, &mut self.buffers)
            .map_err(|e| match e {
                ParametricError::Dimension { expected, found } => {
                    Error::DimensionMismatch { expected, found }
                }
                ParametricError::Format(_) | ParametricError::ZeroRow(_) => {
                    Error::InvalidArgument("malformed mpQP problem")
                }
            })?;
        let mut solver =
            self.qp
                .solver::<f64>(self.settings, &mut self.scalars, &mut self.indices)?;
        // The set-up left the active set empty; a warm start adds the kept
        // one (from an empty set it is the cold start).
        if self.start == Start::Warm {
            solver.set_active_set(&self.previous)?;
        }
        let info = solver.solve(&self.buffers.data(), self.start)?;
        solver.solution(z)?;
        self.previous.clear();
        self.previous.extend(solver.active_set());
        Ok(info.iterations)
    }
}

impl ParametricQpSolver for ActiveSetSolver {
    fn n(&self) -> usize {
        self.qp.n()
    }
    fn p(&self) -> usize {
        self.qp.p()
    }
    fn solve_into(&mut self, theta: &[f64], z: &mut [f64]) -> Result<(), Error> {
        kestrel_core::check_len(theta, self.qp.p())?;
        kestrel_core::check_len(z, self.qp.n())?;
        if !kestrel_core::all_finite(theta) {
            return Err(Error::NonFinite);
        }
        match self.solve_at(theta, z) {
            Ok(iterations) => {
                self.last_iterations = iterations;
                self.worst_iterations = self.worst_iterations.max(iterations);
                self.solves += 1;
                Ok(())
            }
            Err(e) => {
                self.reset();
                Err(e)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel_core::{ControlLaw, Matrix, StateSpace};
    use kestrel_mpc::{Bounds, MpcSettings, SoftPenalty, Terminal, Weight};
    use nalgebra::dvector;

    /// A double integrator sampled at 0.1 s.
    fn double_integrator() -> StateSpace<f64, 2, 1, 1> {
        StateSpace::new(
            Matrix::from_rows([[1.0, 0.1], [0.0, 1.0]]),
            Matrix::from_rows([[0.005], [0.1]]),
            Matrix::from_rows([[1.0, 0.0]]),
            Matrix::from_rows([[0.0]]),
            0.1,
        )
    }

    /// Input, input-move and soft output bounds: simple bounds, general
    /// rows and slacks.
    fn problem() -> MpcProblem {
        MpcProblem::build(
            &double_integrator(),
            &MpcSettings {
                horizon: 12,
                q2: Weight::Scalar(0.01),
                du_weight: Some(Weight::Scalar(0.1)),
                terminal: Terminal::Lq,
                input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0])),
                du_bounds: Some(Bounds::new(dvector![-0.3], dvector![0.3])),
                output_bounds: Some(
                    Bounds::new(dvector![-0.2], dvector![1.1]).with_soft(SoftPenalty::default()),
                ),
                ..MpcSettings::default()
            },
        )
        .unwrap()
    }

    /// Closed loop on the model: the law's inputs equal clarabel's (to
    /// 1e-9, clarabel polished) at every step, cold and warm; warm starts
    /// take fewer active-set changes in all on the smooth trajectory.
    #[test]
    fn the_law_is_the_reference_law_cold_and_warm() {
        let p = problem();
        let mut totals = Vec::new();
        for start in [Start::Cold, Start::Warm] {
            let mut law = ActiveSetSolver::mpc_law(&p, QpSettings::default(), start).unwrap();
            let mut reference = MpcLaw::clarabel(&p, kestrel_mpc::QpSettings::default()).unwrap();
            let (a, b) = (
                nalgebra::dmatrix![1.0, 0.1; 0.0, 1.0],
                nalgebra::dmatrix![0.005; 0.1],
            );
            let mut x = dvector![0.0, 0.0];
            let (mut u, mut u_ref) = ([0.0], [0.0]);
            let mut total = 0;
            for k in 0..80 {
                let r = if k < 40 { 1.0 } else { -0.1 };
                law.control(x.as_slice(), &[r], &mut u).unwrap();
                reference.control(x.as_slice(), &[r], &mut u_ref).unwrap();
                assert!(
                    (u[0] - u_ref[0]).abs() < 1e-9,
                    "{start:?} {k}: {u:?} {u_ref:?}"
                );
                for (z, zr) in law.last_z().iter().zip(reference.last_z()) {
                    assert!((z - zr).abs() < 1e-8, "{start:?} {k}");
                }
                total += law.solver().last_iterations();
                x = &a * &x + &b * dvector![u[0]];
            }
            assert!((x[0] + 0.1).abs() < 1e-2, "{x}");
            assert_eq!(law.solver().solves(), 80);
            assert!(law.solver().worst_iterations() >= 2);
            totals.push(total);
        }
        assert!(
            totals[1] < totals[0],
            "cold {} warm {}",
            totals[0],
            totals[1]
        );
    }

    /// A parameter with no feasible `z` is `Infeasible`; the next solve
    /// starts cold and succeeds. Wrong lengths and NaN are refused.
    #[test]
    fn infeasible_and_bad_parameters_are_errors() {
        // Hard output bounds: from far above them no input keeps y <= 1.1.
        let p = MpcProblem::build(
            &double_integrator(),
            &MpcSettings {
                horizon: 5,
                terminal: Terminal::Lq,
                input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0])),
                output_bounds: Some(Bounds::new(dvector![-2.0], dvector![1.1])),
                ..MpcSettings::default()
            },
        )
        .unwrap();
        let mut s = ActiveSetSolver::new(&p.to_mpqp(), QpSettings::default(), Start::Warm).unwrap();
        let mut z = vec![0.0; p.n()];
        let good = p.theta(&[0.0, 0.0], &[1.0]).unwrap();
        s.solve_into(good.as_slice(), &mut z).unwrap();
        let bad = p.theta(&[5.0, 3.0], &[1.0]).unwrap();
        assert_eq!(s.solve_into(bad.as_slice(), &mut z), Err(Error::Infeasible));
        assert_eq!(s.solves(), 1);
        s.solve_into(good.as_slice(), &mut z).unwrap();
        assert_eq!(s.solves(), 2);
        assert!(matches!(
            s.solve_into(&good.as_slice()[1..], &mut z),
            Err(Error::DimensionMismatch { .. })
        ));
        let mut nan = good.clone();
        nan[0] = f64::NAN;
        assert_eq!(s.solve_into(nan.as_slice(), &mut z), Err(Error::NonFinite));
    }
}
