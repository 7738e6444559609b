//! Design time: preconditioning, folding, certification; the rounding
//! analysis of low-precision solves is in [`rounding`].

mod rounding;

use crate::precond::{Preconditioner, Preconditioning, Spectrum, precondition, scale_hessian};
use crate::runtime::{FgmTables, FgmView, Start, WorkspaceMut, solve_view};
use crate::{BoxQp, FgmError};
use kestrel_core::{Matrix, Scalar};
use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// How the momentum `beta_i` is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Momentum {
    /// The scheme with the smaller certified iteration count.
    #[default]
    Auto,
    /// `alpha_0 = sqrt(mu/L)`: constant `beta = (1 - sqrt(mu/L)) / (1 + sqrt(mu/L))`
    /// (needs `mu > 0`); certified by the linear rate only.
    Constant,
    /// `alpha_0` such that `gamma_0 = L`: a precomputed `beta_i` table
    /// (errata: `beta_i = alpha_i (1 - alpha_i) / (alpha_i^2 + alpha_{i+1})`);
    /// certified by both the linear and the `4 / (i + 2)^2` rate.
    Table,
}

/// The momentum scheme a certificate is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MomentumScheme {
    /// One constant `beta`.
    Constant,
    /// A `beta_i` table.
    Table,
}

impl MomentumScheme {
    /// The name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            MomentumScheme::Constant => "constant",
            MomentumScheme::Table => "table",
        }
    }
}

/// Settings of [`FgmDesign::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FgmSettings {
    /// The diagonal preconditioner.
    pub preconditioner: Preconditioner,
    /// The momentum scheme.
    pub momentum: Momentum,
    /// Largest magnitude of any scaled intermediate quantity (iterates,
    /// extrapolations, `M y + c`); the overall scale of `D` is chosen to
    /// reach it, which uses the range of fixed point well. 8192 leaves a
    /// factor 4 of headroom in `Q16`.
    pub scaled_range: f64,
}

impl Default for FgmSettings {
    fn default() -> Self {
        FgmSettings {
            preconditioner: Preconditioner::default(),
            momentum: Momentum::default(),
            scaled_range: 8192.0,
        }
    }
}

/// A cold-start certificate (Richter, Jones, Morari, IEEE TAC 2012, with a
/// tighter initial bound).
///
/// A cold solve starts at the box centre `s` and takes one projected
/// gradient step; then, for any optimum `z*`,
/// `f(z_0) - f* + L/2 |z_0 - z*|^2 <= 1/2 (s - z*)'(L I - H_s)(s - z*) <= Delta`
/// (scaled units; [`FgmDesign::delta`]), and Nesterov's constant-step
/// scheme gives `f(z_i) - f* <= lambda_i Delta` with
/// `lambda_i <= (1 - sqrt(mu/L))^i` and, for `gamma_0 = L` (the table
/// scheme), `lambda_i <= 4 / (i + 2)^2`. Richter's
/// `Delta = L/2 * max_theta diam(box)^2` (for a start anywhere in the box)
/// is kept in `delta_richter` for comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct Certificate {
    /// The tolerance on `J(z) - J*`.
    pub eps: f64,
    /// Lipschitz constant of the scaled gradient.
    pub l: f64,
    /// Strong convexity of the scaled problem.
    pub mu: f64,
    /// `L / mu`.
    pub condition: f64,
    /// The `Delta` the count is certified for (the cold one, or a warm one).
    pub delta: f64,
    /// Squared diameter of the scaled box, maximised over the parameter box.
    pub diameter_sq: f64,
    /// `L/2 * squared diameter`: Richter, Jones and Morari's `Delta` for a
    /// start anywhere in the box, for comparison with `delta`.
    pub delta_richter: f64,
    /// `ceil(ln(eps/Delta) / ln(1 - sqrt(mu/L)))` (`None` if `mu = 0` or
    /// if it exceeds [`MAX_ITERATION_BOUND`]).
    pub linear_bound: Option<usize>,
    /// `ceil(2 sqrt(Delta/eps) - 2)`, or `None` when that exceeds
    /// [`MAX_ITERATION_BOUND`] (a tolerance far below what the method can
    /// certify), never a saturated `usize::MAX`.
    pub sublinear_bound: Option<usize>,
    /// The scheme the iteration count is for.
    pub scheme: MomentumScheme,
    /// Certified iterations after the initial step.
    pub iterations: usize,
}

/// The largest iteration bound a [`Certificate`] reports (`2^53`, the
/// largest count every `f64` and JSON number holds exactly); a bound beyond
/// it is `None`, and a tolerance with neither bound within it is
/// [`FgmError::NoIterationBound`].
pub const MAX_ITERATION_BOUND: usize = 1 << 53;

/// An iteration bound from its real value: `None` beyond [`MAX_ITERATION_BOUND`].
fn iteration_bound(k: f64) -> Option<usize> {
    let k = k.ceil().max(0.0);
    (k <= MAX_ITERATION_BOUND as f64).then_some(k as usize)
}

