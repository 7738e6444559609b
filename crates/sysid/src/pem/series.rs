//! The data as the residual recursions read them.

use crate::data::IoData;

/// Experiments as row-major sample arrays (scaled).
pub(super) struct Series {
    /// Samples.
    pub(super) n: usize,
    /// Inputs, `n x nu` row-major.
    pub(super) u: Vec<f64>,
    /// Outputs, `n x ny` row-major.
    pub(super) y: Vec<f64>,
}

/// The experiments of `data` as [`Series`].
pub(super) fn series_of(data: &IoData) -> Vec<Series> {
    data.experiments()
        .iter()
        .map(|e| Series {
            n: e.len(),
            u: (0..e.len())
                .flat_map(|t| e.u.row(t).iter().copied().collect::<Vec<_>>())
                .collect(),
            y: (0..e.len())
                .flat_map(|t| e.y.row(t).iter().copied().collect::<Vec<_>>())
                .collect(),
        })
        .collect()
}
