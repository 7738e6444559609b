//! The explicit (kestrel-empc, feature `empc`) and fast-gradient
//! (kestrel-fgm, feature `fgm`) solvers of the condensed QP as
//! [`ParametricQpSolver`]s, so [`MpcLaw`](crate::MpcLaw) and the
//! closed-loop simulator fly them like the clarabel reference.

#[cfg(any(feature = "empc", feature = "fgm"))]
use crate::error::MpcError;
#[cfg(any(feature = "empc", feature = "fgm"))]
use crate::law::ParametricQpSolver;
#[cfg(any(feature = "empc", feature = "fgm"))]
use kestrel_core::Error;
#[cfg(any(feature = "empc", feature = "fgm"))]
use kestrel_core::formats::MpqpProblem;

/// The explicit MPC of kestrel-empc: the multi-parametric solution of the
/// QP, stored as a binary search tree over the whole `z`, evaluated by
/// point location (the run-time evaluator `kestrel_empc::evaluate_with`).
///
/// A parameter outside the explored set (the parameter box or the hull of
/// the regions) gets the clamped law of the nearest region, as on the
/// aircraft; [`ExplicitSolver::outside`] counts those calls.
///
/// ```
/// use kestrel_mpc::{ExplicitSolver, ParametricQpSolver, ProblemSize, QpSettings,
///     ReferenceSolver, default_weights, identified_model, tricopter_problem};
/// let (q1, q2) = default_weights();
/// let p = tricopter_problem(&identified_model().unwrap(), ProblemSize::Thesis, q1, q2).unwrap();
/// let mut explicit = ExplicitSolver::build(&p.to_mpqp(), &kestrel_empc::Settings::default()).unwrap();
/// let mut qp = ReferenceSolver::new(&p.to_mpqp(), QpSettings::default()).unwrap();
/// let theta = p.theta(&[0.1, -0.2, 0.3, 0.0, 0.1], &[1.0, -1.0, 0.5, 1500.0]).unwrap();
/// let (mut ze, mut zq) = (vec![0.0; p.n()], vec![0.0; p.n()]);
/// explicit.solve_into(theta.as_slice(), &mut ze).unwrap();
/// qp.solve_into(theta.as_slice(), &mut zq).unwrap();
/// assert!(ze.iter().zip(&zq).all(|(a, b)| (a - b).abs() < 1e-4));
/// ```
#[cfg(feature = "empc")]
#[derive(Clone, Debug)]
pub struct ExplicitSolver {
    tables: kestrel_empc::OwnedTables<f64>,
    scratch: Vec<f64>,
    outside: usize,
    regions: usize,
}

#[cfg(feature = "empc")]
impl ExplicitSolver {
    /// A solver from the tables of an explicit controller over all of `z`
    /// (`kestrel_empc::Outputs::All`).
    pub fn new(tables: kestrel_empc::OwnedTables<f64>) -> Self {
        ExplicitSolver {
            scratch: vec![0.0; tables.n_params],
            tables,
            outside: 0,
            regions: 0,
        }
    }

    /// Solves `problem` multi-parametrically with kestrel-empc and builds
    /// the search tree over all of `z`.
    ///
    /// # Errors
    /// [`MpcError::ExternalSolver`] when the mpQP solve or the tree
    /// construction fails (too many regions, a degenerate problem).
    pub fn build(
        problem: &MpqpProblem,
        settings: &kestrel_empc::Settings,
    ) -> Result<Self, MpcError> {
        let err = |e: kestrel_empc::EmpcError| MpcError::ExternalSolver {
            solver: "explicit MPC",
            reason: e.to_string(),
        };
        let solution = kestrel_empc::solve(problem, settings).map_err(err)?;
        let controller = kestrel_empc::build_controller(
            problem,
            &solution,
            &kestrel_empc::TreeSettings::default(),
        )
        .map_err(err)?;
        let mut s = ExplicitSolver::new(controller.tables);
        s.regions = solution.regions.len();
        Ok(s)
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
    pub fn tables(&self) -> &kestrel_empc::OwnedTables<f64> {
        &self.tables
    }
}

#[cfg(feature = "empc")]
impl ParametricQpSolver for ExplicitSolver {
    fn n(&self) -> usize {
        self.tables.n_outputs
    }
    fn p(&self) -> usize {
        self.tables.n_params
    }
    fn solve_into(&mut self, theta: &[f64], z: &mut [f64]) -> Result<(), Error> {
        let e = kestrel_empc::evaluate_with(&self.tables.tables(), theta, &mut self.scratch, z)?;
        self.outside += usize::from(e.outside);
        Ok(())
    }
}

/// Where each fast-gradient solve starts.
#[cfg(feature = "fgm")]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FgmStart {
    /// From the centre of the box at the current parameter (the start the
    /// cold-start certificate is for).
    #[default]
    Cold,
    /// From the previous step's solution (clamped into the current box);
    /// the first solve starts cold.
    Warm,
    /// From the previous solution shifted by one block (`nu` entries, the
    /// last block repeated), the usual MPC warm start.
    WarmShifted,
}