/// Which decision variables an input tolerance is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AppliedInputs {
    /// Every decision variable (all blocked moves).
    All,
    /// The first `nu` variables: the move applied to the aircraft (the
    /// first block of an MPC problem).
    FirstMove(usize),
}

/// The tolerance on `J - J*` that keeps the selected inputs within
/// `max_error` of the optimum (see [`FgmDesign::input_tolerance`]).
#[derive(Clone, Debug, PartialEq)]
pub struct InputTolerance {
    /// The allowed input error (in the problem's units).
    pub max_error: f64,
    /// `eps = max_error^2 / (2 max_j (H^-1)_jj)` over the selected `j`.
    pub eps: f64,
    /// The variable with the largest `(H^-1)_jj` (the binding one).
    pub worst_variable: usize,
    /// That largest diagonal entry of `H^-1`.
    pub h_inv_diag: f64,
    /// The cruder `mu_H / 2 * max_error^2` (all variables, from the
    /// smallest eigenvalue), for comparison: never larger than `eps`.
    pub eps_eigenvalue: f64,
}

/// What a warm start may assume about the previous solve.
#[derive(Clone, Debug, PartialEq)]
pub struct WarmStartAssumption {
    /// The previous solution was `prev_eps`-optimal for the previous parameter.
    pub prev_eps: f64,
    /// Largest change of each parameter between two solves, `p` entries.
    pub theta_step: DVector<f64>,
}

/// A warm-start certificate for starting from the previous solution.
///
/// With box widths independent of `theta` (`Lo = Hi`), the solution map is
/// Lipschitz: writing `v = lo(theta) + x`, `x` lives in a fixed box and its
/// linear term moves with `Q theta`, `Q = D F' + D H D Lo`; the solution is
/// the `H_s`-norm projection of `-H_s^-1 q`, which is nonexpansive in that
/// norm, so `|v*(theta_1) - v*(theta_2)| <= sum_j |theta_1 - theta_2|_j
/// (|Lo e_j| + |H_s^-1/2 Q e_j| / sqrt(mu))`. The previous solution is within
/// `sqrt(2 prev_eps / mu)` of its own optimum, so the start is within
/// `r = sqrt(2 prev_eps / mu) + lipschitz-term` of the new optimum and
/// `Delta_warm = (L - mu)/2 r^2` (as `L I - H_s <= (L - mu) I`). When the
/// widths vary with `theta`, or the start is shifted, the warm bound falls
/// back to a start anywhere in the box: `|s - z*|_j <= w_j`, four times the
/// cold `Delta` (which is for the box centre).
///
/// The warm bound can therefore be *longer* than the cold one (a start
/// anywhere is worse than the centre). Each certificate covers only its own
/// start, so the run-time should start warm only when that pays:
/// [`WarmCertificate::recommended`] says which start to use and
/// [`WarmCertificate::recommended_iterations`] how many iterations that
/// start needs; it never exceeds the cold count.
#[derive(Clone, Debug, PartialEq)]
pub struct WarmCertificate {
    /// The cold certificate it refines.
    pub cold: Certificate,
    /// Whether the Lipschitz argument applied (`Lo = Hi`, no shift).
    pub refined: bool,
    /// Bound on the distance of the start from the new optimum (scaled units).
    pub radius: f64,
    /// `min((L - mu)/2 r^2, 4 Delta_cold)`.
    pub delta: f64,
    /// Certified iterations after the initial step, starting from the
    /// (shifted) previous solution.
    pub iterations: usize,
}

/// Which start a fixed-iteration solver should use, given both certificates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecommendedStart {
    /// Start from the previous solution: its certificate is shorter.
    Warm,
    /// Start at the box centre: the warm certificate is not shorter.
    Cold,
}

impl RecommendedStart {
    /// `"warm"` or `"cold"`, for JSON output.
    pub fn name(self) -> &'static str {
        match self {
            RecommendedStart::Warm => "warm",
            RecommendedStart::Cold => "cold",
        }
    }
}

impl WarmCertificate {
    /// The start to use: warm only when its certificate is strictly shorter.
    pub fn recommended(&self) -> RecommendedStart {
        if self.iterations < self.cold.iterations {
            RecommendedStart::Warm
        } else {
            RecommendedStart::Cold
        }
    }

    /// The certified iterations of the [`recommended`](Self::recommended)
    /// start: `min(warm, cold)`, each valid for its own start only.
    pub fn recommended_iterations(&self) -> usize {
        match self.recommended() {
            RecommendedStart::Warm => self.iterations,
            RecommendedStart::Cold => self.cold.iterations,
        }
    }
}

