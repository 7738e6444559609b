//! Constraints of the MPC problem: affine bounds (hard or soft), the extra
//! parameters they may depend on, and a terminal set.

use crate::error::MpcError;
use nalgebra::{DMatrix, DVector};

/// An extra entry of the parameter vector `theta`, after the states, the
/// previous input, the references and the input target: something the
/// bounds may depend on, known at run time (the thesis's throttle is one).
#[derive(Clone, Debug, PartialEq)]
pub struct Parameter {
    /// Its name (for messages and the documentation of `theta`).
    pub name: String,
    /// Smallest value (the parameter box written to `kestrel.mpqp.v1`).
    pub min: f64,
    /// Largest value.
    pub max: f64,
}

impl Parameter {
    /// A parameter named `name` within `[min, max]`.
    pub fn new(name: impl Into<String>, min: f64, max: f64) -> Self {
        Parameter {
            name: name.into(),
            min,
            max,
        }
    }
}

/// The penalty of a soft bound: each bounded component `i` gets one slack
/// variable `s_i >= 0`, shared by every step of the horizon and by both
/// sides (`lower_i - s_i <= v_i <= upper_i + s_i`), with the cost
/// `1/2 quadratic s_i^2 + linear s_i`.
///
/// The linear term makes the penalty exact: when `linear` exceeds the
/// multipliers of the hard problem, the soft problem has the hard one's
/// solution wherever the hard one is feasible, and otherwise the least
/// violation (weighted). The quadratic term keeps the Hessian positive
/// definite, so it must be positive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoftPenalty {
    /// Weight of `1/2 s^2` (> 0).
    pub quadratic: f64,
    /// Weight of `s` (>= 0).
    pub linear: f64,
}

impl Default for SoftPenalty {
    /// `quadratic = 1e2`, `linear = 1e4`.
    fn default() -> Self {
        SoftPenalty {
            quadratic: 1e2,
            linear: 1e4,
        }
    }
}

/// Affine bounds on a vector `v` of `k` entries (inputs, input moves,
/// outputs or states), in the model's coordinates:
/// `lower + lower_shift p <= v <= upper + upper_shift p`, where `p` are the
/// extra parameters ([`MpcSettings::parameters`](crate::MpcSettings::parameters)).
///
/// An infinite entry (`-inf` below, `+inf` above) is no bound: its rows are
/// left out of the QP.
///
/// ```
/// use kestrel_mpc::{Bounds, SoftPenalty};
/// use nalgebra::{dmatrix, dvector};
/// // |u_1| <= 1; u_2 in [-2, 2] shifted down by the one parameter.
/// let b = Bounds::new(dvector![-1.0, -2.0], dvector![1.0, 2.0]).shifted(dmatrix![0.0; -1.0]);
/// let at = b.at(&[0.5]);
/// assert_eq!((at.lower[1], at.upper[1]), (-2.5, 1.5));
/// // A soft upper bound on one output, no lower bound.
/// let y = Bounds::new(dvector![f64::NEG_INFINITY], dvector![0.8]).with_soft(SoftPenalty::default());
/// assert!(y.soft.is_some());
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Bounds {
    /// Lower bounds at `p = 0` (`-inf`: none).
    pub lower: DVector<f64>,
    /// Upper bounds at `p = 0` (`+inf`: none).
    pub upper: DVector<f64>,
    /// Shift of the lower bounds per parameter (`k x np`); `None` is zero.
    pub lower_shift: Option<DMatrix<f64>>,
    /// Shift of the upper bounds per parameter (`k x np`); `None` is zero.
    pub upper_shift: Option<DMatrix<f64>>,
    /// `None`: hard bounds; otherwise soft with this penalty.
    pub soft: Option<SoftPenalty>,
}

/// Bounds evaluated at one parameter value.
#[derive(Clone, Debug, PartialEq)]
pub struct BoundsAt {
    /// Lower bounds.
    pub lower: DVector<f64>,
    /// Upper bounds.
    pub upper: DVector<f64>,
}

impl Bounds {
    /// Hard bounds that do not depend on parameters.
    pub fn new(lower: DVector<f64>, upper: DVector<f64>) -> Self {
        Bounds {
            lower,
            upper,
            lower_shift: None,
            upper_shift: None,
            soft: None,
        }
    }

    /// The same shift `k x np` on both sides: the window moves with the
    /// parameters without changing its width.
    pub fn shifted(mut self, shift: DMatrix<f64>) -> Self {
        self.lower_shift = Some(shift.clone());
        self.upper_shift = Some(shift);
        self
    }

    /// Makes the bounds soft with this penalty.
    pub fn with_soft(mut self, penalty: SoftPenalty) -> Self {
        self.soft = Some(penalty);
        self
    }

    /// Number of bounded entries `k`.
    pub fn len(&self) -> usize {
        self.lower.len()
    }

