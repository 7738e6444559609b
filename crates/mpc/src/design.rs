//! Design-time settings: weights, terminal cost, move blocking, input bounds.

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
        return Err(MpcError::NotPositiveDefinite {
            what: "the condensed Hessian H (add input weight Q2 or output weight Q1 on every input direction)".into(),
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
}

/// Which inputs move with the throttle parameter, and the range of the throttle.
///
/// The bounds on input `i` at throttle `t` are
/// `lower_i + coupling_i t <= u_i - u0_i <= upper_i + coupling_i t`, (6.7).
#[derive(Clone, Debug, PartialEq)]
pub struct ThrottleParameter {
    /// Shift of each input's bounds per unit of throttle (e.g. `-1` for a
    /// motor whose pulse is the throttle plus the input, `0` for an input
    /// the throttle does not move), `nu` entries.
    pub coupling: DVector<f64>,
    /// Smallest throttle (parameter box).
    pub min: f64,
    /// Largest throttle (parameter box).
    pub max: f64,
}

/// Input bounds as deviations from the trim `u0` (the model's input
/// coordinates), optionally moving with the throttle.
#[derive(Clone, Debug, PartialEq)]
pub struct InputBounds {
    /// Lower bounds at zero throttle, `nu` entries.
    pub lower: DVector<f64>,
    /// Upper bounds at zero throttle, `nu` entries.
    pub upper: DVector<f64>,
    /// The throttle dependence; `None` for fixed bounds and no throttle
    /// entry in `theta`.
    pub throttle: Option<ThrottleParameter>,
}

impl InputBounds {
    /// Fixed bounds (no throttle parameter), as deviations from the trim.
    pub fn new(lower: DVector<f64>, upper: DVector<f64>) -> Self {
        InputBounds {
            lower,
            upper,
            throttle: None,
        }
    }

    /// Adds a throttle parameter to fixed bounds.
    pub fn with_throttle(mut self, coupling: DVector<f64>, min: f64, max: f64) -> Self {
        self.throttle = Some(ThrottleParameter { coupling, min, max });
        self
    }

    /// Number of inputs.
    pub fn nu(&self) -> usize {
        self.lower.len()
    }

    /// The bounds at a throttle value (ignored without a throttle parameter).
    pub fn at(&self, throttle: f64) -> BoundsAt {
        match &self.throttle {
            Some(t) => BoundsAt {
                lower: &self.lower + &t.coupling * throttle,
                upper: &self.upper + &t.coupling * throttle,
            },
            None => BoundsAt {
                lower: self.lower.clone(),
                upper: self.upper.clone(),
            },
        }
    }

    /// Checks sizes, finiteness and feasibility for `nu` inputs.
    pub fn validate(&self, nu: usize) -> Result<(), MpcError> {
        for (what, v) in [
            ("input bounds lower", &self.lower),
            ("input bounds upper", &self.upper),
        ] {
            if v.len() != nu {
                return Err(MpcError::dim(
                    what,
                    format!("{nu} entries (one per input)"),
                    format!("{}", v.len()),
                ));
            }
            if v.iter().any(|x| !x.is_finite()) {
                return Err(MpcError::NonFinite(what.into()));
            }
        }
        if let Some(i) = (0..nu).find(|&i| self.lower[i] > self.upper[i]) {
            return Err(MpcError::InfeasibleBounds {
                input: i,
                lower: self.lower[i],
                upper: self.upper[i],
            });
        }
        if let Some(t) = &self.throttle {
            if t.coupling.len() != nu {
                return Err(MpcError::dim(
                    "throttle coupling",
                    format!("{nu} entries (one per input)"),
                    format!("{}", t.coupling.len()),
                ));
            }
            if t.coupling.iter().any(|x| !x.is_finite()) || !t.min.is_finite() || !t.max.is_finite()
            {
                return Err(MpcError::NonFinite("throttle parameter".into()));
            }
            if t.min > t.max {
                return Err(MpcError::setting(
                    "throttle range",
                    format!("min {} exceeds max {}", t.min, t.max),
                ));
            }
        }
        Ok(())
    }
}

/// Input bounds evaluated at one throttle value.
#[derive(Clone, Debug, PartialEq)]
pub struct BoundsAt {
    /// Lower bounds (deviation from the trim).
    pub lower: DVector<f64>,
    /// Upper bounds (deviation from the trim).
    pub upper: DVector<f64>,
}

/// Move blocking (6.24)-(6.25) generalised: the horizon is cut into blocks
/// of these lengths, the input constant within each block. The thesis's
/// `N_s` is `[1; N_s - 1]` followed by one block of `N - N_s + 1`.
///
/// ```
/// use kestrel_mpc::Blocking;
/// assert_eq!(Blocking::thesis(10, 3).unwrap().lengths(), &[1, 1, 8]);
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
    /// The thesis's `N_s` (6.24): free moves at steps `0..N_s-1`, then
    /// constant to the end of the horizon `N`.
    pub fn thesis(horizon: usize, ns: usize) -> Result<Self, MpcError> {
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

/// Settings of the MPC design: horizon, blocking, weights, terminal cost and
/// the parameter box written to `kestrel.mpqp.v1`.
#[derive(Clone, Debug, PartialEq)]
pub struct MpcSettings {
    /// Prediction horizon `N` (steps).
    pub horizon: usize,
    /// Move blocking; `None` means one block per step.
    pub blocking: Option<Blocking>,
    /// Output-error weight `Q1` (`ny x ny`).
    pub q1: Weight,
    /// Input weight `Q2` (`nu x nu`), on the deviation from the trim.
    pub q2: Weight,
    /// Terminal cost.
    pub terminal: Terminal,
    /// Parameter box of the states: `|x_i| <= state_bound`.
    pub state_bound: f64,
    /// Parameter box of the references: `|r_i| <= reference_bound`.
    pub reference_bound: f64,
}

impl Default for MpcSettings {
    /// `N = 2` without blocking, `Q1 = I`, `Q2 = 1e-4 I`, LQ terminal
    /// weight, states within +-10 and references within +-3.
    fn default() -> Self {
        MpcSettings {
            horizon: 2,
            blocking: None,
            q1: Weight::Scalar(1.0),
            q2: Weight::Scalar(1e-4),
            terminal: Terminal::Lq,
            state_bound: 10.0,
            reference_bound: 3.0,
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
}
