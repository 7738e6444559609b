//! The solver's error type.

use core::fmt;

/// Why a set-up or a solve failed. `Copy`, no payload beyond sizes, so
/// firmware can match on it and apply its safe input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QpError {
    /// A slice had the wrong length (the workspace too short, `H` not
    /// `n x n`, `G` not `m x n`, a vector not `n` or `m` long) or `n` is 0.
    Dimension {
        /// The length the solver needs.
        expected: usize,
        /// The length it was given.
        found: usize,
    },
    /// An input contained NaN or an infinity where a finite value is
    /// required (`H`, `G`, `q`), or a bound is NaN.
    NonFinite,
    /// `H` is not (numerically) positive definite: a pivot of its LDL'
    /// factorisation was not positive.
    NotPositiveDefinite,
    /// A lower bound exceeds its upper bound.
    InvalidBounds,
    /// A [`crate::QpSettings`] field is out of range (see
    /// [`crate::QpSettings::validate`]).
    InvalidSettings,
    /// A warm-start active set names a constraint that does not exist,
    /// names one twice, or has more than `n` entries.
    InvalidActiveSet,
    /// The constraints admit no solution (a violated constraint is a
    /// combination of active ones with no multiplier to release: the dual
    /// is unbounded).
    Infeasible,
    /// [`crate::QpSettings::max_iterations`] active-set changes were made
    /// without reaching the optimum.
    IterationLimit,
}

impl fmt::Display for QpError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            QpError::Dimension { expected, found } => {
                write!(f, "dimension mismatch: expected {expected}, found {found}")
            }
            QpError::NonFinite => f.write_str("an input is not finite"),
            QpError::NotPositiveDefinite => f.write_str("H is not positive definite"),
            QpError::InvalidBounds => f.write_str("a lower bound exceeds its upper bound"),
            QpError::InvalidSettings => f.write_str("a solver setting is out of range"),
            QpError::InvalidActiveSet => f.write_str("invalid warm-start active set"),
            QpError::Infeasible => f.write_str("the constraints are infeasible"),
            QpError::IterationLimit => f.write_str("iteration limit reached"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for QpError {}

impl From<QpError> for kestrel_core::Error {
    fn from(e: QpError) -> Self {
        match e {
            QpError::Dimension { expected, found } => {
                kestrel_core::Error::DimensionMismatch { expected, found }
            }
            QpError::NonFinite => kestrel_core::Error::NonFinite,
            QpError::NotPositiveDefinite => kestrel_core::Error::NotPositiveDefinite,
            QpError::InvalidBounds => kestrel_core::Error::InvalidArgument("bounds: lower > upper"),
            QpError::InvalidSettings => kestrel_core::Error::InvalidArgument("QP settings"),
            QpError::InvalidActiveSet => {
                kestrel_core::Error::InvalidArgument("warm-start active set")
            }
            QpError::Infeasible => kestrel_core::Error::Infeasible,
            QpError::IterationLimit => kestrel_core::Error::NotConverged,
        }
    }
}
