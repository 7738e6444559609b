//! What [`n4sid`](crate::n4sid()) does and what it returns.

use crate::model::InnovationModel;
use nalgebra::DVector;

/// The weighting of the oblique projection before the SVD.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Weighting {
    /// MOESP: `W1 = I`, `W2` the projection onto the orthogonal complement
    /// of the future inputs (the SVD of `L32` of the LQ factor).
    #[default]
    Moesp,
    /// Canonical variate analysis: as MOESP with `W1` the inverse square
    /// root of the covariance of the future outputs with the future inputs
    /// projected out; singular values are canonical correlations.
    Cva,
    /// Unweighted N4SID (`W1 = I`, `W2 = I`).
    Unweighted,
}

/// How [`n4sid`](crate::n4sid()) estimates the system matrices once the SVD has given the
/// extended observability matrix `Gamma`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MatrixEstimate {
    /// `A`, `C` from the shift invariance of `Gamma`; `B`, `D` and the
    /// initial states by output-error least squares with `A`, `C` fixed
    /// (the simulation error is linear in them); `K` from the residuals of
    /// the state sequence with these matrices.
    #[default]
    OutputError,
    /// `A`, `B`, `C`, `D` together by least squares on the state sequence
    /// `Gamma^+ O_i` and its shift (Van Overschee and De Moor's
    /// algorithm 2, as SIPPY and nfoursid do), and `K` from the residual
    /// covariances of that same regression (a Riccati equation): one
    /// consistent fit of the one-step predictor rather than of the
    /// simulation. The initial states are then least squares with the
    /// matrices fixed.
    StateRegression,
}

/// Settings of [`n4sid`](crate::n4sid()).
#[derive(Clone, Debug, PartialEq)]
pub struct N4sidSettings {
    /// Model order; `None` takes the suggested order.
    pub order: Option<usize>,
    /// Largest order considered when suggesting one.
    pub max_order: usize,
    /// Number of block rows `i` of the future (and of the past unless
    /// [`past_horizon`](Self::past_horizon) is set); `None` chooses
    /// `max(10, ceil((n_max + 1) / ny) + 1)`, or on a record too short
    /// for that horizon's block Hankel matrix the largest shorter one that
    /// fits with `i ny > n_max` (the result's [`N4sidResult::horizon`]
    /// says which).
    pub horizon: Option<usize>,
    /// Number of block rows `p` of the past when it differs from the
    /// future's; `None` takes the future horizon. A past longer than the
    /// future brings the state estimates closer to a stationary Kalman
    /// filter's (Jansson; Chiuso); on the DaISy steam generator it did
    /// not improve the model.
    pub past_horizon: Option<usize>,
    /// The weighting.
    pub weighting: Weighting,
    /// Estimate a feed-through `D` (otherwise `D = 0`).
    pub feedthrough: bool,
    /// Estimate the innovation gain `K` (otherwise `K = 0`).
    pub estimate_k: bool,
    /// How the system matrices follow from `Gamma`.
    pub matrices: MatrixEstimate,
}

impl Default for N4sidSettings {
    fn default() -> Self {
        N4sidSettings {
            order: None,
            max_order: 10,
            horizon: None,
            past_horizon: None,
            weighting: Weighting::default(),
            feedthrough: false,
            estimate_k: true,
            matrices: MatrixEstimate::default(),
        }
    }
}

/// Result of [`n4sid`](crate::n4sid()).
#[derive(Clone, Debug, PartialEq)]
pub struct N4sidResult {
    /// The estimated model (in the units of the data).
    pub model: InnovationModel,
    /// Estimated initial state of every experiment.
    pub x0: Vec<DVector<f64>>,
    /// The singular values of the weighted oblique projection.
    pub singular_values: Vec<f64>,
    /// The order suggested by the largest gap of the singular values.
    pub suggested_order: usize,
    /// The order used.
    pub order: usize,
    /// The horizon `i` used.
    pub horizon: usize,
}
