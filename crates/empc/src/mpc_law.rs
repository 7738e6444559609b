//! The explicit solution as a solver of kestrel-mpc's condensed QP, so
//! `kestrel_mpc::MpcLaw` and closed-loop simulations fly it like the
//! clarabel reference.

use crate::{
    AnyTables, EmpcError, OwnedTables, Settings, TreeSettings, build_any, evaluate_with, solve,
};
use kestrel_core::Error;
use kestrel_core::formats::MpqpProblem;
use kestrel_mpc::{MpcError, MpcLaw, MpcProblem, ParametricQpSolver};

/// The MPC law with the explicit solution ([`ExplicitSolver`]).
pub type ExplicitMpc = MpcLaw<ExplicitSolver>;

/// The explicit MPC: the multi-parametric solution of the QP, stored as a
/// binary search tree over the whole `z`, evaluated by point location
/// ([`evaluate_with`], the run-time evaluator).
///
/// A parameter outside the explored set (the parameter box or the hull of
/// the regions) gets the clamped law of the nearest region, as on the
/// aircraft; [`ExplicitSolver::outside`] counts those calls.
///
/// ```
/// use kestrel_core::{Matrix, StateSpace};
/// use kestrel_empc::ExplicitSolver;
/// use kestrel_mpc::{Bounds, MpcProblem, MpcSettings, ParametricQpSolver, QpSettings,
///     ReferenceSolver, Terminal};
/// use nalgebra::dvector;
/// // A double integrator sampled at 0.1 s, |u| <= 1, horizon 5.
/// let m = StateSpace::new(Matrix::from_rows([[1.0, 0.1], [0.0, 1.0]]),
///     Matrix::from_rows([[0.005], [0.1]]), Matrix::from_rows([[1.0, 0.0]]),
///     Matrix::from_rows([[0.0]]), 0.1);
/// let p = MpcProblem::build(&m, &MpcSettings { horizon: 5, terminal: Terminal::Lq,
///     input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0])), ..MpcSettings::default() }).unwrap();
/// let mut explicit = ExplicitSolver::build(&p.to_mpqp(), &kestrel_empc::Settings::default()).unwrap();
/// let mut qp = ReferenceSolver::new(&p.to_mpqp(), QpSettings::default()).unwrap();
/// let theta = p.theta(&[0.2, -0.1], &[0.5]).unwrap();
/// let (mut ze, mut zq) = (vec![0.0; p.n()], vec![0.0; p.n()]);
/// explicit.solve_into(theta.as_slice(), &mut ze).unwrap();
/// qp.solve_into(theta.as_slice(), &mut zq).unwrap();
/// assert!(ze.iter().zip(&zq).all(|(a, b)| (a - b).abs() < 1e-6));
/// ```
#[derive(Clone, Debug)]
pub struct ExplicitSolver {
    tables: AnyTables,
    scratch: Vec<f64>,
    outside: usize,
    regions: usize,
}

impl ExplicitSolver {
    /// A solver from the tables of an explicit controller over all of `z`
    /// ([`crate::Outputs::All`]).
    pub fn new(tables: OwnedTables<f64>) -> Self {
        Self::from_any(AnyTables::Narrow(tables))
    }

    /// A solver from tables in either layout ([`crate::build_any`]).
    pub fn from_any(tables: AnyTables) -> Self {
        let p = match &tables {
            AnyTables::Narrow(t) => t.n_params,
            AnyTables::Wide(t) => t.n_params,
        };
        ExplicitSolver {
            scratch: vec![0.0; p],
            tables,
            outside: 0,
            regions: 0,
        }
    }

