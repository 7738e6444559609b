//! What [`pbsid`](crate::pbsid()) does and what it returns.

use crate::model::InnovationModel;

/// The past horizon (VARX lags) of [`pbsid`](crate::pbsid()) when
/// [`PbsidSettings::past`] is `None` and the record is long enough.
pub const PBSID_PAST: usize = 20;

/// Settings of [`pbsid`](crate::pbsid()).
#[derive(Clone, Debug, PartialEq)]
pub struct PbsidSettings {
    /// Model order; `None` takes the order suggested by the largest gap
    /// of the singular values (up to [`max_order`](Self::max_order)).
    pub order: Option<usize>,
    /// Largest order considered when suggesting one.
    pub max_order: usize,
    /// Past horizon `p`: the order of the VARX predictor, the number of
    /// past samples the state is estimated from. It must be long enough
    /// for `(A - K C)^p` to be negligible (the predictor's memory); the
    /// bias of the method decays with it. `None` takes [`PBSID_PAST`],
    /// or on a record too short for that VARX the largest past from
    /// which `p ny` exceeds the largest order considered and whose VARX
    /// has at least twice as many regression rows as parameters per
    /// output ([`PbsidResult::past`] holds the one used).
    pub past: Option<usize>,
    /// Future horizon `f` (block rows of the predictor's observability
    /// matrix, `f ny > order`); `None` takes `p`.
    pub future: Option<usize>,
    /// Estimate a feed-through `D` (the VARX then includes `u(t)`).
    pub feedthrough: bool,
    /// Largest spectral radius of `A`: modes estimated outside it (the
    /// integrators of a rate loop come out at `|z|` slightly above 1 on
    /// closed-loop data) are moved radially onto it and `B`, `K` refitted
    /// with that `A` fixed, so that the model can start
    /// [`pem`](crate::pem()), which needs a stable `A`. `None` keeps `A`
    /// as estimated (the predictor `A - K C` is stable either way).
    pub max_radius: Option<f64>,
}

impl Default for PbsidSettings {
    /// Order suggested up to 10, past and future horizon
    /// [`PBSID_PAST`] (fewer on a short record), no `D`, `A` kept
    /// inside `|z| <= 0.999`.
    fn default() -> Self {
        PbsidSettings {
            order: None,
            max_order: 10,
            past: None,
            future: None,
            feedthrough: false,
            max_radius: Some(0.999),
        }
    }
}

/// Result of [`pbsid`](crate::pbsid()).
#[derive(Clone, Debug, PartialEq)]
pub struct PbsidResult {
    /// The estimated innovation model (in the units of the data), `K`
    /// included.
    pub model: InnovationModel,
    /// Singular values of the weighted product of the predictor's
    /// observability and controllability matrices, descending.
    pub singular_values: Vec<f64>,
    /// The order suggested by their largest gap.
    pub suggested_order: usize,
    /// The order used.
    pub order: usize,
    /// The past horizon used.
    pub past: usize,
    /// The future horizon used.
    pub future: usize,
    /// Spectral radius of `A` as estimated, before any move onto
    /// [`PbsidSettings::max_radius`].
    pub radius_estimated: f64,
}
