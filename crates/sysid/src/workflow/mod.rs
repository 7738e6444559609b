//! The whole identification workflow of `kestrel identify` (and of
//! `kestrel pipeline`) as one library call: select intervals, remove the
//! operating point, optional input map and low-pass, N4SID, PEM, `balred`,
//! transmission zeros and the validation table.
//!
//! The [`IdentifySpec`] says what to do, the [`Segment`]s which samples to
//! use, [`identify`] runs it and returns an [`IdentifyReport`].

mod report;
mod run;
mod segment;
mod spec;
#[cfg(test)]
mod tests;

pub use report::{IdentifyReport, N4sidSummary, PemSummary, ReductionSummary};
pub use run::identify;
pub use segment::{Segment, select_segments};
pub use spec::{AfterReduction, IdentifySpec, InputMap, Lowpass, Method, PemFocus};