/// A bound on how far a solve in a lower-precision scalar can be from
/// exact arithmetic, after `iterations` constant-momentum iterations.
///
/// Every rounding (stored tables, the parameter, dot products, the
/// momentum update) is bounded by the standard model `|fl(x) - x| <= u|x| + a`
/// (floats: `u` = unit roundoff, `a` = 0; fixed point: `u = 0`, `a` = half
/// a least significant bit, dot products rounded once) with the magnitudes
/// that the box and the parameter box allow, and folded into a gradient
/// error `|e_i| <= E`. The box tables are shrunk inwards by the bound on
/// their own rounding, so every iterate stays feasible. Then (Schmidt, Le
/// Roux, Bach 2011, accelerated inexact proximal gradient, strongly convex
/// case) with `rho = 1 - sqrt(mu/L)`:
/// `sqrt(J - J*_shrunk) <= sqrt(2 Delta' rho^k) + sqrt(2/mu) E sum_{j<k} rho^{j/2}`,
/// `Delta' = Delta + E diam`, and the shrunk box costs at most
/// `G delta + L/2 delta^2` more than the true one. The output `z = D v` adds
/// its own rounding.
#[derive(Clone, Debug, PartialEq)]
pub struct RoundingBound {
    /// The scalar: `"f32"`, `"f64"` or `"Q16"`-like names.
    pub scalar: &'static str,
    /// Bound on the gradient error per iteration (scaled units, 2-norm).
    pub gradient_error: f64,
    /// Inward shrink of each bound (scaled units, max over variables).
    pub box_shrink: f64,
    /// Bound on `J(z_S) - J*` after the certified iterations.
    pub cost_bound: f64,
    /// Bound on `|z_S - z_f64|_2` (problem units) when both ran the
    /// certified iterations (`z_f64` being `eps`-optimal).
    pub distance_bound: f64,
}

/// Solver data with run-time dimensions (see [`FgmTables`] for the fields).
#[derive(Clone, Debug, PartialEq)]
pub struct FgmData<S> {
    /// Number of decision variables.
    pub n: usize,
    /// Number of parameters.
    pub p: usize,
    /// `M`, row-major.
    pub m: Vec<S>,
    /// `K`, row-major.
    pub k_theta: Vec<S>,
    /// `k0`.
    pub k0: Vec<S>,
    /// Lower bound map, row-major.
    pub lo_theta: Vec<S>,
    /// Lower bound offset.
    pub lo0: Vec<S>,
    /// Upper bound map, row-major.
    pub hi_theta: Vec<S>,
    /// Upper bound offset.
    pub hi0: Vec<S>,
    /// Scaling.
    pub d: Vec<S>,
    /// Inverse scaling.
    pub d_inv: Vec<S>,
    /// Momentum table.
    pub betas: Vec<S>,
    /// Certified cold-start iterations.
    pub iterations: usize,
    /// Certified warm-start iterations.
    pub warm_iterations: usize,
    /// Warm-start shift.
    pub shift: usize,
}

impl<S: Scalar> FgmData<S> {
    /// The flattened view the kernel works on.
    pub fn view(&self) -> FgmView<'_, S> {
        FgmView {
            n: self.n,
            p: self.p,
            m: &self.m,
            k_theta: &self.k_theta,
            k0: &self.k0,
            lo_theta: &self.lo_theta,
            lo0: &self.lo0,
            hi_theta: &self.hi_theta,
            hi0: &self.hi0,
            d: &self.d,
            d_inv: &self.d_inv,
            betas: &self.betas,
        }
    }

    /// Solves with `iterations` iterations from `start` (allocates its
    /// workspace: for design-time use; the firmware uses [`FgmTables`]).
    ///
    /// # Errors
    /// As [`solve_view`].
    pub fn solve(
        &self,
        theta: &[S],
        start: Start<'_, S>,
        iterations: usize,
    ) -> Result<Vec<S>, kestrel_core::Error> {
        let n = self.n;
        let mut buf = vec![S::ZERO; 6 * n];
        let mut out = vec![S::ZERO; n];
        let (lo, rest) = buf.split_at_mut(n);
        let (hi, rest) = rest.split_at_mut(n);
        let (c, rest) = rest.split_at_mut(n);
        let (z, rest) = rest.split_at_mut(n);
        let (y, w) = rest.split_at_mut(n);
        solve_view(
            &self.view(),
            theta,
            start,
            iterations,
            WorkspaceMut { lo, hi, c, z, y, w },
            &mut out,
        )?;
        Ok(out)
    }

    /// Converts into const-dimension tables.
    ///
    /// # Errors
    /// [`FgmError::Dimension`] if `N`, `P` do not match or `T` is not the
    /// length of the momentum table.
    pub fn to_tables<const N: usize, const P: usize, const T: usize>(
        &self,
    ) -> Result<FgmTables<S, N, P, T>, FgmError> {
        let dim = |what, expected, found| {
            if expected == found {
                Ok(())
            } else {
                Err(FgmError::Dimension {
                    what,
                    expected,
                    found,
                })
            }
        };
        dim("N (decision variables)", self.n, N)?;
        dim("P (parameters)", self.p, P)?;
        dim("T (momentum table)", self.betas.len(), T)?;
        fn mat<S: Scalar, const R: usize, const C: usize>(v: &[S]) -> Matrix<S, R, C> {
            Matrix::from_fn(|i, j| v.get(i * C + j).copied().unwrap_or(S::ZERO))
        }
        let arr = |v: &[S]| core::array::from_fn(|i| v.get(i).copied().unwrap_or(S::ZERO));
        Ok(FgmTables {
            m: mat(&self.m),
            k_theta: mat(&self.k_theta),
            k0: arr(&self.k0),
            lo_theta: mat(&self.lo_theta),
            lo0: arr(&self.lo0),
            hi_theta: mat(&self.hi_theta),
            hi0: arr(&self.hi0),
            d: arr(&self.d),
            d_inv: arr(&self.d_inv),
            betas: core::array::from_fn(|i| self.betas.get(i).copied().unwrap_or(S::ZERO)),
            iterations: self.iterations,
            warm_iterations: self.warm_iterations,
            shift: self.shift,
        })
    }
}

