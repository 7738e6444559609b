//! Prediction-error identification of innovation-form models with a
//! Levenberg-Marquardt search on exact gradients.
//!
//! One file per part: the [`settings`] and the [`result`], the parameter
//! [`layout`], the data as [`series`], the [`residuals`] of a trial step,
//! their exact [`jacobian`] and the [`normal`] equations accumulated
//! from it, the [`criterion`] as residual weights, the
//! [`search`] (the problem handed to the one Levenberg-Marquardt loop,
//! [`crate::lm`]) and the N4SID [`start`] wrapper.

mod criterion;
mod jacobian;
mod layout;
mod limits;
mod normal;
mod residuals;
mod result;
mod search;
mod series;
mod settings;
mod start;
#[cfg(test)]
mod tests;

pub use limits::{MAX_PEM_FLOPS_PER_ITERATION, MAX_PEM_JACOBIAN_BYTES};
pub use result::{PemResult, StopReason};
pub use search::pem;
pub use settings::{Criterion, Focus, PemSettings};
pub use start::{Identified, pem_n4sid};
