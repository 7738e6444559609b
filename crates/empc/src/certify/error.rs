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
        "the cold-start partition is estimated at {regions:.0} regions and {seconds:.0} s (random walks), beyond max_regions {max_regions} or four times the time limit {time_limit:?}; raise the limits or certify a smaller parameter set"
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