/// A designed fast-gradient solver: the problem, the preconditioning and the
/// folded `f64` data of the scaled problem.
#[derive(Clone, Debug, PartialEq)]
pub struct FgmDesign {
    /// The box QP.
    pub problem: BoxQp,
    /// The settings used.
    pub settings: FgmSettings,
    /// The preconditioning (its `d` before the range normalisation).
    pub preconditioning: Preconditioning,
    /// The scaling `z = D v` actually used (range-normalised).
    pub d: DVector<f64>,
    /// Spectrum of the scaled Hessian `D H D`.
    pub spectrum: Spectrum,
    /// Scaled Hessian `D H D`.
    pub h_scaled: DMatrix<f64>,
    /// Squared diameter of the scaled box, maximised over the parameter box.
    pub diameter_sq: f64,
    /// The cold-start `Delta`: the largest `1/2 e'(L I - D H D) e` over
    /// `|e_j| <= w_j / 2` (`w_j` the scaled width of variable `j`, maximised
    /// over the parameter box), which bounds
    /// `f(z_0) - f* + L/2 |z_0 - z*|^2` after the initial projected gradient
    /// step from the box centre (see [`FgmDesign::delta`]).
    pub cold_delta: f64,
    /// `c(theta) = K theta + k0` (scaled), `K` is `n x p`.
    pub k_theta: DMatrix<f64>,
    /// `k0`.
    pub k0: DVector<f64>,
    /// Scaled bounds.
    pub lo_theta: DMatrix<f64>,
    /// Scaled bounds.
    pub lo0: DVector<f64>,
    /// Scaled bounds.
    pub hi_theta: DMatrix<f64>,
    /// Scaled bounds.
    pub hi0: DVector<f64>,
}

impl FgmDesign {
    /// Preconditions and folds a box QP.
    ///
    /// # Errors
    /// [`FgmError::NotConvex`] for a Hessian with a negative eigenvalue,
    /// [`FgmError::Solver`] if the preconditioning SDP fails,
    /// [`FgmError::InvalidSetting`] for a non-positive `scaled_range`,
    /// [`FgmError::Range`] for a parameter box so large that the solver's
    /// intermediate values overflow `f64`,
    /// [`FgmError::Problem`] for a problem without decision variables.
    pub fn new(problem: BoxQp, settings: FgmSettings) -> Result<Self, FgmError> {
        if !(settings.scaled_range.is_finite() && settings.scaled_range > 0.0) {
            return Err(FgmError::InvalidSetting(format!(
                "scaled_range must be positive, got {}",
                settings.scaled_range
            )));
        }
        let n = problem.n();
        if n == 0 {
            return Err(FgmError::Problem(crate::problem::NO_VARIABLES.into()));
        }
        let pc = precondition(&problem.h, settings.preconditioner)?;
        let mut design = Self::fold(problem, settings, pc.clone(), pc.d.clone())?;
        // Normalise the overall scale of D (cond(DHD) is invariant) so that
        // the largest scaled intermediate reaches `scaled_range`.
        let peak = design.intermediate_bounds(design.max_beta()).peak;
        if !peak.is_finite() {
            return Err(overflow(&design.problem));
        }
        if peak > 0.0 && n > 0 {
            let t = peak / settings.scaled_range;
            let d = &pc.d * t;
            design = Self::fold(design.problem, settings, pc, d)?;
        }
        Ok(design)
    }

