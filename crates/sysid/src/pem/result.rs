//! What [`pem`](crate::pem()) returns.

#[cfg(doc)]
use super::settings::{Criterion, PemSettings};
use crate::model::InnovationModel;
use nalgebra::DVector;

pub use crate::lm::StopReason;

/// Result of [`pem`](crate::pem()).
#[derive(Clone, Debug, PartialEq)]
pub struct PemResult {
    /// The estimated model, in the units of the data.
    pub model: InnovationModel,
    /// Estimated initial state of every experiment (of the predictor).
    pub x0: Vec<DVector<f64>>,
    /// Estimated initial state of the simulation term of every
    /// experiment (empty unless [`PemSettings::simulation_weight`] is
    /// positive).
    pub simulation_x0: Vec<DVector<f64>>,
    /// Mean squared prediction error of the outputs scaled to unit
    /// variance (over the steps `1..=horizon`, or [`PemSettings::steps`],
    /// and, with a simulation term, over the simulation errors too,
    /// unweighted), at the start.
    pub initial_cost: f64,
    /// The same at the end.
    pub cost: f64,
    /// `det` of the residual covariance (of the scaled outputs; prediction
    /// errors only) at the end.
    pub det_cost: f64,
    /// The weighted criterion after every accepted iteration (the first
    /// entry is the start; with [`Criterion::Determinant`] and [`Criterion::Fit`] the weight is
    /// renewed every iteration, so only consecutive entries compare).
    pub history: Vec<f64>,
    /// Iterations (Jacobian evaluations) done.
    pub iterations: usize,
    /// Cost evaluations done (including rejected trial steps).
    pub evaluations: usize,
    /// Free parameters after removing the similarity directions.
    pub free_parameters: usize,
    /// Why the search stopped.
    pub stop: StopReason,
}