/// Options of [`FastGradientSolver`].
#[cfg(feature = "fgm")]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FgmOptions {
    /// Fixed number of iterations per solve (after the initial projected
    /// gradient step), as on the aircraft.
    pub iterations: usize,
    /// Where each solve starts.
    pub start: FgmStart,
    /// Preconditioner and momentum of the design.
    pub settings: kestrel_fgm::FgmSettings,
}

#[cfg(feature = "fgm")]
impl Default for FgmOptions {
    /// 12 iterations, cold start, kestrel-fgm's default design.
    fn default() -> Self {
        FgmOptions {
            iterations: 12,
            start: FgmStart::Cold,
            settings: kestrel_fgm::FgmSettings::default(),
        }
    }
}

/// The fast gradient method of kestrel-fgm with a fixed iteration count,
/// in `f64` through the same kernel (`kestrel_fgm::solve_view`) the
/// firmware runs; needs the problem's constraints to be a box on `z`
/// (every MPC problem of this crate is).
///
/// ```
/// use kestrel_mpc::{FastGradientSolver, FgmOptions, ParametricQpSolver, ProblemSize,
///     QpSettings, ReferenceSolver, default_weights, identified_model, tricopter_problem};
/// let (q1, q2) = default_weights();
/// let p = tricopter_problem(&identified_model().unwrap(), ProblemSize::Thesis, q1, q2).unwrap();
/// let opts = FgmOptions { iterations: 200, ..FgmOptions::default() };
/// let mut fgm = FastGradientSolver::new(&p.to_mpqp(), &opts).unwrap();
/// let mut qp = ReferenceSolver::new(&p.to_mpqp(), QpSettings::default()).unwrap();
/// let theta = p.theta(&[0.1, -0.2, 0.3, 0.0, 0.1], &[1.0, -1.0, 0.5, 1500.0]).unwrap();
/// let (mut zf, mut zq) = (vec![0.0; p.n()], vec![0.0; p.n()]);
/// fgm.solve_into(theta.as_slice(), &mut zf).unwrap();
/// qp.solve_into(theta.as_slice(), &mut zq).unwrap();
/// assert!(zf.iter().zip(&zq).all(|(a, b)| (a - b).abs() < 1e-2)); // microseconds
/// ```
#[cfg(feature = "fgm")]
#[derive(Clone, Debug)]
pub struct FastGradientSolver {
    data: kestrel_fgm::FgmData<f64>,
    iterations: usize,
    start: FgmStart,
    nu_shift: usize,
    prev: Vec<f64>,
    start_buf: Vec<f64>,
    work: Vec<f64>,
    has_prev: bool,
}

#[cfg(feature = "fgm")]
impl FastGradientSolver {
    /// Designs the solver for `problem` (conversion to a box QP,
    /// preconditioning) with the given options. Warm starts shift by
    /// `problem`'s first block when it is a [`crate::MpcProblem`]'s
    /// (use [`FastGradientSolver::with_shift`] to set it).
    ///
    /// # Errors
    /// [`MpcError::ExternalSolver`] when the constraints are not a box or
    /// the design fails.
    pub fn new(problem: &MpqpProblem, options: &FgmOptions) -> Result<Self, MpcError> {
        let err = |e: kestrel_fgm::FgmError| MpcError::ExternalSolver {
            solver: "fast gradient",
            reason: e.to_string(),
        };
        let qp = kestrel_fgm::BoxQp::from_mpqp(problem).map_err(err)?;
        let design = kestrel_fgm::FgmDesign::new(qp, options.settings).map_err(err)?;
        Self::from_design(&design, options)
    }