    fn fold(
        problem: BoxQp,
        settings: FgmSettings,
        preconditioning: Preconditioning,
        d: DVector<f64>,
    ) -> Result<Self, FgmError> {
        let h_scaled = scale_hessian(&problem.h, &d);
        if d.iter().chain(h_scaled.iter()).any(|v| !v.is_finite()) {
            return Err(overflow(&problem));
        }
        let spectrum = crate::precond::spectrum(&h_scaled)?;
        let l = spectrum.l;
        let dinv = d.map(|v| 1.0 / v);
        let dm = DMatrix::from_diagonal(&d);
        let dinvm = DMatrix::from_diagonal(&dinv);
        let k_theta = -(&dm * problem.f_theta.transpose()) / l;
        let k0 = -(&dm * &problem.f) / l;
        let lo_theta = &dinvm * &problem.lo_theta;
        let lo0 = &dinvm * &problem.lo0;
        let hi_theta = &dinvm * &problem.hi_theta;
        let hi0 = &dinvm * &problem.hi0;
        let widths = problem.max_widths();
        let diameter_sq = widths
            .iter()
            .zip(dinv.iter())
            .map(|(w, di)| (w * di).powi(2))
            .sum();
        let half_widths = DVector::from_fn(widths.len(), |j, _| 0.5 * widths[j] * dinv[j]);
        let cold_delta = quadratic_box_max(&h_scaled, spectrum, &half_widths);
        Ok(FgmDesign {
            problem,
            settings,
            preconditioning,
            d,
            spectrum,
            h_scaled,
            diameter_sq,
            cold_delta,
            k_theta,
            k0,
            lo_theta,
            lo0,
            hi_theta,
            hi0,
        })
    }

    /// Number of decision variables.
    pub fn n(&self) -> usize {
        self.problem.n()
    }

    /// `M = I - D H D / L`, exactly symmetric (`(M + M') / 2`).
    pub fn m(&self) -> DMatrix<f64> {
        let n = self.n();
        let m = DMatrix::identity(n, n) - &self.h_scaled / self.spectrum.l;
        (&m + m.transpose()) * 0.5
    }

    /// The cold-start `Delta` ([`FgmDesign::cold_delta`]).
    ///
    /// A cold solve starts at the box centre `s = (lo + hi) / 2`, so
    /// `s - z*` lies in `[-w/2, w/2]` for every optimum `z*`. The initial
    /// projected gradient step gives, for the quadratic cost exactly,
    /// `f(z_0) - f* + L/2 |z_0 - z*|^2 <= 1/2 (s - z*)'(L I - H_s)(s - z*)`,
    /// and this convex quadratic is largest at a vertex of that box:
    /// all `2^(n-1)` sign patterns are enumerated up to `n = 20` (Gray
    /// code, `O(n)` each); beyond, `(L - mu)/2 |w/2|^2` is used. Both are at
    /// most a quarter of Richter's `L/2 diam^2`.
    pub fn delta(&self) -> f64 {
        self.cold_delta
    }

    /// The constant momentum `(1 - sqrt(mu/L)) / (1 + sqrt(mu/L))`.
    pub fn constant_beta(&self) -> f64 {
        let q = (self.spectrum.mu / self.spectrum.l).sqrt();
        (1.0 - q) / (1.0 + q)
    }

    fn max_beta(&self) -> f64 {
        1.0
    }

    /// The momentum table for `gamma_0 = L`, `iterations` entries (at least one).
    ///
    /// `alpha_0` solves `alpha_0^2 / (1 - alpha_0) = 1 - q alpha_0 / (1 - alpha_0)`
    /// (i.e. `gamma_0 = L`), `alpha_{i+1}` the positive root of
    /// `alpha^2 = (1 - alpha) alpha_i^2 + q alpha`, `q = mu/L`, and
    /// `beta_i = alpha_i (1 - alpha_i) / (alpha_i^2 + alpha_{i+1})` (errata).
    pub fn beta_table(&self, iterations: usize) -> Vec<f64> {
        let q = self.spectrum.mu / self.spectrum.l;
        // L a^2 + (L - mu) a - L = 0  =>  a^2 + (1 - q) a - 1 = 0.
        let mut a = (-(1.0 - q) + ((1.0 - q).powi(2) + 4.0).sqrt()) / 2.0;
        let mut out = Vec::with_capacity(iterations.max(1));
        for _ in 0..iterations.max(1) {
            // a_next^2 + (a^2 - q) a_next - a^2 = 0.
            let b = a * a - q;
            let next = (-b + (b * b + 4.0 * a * a).sqrt()) / 2.0;
            out.push(a * (1.0 - a) / (a * a + next));
            a = next;
        }
        out
    }

