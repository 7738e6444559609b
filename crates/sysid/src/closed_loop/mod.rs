//! Closed-loop-consistent identification from a high-order VARX step:
//! predictor-based subspace identification (PBSID) and the ARX model
//! reduced by balanced truncation.
//!
//! One file per part: the [`settings`] and result, the [`pbsid`]
//! algorithm, [`arx_reduction`] and [`stabilise`] for starts with
//! unstable modes.

mod arx_reduction;
mod pbsid;
mod settings;
mod stabilise;
#[cfg(test)]
mod tests;

pub use arx_reduction::{ArxReduction, ArxReductionSettings, MAX_REALISATION, arx_reduction};
pub use pbsid::pbsid;
pub use settings::{PBSID_PAST, PbsidResult, PbsidSettings};
pub use stabilise::stabilise_a;
