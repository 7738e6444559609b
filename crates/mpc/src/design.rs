//! Design-time settings: weights, terminal cost, move blocking, constraints.

use crate::constraints::{Bounds, InputTarget, Parameter, TerminalSet};
use crate::error::MpcError;
use nalgebra::{DMatrix, DVector};

/// A weight matrix: a number times the identity, a diagonal, or a full matrix.
#[derive(Clone, Debug, PartialEq)]
pub enum Weight {
    /// `s * I` of the size the weight needs.
    Scalar(f64),
    /// A diagonal matrix with these entries.
    Diagonal(Vec<f64>),
    /// A full (symmetric, positive semidefinite) matrix.
    Matrix(DMatrix<f64>),
}

impl Weight {
    /// The weight as an `n x n` matrix, checked: finite, square of size
    /// `n`, symmetric, positive semidefinite. `what` names it in errors.
    pub fn resolve(&self, n: usize, what: &str) -> Result<DMatrix<f64>, MpcError> {
        let m = match self {
            Weight::Scalar(s) => DMatrix::identity(n, n) * *s,
            Weight::Diagonal(d) => {
                if d.len() != n {
                    return Err(MpcError::dim(
                        what,
                        format!("{n} diagonal entries"),
                        format!("{}", d.len()),
                    ));
                }
                DMatrix::from_diagonal(&DVector::from_column_slice(d))
            }
            Weight::Matrix(m) => {
                if m.shape() != (n, n) {
                    return Err(MpcError::dim(
                        what,
                        format!("a {n} x {n} matrix"),
                        format!("a {} x {} matrix", m.nrows(), m.ncols()),
                    ));
                }
                m.clone()
            }
        };
        check_psd(&m, what)?;
        Ok(m)
    }
}

/// Checks that the condensed Hessian is positive definite.
pub(crate) fn check_hessian(h: &DMatrix<f64>) -> Result<(), MpcError> {
    if h.iter().any(|v| !v.is_finite()) {
        return Err(MpcError::NonFinite("H".into()));
    }
    let eig = h.clone().symmetric_eigenvalues();
    let (min, max) = (eig.min(), eig.max());
    let floor = 1e-12 * max.abs().max(f64::MIN_POSITIVE);
    if min.is_nan() || min <= floor || max <= 0.0 {
        let what = if min > 0.0 && max.is_finite() {
            // Positive, but below the rounding of the largest: as good as
            // singular to any solver.
            format!(
                "the condensed Hessian H (numerically: its largest eigenvalue is {max:.3e}, and the smallest must exceed 1e-12 of it; a larger input weight Q2 or a shorter horizon)"
            )
        } else {
            "the condensed Hessian H (add input weight Q2 or output weight Q1 on every input direction)".into()
        };
        return Err(MpcError::NotPositiveDefinite {
            what,
            kind: "",
            min_eigenvalue: min,
        });
    }
    Ok(())
}

/// Checks that `m` is finite, symmetric and positive semidefinite.
pub(crate) fn check_psd(m: &DMatrix<f64>, what: &str) -> Result<(), MpcError> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(MpcError::NonFinite(what.into()));
    }
    let scale = m.amax().max(1.0);
    let asym = (m - m.transpose()).amax();
    if asym > 1e-9 * scale {
        return Err(MpcError::NotSymmetric {
            what: what.into(),
            asymmetry: asym,
        });
    }
    if m.nrows() > 0 {
        let sym = (m + m.transpose()) * 0.5;
        let min = sym.symmetric_eigenvalues().min();
        if min < -1e-10 * scale {
            return Err(MpcError::NotPositiveDefinite {
                what: what.into(),
                kind: "semi",
                min_eigenvalue: min,
            });
        }
    }
    Ok(())
}