    /// The tolerance on `J - J*` that keeps the selected inputs within
    /// `max_error` of the optimum (in the problem's units, e.g. one
    /// microsecond of a pulse width), computed from `H`.
    ///
    /// For a feasible `z` and the optimum `z*` over the box,
    /// `J(z) - J* >= grad J(z*)'(z - z*) + 1/2 (z - z*)'H(z - z*)` and the
    /// first term is non-negative (optimality), so `J - J* <= eps` gives
    /// `(z - z*)'H(z - z*) <= 2 eps`, and the largest `|z_j - z*_j|` on that
    /// ellipsoid is `sqrt(2 eps (H^-1)_jj)`. Hence
    /// `eps = max_error^2 / (2 max_j (H^-1)_jj)`, which is never smaller
    /// than the eigenvalue form `mu_H / 2 max_error^2`
    /// ([`eps_for_input_error`](crate::eps_for_input_error)).
    ///
    /// # Errors
    /// [`FgmError::InvalidSetting`] for a non-positive or non-finite
    /// `max_error`, an empty or too large selection, or a singular `H`
    /// (then no `eps` bounds the input error).
    pub fn input_tolerance(
        &self,
        max_error: f64,
        applied: AppliedInputs,
    ) -> Result<InputTolerance, FgmError> {
        if !(max_error.is_finite() && max_error > 0.0) {
            return Err(FgmError::InvalidSetting(format!(
                "the input error must be positive and finite, got {max_error}"
            )));
        }
        let n = self.n();
        let count = match applied {
            AppliedInputs::All => n,
            AppliedInputs::FirstMove(k) => k,
        };
        if count == 0 || count > n {
            return Err(FgmError::InvalidSetting(format!(
                "the applied inputs must be 1 ..= {n} variables, got {count}"
            )));
        }
        let mu_h = self.preconditioning.before.mu;
        let sym = (&self.problem.h + self.problem.h.transpose()) * 0.5;
        let inv = if mu_h > 1e-12 * self.preconditioning.before.l {
            sym.cholesky().map(|c| c.inverse())
        } else {
            None
        };
        let Some(inv) = inv else {
            return Err(FgmError::InvalidSetting(
                "H is singular: no tolerance on J - J* bounds the input error".into(),
            ));
        };
        let (worst_variable, h_inv_diag) = (0..count)
            .map(|j| (j, inv[(j, j)]))
            .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
        Ok(InputTolerance {
            max_error,
            eps: max_error * max_error / (2.0 * h_inv_diag),
            worst_variable,
            h_inv_diag,
            eps_eigenvalue: crate::eps_for_input_error(mu_h, max_error),
        })
    }

    /// Certified cold-start iterations for `J - J* <= eps`.
    ///
    /// # Errors
    /// [`FgmError::InvalidEps`] for `eps <= 0` or not finite,
    /// [`FgmError::InvalidSetting`] for [`Momentum::Constant`] with `mu = 0`,
    /// [`FgmError::NoIterationBound`] when no bound the scheme may use stays
    /// within [`MAX_ITERATION_BOUND`] (an `eps` far too small).
    pub fn certify(&self, eps: f64) -> Result<Certificate, FgmError> {
        self.certify_delta(eps, self.delta())
    }

    fn certify_delta(&self, eps: f64, delta: f64) -> Result<Certificate, FgmError> {
        if !(eps.is_finite() && eps > 0.0) {
            return Err(FgmError::InvalidEps(eps));
        }
        let Spectrum { l, mu } = self.spectrum;
        let ratio = delta / eps;
        let linear_bound = if mu > 0.0 {
            let rate = 1.0 - (mu / l).sqrt();
            if ratio <= 1.0 {
                Some(0)
            } else if rate <= 0.0 {
                Some(1)
            } else {
                iteration_bound((eps / delta).ln() / rate.ln())
            }
        } else {
            None
        };
        let sublinear_bound = iteration_bound(2.0 * ratio.sqrt() - 2.0);
        let no_bound = || FgmError::NoIterationBound {
            eps,
            limit: MAX_ITERATION_BOUND,
        };
        // The table scheme satisfies both bounds; `None` is "beyond the limit".
        let table = match (linear_bound, sublinear_bound) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        let (scheme, iterations) = match (self.settings.momentum, linear_bound) {
            (Momentum::Constant, Some(k)) => (MomentumScheme::Constant, k),
            (Momentum::Constant, None) if mu > 0.0 => return Err(no_bound()),
            (Momentum::Constant, None) => {
                return Err(FgmError::InvalidSetting(
                    "constant momentum needs mu > 0 (the scaled Hessian is singular)".into(),
                ));
            }
            (Momentum::Table, _) => (MomentumScheme::Table, table.ok_or_else(no_bound)?),
            (Momentum::Auto, Some(k)) if sublinear_bound.is_none_or(|s| k <= s) => {
                (MomentumScheme::Constant, k)
            }
            (Momentum::Auto, _) => (MomentumScheme::Table, table.ok_or_else(no_bound)?),
        };
        Ok(Certificate {
            eps,
            l,
            mu,
            condition: self.spectrum.condition(),
            delta,
            diameter_sq: self.diameter_sq,
            delta_richter: 0.5 * l * self.diameter_sq,
            linear_bound,
            sublinear_bound,
            scheme,
            iterations,
        })
    }

    /// The certified iteration counts for several tolerances (the thesis's
    /// Table 7.2 lists 1e5, 1e4, 1e3, 1e2).
    ///
    /// # Errors
    /// As [`FgmDesign::certify`].
    pub fn certify_table(&self, eps: &[f64]) -> Result<Vec<Certificate>, FgmError> {
        eps.iter().map(|e| self.certify(*e)).collect()
    }

