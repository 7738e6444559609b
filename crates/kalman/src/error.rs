//! The design-time error type (feature `std`).

use nalgebra::Complex;

/// Why a Riccati equation or a filter design was refused or failed.
///
/// Not `#[non_exhaustive]`: callers in other crates map every variant by
/// name (no wildcard arm that would rename an error added later).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KalmanError {
    /// A matrix has the wrong shape.
    #[error(
        "{name}: expected a {expected_rows} x {expected_cols} matrix, found {found_rows} x {found_cols}"
    )]
    DimensionMismatch {
        /// The matrix, e.g. `"B"`.
        name: &'static str,
        /// Rows it must have.
        expected_rows: usize,
        /// Columns it must have.
        expected_cols: usize,
        /// Rows it has.
        found_rows: usize,
        /// Columns it has.
        found_cols: usize,
    },
    /// A matrix holds NaN or an infinity.
    #[error("{name}: entry ({row}, {col}) is not finite")]
    NonFinite {
        /// The matrix.
        name: &'static str,
        /// Row of the first offending entry.
        row: usize,
        /// Column of the first offending entry.
        col: usize,
    },
    /// A weight or covariance that must be symmetric is not.
    #[error("{name} must be symmetric (relative asymmetry {asymmetry:.1e})")]
    NotSymmetric {
        /// The matrix.
        name: &'static str,
        /// `||M - M'||_F / ||M||_F`.
        asymmetry: f64,
    },
    /// A weight or covariance that must be positive definite is not.
    #[error("{name} must be symmetric positive definite")]
    NotPositiveDefinite {
        /// The matrix.
        name: &'static str,
    },
    /// A weight or covariance that must be positive semidefinite is not.
    #[error("{name} must be positive semidefinite (smallest eigenvalue {min_eigenvalue:.3e})")]
    NotPositiveSemidefinite {
        /// The matrix (for a cross term: `"[Q S; S' R]"`).
        name: &'static str,
        /// Its smallest eigenvalue.
        min_eigenvalue: f64,
    },
    /// `(A, B)` is not stabilisable: the mode `eigenvalue` (|.| >= 1) cannot be moved by the input.
    #[error(
        "(A, B) is not stabilisable: the mode at eigenvalue {} is not reachable from the input (PBH test); for a filter: the process noise does not reach it",
        Mode(*eigenvalue)
    )]
    NotStabilizable {
        /// The unstable, uncontrollable eigenvalue of `A`.
        eigenvalue: Complex<f64>,
    },
    /// `(A, Q)` is not detectable: the mode `eigenvalue` (|.| >= 1) is not seen by the state weight.
    #[error(
        "(A, Q) is not detectable: the mode at eigenvalue {} is not seen by the weight Q (PBH test); for a filter: the output does not observe it",
        Mode(*eigenvalue)
    )]
    NotDetectable {
        /// The unstable, unobservable eigenvalue of `A`.
        eigenvalue: Complex<f64>,
    },
    /// The Riccati equation has no stabilising solution although the PBH
    /// tests pass (for instance a mode exactly on the unit circle).
    #[error("no stabilising solution: {reason}")]
    NoStabilizingSolution {
        /// What was observed.
        reason: String,
    },
    /// The solver stopped with a residual above the acceptance threshold.
    #[error(
        "the Riccati solver did not converge: relative residual {residual:.3e} after {iterations} iterations"
    )]
    NotConverged {
        /// Doubling iterations (plus refinement steps) spent.
        iterations: usize,
        /// Relative residual of the best iterate.
        residual: f64,
    },
    /// The disturbance states of an augmented model cannot be estimated:
    /// `rank [A - I, Bd; C, Cd] < nx + nd` (at steady state a disturbance
    /// cannot be told from a state; for instance an output offset on a
    /// plant with an integrator, or more disturbances than outputs).
    #[error(
        "the disturbance model is not detectable: rank [A - I, Bd; C, Cd] = {rank} < nx + nd = {required}"
    )]
    DisturbanceNotDetectable {
        /// The numerical rank found.
        rank: usize,
        /// `nx + nd`.
        required: usize,
    },
    /// A parameter is outside its documented range.
    #[error("invalid argument {name}: {reason}")]
    InvalidArgument {
        /// The parameter.
        name: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A run-time conversion failed (for instance a const dimension that does not match).
    #[error("run-time filter: {0}")]
    Core(#[from] kestrel_core::Error),
}

/// A number as the messages print it: six decimals, in exponent notation
/// outside `[1e-3, 1e6)` (Rust's `{:.6}` writes every digit of 1e300).
pub(crate) struct Num(pub(crate) f64);

impl core::fmt::Display for Num {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let (x, a) = (self.0, self.0.abs());
        match (a == 0.0 || (1e-3..1e6).contains(&a), f.sign_plus()) {
            (true, false) => write!(f, "{x:.6}"),
            (true, true) => write!(f, "{x:+.6}"),
            (false, false) => write!(f, "{x:.6e}"),
            (false, true) => write!(f, "{x:+.6e}"),
        }
    }
}

/// An eigenvalue as the messages print it: `re +im i (|.| = abs)`.
struct Mode(Complex<f64>);

impl core::fmt::Display for Mode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let z = self.0;
        write!(
            f,
            "{} {:+}i (|.| = {})",
            Num(z.re),
            Num(z.im),
            Num(z.norm())
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_print_compactly() {
        let e = KalmanError::NotStabilizable {
            eigenvalue: Complex::new(1.5, -0.25),
        };
        assert_eq!(
            e.to_string(),
            "(A, B) is not stabilisable: the mode at eigenvalue 1.500000 -0.250000i (|.| = 1.520691) is not reachable from the input (PBH test); for a filter: the process noise does not reach it"
        );
        let e = KalmanError::NotDetectable {
            eigenvalue: Complex::new(1e300, 0.0),
        };
        let text = e.to_string();
        assert!(
            text.contains("eigenvalue 1.000000e300 +0.000000i (|.| = 1.000000e300)"),
            "{text}"
        );
        assert!(text.len() < 200, "{text}");
        assert_eq!(format!("{}", Num(-2.5e-7)), "-2.500000e-7");
        assert_eq!(format!("{:+}", Num(0.0)), "+0.000000");
    }
}
