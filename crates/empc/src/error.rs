//! The design-time error type.

use kestrel_core::formats::FormatError;

/// What can go wrong at design time (solving, reducing, building the tree,
/// reading or exporting a solution).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EmpcError {
    /// The problem file or solution file is malformed.
    #[error(transparent)]
    Format(#[from] FormatError),
    /// The parameter set is not bounded.
    #[error("the parameter set is unbounded: {0}")]
    UnboundedParameterSet(String),
    /// `H` is not symmetric positive definite.
    #[error(
        "H is not positive definite (Cholesky failed or its smallest pivot {min_pivot:e} is not positive); the explicit solution needs a strictly convex QP"
    )]
    IndefiniteHessian {
        /// The smallest Cholesky pivot found (or NaN if the factorisation broke down).
        min_pivot: f64,
    },
    /// No parameter of the parameter set makes the QP feasible.
    #[error("the feasible set is empty: no parameter in the parameter set makes the QP feasible")]
    EmptyFeasibleSet,
    /// The QP is feasible only on a lower-dimensional set of parameters.
    #[error(
        "the set of parameters with a feasible QP has no interior (largest inscribed ball radius {radius:e}); there are no full-dimensional regions"
    )]
    NoInterior {
        /// The radius of the largest ball found.
        radius: f64,
    },
    /// The exploration found more regions than allowed by the settings.
    #[error("more than {0} critical regions; raise Settings::max_regions")]
    TooManyRegions(usize),
    /// An inner LP or QP failed (iteration limit or breakdown).
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// An argument is out of its range (text says which).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// The tables do not fit the `u16` indices of the exported format.
    #[error("the tables are too large for u16 indices: {0}")]
    TooLarge(String),
}