    /// Warm-start certificate: start from the previous solution (unshifted).
    ///
    /// # Errors
    /// As [`FgmDesign::certify`], and [`FgmError::Dimension`] /
    /// [`FgmError::NonFinite`] for a bad `theta_step`.
    pub fn certify_warm(
        &self,
        eps: f64,
        assume: &WarmStartAssumption,
    ) -> Result<WarmCertificate, FgmError> {
        let cold = self.certify(eps)?;
        let p = self.problem.p();
        if assume.theta_step.len() != p {
            return Err(FgmError::Dimension {
                what: "theta_step",
                expected: p,
                found: assume.theta_step.len(),
            });
        }
        if assume.theta_step.iter().any(|v| !v.is_finite() || *v < 0.0)
            || !(assume.prev_eps.is_finite() && assume.prev_eps > 0.0)
        {
            return Err(FgmError::NonFinite("warm-start assumption"));
        }
        let Spectrum { l, mu } = self.spectrum;
        let const_width =
            (&self.lo_theta - &self.hi_theta).amax() <= 1e-12 * (1.0 + self.lo_theta.amax());
        // A start anywhere in the box: |s - z*|_j <= w_j, four times the
        // centre's quadratic bound (homogeneous of degree 2).
        let anywhere = 4.0 * self.cold_delta;
        if !(const_width && mu > 0.0) {
            let any = self.certify_delta(eps, anywhere)?;
            return Ok(WarmCertificate {
                iterations: any.iterations,
                radius: self.diameter_sq.sqrt(),
                delta: anywhere,
                refined: false,
                cold,
            });
        }
        // H_s^-1/2 via the eigen-decomposition.
        let eig = SymmetricEigen::new(self.h_scaled.clone());
        let inv_sqrt = DMatrix::from_diagonal(&eig.eigenvalues.map(|v| 1.0 / v.sqrt()));
        let h_inv_half = &eig.eigenvectors * inv_sqrt * eig.eigenvectors.transpose();
        let q = self.k_theta.clone() * (-l) + &self.h_scaled * &self.lo_theta;
        let hq = &h_inv_half * &q;
        let lip: f64 = (0..p)
            .map(|j| {
                assume.theta_step[j]
                    * (self.lo_theta.column(j).norm() + hq.column(j).norm() / mu.sqrt())
            })
            .sum();
        let radius = (2.0 * assume.prev_eps / mu).sqrt() + lip;
        // 1/2 e'(L I - H_s) e <= (L - mu)/2 |e|^2.
        let delta = (0.5 * (l - mu) * radius * radius).min(anywhere);
        let warm = self.certify_delta(eps, delta)?;
        Ok(WarmCertificate {
            cold,
            refined: true,
            radius,
            delta,
            iterations: warm.iterations,
        })
    }

    /// The folded data in scalar `S` for a certificate (and an optional
    /// warm-start iteration count), with the box shrunk inwards by the
    /// rounding bound of `S` (nothing for `f64`).
    ///
    /// # Errors
    /// [`FgmError::Range`] if a table entry or intermediate does not fit `S`
    /// or the shrunk box would be empty.
    pub fn data<S: Scalar>(
        &self,
        cert: &Certificate,
        warm_iterations: Option<usize>,
    ) -> Result<FgmData<S>, FgmError> {
        let (n, p) = (self.n(), self.problem.p());
        let betas = match cert.scheme {
            MomentumScheme::Constant => vec![self.constant_beta()],
            MomentumScheme::Table => {
                self.beta_table(cert.iterations.max(warm_iterations.unwrap_or(0)))
            }
        };
        let shrink = self.box_shrink::<S>();
        let exact = shrink.is_none();
        let shrink = shrink.unwrap_or_else(|| DVector::zeros(n));
        let mut lo0 = &self.lo0 + &shrink;
        let mut hi0 = &self.hi0 - &shrink;
        if !exact {
            // Keep the box non-empty (a zero-width box stays a point).
            for j in 0..n {
                if lo0[j] > hi0[j] {
                    let mid = 0.5 * (self.lo0[j] + self.hi0[j]);
                    if (self.lo_theta.row(j) - self.hi_theta.row(j)).amax() > 0.0 {
                        return Err(FgmError::Range(format!(
                            "the rounding margin empties the box of variable {j}"
                        )));
                    }
                    lo0[j] = mid;
                    hi0[j] = mid;
                }
            }
        }
        let m = self.m();
        let row_major = |a: &DMatrix<f64>| -> Vec<f64> {
            (0..a.nrows())
                .flat_map(|i| (0..a.ncols()).map(move |j| (i, j)))
                .map(|(i, j)| a[(i, j)])
                .collect()
        };
        let parts: [(&str, Vec<f64>); 11] = [
            ("M", row_major(&m)),
            ("K", row_major(&self.k_theta)),
            ("k0", self.k0.as_slice().to_vec()),
            ("Lo", row_major(&self.lo_theta)),
            ("lo0", lo0.as_slice().to_vec()),
            ("Hi", row_major(&self.hi_theta)),
            ("hi0", hi0.as_slice().to_vec()),
            ("d", self.d.as_slice().to_vec()),
            ("d_inv", self.d.map(|v| 1.0 / v).as_slice().to_vec()),
            ("betas", betas),
            ("theta bounds", {
                let mut v = self.problem.theta_lb.as_slice().to_vec();
                v.extend_from_slice(self.problem.theta_ub.as_slice());
                v
            }),
        ];
        let limit = S::MAX.to_f64() * 0.5;
        for (name, v) in &parts {
            if let Some(x) = v.iter().find(|x| !x.is_finite() || x.abs() > limit) {
                return Err(FgmError::Range(format!(
                    "{name} holds {x:e}, beyond the safe range {limit:e} of the scalar"
                )));
            }
        }
        let ib = self.intermediate_bounds(
            self.constant_beta()
                .max(parts[9].1.iter().fold(0.0f64, |a, b| a.max(*b))),
        );
        if ib.peak > limit {
            return Err(FgmError::Range(format!(
                "intermediates reach {:e}, beyond the safe range {limit:e}",
                ib.peak
            )));
        }
        let conv = |v: &[f64]| v.iter().map(|x| S::from_f64(*x)).collect::<Vec<S>>();
        let [m, k, k0, lo, lo0, hi, hi0, d, dinv, betas, _] = parts;
        Ok(FgmData {
            n,
            p,
            m: conv(&m.1),
            k_theta: conv(&k.1),
            k0: conv(&k0.1),
            lo_theta: conv(&lo.1),
            lo0: conv(&lo0.1),
            hi_theta: conv(&hi.1),
            hi0: conv(&hi0.1),
            d: conv(&d.1),
            d_inv: conv(&dinv.1),
            betas: conv(&betas.1),
            iterations: cert.iterations,
            warm_iterations: warm_iterations.unwrap_or(cert.iterations),
            shift: 0,
        })
    }