    /// Whether there are no entries.
    pub fn is_empty(&self) -> bool {
        self.lower.is_empty()
    }

    /// Whether entry `i` has a finite lower or upper bound (rows in the QP).
    pub fn is_bounded(&self, i: usize) -> bool {
        self.lower[i].is_finite() || self.upper[i].is_finite()
    }

    /// The bounds at parameter value `p` (missing entries of `p` read as 0).
    pub fn at(&self, p: &[f64]) -> BoundsAt {
        let shift = |base: &DVector<f64>, s: &Option<DMatrix<f64>>| {
            let mut v = base.clone();
            if let Some(s) = s {
                for i in 0..v.len() {
                    for (j, pj) in p.iter().enumerate().take(s.ncols()) {
                        v[i] += s[(i, j)] * pj;
                    }
                }
            }
            v
        };
        BoundsAt {
            lower: shift(&self.lower, &self.lower_shift),
            upper: shift(&self.upper, &self.upper_shift),
        }
    }

    /// The widest range of each entry over the parameter box: the least
    /// lower and the greatest upper bound over all its corners.
    pub(crate) fn range_over(&self, params: &[Parameter]) -> BoundsAt {
        self.extremes(params, true)
    }

    /// The narrowest range over the parameter box: the greatest lower and
    /// the least upper bound over all its corners.
    pub(crate) fn tightest_over(&self, params: &[Parameter]) -> BoundsAt {
        self.extremes(params, false)
    }

    fn extremes(&self, params: &[Parameter], widest: bool) -> BoundsAt {
        let go = |base: &DVector<f64>, s: &Option<DMatrix<f64>>, down: bool| {
            let mut v = base.clone();
            if let Some(s) = s {
                for i in 0..v.len() {
                    for (j, p) in params.iter().enumerate() {
                        let (a, b) = (s[(i, j)] * p.min, s[(i, j)] * p.max);
                        v[i] += if down { a.min(b) } else { a.max(b) };
                    }
                }
            }
            v
        };
        BoundsAt {
            lower: go(&self.lower, &self.lower_shift, widest),
            upper: go(&self.upper, &self.upper_shift, !widest),
        }
    }

