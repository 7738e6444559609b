//! MIMO ARX models by linear least squares: the baseline every state-space
//! model should beat, a start for the closed-loop methods, and an exact
//! state-space realisation.
//!
//! One file per part: the [`model`] and its settings, the least-squares
//! [`estimate`], the k-step [`predict`]ion and its fit, the exact
//! [`realise`]ation as an [`InnovationModel`](crate::InnovationModel), and
//! the [`baseline`] of the fit tables (best of several lag counts).

mod baseline;
mod estimate;
mod model;
mod predict;
mod realise;
#[cfg(test)]
mod tests;

pub use baseline::{ArxBaseline, ArxBaselineCandidate, ArxBaselineRow, arx_baseline};
pub(crate) use estimate::{
    CHUNK, NormalEquations, arx_with_normal_equations, solve_normal_equations,
};
pub use estimate::{MAX_ARX_OPERATIONS, arx};
pub(crate) use model::default_lags;
pub use model::{ArxModel, ArxSettings};
