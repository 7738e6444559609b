//! Closed-loop-consistent subspace identification: predictor-based
//! subspace identification (PBSID) from a high-order VARX step.
//!
//! One file per part: the [`settings`] and result, the [`pbsid`]
//! algorithm.

mod pbsid;
mod settings;
#[cfg(test)]
mod tests;

pub use pbsid::pbsid;
pub use settings::{PbsidResult, PbsidSettings};
