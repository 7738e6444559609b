//! Why a certification fails.

use kestrel_qp::parametric::ParametricError;
use std::time::Duration;

/// Why a certification failed.
#[derive(Debug, thiserror::Error)]
pub enum CertifyError {
    /// The problem cannot be put in the solver's form.
    #[error(transparent)]
    Problem(#[from] ParametricError),
    /// `H` is not positive definite.
    #[error("H is not positive definite")]
    NotPositiveDefinite,
    /// A settings field is out of range.
    #[error("invalid certification settings: {0}")]
    InvalidSettings(String),
    /// The parameter set (the box cut by the problem's `theta_poly`) has
    /// no interior.
    #[error("the parameter set (the box and theta_poly) has no interior: nothing to certify")]
    EmptyParameterSet,
    /// For some parameters of the set a constraint's lower bound exceeds
    /// its upper bound: the solver refuses them
    /// ([`kestrel_qp::QpError::InvalidBounds`]) before any iteration, so
    /// there is no iteration count to certify there.
    #[error(
        "the bounds of constraint {constraint} cross inside the parameter set (at theta = {theta:?} its lower bound {lower:.6e} exceeds its upper bound {upper:.6e}); the solver refuses such parameters (invalid bounds): shrink the parameter set or correct the rows"
    )]
    CrossedBounds {
        /// The constraint (`r3`: general row 3; `b0`: the bound on `z_0`).
        constraint: String,
        /// A parameter where they cross (the centre of the largest ball
        /// inside the crossing part of the set).
        theta: Vec<f64>,
        /// The lower bound there.
        lower: f64,
        /// The upper bound there.
        upper: f64,
    },
    /// A linear algebra step failed.
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// The region or time limit was reached: the problem is too large for
    /// these settings.
    #[error(
        "{what} limit reached in the {phase} certification after {elapsed:.1?}: {regions} regions finished (the most iterations on them {worst_so_far}, a lower bound of the worst case), {open} open, {nodes} split, deepest path {deepest} iterations, start sets {start_sets_done} of {start_sets}; raise max_regions / time_limit or certify a smaller parameter set"
    )]
    Limit {
        /// `"region"` or `"time"`.
        what: &'static str,
        /// `"cold"` or `"warm"`.
        phase: &'static str,
        /// Finished regions.
        regions: usize,
        /// Open regions.
        open: usize,
        /// Regions split.
        nodes: usize,
        /// The longest path seen.
        deepest: usize,
        /// The most iterations of a finished region.
        worst_so_far: usize,
        /// Warm start sets done.
        start_sets_done: usize,
        /// Warm start sets in all.
        start_sets: usize,
        /// Time spent.
        elapsed: Duration,
    },
    /// The up-front estimate says the partition is too large for the
    /// settings' limits.
    #[error(
        "the cold-start partition is estimated at {} regions and {} s (random walks), beyond max_regions {max_regions}{}; raise the limits or certify a smaller parameter set",
        Count(*regions), Count(*seconds),
        time_limit.map_or(String::new(), |t| format!(" or four times the time limit ({} s)", Count(t.as_secs_f64())))
    )]
    TooLarge {
        /// Estimated regions.
        regions: f64,
        /// Estimated seconds.
        seconds: f64,
        /// The settings' region limit.
        max_regions: usize,
        /// The settings' time limit.
        time_limit: Option<Duration>,
    },
}

/// A count as the messages print it: whole below 1e7, else in exponent
/// notation (`{:.0}` writes every digit of 3e128).
pub struct Count(pub f64);

impl std::fmt::Display for Count {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.abs() < 1e7 {
            write!(f, "{:.0}", self.0)
        } else {
            write!(f, "{:.1e}", self.0)
        }
    }
}