    /// The solver of an existing kestrel-fgm design.
    ///
    /// # Errors
    /// [`MpcError::ExternalSolver`] when the design's tables cannot be formed.
    pub fn from_design(
        design: &kestrel_fgm::FgmDesign,
        options: &FgmOptions,
    ) -> Result<Self, MpcError> {
        let err = |e: kestrel_fgm::FgmError| MpcError::ExternalSolver {
            solver: "fast gradient",
            reason: e.to_string(),
        };
        // The certificate only sizes the momentum table; the iteration
        // count is the caller's.
        let cert = design.certify(1e-6).map_err(err)?;
        let data = design
            .data::<f64>(&cert, Some(options.iterations))
            .map_err(err)?;
        let n = data.n;
        Ok(FastGradientSolver {
            data,
            iterations: options.iterations,
            start: options.start,
            nu_shift: 0,
            prev: vec![0.0; n],
            start_buf: vec![0.0; n],
            work: vec![0.0; 6 * n],
            has_prev: false,
        })
    }

    /// Sets the shift of [`FgmStart::WarmShifted`] (entries of `z` per
    /// first block, i.e. `nu`).
    pub fn with_shift(mut self, nu: usize) -> Self {
        self.nu_shift = nu;
        self
    }

    /// Iterations per solve.
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// Forgets the previous solution (the next solve starts cold).
    pub fn reset(&mut self) {
        self.has_prev = false;
    }
}

#[cfg(feature = "fgm")]
impl ParametricQpSolver for FastGradientSolver {
    fn n(&self) -> usize {
        self.data.n
    }
    fn p(&self) -> usize {
        self.data.p
    }
    fn solve_into(&mut self, theta: &[f64], z: &mut [f64]) -> Result<(), Error> {
        use kestrel_fgm::{Start, WorkspaceMut, shift_into, solve_view};
        let n = self.data.n;
        kestrel_core::check_len(z, n)?;
        let start = match (self.start, self.has_prev) {
            (FgmStart::Cold, _) | (_, false) => Start::Cold,
            (FgmStart::Warm, true) => Start::Warm(&self.prev),
            (FgmStart::WarmShifted, true) => {
                shift_into(&self.prev, self.nu_shift, &mut self.start_buf)?;
                Start::Warm(&self.start_buf)
            }
        };
        let (lo, rest) = self.work.split_at_mut(n);
        let (hi, rest) = rest.split_at_mut(n);
        let (c, rest) = rest.split_at_mut(n);
        let (zs, rest) = rest.split_at_mut(n);
        let (y, w) = rest.split_at_mut(n);
        solve_view(
            &self.data.view(),
            theta,
            start,
            self.iterations,
            WorkspaceMut {
                lo,
                hi,
                c,
                z: zs,
                y,
                w,
            },
            z,
        )?;
        self.prev.copy_from_slice(z);
        self.has_prev = true;
        Ok(())
    }
}

#[cfg(all(test, feature = "empc", feature = "fgm"))]
mod tests {
    use super::*;
    use crate::sim::{RunResult, RunSettings, fly_mpc};
    use crate::{
        MpcLaw, MpcProblem, ProblemSize, QpSettings, default_weights, identified_model,
        tricopter_problem,
    };

    fn thesis() -> (kestrel_core::formats::SsModel, MpcProblem) {
        let model = identified_model().unwrap();
        let (q1, q2) = default_weights();
        let problem = tricopter_problem(&model, ProblemSize::Thesis, q1, q2).unwrap();
        (model, problem)
    }

    fn qp_run(settings: &RunSettings) -> RunResult {
        let (model, problem) = thesis();
        let mut law = MpcLaw::clarabel(
            &problem,
            QpSettings {
                kkt_tolerance: Some(1e-7),
                ..QpSettings::default()
            },
        )
        .unwrap();
        fly_mpc(&model, &problem, &mut law, settings).unwrap()
    }