/// The terminal cost of the horizon, the first term of (6.3a).
#[derive(Clone, Debug, PartialEq)]
pub enum Terminal {
    /// `Q1N = Q1`: the output error at `k + N` weighted like the others.
    StageWeight,
    /// `1/2 |y_N - r|^2_{Q1N}` with this output weight.
    Output(Weight),
    /// `1/2 |x_N - C^+ r|^2_P` with this state weight `P` (`nx x nx`).
    State(DMatrix<f64>),
    /// The LQ terminal weight (7.18)-(7.19): `P = S` from the discrete
    /// algebraic Riccati equation of `(A, B, C'Q1C, Q2)` (errata applied:
    /// `A'SA - S - A'SB (Q2 + B'SB)^-1 B'SA + C'Q1C = 0`), on the state
    /// error `x_N - C^+ r` with the pseudo-inverse reference map.
    Lq,
    /// No terminal cost: the prediction ends with the last stage cost.
    None,
}

/// Move blocking (6.24)-(6.25) generalised: the horizon is cut into blocks
/// of these lengths, the input constant within each block. The thesis's
/// `N_s` is `[1; N_s - 1]` followed by one block of `N - N_s + 1`.
///
/// ```
/// use kestrel_mpc::Blocking;
/// assert_eq!(Blocking::control_horizon(10, 3).unwrap().lengths(), &[1, 1, 8]);
/// assert_eq!(Blocking::none(3).lengths(), &[1, 1, 1]);
/// assert!(Blocking::new(vec![1, 0]).is_err());
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Blocking(Vec<usize>);

impl Blocking {
    /// Blocks of the given lengths (each at least 1).
    pub fn new(lengths: Vec<usize>) -> Result<Self, MpcError> {
        if lengths.is_empty() {
            return Err(MpcError::setting("blocks", "at least one block is needed"));
        }
        if let Some(i) = lengths.iter().position(|&l| l == 0) {
            return Err(MpcError::setting(
                "blocks",
                format!("block {i} has length 0; every block needs at least one step"),
            ));
        }
        Ok(Blocking(lengths))
    }
    /// No blocking: `horizon` blocks of one step.
    pub fn none(horizon: usize) -> Self {
        Blocking(vec![1; horizon])
    }
    /// A control horizon of `ns` moves (MATLAB's `ControlHorizon`, the
    /// thesis's `N_s` (6.24)): free moves at steps `0..ns-1`, the last one
    /// held to the end of the horizon.
    ///
    /// # Errors
    /// [`MpcError::InvalidSetting`] unless `1 <= ns <= horizon`.
    pub fn control_horizon(horizon: usize, ns: usize) -> Result<Self, MpcError> {
        if ns == 0 || ns > horizon {
            return Err(MpcError::setting(
                "Ns",
                format!("must satisfy 1 <= Ns <= N = {horizon}, found {ns}"),
            ));
        }
        let mut v = vec![1; ns - 1];
        v.push(horizon - ns + 1);
        Ok(Blocking(v))
    }
    /// The block lengths.
    pub fn lengths(&self) -> &[usize] {
        &self.0
    }
    /// Number of blocks (free input moves).
    pub fn count(&self) -> usize {
        self.0.len()
    }
    /// Total length (must equal the horizon).
    pub fn total(&self) -> usize {
        self.0.iter().sum()
    }
    /// The block of each step of the horizon.
    pub fn block_of_step(&self) -> Vec<usize> {
        self.0
            .iter()
            .enumerate()
            .flat_map(|(b, &l)| std::iter::repeat_n(b, l))
            .collect()
    }
}