    /// Solves `problem` multi-parametrically and builds the search tree
    /// over all of `z` ([`crate::build_any`] with the default settings: the
    /// `u16` tables when the tree fits them, else the `u32` ones).
    ///
    /// # Errors
    /// [`MpcError::ExternalSolver`] when the mpQP solve or the tree
    /// construction fails (too many regions, a degenerate problem), or
    /// when the tree has a leaf it could not narrow to one law
    /// ([`TreeStats::ambiguous_leaves`](crate::tree::TreeStats::ambiguous_leaves)):
    /// its answers would not be the QP's everywhere.
    pub fn build(problem: &MpqpProblem, settings: &Settings) -> Result<Self, MpcError> {
        let err = |e: EmpcError| MpcError::ExternalSolver {
            solver: "explicit MPC",
            reason: e.to_string(),
        };
        let solution = solve(problem, settings).map_err(err)?;
        let controller = build_any(problem, &solution, &TreeSettings::default()).map_err(err)?;
        let ambiguous = controller.stats.ambiguous_leaves;
        if ambiguous > 0 {
            return Err(MpcError::ExternalSolver {
                solver: "explicit MPC",
                reason: format!(
                    "the search tree has {ambiguous} leaves that hold regions of different laws (numerically degenerate regions): it would not give the QP's z everywhere"
                ),
            });
        }
        let mut s = ExplicitSolver::from_any(controller.tables);
        s.regions = solution.regions.len();
        Ok(s)
    }

    /// The explicit MPC law of `problem`: solved multi-parametrically,
    /// evaluated by point location in its search tree (formerly
    /// `kestrel_mpc::MpcLaw::explicit`).
    ///
    /// # Errors
    /// As [`ExplicitSolver::build`].
    pub fn mpc_law(problem: &MpcProblem, settings: &Settings) -> Result<ExplicitMpc, MpcError> {
        MpcLaw::new(problem, Self::build(&problem.to_mpqp(), settings)?)
    }

    /// Calls so far whose parameter was outside the explored set.
    pub fn outside(&self) -> usize {
        self.outside
    }

    /// Critical regions of the solution (0 when made from tables).
    pub fn regions(&self) -> usize {
        self.regions
    }

    /// The tree tables.
    pub fn tables(&self) -> &AnyTables {
        &self.tables
    }
}

