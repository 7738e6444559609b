//! MPC control laws: a receding-horizon wrapper around any solver of the
//! condensed parametric QP.

use crate::condense::MpcProblem;
use crate::error::MpcError;
use crate::layout::ThetaLayout;
use crate::qp::{QpSettings, ReferenceSolver};
use kestrel_core::{ControlLaw, Error};
use nalgebra::DVector;

/// A solver of the parametric QP `min 1/2 z'Hz + theta'F z s.t. G z <= W + E theta`.
///
/// This is the slot through which the solvers plug into [`MpcLaw`] and the
/// closed-loop simulators: the clarabel [`ReferenceSolver`] here, the
/// explicit solver of kestrel-empc (`kestrel_empc::ExplicitSolver`) and the
/// fast-gradient solver of kestrel-fgm (`kestrel_fgm::FastGradientSolver`)
/// in their crates.
pub trait ParametricQpSolver {
    /// Number of decision variables `n`.
    fn n(&self) -> usize;
    /// Number of parameters `p`.
    fn p(&self) -> usize;
    /// Writes a (near-)minimiser for `theta` into `z`.
    fn solve_into(&mut self, theta: &[f64], z: &mut [f64]) -> Result<(), Error>;
}

impl From<MpcError> for Error {
    /// The run-time error closest to each design-time error; the text of
    /// the design-time error (names, values) is lost, its kind is kept.
    fn from(e: MpcError) -> Self {
        match e {
            MpcError::Dimension { .. } => Error::InvalidArgument("dimension mismatch"),
            MpcError::NonFinite(_) => Error::NonFinite,
            MpcError::InvalidSetting { .. } => Error::InvalidArgument("invalid MPC setting"),
            MpcError::InfeasibleBounds { .. } | MpcError::Infeasible => Error::Infeasible,
            MpcError::NotSymmetric { .. } => {
                Error::InvalidArgument("a weight or the Hessian is not symmetric")
            }
            MpcError::NotPositiveDefinite { .. } => Error::NotPositiveDefinite,
            MpcError::FeedThrough { .. } => {
                Error::InvalidArgument("the model has a non-zero feed-through D")
            }
            // The Riccati iteration of the LQ terminal weight failed.
            MpcError::Terminal(_) => Error::NotConverged,
            // The interior-point method stopped without a solution.
            MpcError::Solver(_) => Error::NotConverged,
            MpcError::ExternalSolver { .. } => {
                Error::InvalidArgument("the explicit or fast-gradient solver refused the problem")
            }
            MpcError::TooLarge { .. } => {
                Error::InvalidArgument("the problem is too large to condense")
            }
            MpcError::Format(_) => Error::InvalidArgument("malformed interchange file"),
            MpcError::Core(e) => e,
        }
    }
}

impl ParametricQpSolver for ReferenceSolver {
    fn n(&self) -> usize {
        self.problem().n()
    }
    fn p(&self) -> usize {
        self.problem().p()
    }
    fn solve_into(&mut self, theta: &[f64], z: &mut [f64]) -> Result<(), Error> {
        kestrel_core::check_len(theta, self.problem().p())?;
        kestrel_core::check_len(z, self.problem().n())?;
        let sol = self.solve(&DVector::from_column_slice(theta))?;
        z.copy_from_slice(sol.z.as_slice());
        Ok(())
    }
}

/// The receding-horizon MPC law: assembles `theta = [x; u_prev; r]`
/// ([`ThetaLayout`]), solves the QP with any [`ParametricQpSolver`], and
/// applies the first move (the `nu` inputs of the first block, deviations
/// from the trim). It keeps its last input as `u_prev` when the problem
/// has input-move terms.
///
/// As a [`ControlLaw`]: `x` the state estimate (`nx`), `r` the output
/// references of the preview, then the input target and the extra
/// parameters when the problem has them (the thesis: `[r; throttle]`), `u` the
/// input deviation from the trim (`nu`).
///
/// ```
/// use kestrel_core::{ControlLaw, Matrix, StateSpace};
/// use kestrel_mpc::{Bounds, MpcLaw, MpcProblem, MpcSettings, QpSettings, Terminal, Weight};
/// use nalgebra::dvector;
/// let m = StateSpace::new(Matrix::from_rows([[0.9]]), Matrix::from_rows([[0.1]]),
///     Matrix::from_rows([[1.0]]), Matrix::from_rows([[0.0]]), 0.02);
/// let p = MpcProblem::build(&m, &MpcSettings { horizon: 5, terminal: Terminal::Lq,
///     input_bounds: Some(Bounds::new(dvector![-0.5], dvector![0.5])),
///     ..MpcSettings::default() }).unwrap();
/// let mut law = MpcLaw::clarabel(&p, QpSettings::default()).unwrap();
/// let mut u = [0.0];
/// law.control(&[0.0], &[2.0], &mut u).unwrap(); // far below the reference
/// assert!((u[0] - 0.5).abs() < 1e-6);           // full push, at the bound
///
/// // With an input-move bound the law remembers its last input: from rest
/// // it can move by at most 0.1 per step.
/// let p = MpcProblem::build(&m, &MpcSettings { horizon: 5, terminal: Terminal::Lq,
///     du_weight: Some(Weight::Scalar(0.0)),
///     du_bounds: Some(Bounds::new(dvector![-0.1], dvector![0.1])),
///     ..MpcSettings::default() }).unwrap();
/// let mut law = MpcLaw::clarabel(&p, QpSettings::default()).unwrap();
/// law.control(&[0.0], &[2.0], &mut u).unwrap();
/// assert!((u[0] - 0.1).abs() < 1e-9);
/// law.control(&[0.0], &[2.0], &mut u).unwrap();
/// assert!((u[0] - 0.2).abs() < 1e-9);
/// ```
#[derive(Debug)]
pub struct MpcLaw<S> {
    layout: ThetaLayout,
    nu: usize,
    solver: S,
    theta: Vec<f64>,
    z: Vec<f64>,
    /// The input applied last (deviation from the trim), when `theta`
    /// holds it.
    u_prev: Vec<f64>,
}

