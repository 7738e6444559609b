//! The fast gradient method as a solver of kestrel-mpc's condensed QP, so
//! `kestrel_mpc::MpcLaw` and closed-loop simulations fly it like the
//! clarabel reference.

mod refusal;

use crate::BoxQp;
use crate::{
    FgmData, FgmDesign, FgmError, FgmSettings, Start, WorkspaceMut, shift_into, solve_view,
};
use kestrel_core::Error;
use kestrel_core::formats::MpqpProblem;
use kestrel_mpc::{MpcError, MpcLaw, MpcProblem, ParametricQpSolver};

/// The MPC law with the fast gradient method ([`FastGradientSolver`]).
pub type FgmMpc = MpcLaw<FastGradientSolver>;

/// Where each fast-gradient solve starts.
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
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FgmOptions {
    /// Fixed number of iterations per solve (after the initial projected
    /// gradient step), as on the aircraft.
    pub iterations: usize,
    /// Where each solve starts.
    pub start: FgmStart,
    /// Preconditioner and momentum of the design.
    pub settings: FgmSettings,
}

impl Default for FgmOptions {
    /// 12 iterations, cold start, kestrel-fgm's default design.
    fn default() -> Self {
        FgmOptions {
            iterations: 12,
            start: FgmStart::Cold,
            settings: FgmSettings::default(),
        }
    }
}

/// The fast gradient method of kestrel-fgm with a fixed iteration count,
/// in `f64` through the same kernel ([`solve_view`]) the
/// firmware runs; needs the problem's constraints to be a box on `z` that
/// moves affinely with `theta`: every row of `G` a bound on one decision
/// variable, each variable bounded on both sides (several bounds on one
/// side only when one is the tighter for every `theta`). Of an MPC's
/// constraints that is the input bounds (parameter-dependent or not) and,
/// with a single input block, the bounds on the first input move; soft
/// constraints, later input moves and output or state bounds beyond the
/// first step couple several variables and are refused
/// ([`FastGradientSolver::for_problem`] names the constraint).
///
/// ```
/// use kestrel_core::{Matrix, StateSpace};
/// use kestrel_fgm::{FastGradientSolver, FgmOptions};
/// use kestrel_mpc::{Bounds, MpcProblem, MpcSettings, ParametricQpSolver, QpSettings,
///     ReferenceSolver, Terminal};
/// use nalgebra::dvector;
/// // A double integrator sampled at 0.1 s, |u| <= 1, horizon 5.
/// let m = StateSpace::new(Matrix::from_rows([[1.0, 0.1], [0.0, 1.0]]),
///     Matrix::from_rows([[0.005], [0.1]]), Matrix::from_rows([[1.0, 0.0]]),
///     Matrix::from_rows([[0.0]]), 0.1);
/// let p = MpcProblem::build(&m, &MpcSettings { horizon: 5, terminal: Terminal::Lq,
///     input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0])), ..MpcSettings::default() }).unwrap();
/// let opts = FgmOptions { iterations: 500, ..FgmOptions::default() };
/// let mut fgm = FastGradientSolver::new(&p.to_mpqp(), &opts).unwrap();
/// let mut qp = ReferenceSolver::new(&p.to_mpqp(), QpSettings::default()).unwrap();
/// let theta = p.theta(&[0.2, -0.1], &[0.5]).unwrap();
/// let (mut zf, mut zq) = (vec![0.0; p.n()], vec![0.0; p.n()]);
/// fgm.solve_into(theta.as_slice(), &mut zf).unwrap();
/// qp.solve_into(theta.as_slice(), &mut zq).unwrap();
/// assert!(zf.iter().zip(&zq).all(|(a, b)| (a - b).abs() < 1e-3));
/// ```
#[derive(Clone, Debug)]
pub struct FastGradientSolver {
    data: FgmData<f64>,
    iterations: usize,
    start: FgmStart,
    nu_shift: usize,
    prev: Vec<f64>,
    start_buf: Vec<f64>,
    work: Vec<f64>,
    has_prev: bool,
}

impl FastGradientSolver {
    /// Designs the solver for `problem` (conversion to a box QP,
    /// preconditioning) with the given options. Warm starts shift by
    /// `with_shift`'s entries, none unless set
    /// ([`FastGradientSolver::with_shift`]; [`FastGradientSolver::mpc_law`]
    /// sets it to the problem's `nu`).
    ///
    /// # Errors
    /// [`MpcError::ExternalSolver`] when the constraints are not a box or
    /// the design fails.
    pub fn new(problem: &MpqpProblem, options: &FgmOptions) -> Result<Self, MpcError> {
        let err = |e: FgmError| MpcError::ExternalSolver {
            solver: "fast gradient",
            reason: e.to_string(),
        };
        let qp = BoxQp::from_mpqp(problem).map_err(err)?;
        let design = FgmDesign::new(qp, options.settings).map_err(err)?;
        Self::from_design(&design, options)
    }

