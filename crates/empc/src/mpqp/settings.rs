//! The settings of the mpQP solver.

/// Settings of the mpQP solver.
#[derive(Clone, Debug)]
pub struct Settings {
    /// A region (or facet) whose largest inscribed ball has a radius below
    /// `radius_tol * max(1, |theta bounds|)` counts as lower-dimensional.
    pub radius_tol: f64,
    /// Step beyond a facet (relative to the parameter scale) to probe the neighbour.
    pub step: f64,
    /// Stop with [`EmpcError::TooManyRegions`](crate::EmpcError::TooManyRegions) beyond this many regions.
    pub max_regions: usize,
    /// In degenerate points, try all subsets of at most this many active constraints.
    pub max_degenerate_set: usize,
    /// Explore in parallel (needs the `parallel` feature; ignored otherwise).
    pub parallel: bool,
    /// Show a progress bar on standard error (needs the `progress` feature).
    pub progress: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            radius_tol: 1e-8,
            step: 1e-6,
            max_regions: 200_000,
            max_degenerate_set: 12,
            parallel: true,
            progress: false,
        }
    }
}
