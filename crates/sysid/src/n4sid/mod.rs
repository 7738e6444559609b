//! Subspace identification (N4SID family) with MOESP or CVA weighting.
//!
//! One file per operation: the [`settings`] and result, the [`scaling`] of
//! the signals, the [`subspace`] algorithm itself, the
//! [`state_sequence`] regression, the [`output_error`] least squares, the
//! stabilising [`gain`] and the suggested [`order`].

mod gain;
mod limits;
mod order;
mod output_error;
mod scaling;
mod settings;
mod state_sequence;
mod subspace;
#[cfg(test)]
mod tests;

pub(crate) use gain::stabilise_k;
pub use limits::{MAX_HANKEL_BYTES, MAX_ORDER, model_parameters};
pub use order::suggest_order;
pub(crate) use scaling::Scaling;
pub use settings::{MatrixEstimate, N4sidResult, N4sidSettings, Weighting};
pub use subspace::n4sid;

#[cfg(test)]
use crate::data::IoData;

/// N4SID of the given `order` with the default settings, unwrapped: the
/// start the tests of this crate (N4SID, PEM, the workflow) compare with.
#[cfg(test)]
pub(crate) fn n4sid_of_order(data: &IoData, order: usize) -> N4sidResult {
    n4sid(
        data,
        &N4sidSettings {
            order: Some(order),
            ..Default::default()
        },
    )
    .unwrap()
}