    /// Largest pulse difference between two runs (us).
    fn max_pwm_diff(a: &RunResult, b: &RunResult) -> f64 {
        a.trace
            .rows
            .iter()
            .zip(&b.trace.rows)
            .flat_map(|(r, s)| (0..4).map(move |i| (r.pwm[i] - s.pwm[i]).abs()))
            .fold(0.0, f64::max)
    }

    #[test]
    fn explicit_law_flies_the_qp_law() {
        let (model, problem) = thesis();
        let mut law = MpcLaw::explicit(&problem, &kestrel_empc::Settings::default()).unwrap();
        for settings in [RunSettings::default(), RunSettings::noisy()] {
            let qp = qp_run(&settings);
            let ex = fly_mpc(&model, &problem, &mut law, &settings).unwrap();
            let d = max_pwm_diff(&qp, &ex);
            let dj = qp
                .trace
                .rows
                .iter()
                .zip(&ex.trace.rows)
                .map(|(r, s)| (r.cost - s.cost).abs() / r.cost.abs().max(1.0))
                .fold(0.0, f64::max);
            eprintln!(
                "explicit vs QP: {} regions, {} of {} steps outside the explored set, max |pwm diff| {d:.2e} us, max rel |J diff| {dj:.2e}",
                law.solver().regions(),
                law.solver().outside(),
                ex.trace.rows.len()
            );
            assert!(law.solver().regions() > 1);
            // Same law: the same pulses and costs to solver precision.
            assert!(d < 1e-3, "{d}");
            assert!(dj < 1e-6, "{dj}");
        }
        // Wrong lengths and NaN parameters give errors, not panics.
        let ex = law.solver_mut();
        let mut z = vec![0.0; problem.n()];
        let mut theta = vec![0.0; problem.p()];
        theta[0] = f64::NAN;
        assert!(ex.solve_into(&theta, &mut z).is_err());
        assert!(ex.solve_into(&[0.0; 3], &mut z).is_err());
    }

    #[test]
    fn fast_gradient_approaches_the_qp_law_with_more_iterations() {
        let (model, problem) = thesis();
        let settings = RunSettings::default();
        let qp = qp_run(&settings);
        let mut last = f64::INFINITY;
        for iterations in [2, 12, 50, 400] {
            let mut diffs = Vec::new();
            for start in [FgmStart::Cold, FgmStart::Warm, FgmStart::WarmShifted] {
                let opts = FgmOptions {
                    iterations,
                    start,
                    ..FgmOptions::default()
                };
                let mut law = MpcLaw::fast_gradient(&problem, &opts).unwrap();
                let run = fly_mpc(&model, &problem, &mut law, &settings).unwrap();
                // Always inside the bounds, whatever the iteration count.
                assert!(run.metrics.max_bound_violation <= 0.0);
                diffs.push(max_pwm_diff(&qp, &run));
            }
            eprintln!(
                "FGM {iterations} iterations: max |pwm - pwm_QP| cold/warm/shifted {diffs:?} us"
            );
            assert!(diffs[0] <= last, "{iterations}: {} > {last}", diffs[0]);
            last = diffs[0];
        }
        assert!(last < 0.1, "{last}");
    }

    #[test]
    fn solver_errors_are_values() {
        // An mpQP whose constraints are not a box is refused by the fast gradient.
        let (_, problem) = thesis();
        let mut mp = problem.to_mpqp();
        mp.g[(0, 1)] = 1.0;
        let e = FastGradientSolver::new(&mp, &FgmOptions::default()).unwrap_err();
        assert!(matches!(e, MpcError::ExternalSolver { .. }), "{e}");
        // Wrong lengths and NaN parameters give errors, not panics.
        let mut fgm = FastGradientSolver::new(&problem.to_mpqp(), &FgmOptions::default()).unwrap();
        let mut z = vec![0.0; problem.n()];
        assert!(fgm.solve_into(&[0.0; 3], &mut z).is_err());
        let mut theta = vec![0.0; problem.p()];
        theta[0] = f64::NAN;
        assert!(fgm.solve_into(&theta, &mut z).is_err());
    }
}