/// Settings of the MPC design: horizon, blocking, weights, terminal cost,
/// constraints, and the parameter box written to `kestrel.mpqp.v1`.
///
/// Everything is in the model's coordinates: inputs as deviations from the
/// trim `u0`, outputs `y = C x`. The cost over the horizon `N` is
///
/// ```text
/// sum_{j=0}^{N-1} 1/2 |C x_j - r_j|^2_Q1 + 1/2 |u_j - u_t|^2_Q2 + 1/2 |u_j - u_{j-1}|^2_Qdu
///   + terminal cost on x_N,
/// ```
///
/// with `u_{-1}` the input applied last (a parameter when `du_weight` or
/// `du_bounds` is set), `r_j` the reference of step `j` (held after the
/// preview) and `u_t` the input target. See [`ThetaLayout`](crate::ThetaLayout)
/// for the parameter vector.
///
/// ```
/// use kestrel_mpc::{Bounds, MpcSettings, SoftPenalty, Terminal, Weight};
/// use nalgebra::dvector;
/// // |u| <= 1, |du| <= 0.2 per step, y <= 1.5 (soft), 5 reference steps.
/// let settings = MpcSettings {
///     horizon: 10,
///     q2: Weight::Scalar(0.1),
///     du_weight: Some(Weight::Scalar(1.0)),
///     input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0])),
///     du_bounds: Some(Bounds::new(dvector![-0.2], dvector![0.2])),
///     output_bounds: Some(Bounds::new(dvector![f64::NEG_INFINITY], dvector![1.5])
///         .with_soft(SoftPenalty::default())),
///     preview: 5,
///     terminal: Terminal::Lq,
///     ..MpcSettings::default()
/// };
/// assert!(settings.validate(1, 1, 2).is_ok());
/// let bad = MpcSettings { preview: 11, ..settings };
/// assert!(bad.validate(1, 1, 2).unwrap_err().to_string().contains("preview"));
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct MpcSettings {
    /// Prediction horizon `N` (steps).
    pub horizon: usize,
    /// Move blocking; `None` means one block per step.
    pub blocking: Option<Blocking>,
    /// Output-error weight `Q1` (`ny x ny`).
    pub q1: Weight,
    /// Input weight `Q2` (`nu x nu`), on the deviation from the input
    /// target ([`MpcSettings::input_target`]).
    pub q2: Weight,
    /// Terminal cost.
    pub terminal: Terminal,
    /// Parameter box of the states: `|x_i| <= state_bound`.
    pub state_bound: f64,
    /// Parameter box of the references: `|r_i| <= reference_bound`.
    pub reference_bound: f64,
    /// Weight on the input moves `du_j = u_j - u_{j-1}` (`nu x nu`); with
    /// move blocking only the first step of each block moves. Setting it
    /// (or [`MpcSettings::du_bounds`]) puts the previous input in `theta`.
    pub du_weight: Option<Weight>,
    /// Reference steps in `theta`, `1..=horizon`: `y_j` is compared with
    /// `r_min(j, P)` (`y_0` with `r_1`), the terminal cost with `r_P`.
    /// `1` (the default) is a constant reference.
    pub preview: usize,
    /// What `Q2` pulls the inputs towards.
    pub input_target: InputTarget,
    /// Bounds on the inputs `u_j`, `j = 0..N-1` (deviations from the trim).
    pub input_bounds: Option<Bounds>,
    /// Bounds on the input moves `du_j`, `j = 0..N-1` (`du_0 = u_0 - u_prev`).
    pub du_bounds: Option<Bounds>,
    /// Bounds on the predicted outputs `y_j = C x_j`, `j = 1..N`.
    pub output_bounds: Option<Bounds>,
    /// Bounds on the predicted states `x_j`, `j = 1..N`.
    pub state_bounds: Option<Bounds>,
    /// A hard terminal set `A x_N <= b`.
    pub terminal_set: Option<TerminalSet>,
    /// Extra parameters in `theta`, last (the bounds' shifts read them).
    pub parameters: Vec<Parameter>,
    /// Parameter box of the previous input and of an input target in
    /// `theta` where the input bounds do not give one: `|u_i| <= this`.
    pub input_parameter_bound: f64,
}

