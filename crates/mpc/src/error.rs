//! The design-time error type of the crate.

use kestrel_core::formats::FormatError;

/// What went wrong building, solving or simulating an MPC problem.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MpcError {
    /// A matrix or vector has the wrong shape for the model.
    #[error("{what}: expected {expected}, found {found}")]
    Dimension {
        /// The offending quantity (`"Q1"`, `"input bounds lower"`, ...).
        what: String,
        /// The shape it must have.
        expected: String,
        /// The shape it has.
        found: String,
    },
    /// A matrix or vector holds NaN or an infinity.
    #[error("{0} contains NaN or an infinity")]
    NonFinite(String),
    /// A setting is outside its range.
    #[error("invalid setting {what}: {reason}")]
    InvalidSetting {
        /// The setting.
        what: String,
        /// Why it is refused.
        reason: String,
    },
    /// The input bounds admit no input.
    #[error(
        "infeasible input bounds: input {input} has lower bound {lower} above upper bound {upper}"
    )]
    InfeasibleBounds {
        /// Index of the input.
        input: usize,
        /// Its lower bound (deviation from the trim).
        lower: f64,
        /// Its upper bound (deviation from the trim).
        upper: f64,
    },
    /// A weight or the condensed Hessian is not symmetric.
    #[error("{what} is not symmetric (largest asymmetry {asymmetry:e})")]
    NotSymmetric {
        /// The matrix.
        what: String,
        /// `max |M - M'|`.
        asymmetry: f64,
    },
    /// A weight is not positive semidefinite, or the condensed Hessian `H`
    /// is not positive definite.
    #[error("{what} is not positive {kind}definite (smallest eigenvalue {min_eigenvalue:e})")]
    NotPositiveDefinite {
        /// The matrix.
        what: String,
        /// `"semi"` for weights that may be singular, `""` for `H`.
        kind: &'static str,
        /// Its smallest eigenvalue.
        min_eigenvalue: f64,
    },
    /// The model has a non-zero feed-through `D`; the thesis formulation
    /// (6.3c) assumes `y = C x`.
    #[error(
        "the model has a non-zero feed-through D (largest entry {max_abs:e}); the MPC needs y = C x"
    )]
    FeedThrough {
        /// `max |D_ij|`.
        max_abs: f64,
    },
    /// The LQ terminal weight could not be computed.
    #[error("LQ terminal weight: {0}")]
    Terminal(String),
    /// The QP at this parameter has no feasible point.
    #[error("the QP is infeasible at this parameter")]
    Infeasible,
    /// The reference solver stopped without a solution.
    #[error("QP solver stopped with status {0}")]
    Solver(String),
    /// A solver of another crate plugged into the MPC law (the explicit
    /// solver of kestrel-empc, the fast gradient method of kestrel-fgm)
    /// refused the problem or failed.
    #[error("{solver}: {reason}")]
    ExternalSolver {
        /// `"explicit MPC"` or `"fast gradient"`.
        solver: &'static str,
        /// The solver's message.
        reason: String,
    },
    /// The problem is too large to condense: the estimated memory or
    /// time exceeds a documented limit (see [`CondensingCost`](crate::CondensingCost)).
    #[error("{what} is too large to condense: it would need {cost} ({limit})")]
    TooLarge {
        /// The size asked for.
        what: String,
        /// What it would cost.
        cost: String,
        /// The limits.
        limit: String,
    },
    /// An interchange file is malformed.
    #[error(transparent)]
    Format(#[from] FormatError),
    /// A run-time error of the shared core.
    #[error(transparent)]
    Core(#[from] kestrel_core::Error),
}

impl MpcError {
    /// A [`MpcError::Dimension`] error: `what` should have the shape
    /// `expected` and has `found`.
    ///
    /// ```
    /// use kestrel_mpc::MpcError;
    ///
    /// let e = MpcError::dim("Q1", "3 x 3", "2 x 2");
    /// assert_eq!(e.to_string(), "Q1: expected 3 x 3, found 2 x 2");
    /// ```
    pub fn dim(
        what: impl Into<String>,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> Self {
        MpcError::Dimension {
            what: what.into(),
            expected: expected.into(),
            found: found.into(),
        }
    }
    /// A [`MpcError::InvalidSetting`] error: the setting `what` is refused
    /// because of `reason`.
    ///
    /// ```
    /// use kestrel_mpc::MpcError;
    ///
    /// let e = MpcError::setting("horizon", "must be at least 1");
    /// assert_eq!(e.to_string(), "invalid setting horizon: must be at least 1");
    /// ```
    pub fn setting(what: impl Into<String>, reason: impl Into<String>) -> Self {
        MpcError::InvalidSetting {
            what: what.into(),
            reason: reason.into(),
        }
    }
}