/// The MPC law with the clarabel reference solver.
pub type QpMpc = MpcLaw<ReferenceSolver>;

impl MpcLaw<ReferenceSolver> {
    /// The MPC law of `problem` solved exactly by clarabel.
    pub fn clarabel(problem: &MpcProblem, settings: QpSettings) -> Result<Self, MpcError> {
        let solver = ReferenceSolver::new(&problem.to_mpqp(), settings)?;
        MpcLaw::new(problem, solver)
    }
}

impl<S: ParametricQpSolver> MpcLaw<S> {
    /// The MPC law of `problem` with any solver of its QP; the solver's
    /// sizes must match the problem's.
    pub fn new(problem: &MpcProblem, solver: S) -> Result<Self, MpcError> {
        if solver.n() != problem.n() || solver.p() != problem.p() {
            return Err(MpcError::dim(
                "QP solver",
                format!("n = {}, p = {}", problem.n(), problem.p()),
                format!("n = {}, p = {}", solver.n(), solver.p()),
            ));
        }
        Ok(MpcLaw {
            layout: problem.layout,
            nu: problem.nu,
            theta: vec![0.0; problem.p()],
            z: vec![0.0; problem.n()],
            u_prev: vec![0.0; problem.layout.nu_prev],
            solver,
        })
    }
    /// The solver.
    pub fn solver(&self) -> &S {
        &self.solver
    }
    /// The solver, mutably.
    pub fn solver_mut(&mut self) -> &mut S {
        &mut self.solver
    }
    /// The solver, giving up the law.
    pub fn into_solver(self) -> S {
        self.solver
    }
    /// The parameter vector of the last call.
    pub fn last_theta(&self) -> &[f64] {
        &self.theta
    }
    /// The whole blocked input sequence `z` of the last call.
    pub fn last_z(&self) -> &[f64] {
        &self.z
    }
    /// The previous input the next call puts in `theta` (empty when the
    /// problem has no input-move terms): the law's last output, zero (the
    /// trim) before the first call.
    pub fn previous_input(&self) -> &[f64] {
        &self.u_prev
    }
    /// Sets the previous input (deviation from the trim), e.g. the input
    /// actually applied when it differed from the law's (saturation,
    /// manual flight). A problem without input-move terms has none:
    /// `u_prev` must then be empty.
    pub fn set_previous_input(&mut self, u_prev: &[f64]) -> Result<(), Error> {
        kestrel_core::check_len(u_prev, self.u_prev.len())?;
        if !kestrel_core::all_finite(u_prev) {
            return Err(Error::NonFinite);
        }
        self.u_prev.copy_from_slice(u_prev);
        Ok(())
    }
}

impl<S: ParametricQpSolver> ControlLaw for MpcLaw<S> {
    type Scalar = f64;
    fn nx(&self) -> usize {
        self.layout.nx
    }
    fn nr(&self) -> usize {
        self.layout.n_law_reference()
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn control(&mut self, x: &[f64], r: &[f64], u: &mut [f64]) -> Result<(), Error> {
        kestrel_core::check_len(u, self.nu)?;
        if !kestrel_core::all_finite(x) || !kestrel_core::all_finite(r) {
            return Err(Error::NonFinite);
        }
        self.layout
            .assemble_into(x, &self.u_prev, r, &mut self.theta)?;
        self.solver.solve_into(&self.theta, &mut self.z)?;
        u.copy_from_slice(&self.z[..self.nu]);
        if !self.u_prev.is_empty() {
            self.u_prev.copy_from_slice(&self.z[..self.nu]);
        }
        Ok(())
    }
}