impl Default for MpcSettings {
    /// `N = 2` without blocking, `Q1 = I`, `Q2 = 1e-4 I`, LQ terminal
    /// weight, states within +-10 and references within +-3, no
    /// constraints, no input-move weight, a constant reference, the trim
    /// as input target, no extra parameters.
    fn default() -> Self {
        MpcSettings {
            horizon: 2,
            blocking: None,
            q1: Weight::Scalar(1.0),
            q2: Weight::Scalar(1e-4),
            terminal: Terminal::Lq,
            state_bound: 10.0,
            reference_bound: 3.0,
            du_weight: None,
            preview: 1,
            input_target: InputTarget::Zero,
            input_bounds: None,
            du_bounds: None,
            output_bounds: None,
            state_bounds: None,
            terminal_set: None,
            parameters: Vec::new(),
            input_parameter_bound: 10.0,
        }
    }
}

impl MpcSettings {
    /// The blocking in force (one block per step when unset).
    pub fn blocking(&self) -> Blocking {
        self.blocking
            .clone()
            .unwrap_or_else(|| Blocking::none(self.horizon))
    }

    /// Whether the previous input is a parameter (an input-move weight or
    /// bound is set).
    pub fn uses_previous_input(&self) -> bool {
        self.du_weight.is_some() || self.du_bounds.is_some()
    }

    /// Checks every setting against a model of `nu` inputs, `ny` outputs
    /// and `nx` states (the weights' definiteness is checked when they are
    /// resolved). Errors name the setting.
    pub fn validate(&self, nu: usize, ny: usize, nx: usize) -> Result<(), MpcError> {
        if self.horizon == 0 {
            return Err(MpcError::setting("horizon", "must be at least 1"));
        }
        if self.preview == 0 || self.preview > self.horizon {
            return Err(MpcError::setting(
                "preview",
                format!(
                    "must satisfy 1 <= preview <= horizon N = {}, found {}",
                    self.horizon, self.preview
                ),
            ));
        }
        for (what, v) in [
            ("state_bound", self.state_bound),
            ("reference_bound", self.reference_bound),
            ("input_parameter_bound", self.input_parameter_bound),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(MpcError::setting(
                    what,
                    format!("must be finite and > 0, found {v}"),
                ));
            }
        }
        for (i, p) in self.parameters.iter().enumerate() {
            if !(p.min.is_finite() && p.max.is_finite()) {
                return Err(MpcError::NonFinite(format!("parameter {i} ({})", p.name)));
            }
            if p.min > p.max {
                return Err(MpcError::setting(
                    format!("parameter {i} ({})", p.name),
                    format!("min {} exceeds max {}", p.min, p.max),
                ));
            }
        }
        if let InputTarget::Fixed(t) = &self.input_target {
            if t.len() != nu {
                return Err(MpcError::dim(
                    "input_target",
                    format!("{nu} entries (one per input)"),
                    format!("{}", t.len()),
                ));
            }
            if t.iter().any(|v| !v.is_finite()) {
                return Err(MpcError::NonFinite("input_target".into()));
            }
        }
        if let Some(b) = &self.input_bounds
            && b.len() == nu
            && let Some(i) = (0..nu).find(|&i| b.lower[i] > b.upper[i])
        {
            return Err(MpcError::InfeasibleBounds {
                input: i,
                lower: b.lower[i],
                upper: b.upper[i],
            });
        }
        let families = [
            ("input_bounds", &self.input_bounds, nu),
            ("du_bounds", &self.du_bounds, nu),
            ("output_bounds", &self.output_bounds, ny),
            ("state_bounds", &self.state_bounds, nx),
        ];
        for (what, b, k) in families {
            if let Some(b) = b {
                b.validate(k, &self.parameters, what)?;
            }
        }
        if let Some(b) = &self.du_bounds {
            let at = b.tightest_over(&self.parameters);
            for i in 0..nu {
                if at.lower[i] > 0.0 || at.upper[i] < 0.0 {
                    return Err(MpcError::setting(
                        "du_bounds",
                        format!(
                            "entry {i}: the bounds [{}, {}] exclude a zero move, so holding the input would be infeasible",
                            at.lower[i], at.upper[i]
                        ),
                    ));
                }
            }
        }
        if let Some(t) = &self.terminal_set {
            t.validate(nx)?;
        }
        Ok(())
    }
}