    /// Checks the bounds for `k` entries and `np` parameters; `what` names
    /// them in errors (`"input_bounds"`, `"output_bounds"`, ...).
    pub fn validate(&self, k: usize, params: &[Parameter], what: &str) -> Result<(), MpcError> {
        let np = params.len();
        for (side, v) in [("lower", &self.lower), ("upper", &self.upper)] {
            if v.len() != k {
                return Err(MpcError::dim(
                    format!("{what} {side}"),
                    format!("{k} entries"),
                    format!("{}", v.len()),
                ));
            }
            if v.iter().any(|x| x.is_nan()) {
                return Err(MpcError::NonFinite(format!("{what} {side}")));
            }
        }
        if let Some(i) = (0..k).find(|&i| self.lower[i] == f64::INFINITY) {
            return Err(MpcError::setting(
                format!("{what} lower"),
                format!("entry {i} is +inf; use -inf for no lower bound"),
            ));
        }
        if let Some(i) = (0..k).find(|&i| self.upper[i] == f64::NEG_INFINITY) {
            return Err(MpcError::setting(
                format!("{what} upper"),
                format!("entry {i} is -inf; use +inf for no upper bound"),
            ));
        }
        for (side, s) in [
            ("lower_shift", &self.lower_shift),
            ("upper_shift", &self.upper_shift),
        ] {
            if let Some(s) = s {
                if s.shape() != (k, np) {
                    return Err(MpcError::dim(
                        format!("{what} {side}"),
                        format!("a {k} x {np} matrix (entries x parameters)"),
                        format!("a {} x {} matrix", s.nrows(), s.ncols()),
                    ));
                }
                if s.iter().any(|x| !x.is_finite()) {
                    return Err(MpcError::NonFinite(format!("{what} {side}")));
                }
            }
        }
        // Shifts only move finite bounds.
        for (side, base, s) in [
            ("lower_shift", &self.lower, &self.lower_shift),
            ("upper_shift", &self.upper, &self.upper_shift),
        ] {
            if let Some(s) = s
                && let Some(i) = (0..k).find(|&i| !base[i].is_finite() && s.row(i).amax() > 0.0)
            {
                return Err(MpcError::setting(
                    format!("{what} {side}"),
                    format!("entry {i} shifts an infinite bound"),
                ));
            }
        }
        if let Some(sp) = &self.soft {
            if !(sp.quadratic.is_finite() && sp.quadratic > 0.0) {
                return Err(MpcError::setting(
                    format!("{what} soft penalty quadratic"),
                    format!(
                        "must be finite and > 0 (it keeps the Hessian positive definite), found {}",
                        sp.quadratic
                    ),
                ));
            }
            if !(sp.linear.is_finite() && sp.linear >= 0.0) {
                return Err(MpcError::setting(
                    format!("{what} soft penalty linear"),
                    format!("must be finite and >= 0, found {}", sp.linear),
                ));
            }
        }
        // Hard bounds must admit a value at every parameter of the box:
        // lower - upper is affine in p, so its largest value over the box
        // is at a corner, found entry by entry.
        if self.soft.is_none() {
            for i in 0..k {
                if !(self.lower[i].is_finite() && self.upper[i].is_finite()) {
                    continue;
                }
                let mut gap = self.lower[i] - self.upper[i];
                for (j, p) in params.iter().enumerate() {
                    let c = self.lower_shift.as_ref().map_or(0.0, |s| s[(i, j)])
                        - self.upper_shift.as_ref().map_or(0.0, |s| s[(i, j)]);
                    gap += (c * p.min).max(c * p.max);
                }
                if gap > 0.0 {
                    return Err(MpcError::setting(
                        what,
                        format!(
                            "entry {i}: the lower bound {} is above the upper bound {} (by {gap} at the worst parameter)",
                            self.lower[i], self.upper[i]
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// A hard terminal constraint `A x_N <= b` on the last predicted state (in
/// the model's coordinates).
#[derive(Clone, Debug, PartialEq)]
pub struct TerminalSet {
    /// `A` (`k x nx`).
    pub a: DMatrix<f64>,
    /// `b` (`k`).
    pub b: DVector<f64>,
}

impl TerminalSet {
    /// Checks the shapes for `nx` states.
    pub fn validate(&self, nx: usize) -> Result<(), MpcError> {
        if self.a.ncols() != nx || self.a.nrows() != self.b.len() {
            return Err(MpcError::dim(
                "terminal_set",
                format!("A with {nx} columns and as many rows as b"),
                format!(
                    "A {} x {}, b of {}",
                    self.a.nrows(),
                    self.a.ncols(),
                    self.b.len()
                ),
            ));
        }
        if self.a.iter().chain(self.b.iter()).any(|v| !v.is_finite()) {
            return Err(MpcError::NonFinite("terminal_set".into()));
        }
        Ok(())
    }
}

/// What the input weight `Q2` pulls the inputs towards.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum InputTarget {
    /// The trim `u0` (zero deviation), as in the thesis.
    #[default]
    Zero,
    /// A fixed input (deviation from the trim, `nu` entries).
    Fixed(DVector<f64>),
    /// A parameter: `nu` entries of `theta`, set at run time.
    Parameter,
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{dmatrix, dvector};

    #[test]
    fn validation_names_the_setting() {
        let p = [Parameter::new("t", 0.0, 1.0)];
        let b = Bounds::new(dvector![1.0], dvector![0.0]);
        let e = b.validate(1, &p, "du_bounds").unwrap_err().to_string();
        assert!(e.contains("du_bounds"), "{e}");
        // Feasible at p = 0 but not at p = 1.
        let b = Bounds::new(dvector![0.0], dvector![0.5]).with_soft(SoftPenalty::default());
        assert!(b.validate(1, &p, "y").is_ok());
        let mut b = Bounds::new(dvector![0.0], dvector![0.5]);
        b.upper_shift = Some(dmatrix![-1.0]);
        let e = b.validate(1, &p, "input_bounds").unwrap_err().to_string();
        assert!(
            e.contains("input_bounds") && e.contains("worst parameter"),
            "{e}"
        );
        let b = Bounds::new(dvector![0.0], dvector![1.0]).with_soft(SoftPenalty {
            quadratic: 0.0,
            linear: 1.0,
        });
        let e = b.validate(1, &p, "output_bounds").unwrap_err().to_string();
        assert!(e.contains("output_bounds soft penalty quadratic"), "{e}");
        let b = Bounds::new(dvector![0.0, 0.0], dvector![1.0, 1.0]);
        let e = b.validate(3, &p, "output_bounds").unwrap_err().to_string();
        assert!(
            e.contains("output_bounds lower") && e.contains("3 entries"),
            "{e}"
        );
        let b = Bounds::new(dvector![0.0], dvector![1.0]).shifted(dmatrix![1.0, 2.0]);
        let e = b.validate(1, &p, "input_bounds").unwrap_err().to_string();
        assert!(e.contains("1 x 1"), "{e}");
    }

    #[test]
    fn range_over_the_parameter_box_takes_the_extreme_corners() {
        let p = [
            Parameter::new("a", -1.0, 2.0),
            Parameter::new("b", 0.0, 1.0),
        ];
        let b = Bounds::new(dvector![-1.0], dvector![1.0]).shifted(dmatrix![1.0, -3.0]);
        let r = b.range_over(&p);
        assert_eq!((r.lower[0], r.upper[0]), (-1.0 - 1.0 - 3.0, 1.0 + 2.0));
    }
}
