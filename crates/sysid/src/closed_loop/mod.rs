//! Closed-loop-consistent subspace identification: predictor-based
//! subspace identification (PBSID) from a high-order VARX step.
//!
//! One file per part: the [`settings`] and result, the [`pbsid`]
//! algorithm, and [`stabilise`] for starts with unstable modes.

mod pbsid;
mod settings;
mod stabilise;
#[cfg(test)]
mod tests;

pub use pbsid::pbsid;
pub use settings::{PbsidResult, PbsidSettings};
pub use stabilise::stabilise_a;