    /// Const-dimension tables in scalar `S` (see [`FgmDesign::data`]).
    ///
    /// # Errors
    /// As [`FgmDesign::data`] and [`FgmData::to_tables`].
    pub fn tables<S: Scalar, const N: usize, const P: usize, const T: usize>(
        &self,
        cert: &Certificate,
        warm_iterations: Option<usize>,
    ) -> Result<FgmTables<S, N, P, T>, FgmError> {
        self.data::<S>(cert, warm_iterations)?.to_tables()
    }

    /// Solves in `f64` with `iterations` iterations (cold start, or warm
    /// from `start` in problem units).
    ///
    /// # Errors
    /// [`FgmError::Dimension`], [`FgmError::NonFinite`] for a bad `theta`,
    /// [`FgmError::Runtime`] from the kernel.
    pub fn solve(
        &self,
        cert: &Certificate,
        theta: &[f64],
        start: Option<&[f64]>,
        iterations: usize,
    ) -> Result<Vec<f64>, FgmError> {
        self.problem.check_theta(theta)?;
        let data = self.data::<f64>(cert, Some(iterations))?;
        let start = match start {
            Some(s) => Start::Warm(s),
            None => Start::Cold,
        };
        Ok(data.solve(theta, start, iterations)?)
    }
}

/// The largest `1/2 e'(L I - H) e` over the box `|e_j| <= r_j` (see
/// [`FgmDesign::delta`]).
fn quadratic_box_max(h: &DMatrix<f64>, spectrum: Spectrum, r: &DVector<f64>) -> f64 {
    let n = r.len();
    let Spectrum { l, mu } = spectrum;
    let fallback = 0.5 * (l - mu).max(0.0) * r.norm_squared();
    if n == 0 || n > 20 {
        return fallback;
    }
    let a = DMatrix::identity(n, n) * l - h;
    // e = sigma .* r, sigma_0 = +1 fixed (e and -e give the same value).
    let mut e = r.clone();
    let mut u = &a * &e;
    let mut value = e.dot(&u);
    let mut best = value;
    for k in 1u64..(1u64 << (n - 1)) {
        // Gray code: flip the sign of entry 1 + trailing_zeros(k).
        let j = 1 + k.trailing_zeros() as usize;
        let de = -2.0 * e[j];
        value += 2.0 * de * u[j] + de * de * a[(j, j)];
        u.axpy(de, &a.column(j), 1.0);
        e[j] = -e[j];
        best = best.max(value);
    }
    // The updates accumulate rounding (relative ~1e-13 here): a relative
    // margin of 1e-9 covers it; the eigenvalue bound caps it.
    (0.5 * best * (1.0 + 1e-9)).min(fallback).max(0.0)
}

/// The error for a parameter box whose scaling overflows `f64`: the
/// largest intermediate value, and with it the preconditioner's scale,
/// grows with the box.
fn overflow(problem: &BoxQp) -> FgmError {
    let theta = problem
        .theta_lb
        .iter()
        .chain(problem.theta_ub.iter())
        .fold(0.0_f64, |m, v| m.max(v.abs()));
    FgmError::Range(format!(
        "the solver's intermediate values over the parameter box overflow f64 (|theta| up to {theta:.1e}): give a smaller parameter box"
    ))
}