impl ParametricQpSolver for ExplicitSolver {
    fn n(&self) -> usize {
        match &self.tables {
            AnyTables::Narrow(t) => t.n_outputs,
            AnyTables::Wide(t) => t.n_outputs,
        }
    }
    fn p(&self) -> usize {
        self.scratch.len()
    }
    fn solve_into(&mut self, theta: &[f64], z: &mut [f64]) -> Result<(), Error> {
        let outside = match &self.tables {
            AnyTables::Narrow(t) => {
                evaluate_with(&t.tables(), theta, &mut self.scratch, z)?.outside
            }
            AnyTables::Wide(t) => evaluate_with(&t.tables(), theta, &mut self.scratch, z)?.outside,
        };
        self.outside += usize::from(outside);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel_core::{ControlLaw, Matrix, StateSpace};
    use kestrel_mpc::{
        Bounds, MpcSettings, Parameter, QpSettings, ReferenceSolver, SoftPenalty, Terminal, Weight,
    };
    use nalgebra::{dmatrix, dvector};

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

    /// The double integrator with |u| <= 1, horizon 3.
    fn problem() -> MpcProblem {
        let m = double_integrator();
        let settings = MpcSettings {
            horizon: 3,
            q2: Weight::Scalar(1e-3),
            terminal: Terminal::Lq,
            input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0])),
            ..MpcSettings::default()
        };
        MpcProblem::build(&m, &settings).unwrap()
    }

    #[test]
    fn explicit_law_is_the_qp_law() {
        let p = problem();
        let mut explicit = ExplicitSolver::mpc_law(&p, &Settings::default()).unwrap();
        let mut qp = MpcLaw::clarabel(&p, QpSettings::default()).unwrap();
        assert!(explicit.solver().regions() > 1);
        let (mut ue, mut uq) = ([0.0], [0.0]);
        let mut saturated = 0;
        for k in 0..60 {
            let t = k as f64 * 0.37;
            let x = [0.3 * t.sin(), 0.8 * (1.3 * t).cos()];
            let r = [0.2 * (0.7 * t).cos()];
            explicit.control(&x, &r, &mut ue).unwrap();
            qp.control(&x, &r, &mut uq).unwrap();
            assert!((ue[0] - uq[0]).abs() < 1e-6, "{k}: {ue:?} vs {uq:?}");
            saturated += usize::from(uq[0].abs() > 1.0 - 1e-9);
        }
        // Both the saturated and the unconstrained pieces were visited.
        assert!(saturated > 0 && saturated < 60, "{saturated}");
        assert_eq!(explicit.solver().outside(), 0);
    }

    #[test]
    fn solver_errors_are_values() {
        let p = problem();
        let mut s = ExplicitSolver::build(&p.to_mpqp(), &Settings::default()).unwrap();
        let mut z = vec![0.0; p.n()];
        let mut theta = vec![0.0; p.p()];
        assert!(s.solve_into(&theta[..1], &mut z).is_err());
        theta[0] = f64::NAN;
        assert!(s.solve_into(&theta, &mut z).is_err());
    }

    /// A double integrator with input-move bounds, soft output bounds and
    /// an input window that moves with a parameter, horizon 3:
    /// `theta = [x (2); u_prev; r; p]`, `z = [u_0, u_1, u_2; s]`.
    fn general_problem() -> MpcProblem {
        let m = double_integrator();
        let settings = MpcSettings {
            horizon: 3,
            q2: Weight::Scalar(1e-2),
            terminal: Terminal::Lq,
            state_bound: 2.0,
            reference_bound: 1.0,
            du_weight: Some(Weight::Scalar(0.1)),
            du_bounds: Some(Bounds::new(dvector![-0.3], dvector![0.3])),
            output_bounds: Some(Bounds::new(dvector![-0.5], dvector![0.5]).with_soft(
                SoftPenalty {
                    quadratic: 10.0,
                    linear: 1.0,
                },
            )),
            // u in [-1 - p, 1 - p], p in [0, 0.5].
            input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0]).shifted(dmatrix![-1.0])),
            parameters: vec![Parameter::new("p", 0.0, 0.5)],
            ..MpcSettings::default()
        };
        MpcProblem::build(&m, &settings).unwrap()
    }

    #[test]
    fn explicit_law_solves_rate_soft_and_parameter_dependent_bounds() {
        let p = general_problem();
        let mp = p.to_mpqp();
        // The new pieces are in the mpQP: a constant linear term (the
        // linear soft penalty), a slack variable, more rows than 2 n.
        assert_eq!(p.n_slack, 1);
        assert!(mp.f.iter().any(|v| *v != 0.0), "{}", mp.f);
        assert!(mp.m() > 2 * mp.n());
        // E moves the rows with the state, the previous input and the
        // parameter.
        let l = p.layout;
        for j in [
            l.state().start,
            l.previous_input().start,
            l.parameters().start,
        ] {
            assert!(mp.e.column(j).iter().any(|v| *v != 0.0), "column {j} of E");
        }
        let mut explicit = ExplicitSolver::build(&mp, &Settings::default()).unwrap();
        let mut qp = ReferenceSolver::new(&mp, QpSettings::default()).unwrap();
        assert!(explicit.regions() > 100, "{}", explicit.regions());
        let mut rng = crate::rng::Rng::new(22);
        let (mut ze, mut zq) = (vec![0.0; p.n()], vec![0.0; p.n()]);
        let (mut worst, mut soft, mut rate) = (0.0_f64, 0, 0);
        for _ in 0..400 {
            let mut theta = vec![0.0; p.p()];
            for v in &mut theta[l.state()] {
                *v = 2.0 * rng.sym();
            }
            theta[l.references()][0] = rng.sym();
            let par = 0.25 * (1.0 + rng.sym());
            theta[l.parameters()][0] = par;
            // A previous input inside the window at p, so that the
            // input-move bound leaves a feasible first move.
            theta[l.previous_input()][0] = -par + rng.sym();
            explicit.solve_into(&theta, &mut ze).unwrap();
            qp.solve_into(&theta, &mut zq).unwrap();
            let d = (ze[0] - zq[0]).abs() / (1.0 + zq[0].abs());
            worst = worst.max(d);
            soft += usize::from(zq[3] > 1e-9);
            rate += usize::from((zq[0] - theta[l.previous_input()][0]).abs() > 0.3 - 1e-9);
        }
        assert!(worst < 1e-8, "largest first-move difference {worst:e}");
        // Both the softened and the rate-limited pieces were visited.
        assert!(soft > 0 && rate > 0, "soft {soft}, rate {rate}");
        assert_eq!(explicit.outside(), 0);
    }
}
