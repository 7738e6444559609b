//! The whole identification workflow of `kestrel identify` (and of
//! `kestrel pipeline`) as one library call: select intervals, remove the
//! operating point, optional input map and low-pass, N4SID, PEM, `balred`,
//! transmission zeros and the validation table.
//!
//! The [`IdentifySpec`] says what to do, the [`Segment`]s which samples to
//! use, [`identify`] runs it and returns an [`IdentifyReport`].

mod choice;
mod fit;
#[cfg(test)]
mod order_study;
mod prefilter;
mod rate;
mod report;
mod run;
mod segment;
mod select;
#[cfg(test)]
mod select_tests;
mod spec;
#[cfg(test)]
mod tests;

pub use choice::{Candidate, CandidateScore, SelectionReport};
pub use prefilter::{Prefilter, PrefilterChoice, choose_prefilter};
pub use rate::{rate_factor, resample_model};
pub use report::{IdentifyReport, N4sidSummary, PemSummary, ReductionSummary};
pub use run::{SIMULATION_FIT_FLOOR, identify, identify_with_progress};
pub use segment::{SampleSpan, Segment, select_segments};
pub use select::{MIN_FOLD_BLOCK, Progress};
pub use spec::{
    AfterReduction, AutoSelect, IdentifySpec, InputMap, Lowpass, Method, PemFocus, Start,
};
