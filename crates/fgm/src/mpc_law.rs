//! The fast gradient method as a solver of kestrel-mpc's condensed QP, so
//! `kestrel_mpc::MpcLaw` and closed-loop simulations fly it like the
//! clarabel reference.

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
/// firmware runs; needs the problem's constraints to be a box on `z`
/// (every `kestrel_mpc::MpcProblem`'s are).
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

    /// The fast-gradient MPC law of `problem` with a fixed iteration count;
    /// [`FgmStart::WarmShifted`] shifts by one input move (`nu`) (formerly
    /// `kestrel_mpc::MpcLaw::fast_gradient`).
    ///
    /// # Errors
    /// As [`FastGradientSolver::new`].
    pub fn mpc_law(problem: &MpcProblem, options: &FgmOptions) -> Result<FgmMpc, MpcError> {
        let solver = Self::new(&problem.to_mpqp(), options)?.with_shift(problem.nu);
        MpcLaw::new(problem, solver)
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
    use kestrel_mpc::{Bounds, MpcSettings, QpSettings, Terminal, Weight};
    use nalgebra::dvector;

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
}
