//! The design-time error type.

/// What can go wrong designing, certifying or exporting a fast-gradient solver.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FgmError {
    /// The problem file is malformed (its own validation failed).
    #[error("invalid problem: {0}")]
    Problem(String),
    /// A constraint row does not bound exactly one variable.
    #[error(
        "constraint row {row} has {nonzeros} non-zero coefficients; the fast gradient method \
         needs box constraints, every row of G bounding a single variable"
    )]
    NotBoxConstraint {
        /// The row of `G`.
        row: usize,
        /// How many non-zero coefficients it has.
        nonzeros: usize,
    },
    /// A variable lacks a lower or an upper bound.
    #[error("the box is unbounded: variable {variable} has no {side} bound")]
    UnboundedBox {
        /// The variable.
        variable: usize,
        /// `"lower"` or `"upper"`.
        side: &'static str,
    },
    /// Two bounds on the same side of a variable cross inside the parameter box.
    #[error(
        "rows {rows:?} both give an {side} bound on variable {variable} and neither is the \
         tighter for every theta: the feasible set is not a box affine in theta"
    )]
    CrossingBounds {
        /// The variable.
        variable: usize,
        /// `"lower"` or `"upper"`.
        side: &'static str,
        /// The two rows of `G`.
        rows: [usize; 2],
    },
    /// The box is empty for some parameter in the parameter box.
    #[error("the box is empty for some theta: variable {variable} has width down to {width}")]
    EmptyBox {
        /// The variable.
        variable: usize,
        /// The smallest width `hi - lo` over the parameter box.
        width: f64,
    },
    /// The Hessian has a negative eigenvalue.
    #[error("the Hessian is not convex: smallest eigenvalue {min_eigenvalue:e} < 0")]
    NotConvex {
        /// The smallest eigenvalue.
        min_eigenvalue: f64,
    },
    /// The tolerance must be a positive finite number.
    #[error("eps must be a positive finite number, got {0}")]
    InvalidEps(f64),
    /// No iteration count within the limit certifies the tolerance.
    #[error(
        "no iteration count up to {limit} certifies J - J* <= {eps:e} for this problem: choose a larger eps"
    )]
    NoIterationBound {
        /// The tolerance asked for.
        eps: f64,
        /// The largest bound reported ([`crate::MAX_ITERATION_BOUND`]).
        limit: usize,
    },
    /// A setting is outside its range.
    #[error("invalid setting: {0}")]
    InvalidSetting(String),
    /// A vector has the wrong length.
    #[error("{what}: expected {expected} entries, found {found}")]
    Dimension {
        /// What the vector is.
        what: &'static str,
        /// The length needed.
        expected: usize,
        /// The length given.
        found: usize,
    },
    /// A vector holds NaN or an infinity.
    #[error("{0}: non-finite value")]
    NonFinite(&'static str),
    /// The preconditioning SDP or the reference QP solve failed.
    #[error("clarabel: {0}")]
    Solver(String),
    /// A fixed-point or float table would overflow or lose the problem.
    #[error("scalar range: {0}")]
    Range(String),
    /// An error of the run-time kernel.
    #[error("run-time solver: {0}")]
    Runtime(#[from] kestrel_core::Error),
}