    /// The solver of an existing kestrel-fgm design.
    ///
    /// # Errors
    /// [`MpcError::ExternalSolver`] when the design's tables cannot be formed.
    pub fn from_design(design: &FgmDesign, options: &FgmOptions) -> Result<Self, MpcError> {
        let err = |e: FgmError| MpcError::ExternalSolver {
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

    /// Designs the solver for an MPC `problem` as [`FastGradientSolver::new`]
    /// does for its QP, the warm-start shift set to one input move (`nu`);
    /// a refusal names the MPC's constraint or input at fault
    /// ([`MpcProblem::row_label`]).
    ///
    /// ```
    /// use kestrel_core::{Matrix, StateSpace};
    /// use kestrel_fgm::{FastGradientSolver, FgmOptions};
    /// use kestrel_mpc::{Bounds, MpcProblem, MpcSettings};
    /// use nalgebra::dvector;
    /// let m = StateSpace::new(Matrix::from_rows([[1.0, 0.1], [0.0, 1.0]]),
    ///     Matrix::from_rows([[0.005], [0.1]]), Matrix::from_rows([[1.0, 0.0]]),
    ///     Matrix::from_rows([[0.0]]), 0.1);
    /// let inputs = Bounds::new(dvector![-1.0], dvector![1.0]);
    /// let boxed = MpcSettings { horizon: 5, input_bounds: Some(inputs.clone()), ..MpcSettings::default() };
    /// assert!(FastGradientSolver::for_problem(&MpcProblem::build(&m, &boxed).unwrap(),
    ///     &FgmOptions::default()).is_ok());
    /// // A bound on the position two steps ahead couples the first two inputs.
    /// let limited = MpcSettings { output_bounds: Some(Bounds::new(dvector![-2.0], dvector![2.0])), ..boxed };
    /// let e = FastGradientSolver::for_problem(&MpcProblem::build(&m, &limited).unwrap(),
    ///     &FgmOptions::default()).unwrap_err();
    /// assert!(e.to_string().contains("output 0 upper bound at step 2 is not a bound on one decision variable"), "{e}");
    /// ```
    ///
    /// # Errors
    /// [`MpcError::ExternalSolver`] when the constraints are not a box
    /// (naming the constraint) or the design fails.
    pub fn for_problem(problem: &MpcProblem, options: &FgmOptions) -> Result<Self, MpcError> {
        let err = |e: FgmError| MpcError::ExternalSolver {
            solver: "fast gradient",
            reason: refusal::describe(&e, problem),
        };
        let qp = BoxQp::from_mpqp(&problem.to_mpqp()).map_err(err)?;
        let design = FgmDesign::new(qp, options.settings).map_err(err)?;
        Ok(Self::from_design(&design, options)?.with_shift(problem.nu))
    }

    /// The fast-gradient MPC law of `problem` with a fixed iteration count;
    /// [`FgmStart::WarmShifted`] shifts by one input move (`nu`) (formerly
    /// `kestrel_mpc::MpcLaw::fast_gradient`).
    ///
    /// # Errors
    /// As [`FastGradientSolver::for_problem`].
    pub fn mpc_law(problem: &MpcProblem, options: &FgmOptions) -> Result<FgmMpc, MpcError> {
        MpcLaw::new(problem, Self::for_problem(problem, options)?)
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

impl ParametricQpSolver for FastGradientSolver {
    fn n(&self) -> usize {
        self.data.n
    }
    fn p(&self) -> usize {
        self.data.p
    }
    fn solve_into(&mut self, theta: &[f64], z: &mut [f64]) -> Result<(), Error> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel_core::{ControlLaw, Matrix, StateSpace};
    use kestrel_mpc::{
        Blocking, Bounds, InputTarget, MpcSettings, Parameter, QpSettings, ReferenceSolver,
        SoftPenalty, Terminal, Weight,
    };
    use nalgebra::{dmatrix, dvector};

    /// A lightly damped oscillator with two inputs, |u| <= 0.5, horizon 4.
    fn problem() -> MpcProblem {
        let m = StateSpace::new(
            Matrix::from_rows([[0.95, 0.2], [-0.2, 0.95]]),
            Matrix::from_rows([[0.1, 0.0], [0.0, 0.1]]),
            Matrix::from_rows([[1.0, 0.0], [0.0, 1.0]]),
            Matrix::from_rows([[0.0, 0.0], [0.0, 0.0]]),
            0.05,
        );
        let settings = MpcSettings {
            horizon: 4,
            q2: Weight::Scalar(0.05),
            terminal: Terminal::Lq,
            input_bounds: Some(Bounds::new(dvector![-0.5, -0.5], dvector![0.5, 0.5])),
            ..MpcSettings::default()
        };
        MpcProblem::build(&m, &settings).unwrap()
    }

    /// Largest input difference to the QP law over a closed loop of the
    /// linear model (the QP law's trajectory, so every law sees the same
    /// states).
    fn max_diff(p: &MpcProblem, law: &mut FgmMpc) -> f64 {
        let mut qp = MpcLaw::clarabel(p, QpSettings::default()).unwrap();
        // The model of `problem()`.
        let a = nalgebra::dmatrix![0.95, 0.2; -0.2, 0.95];
        let b = nalgebra::DMatrix::<f64>::identity(2, 2) * 0.1;
        let mut x = dvector![2.0, -1.5];
        let r = [0.3, -0.2];
        let (mut uf, mut uq) = ([0.0; 2], [0.0; 2]);
        let mut worst: f64 = 0.0;
        for _ in 0..40 {
            law.control(x.as_slice(), &r, &mut uf).unwrap();
            qp.control(x.as_slice(), &r, &mut uq).unwrap();
            for i in 0..2 {
                // Always inside the bounds, whatever the iteration count.
                assert!(uf[i].abs() <= 0.5 + 1e-12, "{uf:?}");
                worst = worst.max((uf[i] - uq[i]).abs());
            }
            x = &a * &x + &b * nalgebra::DVector::from_column_slice(&uq);
        }
        worst
    }

    #[test]
    fn fast_gradient_approaches_the_qp_law_with_more_iterations() {
        let p = problem();
        let mut last = f64::INFINITY;
        for iterations in [1, 5, 30, 300] {
            let mut diffs = Vec::new();
            for start in [FgmStart::Cold, FgmStart::Warm, FgmStart::WarmShifted] {
                let opts = FgmOptions {
                    iterations,
                    start,
                    ..FgmOptions::default()
                };
                let mut law = FastGradientSolver::mpc_law(&p, &opts).unwrap();
                diffs.push(max_diff(&p, &mut law));
            }
            assert!(diffs[0] <= last, "{iterations}: {} > {last}", diffs[0]);
            last = diffs[0];
        }
        assert!(last < 1e-6, "{last}");
    }

    #[test]
    fn solver_errors_are_values() {
        // An mpQP whose constraints are not a box is refused.
        let p = problem();
        let mut mp = p.to_mpqp();
        mp.g[(0, 1)] = 1.0;
        let e = FastGradientSolver::new(&mp, &FgmOptions::default()).unwrap_err();
        assert!(matches!(e, MpcError::ExternalSolver { .. }), "{e}");
        // Wrong lengths and NaN parameters give errors, not panics.
        let mut fgm = FastGradientSolver::new(&p.to_mpqp(), &FgmOptions::default()).unwrap();
        let mut z = vec![0.0; p.n()];
        assert!(fgm.solve_into(&[0.0; 3], &mut z).is_err());
        let mut theta = vec![0.0; p.p()];
        theta[0] = f64::NAN;
        assert!(fgm.solve_into(&theta, &mut z).is_err());
    }

    /// The double integrator of the doc example with `settings`.
    fn integrator(settings: MpcSettings) -> MpcProblem {
        let m = StateSpace::new(
            Matrix::from_rows([[1.0, 0.1], [0.0, 1.0]]),
            Matrix::from_rows([[0.005], [0.1]]),
            Matrix::from_rows([[1.0, 0.0]]),
            Matrix::from_rows([[0.0]]),
            0.1,
        );
        MpcProblem::build(&m, &settings).unwrap()
    }

    /// Largest difference of the fast gradient method's `z` (many
    /// iterations) to the reference's over parameters along a curve
    /// through the parameter box.
    fn max_diff_to_reference(p: &MpcProblem) -> f64 {
        let opts = FgmOptions {
            iterations: 3000,
            ..FgmOptions::default()
        };
        let mut fgm = FastGradientSolver::for_problem(p, &opts).unwrap();
        let mut qp = ReferenceSolver::new(&p.to_mpqp(), QpSettings::default()).unwrap();
        let (mut zf, mut zq) = (vec![0.0; p.n()], vec![0.0; p.n()]);
        let mut worst: f64 = 0.0;
        for k in 0..40 {
            let theta: Vec<f64> = (0..p.p())
                .map(|i| {
                    let s = (0.37 * k as f64 * (1.0 + i as f64)).sin();
                    let (lo, hi) = (p.theta_lb[i], p.theta_ub[i]);
                    0.5 * (lo + hi) + 0.45 * (hi - lo) * s
                })
                .collect();
            fgm.solve_into(&theta, &mut zf).unwrap();
            qp.solve_into(&theta, &mut zq).unwrap();
            for (a, b) in zf.iter().zip(&zq) {
                worst = worst.max((a - b).abs());
            }
        }
        worst
    }

    #[test]
    fn takes_what_is_a_box_after_condensing() {
        // Input bounds moving with a parameter, u in [-1 - p, 1 - p], and a
        // fixed input target (a constant linear term q).
        let shifted = integrator(MpcSettings {
            horizon: 4,
            terminal: Terminal::Lq,
            input_target: InputTarget::Fixed(dvector![0.2]),
            input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0]).shifted(dmatrix![-1.0])),
            parameters: vec![Parameter::new("p", 0.0, 0.5)],
            ..MpcSettings::default()
        });
        assert!(shifted.q.iter().any(|v| *v != 0.0), "{}", shifted.q);
        let d = max_diff_to_reference(&shifted);
        assert!(d < 1e-6, "{d:e}");
        // One input block: its only move bound is a box around the
        // previous input (in theta), bounded on both sides without input
        // bounds.
        let rate = integrator(MpcSettings {
            horizon: 5,
            blocking: Some(Blocking::new(vec![5]).unwrap()),
            du_weight: Some(Weight::Scalar(0.1)),
            du_bounds: Some(Bounds::new(dvector![-0.2], dvector![0.2])),
            ..MpcSettings::default()
        });
        let d = max_diff_to_reference(&rate);
        assert!(d < 1e-6, "{d:e}");
        // The law keeps the move bound in closed loop (it remembers the
        // input it applied).
        let mut law = FastGradientSolver::mpc_law(&rate, &FgmOptions::default()).unwrap();
        let (mut x, mut u, mut last) = (dvector![1.0, 0.0], [0.0], 0.0);
        let a = nalgebra::dmatrix![1.0, 0.1; 0.0, 1.0];
        let b = dvector![0.005, 0.1];
        for k in 0..30 {
            law.control(x.as_slice(), &[0.0], &mut u).unwrap();
            assert!(
                (u[0] - last).abs() <= 0.2 + 1e-12,
                "{k}: {} after {last}",
                u[0]
            );
            last = u[0];
            x = &a * &x + &b * u[0];
        }
    }

    /// The reason of the fast gradient method's refusal of `p`.
    fn refusal(p: &MpcProblem) -> String {
        match FastGradientSolver::for_problem(p, &FgmOptions::default()) {
            Err(MpcError::ExternalSolver {
                solver: "fast gradient",
                reason,
            }) => reason,
            other => panic!("not refused as expected: {other:?}"),
        }
    }

    #[test]
    fn refuses_the_rest_naming_the_constraint() {
        let inputs = Some(Bounds::new(dvector![-1.0], dvector![1.0]));
        let base = MpcSettings {
            horizon: 3,
            input_bounds: inputs.clone(),
            ..MpcSettings::default()
        };
        // Soft output bounds: each row couples moves and a slack.
        let soft = integrator(MpcSettings {
            output_bounds: Some(
                Bounds::new(dvector![-2.0], dvector![2.0]).with_soft(SoftPenalty::default()),
            ),
            ..base.clone()
        });
        let e = refusal(&soft);
        assert!(
            e.starts_with(
                "output 0 upper bound at step 1 (soft) is not a bound on one decision variable"
            ) && e.ends_with("use the explicit or the reference solver"),
            "{e}"
        );
        // Input moves after the first couple two moves.
        let rate = integrator(MpcSettings {
            du_bounds: Some(Bounds::new(dvector![-0.2], dvector![0.2])),
            ..base.clone()
        });
        let e = refusal(&rate);
        assert!(
            e.starts_with("input move du 0 upper bound at step 1 is not a bound on one"),
            "{e}"
        );
        // With one block the first move's bound is on one variable, but it
        // and the input bound are two upper bounds neither of which is the
        // tighter for every previous input: not a box affine in theta.
        let crossing = integrator(MpcSettings {
            blocking: Some(Blocking::new(vec![3]).unwrap()),
            du_bounds: Some(Bounds::new(dvector![-0.2], dvector![0.2])),
            ..base.clone()
        });
        let e = refusal(&crossing);
        assert!(
            e.starts_with("the input 0 lower bound at step 0 and the input move du 0 lower bound at step 0 both bound input 0 at step 0 from below"),
            "{e}"
        );
        // An input without a lower bound (its row is left out).
        let open = integrator(MpcSettings {
            input_bounds: Some(Bounds::new(dvector![f64::NEG_INFINITY], dvector![1.0])),
            ..base
        });
        let e = refusal(&open);
        assert!(e.starts_with("input 0 at step 0 has no lower bound"), "{e}");
    }
}
