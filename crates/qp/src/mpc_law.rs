//! The dual active-set solver as a solver of kestrel-mpc's condensed QP
//! (feature `mpc`), so `kestrel_mpc::MpcLaw` and closed-loop simulations
//! fly the exact online solver like the clarabel reference.

use crate::parametric::{ParametricError, ParametricQp, QpBuffers};
use crate::solver::Parked;
use crate::{QpSettings, QpSolver, Start};
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
/// The solver is set up once (the factorisation of `H`, `O(n^3 + m n^2)`)
/// on the owned workspaces and kept there between calls, as a
/// [`crate::QpSolver`] on static workspaces is kept on a target: a call
/// fills the period's data and solves, nothing more.
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
    start: Start,
    scalars: Vec<f64>,
    indices: Vec<usize>,
    buffers: QpBuffers<f64>,
    /// The set-up solver, its workspaces being `scalars` and `indices`.
    parked: Parked,
    /// The next solve starts cold (after a failure or [`Self::reset`]);
    /// before the first solve the active set is empty, and a warm start
    /// from it is the cold start.
    cold_next: bool,
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
        let (mut scalars, mut indices) = (vec![0.0; ns], vec![0; ni]);
        let parked = qp
            .solver::<f64>(settings, &mut scalars, &mut indices)
            .map_err(|e| err(e.to_string()))?
            .park();
        Ok(ActiveSetSolver {
            buffers: qp.buffers(),
            qp,
            start,
            scalars,
            indices,
            parked,
            cold_next: false,
            last_iterations: 0,
            worst_iterations: 0,
            solves: 0,
        })
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
        self.cold_next = true;
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
        let mut solver = QpSolver::resume(self.parked, &mut self.scalars, &mut self.indices)?;
        let start = if self.cold_next {
            Start::Cold
        } else {
            self.start
        };
        let data = self.buffers.data();
        let info = solver
            .solve(&data, start)
            .and_then(|info| solver.refine(&data).map(|()| info))
            .and_then(|info| solver.solution(z).map(|()| info));
        self.parked = solver.park();
        let info = info?;
        self.cold_next = false;
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

    /// The owned solver is one `QpSolver` set up once and kept: over a
    /// closed-loop-like sequence of parameters with an infeasible one (the
    /// next solve then starts cold) and a reset, every `z` and iteration
    /// count equals, bit for bit, that of a solver kept on workspaces of
    /// its own and started as the docs say.
    #[test]
    fn the_owned_solver_is_a_kept_solver() {
        let p = MpcProblem::build(
            &double_integrator(),
            &MpcSettings {
                horizon: 8,
                terminal: Terminal::Lq,
                du_bounds: Some(Bounds::new(dvector![-0.4], dvector![0.4])),
                input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0])),
                output_bounds: Some(Bounds::new(dvector![-2.0], dvector![1.1])),
                ..MpcSettings::default()
            },
        )
        .unwrap();
        let mpqp = p.to_mpqp();
        let qp = ParametricQp::from_mpqp(&mpqp).unwrap();
        let (ns, ni) = qp.workspace_len();
        let (mut scalars, mut indices) = (vec![0.0; ns], vec![0; ni]);
        let mut kept = qp
            .solver::<f64>(QpSettings::default(), &mut scalars, &mut indices)
            .unwrap();
        let mut buf = qp.buffers::<f64>();
        let mut owned = ActiveSetSolver::new(&mpqp, QpSettings::default(), Start::Warm).unwrap();
        let (mut z, mut z_kept) = (vec![0.0; p.n()], vec![0.0; p.n()]);
        let (mut cold_next, mut failures, mut changes) = (false, 0, 0);
        for k in 0..60 {
            let t = k as f64 * 0.21;
            let x = if k == 17 {
                [5.0, 3.0] // no input keeps y <= 1.1
            } else {
                [0.8 * t.sin(), 0.5 * (1.7 * t).cos()]
            };
            let theta = p
                .theta_with_previous(&x, &[0.6 * (0.9 * t).sin()], &[0.9 * (0.4 * t).cos()])
                .unwrap();
            qp.fill(theta.as_slice(), &mut buf).unwrap();
            let start = if cold_next { Start::Cold } else { Start::Warm };
            let want = kept.solve(&buf.data(), start);
            let got = owned.solve_into(theta.as_slice(), &mut z);
            match want {
                Ok(info) => {
                    got.unwrap();
                    kept.refine(&buf.data()).unwrap();
                    kept.solution(&mut z_kept).unwrap();
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&z), bits(&z_kept), "{k}");
                    assert_eq!(owned.last_iterations(), info.iterations, "{k}");
                    changes += info.iterations;
                    cold_next = false;
                }
                Err(e) => {
                    assert_eq!(got, Err(Error::from(e)), "{k}");
                    failures += 1;
                    cold_next = true;
                }
            }
            if k == 40 {
                owned.reset();
                cold_next = true;
            }
        }
        assert_eq!(failures, 1);
        assert_eq!(owned.solves(), 59);
        assert!(changes > 59, "{changes}");
    }
}
