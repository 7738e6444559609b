//! The certification's settings and its progress report.

use super::error::CertifyError;
use kestrel_qp::QpSettings;
use std::time::Duration;

/// What the certification needs and how far it may go.
#[derive(Debug, Clone, PartialEq)]
pub struct CertifySettings {
    /// The solver settings certified (tolerances, iteration cap): the
    /// decisions are mirrored with these values.
    pub qp: QpSettings,
    /// Warm start: also certify a start from the previous period's optimal
    /// active set with `|theta_k - theta_prev,k| <= step (ub_k - lb_k)`
    /// (a fraction of each parameter's box width). `None`: cold only.
    pub warm_step: Option<f64>,
    /// The most regions (finished plus open) of one run before
    /// [`CertifyError::Limit`]. Default 2,000,000.
    pub max_regions: usize,
    /// The longest the whole certification may take before
    /// [`CertifyError::Limit`]. Default 10 minutes.
    pub time_limit: Option<Duration>,
    /// Regions whose largest inscribed ball (in the box normalised to `[-1,
    /// 1]^p`) is smaller are lower-dimensional and dropped. Default 1e-9.
    pub min_radius: f64,
    /// Warm start from the previous optimal active set in any stored order
    /// (every permutation certified: the solver re-adds the set in its
    /// stored order, and the order can change the path) instead of sorted
    /// by constraint index. Sets of at most 8 constraints. Default off.
    pub warm_any_order: bool,
    /// Random walks of the up-front size estimate ([`crate::certify::Estimate`]):
    /// the certification is refused with [`CertifyError::TooLarge`] when the
    /// estimated regions exceed `max_regions` or the estimated time is more
    /// than four times `time_limit`. 0: no estimate. Default 64.
    pub estimate_probes: usize,
    /// Keep every region (for [`crate::certify::Certificate::iterations_at`]); off for
    /// large problems to save memory. Default on.
    pub keep_regions: bool,
    /// `Some(h)`: over-approximate by merging on canonical solver states
    /// (after every full dual step the solver's future depends on its
    /// active set and the parameter only), remembering `h >= 1` segments
    /// of history: an upper bound on iterations and flops valid for every
    /// parameter, `exact: false`, no regions kept, no up-front estimate;
    /// `max_regions` then limits the memoised bounds (and the pieces kept
    /// for them to 4 GB, as the same region limit). Larger `h` is
    /// tighter and slower. docs/qp-certify.md. Default `None` (the exact
    /// partition).
    pub merge: Option<usize>,
    /// Exact certification with regions merged: explored breadth first by
    /// iteration count, the regions reaching the same canonical solver
    /// state (active set after a full dual step) after the same count are
    /// merged wherever their union is convex (module `union`,
    /// docs/qp-certify.md). Iterations stay exact; the flops become an
    /// upper bound where merged regions' flops or list orders differed
    /// ([`crate::certify::UnionStats::flops_exact`]). The up-front
    /// estimate (of the exact partition, which bounds the merged one) and
    /// its limits apply as in the exact mode. Default off.
    pub union_merge: bool,
}

impl Default for CertifySettings {
    fn default() -> Self {
        CertifySettings {
            qp: QpSettings::default(),
            warm_step: None,
            max_regions: 2_000_000,
            time_limit: Some(Duration::from_secs(600)),
            min_radius: 1e-9,
            warm_any_order: false,
            estimate_probes: 64,
            keep_regions: true,
            merge: None,
            union_merge: false,
        }
    }
}

impl CertifySettings {
    /// Checks the fields: valid solver settings, a warm step in `(0, 1]`,
    /// at least one region, a positive time limit, a radius in `(0, 1)`.
    pub fn validate(&self) -> Result<(), CertifyError> {
        let bad = |s: &str| Err(CertifyError::InvalidSettings(s.to_string()));
        if self.qp.validate().is_err() {
            return bad("qp: a solver setting is out of range");
        }
        if let Some(s) = self.warm_step
            && !(s > 0.0 && s <= 1.0)
        {
            return bad("warm_step must be in (0, 1] (a fraction of the box width)");
        }
        if self.max_regions == 0 {
            return bad("max_regions must be at least 1");
        }
        if self.time_limit.is_some_and(|t| t.is_zero()) {
            return bad("time_limit must be positive");
        }
        if !(self.min_radius > 0.0 && self.min_radius < 1.0) {
            return bad("min_radius must be in (0, 1)");
        }
        if self.merge == Some(0) {
            return bad("merge must be at least 1 segment of history");
        }
        if self.merge.is_some() && self.union_merge {
            return bad("merge and union_merge exclude each other");
        }
        if self.merge.is_some() && self.warm_any_order {
            return bad("merge does not support warm_any_order");
        }
        Ok(())
    }
}

/// How far a certification has got (for a progress display).
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    /// `"cold"` or `"warm"`.
    pub phase: &'static str,
    /// Finished regions of this phase.
    pub regions: usize,
    /// Regions still to split.
    pub open: usize,
    /// Regions split so far.
    pub nodes: usize,
    /// LPs solved (all phases).
    pub lps: usize,
    /// The most iterations of a finished region so far.
    pub worst_iterations: usize,
    /// Warm start: start sets done.
    pub start_sets_done: usize,
    /// Warm start: start sets (critical regions) in all.
    pub start_sets: usize,
    /// Time since the start.
    pub elapsed: Duration,
    /// The up-front size estimate, once (then `None`).
    pub estimate: Option<crate::certify::Estimate>,
    /// Merged mode: canonical states memoised so far (0 otherwise).
    pub states: usize,
}
